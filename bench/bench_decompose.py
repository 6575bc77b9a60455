"""Benchmark of the surface decomposition: ground truth on the fixtures (recon.fixtures) and the synthetic
rounded box, the real meshes in ../shared/meshes (skipped if absent), and time / peak memory against size.

    python bench/bench_decompose.py [--quick]

Prints the tables and writes them to bench/decompose.md; previews go to bench/out/.
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


LINES: list[str] = []


def say(line: str = "") -> None:
    print(line, flush=True)
    LINES.append(line)


def fixtures():
    from recon.fixtures import VARIANTS, list_fixtures, load_fixture

    have = set(list_fixtures())
    say("## Fixtures (recovered: true faces with IoU >= 0.5)")
    say()
    say("| part | variant | triangles | true faces | patch | junction | linear | terminal | recovered | mean IoU | s |")
    say("|---|---|---|---|---|---|---|---|---|---|---|")
    for part in sorted({p for p, _ in have}):
        for variant in VARIANTS:
            if (part, variant) not in have:
                continue
            fx = load_fixture(part, variant)
            t = time.perf_counter()
            d = decompose((fx.vertices, fx.faces))
            dt = time.perf_counter() - t
            r = face_recovery(d.labels, fx.labels, _areas(fx.vertices, fx.faces))
            c = d.counts()
            say(
                f"| {part} | {variant} | {len(fx.faces)} | {len(fx.true_faces)} | {c['patch']} | {c['junction']} | "
                f"{c['linear']} | {c['terminal']} | {100 * r.recovered:.0f} % | {r.mean_iou:.3f} | {dt:.2f} |"
            )
    say()


def synthetic():
    say("## Synthetic rounded box 40x30x20, 3 mm fillets (26 true faces); sigma in % of the diagonal (53.9)")
    say()
    for spacing, sigma in [(0.5, 0.0), (1.0, 0.0), (0.5, 0.027), (0.5, 0.108)]:
        V, F, L = rounded_box(spacing=spacing, sigma=sigma)
        t = time.perf_counter()
        d = decompose((V, F))
        dt = time.perf_counter() - t
        r = face_recovery(d.labels, L, _areas(V, F))
        say(
            f"- spacing {spacing} sigma {100 * sigma / 53.85:.2f}%: {len(F)} tris {dt:.2f} s {d.counts()} "
            f"recovered {r.recovered:.2f} mean IoU {r.mean_iou:.3f}"
        )
    say()


def real():
    from recon.mesh import load_mesh
    from recon.preview import render_parts

    OUT.mkdir(exist_ok=True)
    say("## Real meshes (peak MB: resident set of a fresh process running load + decompose)")
    say()
    say("| mesh | triangles | patch | junction | linear | terminal | s | peak MB |")
    say("|---|---|---|---|---|---|---|---|")
    for name in REAL:
        path = MESHES / name
        if not path.exists():
            say(f"| {name} | absent | | | | | | |")
            continue
        mesh = load_mesh(path)
        t = time.perf_counter()
        d = decompose(mesh)
        dt = time.perf_counter() - t
        code = (
            "import resource;from recon.mesh import load_mesh;from recon.decompose import decompose;"
            f"decompose(load_mesh({str(path)!r}));print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss//1024)"
        )
        peak = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip()
        render_parts(
            OUT / f"{path.stem}.png", mesh.vertices, mesh.faces, d.labels, [p.kind for p in d.parts],
            skeleton_vertices=d.skeleton.vertices, skeleton_edges=d.skeleton.edges, skeleton_faces=d.skeleton.faces,
            title=f"{name}: " + ", ".join(f"{v} {k}" for k, v in d.counts().items()),
        )
        c = d.counts()
        say(
            f"| {name} | {len(mesh.faces)} | {c['patch']} | {c['junction']} | {c['linear']} | {c['terminal']} | "
            f"{dt:.2f} | {peak} |"
        )
    say()


def scaling(sizes):
    """Each size in a fresh process so the peak RSS is that run's."""
    for spacing in sizes:
        code = (
            "import time,resource;from recon.decompose._synthetic import rounded_box;from recon.decompose import decompose;"
            f"V,F,L=rounded_box(size=(80,60,40),radius=6.0,spacing={spacing});t=time.perf_counter();d=decompose((V,F));"
            "print(len(F), round(time.perf_counter()-t,2), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss//1024, d.counts())"
        )
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        say("- triangles, seconds, peak MB, counts: " + (out.stdout.strip() or out.stderr.strip()[-300:]))


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="skip the 1M-triangle run")
    args = ap.parse_args()
    say("# Surface decomposition benchmark (python bench/bench_decompose.py)")
    say()
    fixtures()
    synthetic()
    real()
    say("## Scaling (rounded box 80x60x40, 6 mm fillets)")
    say()
    scaling([0.5, 0.25] if args.quick else [0.5, 0.25, 0.125])
    (HERE / "decompose.md").write_text("\n".join(LINES) + "\n")
