"""Guard for speed work on the decomposition: a hash of every result, recovery on the fixtures, CPU times.

    python bench/decompose_guard.py OUT.json [--real] [--large] [--only NAME ...]

Decomposes the 35 fixture variants (and with ``--real`` the real meshes in ../shared/meshes, with ``--large``
the 100k / 1M scaling meshes), and writes per mesh: a hash of ``labels`` and the part kinds, the kind counts,
recovered share and mean IoU (where there is a truth), and the CPU time (``time.process_time``) of
``decompose`` alone. Compare two runs with ``--compare A.json B.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

from recon.decompose import decompose, face_recovery

HERE = Path(__file__).resolve().parent
MESHES = HERE.parent.parent / "shared" / "meshes"
REAL = ["fandisk.off", "block.off", "rocker-arm2500.off", "joint.off", "casting.off", "rocker-arm.off", "crank.off"]
LARGE = HERE.parent / "fixtures" / "large" / "scaling"  # where bench.run caches the scaling meshes


def _areas(V, F):
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def _digest(d) -> str:
    h = hashlib.blake2b(digest_size=8)
    h.update(np.ascontiguousarray(d.labels, dtype=np.int64).tobytes())
    h.update(",".join(f"{p.kind}{int(p.sharp)}" for p in d.parts).encode())
    return h.hexdigest()


def _one(name, V, F, truth):
    t = time.process_time()
    d = decompose((V, F))
    cpu = time.process_time() - t
    row = {"name": name, "triangles": len(F), "cpu": round(cpu, 3), "hash": _digest(d), "counts": d.counts()}
    if truth is not None:
        r = face_recovery(d.labels, truth, _areas(V, F))
        row.update(recovered=round(float(r.recovered), 4), mean_iou=round(float(r.mean_iou), 4))
    print(json.dumps(row), flush=True)
    return row


def run(args):
    from recon.fixtures import list_fixtures, load_fixture
    from recon.mesh import load_mesh

    rows = []
    want = set(args.only or [])
    if not args.no_fixtures:
        for part, variant in list_fixtures():
            name = f"{part}_{variant}"
            if want and name not in want:
                continue
            fx = load_fixture(part, variant)
            rows.append(_one(name, fx.vertices, fx.faces, fx.labels))
    paths = []
    if args.real:
        paths += [MESHES / n for n in REAL]
    if args.large:
        paths += [LARGE / "box_fillet_100k.stl", LARGE / "box_fillet_1M.stl"]
    for p in paths:
        if want and p.name not in want:
            continue
        m = load_mesh(p)
        truth_p = p.with_suffix(".labels.npy")
        truth = np.load(truth_p) if truth_p.exists() else None
        rows.append(_one(p.name, np.asarray(m.vertices), np.asarray(m.faces), truth))
    Path(args.out).write_text(json.dumps(rows, indent=1))


def compare(a_path, b_path):
    a = {r["name"]: r for r in json.loads(Path(a_path).read_text())}
    b = {r["name"]: r for r in json.loads(Path(b_path).read_text())}
    ta = tb = 0.0
    for name in a:
        if name not in b:
            continue
        ra, rb = a[name], b[name]
        ta += ra["cpu"]
        tb += rb["cpu"]
        same = "identical" if ra["hash"] == rb["hash"] else "CHANGED"
        rec = ""
        if "recovered" in ra:
            rec = f" rec {ra['recovered']:.3f}->{rb['recovered']:.3f} iou {ra['mean_iou']:.3f}->{rb['mean_iou']:.3f}"
            if rb["recovered"] < ra["recovered"] or rb["mean_iou"] < ra["mean_iou"] - 1e-9:
                rec += "  WORSE"
        print(f"{name:28s} {ra['cpu']:7.2f} -> {rb['cpu']:7.2f} s  {same}{rec}")
    print(f"{'total':28s} {ta:7.2f} -> {tb:7.2f} s")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("out", nargs="?")
    ap.add_argument("--real", action="store_true")
    ap.add_argument("--large", action="store_true")
    ap.add_argument("--no-fixtures", action="store_true")
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--compare", nargs=2)
    a = ap.parse_args()
    if a.compare:
        compare(*a.compare)
    else:
        run(a)
        sys.exit(0)
