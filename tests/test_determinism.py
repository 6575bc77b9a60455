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



def test_build_decides_by_counts_not_by_the_clock():
    """The face strategies and the filling fallback read no clock: a budget in seconds let a loaded or slower machine
    fill fewer parts (crank: patch_23's second MakeFilling got the 0.2 s its first left of a shared 5 s)."""
    import recon.brep._build
    import recon.brep._filling
    import recon.brep._strategies

    for module in (recon.brep._build, recon.brep._filling, recon.brep._strategies):
        source = Path(module.__file__).read_text()
        assert not any(clock in source for clock in ("monotonic", "perf_counter", "time.time")), module.__name__


def test_filling_calls_are_counted_per_build(monkeypatch):
    """Each MakeFilling call takes one of the build's :data:`FILLING_ATTEMPTS`; none left, none is made."""
    import numpy as np

    from recon.brep import _filling

    calls = []

    def through(loops, edges, points, normals, context, *, precision, timeout):
        calls.append(len(points))
        return "face", 5.0, "filled", ""  # 5× the part's area: the second point set is wanted

    monkeypatch.setattr(_filling, "fallback_face_through", through)
    pts = np.zeros((48, 3))
    budget = _filling.FillingBudget(3)
    first = _filling.fallback_face([], [], pts, pts, None, precision=1e-3, expected_area=1.0, budget=budget)
    second = _filling.fallback_face([], [], pts, pts, None, precision=1e-3, expected_area=1.0, budget=budget)
    third = _filling.fallback_face([], [], pts, pts, None, precision=1e-3, expected_area=1.0, budget=budget)
    assert calls == [16, 48, 16] and budget.left == 0
    assert first[0] == second[0] == "face"
    assert third[0] is None and "MakeFilling calls are spent" in third[3]


def test_a_safety_time_limit_that_fires_fails_the_part(monkeypatch):
    """A child killed at its time limit (a hang, or a slow machine): the part fails, reported, instead of taking the
    next strategy's face, which a faster machine would not have taken; and the build's fillings stop."""
    import time
    from types import SimpleNamespace

    import numpy as np

    from recon._parallel import isolated
    from recon.brep import _strategies
    from recon.brep._filling import FillingBudget

    def hangs(job, message):
        isolated(time.sleep, 30, timeout=0.05, what="a hanging call")
        return _strategies._none("it hung")

    def would_build(job, message):
        return _strategies.Attempt("face", 1.0, _strategies.FaceStatus.OK, message)

    monkeypatch.setitem(_strategies.ORDERS, "own surface", (hangs, would_build))
    job = _strategies.FaceJob(
        part=0, name="patch_0", kind="patch", model=SimpleNamespace(kind="plane"), fit=None, fit_ok=True, near=False,
        loops=[np.array([1])],  # a bounded part (one with no loop is a whole sphere's or torus's, built apart)
        points=np.zeros((0, 3)), normals=np.zeros((0, 3)), vote=1, network=None, geo=None, edges=[], context=None,
        tolerance=0.01, expected_area=None, fill_budget=FillingBudget(72))
    warnings: list[str] = []
    rec = _strategies.build_face(job, warnings)
    assert rec.status == "failed" and rec.face is None and "time limit" in rec.message
    assert job.fill_budget.left == 0 and any("time limit" in w for w in warnings)
    monkeypatch.setitem(_strategies.ORDERS, "own surface", (would_build,))
    assert _strategies.build_face(job, []).face == "face"  # (without the hang, the same part gets its face)


def _blas_threads() -> list:
    from threadpoolctl import threadpool_info

    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})


def test_a_spawned_child_runs_blas_on_one_thread_as_its_parent(monkeypatch):
    """Under spawn (macOS, Windows) a child is a fresh interpreter: without its own pin its BLAS would take the
    machine's threads while the parent (``convert()``) takes one, and an item would round by who computed it."""
    from recon._parallel import isolated

    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")  # (what a fresh interpreter would take on this 2-core machine)
    assert isolated(_blas_threads, timeout=120, method="spawn") == [1]
    assert isolated(_blas_threads, timeout=120, method="fork") == _blas_threads()  # (forked: the parent's own)
