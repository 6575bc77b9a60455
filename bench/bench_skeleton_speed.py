"""Speed of the 2D skeleton + decomposition (§2-3) on a shape with 10,000 boundary points, on one core.

Run: ``python bench/bench_skeleton_speed.py [--points 10000] [--repeat 15]``. Prints a Markdown table:
Qhull alone (``scipy.spatial.Delaunay`` on the same sites) and the whole ``skeletonize`` (resampling,
triangulation, inside test, §2 pruning, merging, §3 parts and polygons). Target: ≤ 100 ms at 10k points.
The machine is shared, so medians and minima of several runs are reported.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial import Delaunay  # noqa: E402

from recon.skeleton2d import Shape2D, _skeleton, skeletonize  # noqa: E402


def bench_shape() -> Shape2D:
    """A 7-pointed star with rounded tips' worth of curvature, plus three circular holes."""
    th = np.linspace(0, 2 * np.pi, 30000, endpoint=False)
    r = 1.0 + 0.35 * np.cos(7 * th) + 0.05 * np.cos(23 * th)
    outer = np.c_[r * np.cos(th), r * np.sin(th)]
    holes = []
    for i in range(3):
        a = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
        c = 0.3 * np.array([np.cos(2 * np.pi * i / 3), np.sin(2 * np.pi * i / 3)])
        holes.append(np.c_[c[0] + 0.12 * np.cos(a), c[1] - 0.12 * np.sin(a)])
    return Shape2D((outer, *holes))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args(argv)
    shape = bench_shape()
    perimeter = sum(np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1).sum() for c in shape.curves)
    spacing = perimeter / args.points

    # time the triangulations inside skeletonize too, so "the rest" comes from the same run (the load drifts)
    inner = []
    real_delaunay = _skeleton._delaunay

    def timed_delaunay(points):
        t0 = time.perf_counter()
        out = real_delaunay(points)
        inner.append(time.perf_counter() - t0)
        return out

    _skeleton._delaunay = timed_delaunay
    res = skeletonize(shape, spacing=spacing)  # warm up
    qhull, total, rest = [], [], []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        Delaunay(res.points)
        qhull.append(time.perf_counter() - t0)
        inner.clear()
        t0 = time.perf_counter()
        skeletonize(shape, spacing=spacing)
        total.append(time.perf_counter() - t0)
        rest.append(total[-1] - sum(inner))
    _skeleton._delaunay = real_delaunay

    kinds = {k: sum(p.kind == k for p in res.parts) for k in ("junction", "terminal", "linear")}
    print(f"shape: {len(shape.curves)} curves, {len(res.points)} boundary points "
          f"({res.extra['inserted_points']} inserted), {len(res.extra['triangles'])} triangles; "
          f"skeleton {len(res.skeleton.vertices)} vertices, {len(res.skeleton.edges)} edges; parts {kinds}; "
          f"{args.repeat} runs, one thread\n")
    print("| step | median ms | min ms |")
    print("|---|---:|---:|")
    for name, ts in [("Qhull Delaunay alone", qhull), ("skeletonize (skeleton + decomposition)", total),
                     ("skeletonize without its Qhull call (same runs)", rest)]:
        print(f"| {name} | {1e3 * np.median(ts):.1f} | {1e3 * np.min(ts):.1f} |")


if __name__ == "__main__":
    main()
