"""Benchmark of the surface decomposition: ground-truth IoU on the synthetic rounded box, the real meshes
in ../shared/meshes (skipped if absent), and time / peak memory against triangle count.

    python bench/bench_decompose.py [--quick]

Previews go to bench/out/.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from recon.decompose import decompose, face_recovery
from recon.decompose._synthetic import rounded_box

HERE = Path(__file__).resolve().parent
OUT = HERE / "out"
MESHES = HERE.parent.parent / "shared" / "meshes"
REAL = ["fandisk.off", "block.off", "casting.off", "joint.off", "rocker-arm.off", "crank.off", "abc_00000050.stl"]


def _areas(V, F):
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def synthetic():
    print("rounded box 40x30x20, 3 mm fillets (26 true faces); sigma in % of the diagonal (53.9)")
    for spacing, sigma in [(0.5, 0.0), (1.0, 0.0), (0.5, 0.027), (0.5, 0.108)]:
        V, F, L = rounded_box(spacing=spacing, sigma=sigma)
        t = time.perf_counter()
        d = decompose((V, F))
        dt = time.perf_counter() - t
        r = face_recovery(d.labels, L, _areas(V, F))
        print(
            f"  spacing {spacing} sigma {100 * sigma / 53.85:.2f}%: {len(F)} tris {dt:.2f} s {d.counts()} "
            f"recovered {r.recovered:.2f} mean IoU {r.mean_iou:.3f}"
        )


def real():
    from recon.mesh import load_mesh
    from recon.preview import render_parts

    OUT.mkdir(exist_ok=True)
    for name in REAL:
        path = MESHES / name
        if not path.exists():
            print(f"  {name}: absent, skipped")
            continue
        mesh = load_mesh(path)
        t = time.perf_counter()
        d = decompose(mesh)
        dt = time.perf_counter() - t
        render_parts(
            OUT / f"{path.stem}.png", mesh.vertices, mesh.faces, d.labels, [p.kind for p in d.parts],
            skeleton_vertices=d.skeleton.vertices, skeleton_edges=d.skeleton.edges, skeleton_faces=d.skeleton.faces,
            title=f"{name}: " + ", ".join(f"{v} {k}" for k, v in d.counts().items()),
        )
        print(f"  {name}: {len(mesh.faces)} tris {dt:.2f} s scale {d.scale:.4g} {d.counts()}")


def scaling(sizes):
    """Each size in a fresh process so the peak RSS is that run's."""
    for spacing in sizes:
        code = (
            "import time,resource;from recon.decompose._synthetic import rounded_box;from recon.decompose import decompose;"
            f"V,F,L=rounded_box(size=(80,60,40),radius=6.0,spacing={spacing});t=time.perf_counter();d=decompose((V,F));"
            "print(len(F), round(time.perf_counter()-t,2), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss//1024, d.counts())"
        )
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        print("  triangles, seconds, peak MB, counts:", out.stdout.strip() or out.stderr.strip()[-300:])


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="skip the 1M-triangle run")
    args = ap.parse_args()
    synthetic()
    print("real meshes")
    real()
    print("scaling (rounded box 80x60x40, 6 mm fillets)")
    scaling([0.5, 0.25] if args.quick else [0.5, 0.25, 0.125])
