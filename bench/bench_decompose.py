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

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # run as a script: the repository root, for bench.synthetic

from bench.synthetic import rounded_box  # noqa: E402
from recon.decompose import decompose, face_recovery  # noqa: E402

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


#: Scaling cases: (label, Python expression giving (V, F)). The rounded box 80x60x40 with 6 mm fillets at grid
#: spacings 2 … 0.2 (10k … 1M triangles, exact geometry at every size), and crank.off midpoint-subdivided once
#: (a real mesh at 4x its triangles; generated here, never stored).
SCALING = [
    ("rounded box s=2.0", "rounded_box(size=(80,60,40),radius=6.0,spacing=2.0)[:2]"),
    ("rounded box s=1.0", "rounded_box(size=(80,60,40),radius=6.0,spacing=1.0)[:2]"),
    ("rounded box s=0.5", "rounded_box(size=(80,60,40),radius=6.0,spacing=0.5)[:2]"),
    ("rounded box s=0.25", "rounded_box(size=(80,60,40),radius=6.0,spacing=0.25)[:2]"),
    ("rounded box s=0.2", "rounded_box(size=(80,60,40),radius=6.0,spacing=0.2)[:2]"),
    ("crank.off", f"_mesh({str(MESHES / 'crank.off')!r})"),
    ("crank.off subdivided x4", f"subdivide(*_mesh({str(MESHES / 'crank.off')!r}))"),
]
#: The cases --quick leaves out (over 500k triangles).
LARGE = ("rounded box s=0.25", "rounded box s=0.2", "crank.off subdivided x4")


def subdivide(V, F):
    """One midpoint subdivision: every triangle into four (the surface unchanged, 4x the triangles)."""
    n = len(V)
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key = np.minimum(e[:, 0], e[:, 1]) * np.int64(n) + np.maximum(e[:, 0], e[:, 1])
    uniq, inv = np.unique(key, return_inverse=True)
    mid = n + inv.reshape(3, -1).T  # (m, 3): midpoints of edges 01, 12, 20
    V2 = np.vstack([V, 0.5 * (V[uniq // n] + V[uniq % n])])
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    m01, m12, m20 = mid[:, 0], mid[:, 1], mid[:, 2]
    F2 = np.concatenate([np.stack(t, axis=1) for t in ((a, m01, m20), (m01, b, m12), (m20, m12, c), (m01, m12, m20))])
    return V2, F2


def _mesh(path):
    from recon.mesh import load_mesh

    m = load_mesh(path)
    return m.vertices, m.faces


def scaling(quick: bool, repeat: int = 2):
    """Each case in a fresh process (peak RSS is that run's: mesh generation + decomposition); min of ``repeat``."""
    say(f"Time of `decompose` alone (min of {repeat} runs in one process; 1 run over 500k triangles), peak resident set")
    say("of that process (mesh generation included).")
    say()
    say("| case | triangles | s (min) | s per 100k | peak MB | patch | junction | linear | terminal |")
    say("|---|---|---|---|---|---|---|---|---|")
    for label, expr in SCALING:
        if quick and label in LARGE:
            continue
        if "crank" in label and not (MESHES / "crank.off").exists():
            continue
        code = (
            "import sys,time,resource;sys.path.insert(0,%r);from bench.bench_decompose import subdivide,_mesh;"
            "from bench.synthetic import rounded_box;from recon.decompose import decompose;"
            "V,F=%s;ts=[];"
            "exec('for _ in range(%d):\\n t=time.perf_counter();d=decompose((V,F));ts.append(time.perf_counter()-t)');"
            "c=d.counts();print(len(F),round(min(ts),2),resource.getrusage(resource.RUSAGE_SELF).ru_maxrss//1024,"
            "c['patch'],c['junction'],c['linear'],c['terminal'])"
        ) % (str(HERE.parent), expr, 1 if label in LARGE else repeat)
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        if out.returncode or not out.stdout.strip():
            say(f"| {label} | failed: {out.stderr.strip()[-200:]} | | | | | | | |")
            continue
        m, t, mb, *c = out.stdout.split()
        say(f"| {label} | {m} | {t} | {100000 * float(t) / int(m):.2f} | {mb} | " + " | ".join(c) + " |")
    say()


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="skip the scaling cases over 500k triangles")
    ap.add_argument("--scaling", action="store_true", help="only the scaling table (printed, decompose.md untouched)")
    args = ap.parse_args()
    if args.scaling:
        scaling(args.quick)
        sys.exit(0)
    say("# Surface decomposition benchmark (python bench/bench_decompose.py)")
    say()
    fixtures()
    synthetic()
    real()
    say("## Scaling with the triangle count")
    say()
    scaling(args.quick)
    (HERE / "decompose.md").write_text("\n".join(LINES) + "\n")
