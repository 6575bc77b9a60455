"""Fuzzing ``recon convert`` with corruptions of a fixture mesh: dropped, duplicated and flipped triangles,
jittered and NaN vertices, truncated files. Whatever comes in: never a traceback, an exit code in {0, 1, 2}, one
line for a refusal (2), the input unchanged, nothing left behind, and never exit 0 with a result that is not
good by recon's own report (exit 0 re-reads as a valid solid)."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pytest

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from cli_harness import FIXTURES, binary_stl, read_stl, run_in_process, step_is_valid_solid

BASE = "prism_coarse.stl"  # 276 triangles: a conversion takes about a second here

CORRUPTIONS = st.lists(
    st.one_of(
        st.tuples(st.just("drop"), st.floats(0.005, 0.3)),
        st.tuples(st.just("duplicate"), st.floats(0.005, 0.3)),
        st.tuples(st.just("flip"), st.floats(0.005, 0.5)),
        st.tuples(st.just("jitter"), st.floats(1e-6, 0.05)),
        st.tuples(st.just("nan"), st.floats(0.0, 1.0)),
        st.tuples(st.just("truncate"), st.floats(0.0, 1.0)),
    ),
    min_size=1,
    max_size=3,
)


def _corrupt(vertices, faces, corruptions, seed) -> bytes:
    rng = np.random.default_rng(seed)
    v, f = vertices.copy(), faces.copy()
    diag = float(np.linalg.norm(np.ptp(v, axis=0)))
    cut = None
    for kind, amount in corruptions:
        pick = rng.random(len(f)) < amount
        if kind == "drop" and (~pick).any():
            f = f[~pick]
        elif kind == "duplicate":
            f = np.concatenate([f, f[pick]])
        elif kind == "flip":
            f[pick] = f[pick][:, ::-1]
        elif kind == "jitter":
            v = v + rng.normal(scale=amount * diag, size=v.shape)
        elif kind == "nan":
            v[int(amount * (len(v) - 1))] = np.nan
        elif kind == "truncate":
            cut = amount
    data = binary_stl(v, f)
    return data if cut is None else data[: int(cut * len(data))]


def _good_by_report(report: dict) -> bool:
    """The report's own word on the result: its acceptance verdict."""
    return bool(report["verdict"]["ok"])


@pytest.fixture(scope="module")
def base():
    return read_stl(FIXTURES / BASE)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(corruptions=CORRUPTIONS, seed=st.integers(0, 2**16))
def test_corrupted_mesh_never_a_traceback_nor_a_false_success(base, scratch, corruptions, seed, capfd,
                                                              monkeypatch):
    with tempfile.TemporaryDirectory(dir=scratch) as root:
        work = Path(root) / "work"
        work.mkdir()
        (work / "in.stl").write_bytes(_corrupt(*base, corruptions, seed))
        run = run_in_process(["convert", "in.stl", "o.step", "--report", "r.json", "--jobs", "1"], work, capfd,
                             monkeypatch)
        event(f"exit {run.code}")  # (pytest --hypothesis-show-statistics: how many runs each code had)
        assert run.code in (0, 1, 2, 3), (run.code, run.stderr)  # 3: no result (README's exit codes)
        assert "Traceback" not in run.stderr and "internal error" not in run.stderr, run.stderr
        run.assert_inputs_unchanged()
        assert list(run.tmp.iterdir()) == []
        if run.code in (2, 3):
            assert len(run.lines) == 1 and run.new_files() == set(), run.stderr
            return
        assert run.new_files() == {"o.step", "r.json"}
        report = json.loads((work / "r.json").read_text())
        assert run.code == (0 if _good_by_report(report) else 1), run.stderr
        if run.code == 0:
            assert step_is_valid_solid(work / "o.step", shell=report["mesh"]["open"])
