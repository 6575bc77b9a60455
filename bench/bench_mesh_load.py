"""Benchmark: ``load_mesh`` (read + clean) on unwelded binary STL at ~100k and ~1M triangles.

The mesh is a torus grid of ``n × n`` quads (``2 n²`` triangles, genus 1) written as binary STL, so the
reader sees three vertices per triangle and welding has the most to do — the worst ordinary case.
A tenth of the triangles are flipped before writing, so orientation has work too. Each size runs in a
fresh subprocess so the peak memory (``ru_maxrss``, whole process, includes Python + numpy + trimesh)
and the tracemalloc peak (numpy buffers allocated during the call) belong to that size alone.

Run from the repository root::

    python bench/bench_mesh_load.py            # both sizes, best of 3
    python bench/bench_mesh_load.py --repeat 1

The machine is shared: treat timings as ±20 %.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

SIZES = {"100k": 224, "1M": 707}  # 2 n^2 triangles: 100,352 and 999,698


def torus(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n, endpoint=False), np.linspace(0, 2 * np.pi, n, endpoint=False))
    x = (2 + np.cos(v)) * np.cos(u)
    y = (2 + np.cos(v)) * np.sin(u)
    z = np.sin(v)
    verts = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    a = j * n + i
    b = j * n + (i + 1) % n
    c = ((j + 1) % n) * n + (i + 1) % n
    d = ((j + 1) % n) * n + i
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    faces = faces[rng.permutation(len(faces))]
    flip = rng.random(len(faces)) < 0.1
    faces[flip] = faces[flip][:, ::-1]
    return verts, faces


def run_case(n: int, repeat: int) -> dict:
    import trimesh

    from recon import load_mesh

    rng = np.random.default_rng(0)
    verts, faces = torus(n, rng)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "torus.stl"
        trimesh.Trimesh(verts, faces, process=False).export(path)
        times = []
        for _ in range(repeat):
            t = time.perf_counter()
            mesh = load_mesh(path)
            times.append(time.perf_counter() - t)
        tracemalloc.start()
        load_mesh(path)
        _, traced_peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    r = mesh.report
    return {
        "triangles": int(len(faces)),
        "input_vertices": r.n_input_vertices,
        "vertices": int(len(mesh.vertices)),
        "flipped": r.flipped_faces,
        "closed": r.closed,
        "euler": int(len(mesh.vertices) - len(mesh.edges_unique) + len(mesh.faces)),
        "best_s": min(times),
        "traced_peak_mb": traced_peak / 2**20,
        "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--case", choices=list(SIZES), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        print(json.dumps(run_case(SIZES[args.case], args.repeat)))
        return
    print(f"{'size':>5} {'triangles':>10} {'STL verts':>10} {'welded to':>10} {'flipped':>8} {'euler':>5} "
          f"{'best s':>7} {'traced MB':>9} {'maxrss MB':>9}")
    for name in SIZES:
        out = subprocess.run([sys.executable, __file__, "--case", name, "--repeat", str(args.repeat)],
                             check=True, capture_output=True, text=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        print(f"{name:>5} {r['triangles']:>10,} {r['input_vertices']:>10,} {r['vertices']:>10,} {r['flipped']:>8,} "
              f"{r['euler']:>5} {r['best_s']:>7.2f} {r['traced_peak_mb']:>9.0f} {r['maxrss_mb']:>9.0f}")


if __name__ == "__main__":
    main()
