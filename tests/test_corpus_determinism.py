"""The corpus generator makes the same mesh, bit for bit, whatever the machine and the process (issue 22).

Each configuration runs in its own process: another string-hash salt, another thread count, another OpenBLAS kernel
(``OPENBLAS_CORETYPE``: what a machine with other CPU features gets; the remesher's lengths once came from BLAS, and
an AVX-512 machine's meshes had other triangle counts than an AVX2 machine's, bench/scan.md "s40-det").
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: a revolved part (planes, cones, a cylinder) whose scan10 mesh (~40k triangles) is remeshed at ~600 triangles in about
#: a second; with the remesher's lengths from BLAS, three OpenBLAS kernels gave it three different meshes
SEED = 7

_CODE = f"""
import hashlib, json
import numpy as np
from bench.corpus.parts import part
from bench.corpus.regimes import tessellate

def digest(*arrays):
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()

solid, _ = part({SEED})
out = {{}}
for regime in ("export", "scan10"):
    v, t, lab = tessellate(solid, regime, {SEED})
    out[regime] = [len(t), digest(v), digest(t), digest(lab)]
print(json.dumps(out))
"""

#: two processes that differ in everything a machine or a run may change and the generator must not depend on
_CONFIGS = (
    {"PYTHONHASHSEED": "0", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "OPENBLAS_CORETYPE": "Haswell"},
    {"PYTHONHASHSEED": "4242", "OMP_NUM_THREADS": "2", "OPENBLAS_NUM_THREADS": "2", "OPENBLAS_CORETYPE": "Prescott"},
)


def _start(config: dict) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OPENBLAS", "OMP_", "PYTHONHASHSEED"))}
    env.update(config, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-c", _CODE], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _result(proc: subprocess.Popen) -> dict:
    out, err = proc.communicate()
    assert proc.returncode == 0, err[-2000:]
    return json.loads(out.strip().splitlines()[-1])


def test_scan_and_export_meshes_are_bit_identical_across_processes_and_blas_kernels():
    procs = [_start(c) for c in _CONFIGS]  # side by side: one per core
    first, second = (_result(p) for p in procs)
    assert first["scan10"][0] > 30_000 and first["export"][0] > 100  # the regimes' meshes, not empty ones
    assert first == second
