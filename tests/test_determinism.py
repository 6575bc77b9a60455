"""The same result on every machine (issue 25): ``recon convert`` run as on two different machines gives the same
faces, types, validity, volume and STEP geometry.

"Another machine" is emulated in a subprocess: another OpenBLAS kernel family (``OPENBLAS_CORETYPE``: an EPYC runs
Haswell's kernels where a Xeon runs SkylakeX's), numpy without its AVX-512 loops (``NPY_DISABLE_CPU_FEATURES``: an
EPYC before Zen 4 has none), two BLAS threads, and ``--jobs`` 1 vs 2. Before the CLI pinned its arithmetic, these
gave box_fillet/noisy20 other fits and other STEP geometry (bench/determinism.md).
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from recon.fixtures import FIXTURE_DIR

ROOT = Path(__file__).resolve().parent.parent

#: A fixture whose fits are nonlinear least squares on noisy points (cylinders, spheres, a cone, B-splines): where
#: the last bits of BLAS and of numpy's exp/arctan2 reach the fitted parameters. ~4 s a run.
MESH = FIXTURE_DIR / "box_fillet_noisy20.stl"

#: Two machines, as far as the arithmetic sees them: this CPU's own kernels with one BLAS thread and one process,
#: against another x86-64 kernel family, no AVX-512 loops, two BLAS threads and two processes.
MACHINES = {
    "native": ({"OPENBLAS_CORETYPE": None, "NPY_DISABLE_CPU_FEATURES": None, "OPENBLAS_NUM_THREADS": "1"}, 1),
    "other": ({"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
               "OPENBLAS_NUM_THREADS": "2"}, 2),
}

pytestmark = pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64") or not MESH.exists(),
                                reason="the kernel families emulated are x86-64's; needs the committed fixture")


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    line = next((ln for ln in text.splitlines() if ln.startswith("flags")), "")
    return set(line.split(":", 1)[-1].split())


def convert_as(machine: str, mesh: Path, out: Path) -> tuple[dict, str]:
    """``recon convert`` of ``mesh`` in a subprocess as on ``machine`` (:data:`MACHINES`): its report and the STEP
    file's DATA section (the header holds the time of writing)."""
    overrides, jobs = MACHINES[machine]
    env = {k: v for k, v in os.environ.items() if k not in overrides}
    env.update({k: v for k, v in overrides.items() if v is not None})
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    out.mkdir(parents=True, exist_ok=True)
    step, report = out / "part.step", out / "part.json"  # (the same name: the product in the STEP file is named so)
    cmd = [sys.executable, "-m", "recon", "convert", str(mesh), str(step), "--report", str(report), "--no-deviation",
           "--jobs", str(jobs), "-q"]
    got = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert got.returncode in (0, 1), got.stderr[-2000:]
    text = step.read_text()
    return json.loads(report.read_text()), text[text.index("\nDATA;"):]


def summary(report: dict) -> dict:
    """What a user compares between two runs: faces, their types and statuses, validity."""
    validity = {k: v for k, v in report["validity"].items() if k != "volume"}
    faces = [(f["name"], f["surface"], f["status"], f["built"]) for f in report["faces"]]
    return {"n_faces": report["n_faces"], "by_type": report["faces_by_type"], "validity": validity, "faces": faces}


def first_difference(a: str, b: str) -> str:
    """The first differing line of two STEP DATA sections, for the failure message."""
    for x, y in zip(a.splitlines(), b.splitlines()):
        if x != y:
            return f"{x!r} vs {y!r}"
    return f"{len(a.splitlines())} vs {len(b.splitlines())} lines"


def test_same_result_as_on_another_machine(tmp_path):
    if "avx2" not in _cpu_flags():
        pytest.skip("Haswell's kernels need AVX2")
    with ThreadPoolExecutor(2) as pool:  # (two subprocesses at once: the test takes one run's time on two cores)
        runs = dict(zip(MACHINES, pool.map(lambda m: convert_as(m, MESH, tmp_path / m), MACHINES)))
    (a, step_a), (b, step_b) = runs["native"], runs["other"]
    assert summary(a) == summary(b)
    va, vb = a["validity"]["volume"], b["validity"]["volume"]
    assert va == pytest.approx(vb, rel=1e-12)  # (the STEP text below is the stricter test: 12 digits each number)
    assert step_a == step_b, f"STEP geometry differs: first {first_difference(step_a, step_b)}"

