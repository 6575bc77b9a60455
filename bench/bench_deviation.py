"""Speed of ``recon compare``'s deviation analysis at 10k, 100k and 1M mesh points.

The part is a 40 × 30 × 20 box with every edge filleted (r = 3) and a Ø10 through hole: planes,
cylinders and spheres, 27 faces. The mesh is its OpenCascade triangulation, subdivided until it has
at least N vertices, with Gaussian noise σ = 0.02 on the vertices (the deviation is not zero, so every
point takes the full path). A B-spline surface patch is timed separately: its points are projected
one by one with OCP (``ShapeAnalysis_Surface.NextValueOfUV``), the analytic faces in numpy.

Columns: ``prepare`` (tessellate + index the B-rep), ``mesh→shape`` (exact signed distances of
exactly N noisy points on the part), then on the subdivided mesh nearest N vertices: ``deviation()`` (both directions + per-face report, 20k B-rep samples for the way back),
``preview`` (PNG), in seconds, best of ``--repeat`` runs.

    python bench/bench_deviation.py            # 10k, 100k, 1M
    python bench/bench_deviation.py 10000 --repeat 1
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh


def best_of(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def part():
    import build123d as bd

    return bd.fillet(bd.Box(40, 30, 20).edges(), 3) - bd.Cylinder(5, 30)


def noisy_mesh(shape, n, sigma, rng):
    """The triangulation subdivided to the vertex count nearest ``n`` (a factor ~4 per step)."""
    verts, tris = shape.tessellate(0.05)
    mesh = trimesh.Trimesh(np.array([(p.X, p.Y, p.Z) for p in verts]), np.array(tris), process=True)
    while abs(np.log(len(mesh.vertices) * 4 / n)) < abs(np.log(len(mesh.vertices) / n)):
        mesh = mesh.subdivide()
    v = mesh.vertices + rng.normal(scale=sigma, size=mesh.vertices.shape)
    return v, np.asarray(mesh.faces)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sizes", nargs="*", type=int, default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()

    import build123d as bd

    from recon.brep._distance import BrepDistance
    from recon.deviation import deviation, plot_deviation

    shape = part()
    rng = np.random.default_rng(0)
    print(f"part: {len(shape.faces())} faces; noise σ = 0.02")
    print(f"{'points':>9} {'prepare':>8} {'mesh→shape':>11} {'µs/pt':>6} | {'mesh verts':>10} {'triangles':>10} "
          f"{'deviation()':>12} {'preview':>8} {'max |d|':>8} {'rms':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            v, f = noisy_mesh(shape, n, 0.02, rng)
            t_prep, brep = best_of(lambda: BrepDistance(shape.wrapped), args.repeat)
            # Exactly n points for the mesh → shape column: noisy area-uniform points on the part.
            pts, _ = brep.surface_samples(n)
            pts = pts[rng.permutation(len(pts))[:n]] + rng.normal(scale=0.02, size=(min(n, len(pts)), 3))
            t_m2s, _ = best_of(lambda: brep.signed_distance(pts), args.repeat)
            t_dev, rep = best_of(lambda: deviation(v, f, shape), args.repeat)
            t_png, _ = best_of(lambda: plot_deviation(v, f, rep.signed, Path(tmp) / "p.png"), 1)
            m = rep.mesh_to_shape
            print(f"{len(pts):>9} {t_prep:>8.2f} {t_m2s:>11.2f} {1e6 * t_m2s / len(pts):>6.1f} | {len(v):>10} "
                  f"{len(f):>10} {t_dev:>12.2f} {t_png:>8.2f} {m.max:>8.4f} {m.rms:>8.4f}")

    # A B-spline patch: per-point OCP projection.
    grid = [[(x, y, 2 * np.sin(x / 5) * np.cos(y / 7)) for x in np.linspace(0, 20, 6)] for y in np.linspace(0, 20, 6)]
    face = bd.Face.make_surface_from_array_of_points(grid)
    brep = BrepDistance(face.wrapped)
    for n in (10_000, 100_000):
        pts, _ = brep.surface_samples(n)
        p = pts + rng.normal(scale=0.02, size=pts.shape)
        t, _ = best_of(lambda: brep.signed_distance(p), 1)
        print(f"B-spline patch, {len(p)} points: mesh→shape {t:.2f} s ({1e6 * t / len(p):.1f} µs/pt)")


if __name__ == "__main__":
    main()
