"""Benchmark: fit_surface on ~100 patches totalling 100k points (a mix of types). Target ≤ 2 s in all.

Run: ``python bench/bench_fit.py [--no-normals] [--repeat 3]``. Patches are seeded 90°-ish sectors with
σ = 0.02 mm noise on ~20 mm parts, each in a random pose; free-form patches are z = sin x cos y height fields.
Prints the total wall time (best of the repeats), per-type time and how many types were picked right.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

# run as a script (python bench/bench_fit.py): the repository root on the path, for bench.synthetic
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from recon.fit import fit_surface  # noqa: E402
from bench.synthetic import (  # noqa: E402
    add_noise,
    random_rotation,
    sample_cone,
    sample_cylinder,
    sample_plane,
    sample_sphere,
    sample_torus,
)

SIGMA = 0.02
MIX = {"plane": 30, "cylinder": 20, "sphere": 15, "cone": 15, "torus": 15, "bspline": 5}
SAMPLERS = {
    "plane": lambda n, rng: sample_plane(n, rng, size=rng.uniform(10, 30)),
    "cylinder": lambda n, rng: sample_cylinder(n, rng, radius=rng.uniform(3, 15)),
    "sphere": lambda n, rng: sample_sphere(n, rng, radius=rng.uniform(5, 15)),
    "cone": lambda n, rng: sample_cone(n, rng, half_angle=np.deg2rad(rng.uniform(15, 60))),
    "torus": lambda n, rng: sample_torus(n, rng, major=rng.uniform(8, 15), minor=rng.uniform(1, 4)),
}


def _freeform(n, rng):
    xy = rng.uniform(-3, 3, size=(n, 2))
    pts = np.column_stack([xy, np.sin(xy[:, 0]) * np.cos(xy[:, 1])])
    return pts, None


def patches(seed: int = 0, total: int = 100_000):
    rng = np.random.default_rng(seed)
    kinds = [k for k, c in MIX.items() for _ in range(c)]
    sizes = rng.dirichlet(np.full(len(kinds), 4.0)) * total
    out = []
    for kind, n in zip(kinds, sizes.astype(int)):
        n = max(n, 200)
        pts, nrm = _freeform(n, rng) if kind == "bspline" else SAMPLERS[kind](n, rng)
        rot = random_rotation(rng)
        shift = rng.uniform(-50, 50, 3)
        pts = add_noise(pts @ rot.T + shift, SIGMA, rng)
        out.append((kind, pts, None if nrm is None else nrm @ rot.T))
    return out


def run(data, *, use_normals: bool):
    per_type = defaultdict(float)
    right = 0
    t_all = time.perf_counter()
    cpu = time.process_time()
    for kind, pts, nrm in data:
        t = time.perf_counter()
        fit = fit_surface(pts, nrm if use_normals else None, tolerance=4 * SIGMA)
        per_type[kind] += time.perf_counter() - t
        right += fit.type == kind and bool(fit)
    return time.perf_counter() - t_all, time.process_time() - cpu, per_type, right


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-normals", action="store_true", help="estimate normals (k-NN PCA) instead of passing them")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    data = patches()
    n_pts = sum(len(p) for _, p, _ in data)
    best = None
    for _ in range(args.repeat):
        result = run(data, use_normals=not args.no_normals)
        if best is None or result[0] < best[0]:
            best = result
    total, cpu, per_type, right = best
    print(f"{len(data)} patches, {n_pts} points, normals {'estimated' if args.no_normals else 'given'}")
    # CPU time too: the machine is shared, and wall time under load overstates the cost
    print(f"total {total:.2f} s wall, {cpu:.2f} s CPU (best of {args.repeat}); types right: {right}/{len(data)}")
    for kind, t in per_type.items():
        print(f"  {kind:9s} {MIX[kind]:3d} patches  {t:.3f} s")


if __name__ == "__main__":
    main()
