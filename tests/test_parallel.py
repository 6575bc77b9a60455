"""recon._parallel: the one process layer, under both start methods (fork on Linux, spawn elsewhere)."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from recon._parallel import Failure, FailureKind, Worker, isolated, shared_map

METHODS = ["fork", "spawn"]
REPO = Path(__file__).resolve().parents[1]


def _grid(n):
    return np.arange(n * 3, dtype=np.float64).reshape(n, 3) ** 0.5


def _aborts():
    import faulthandler

    faulthandler.disable()  # (pytest's crash dump of the child would read like a failure of the run)
    os.abort()


def _raises():
    raise ValueError("no such surface")


def _interrupted_then_done():
    os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C reaches the whole process group: a child must not turn it into a fault
    time.sleep(0.2)
    return "done"


def _square_not_in_child(parent, i):
    if os.getpid() != parent and i % 3 == 0:
        raise RuntimeError("not here")
    return i * i


class _Square:
    def __init__(self, parent):
        self.parent = parent

    def __call__(self, i):
        return _square_not_in_child(self.parent, i)


def _scaled(state, k):
    return state * k


def _exits(state, *args):
    os._exit(3)


def _fails(state, *args):
    raise MemoryError("no room")


@pytest.mark.parametrize("method", METHODS)
def test_a_value_comes_back_the_same_from_fork_and_spawn(method):
    got = isolated(_grid, 1000, timeout=60, method=method)
    np.testing.assert_array_equal(got, _grid(1000))


@pytest.mark.parametrize("method", METHODS)
def test_a_crash_is_a_typed_failure_with_its_signal(method):
    got = isolated(_aborts, timeout=60, method=method)
    assert isinstance(got, Failure) and not got
    assert got.kind is FailureKind.CRASHED and got.signal == signal.SIGABRT


@pytest.mark.parametrize("method", METHODS)
def test_a_child_past_its_time_is_killed_and_a_typed_failure(method):
    t = time.monotonic()
    got = isolated(time.sleep, 60, timeout=0.5 if method == "fork" else 10, method=method)
    assert isinstance(got, Failure) and got.kind is FailureKind.TIMED_OUT
    assert time.monotonic() - t < 30  # not the 60 s it sleeps


@pytest.mark.parametrize("method", METHODS)
def test_an_exception_is_a_typed_failure_with_its_type_and_message(method):
    got = isolated(_raises, timeout=60, method=method)
    assert got.kind is FailureKind.RAISED and got.error_type == "ValueError" and got.message == "no such surface"


@pytest.mark.parametrize("method", METHODS)
def test_a_child_ignores_ctrl_c(method):
    assert isolated(_interrupted_then_done, timeout=60, method=method) == "done"


def test_a_function_spawn_cannot_pickle_runs_here_with_the_same_result():
    offset = 5
    assert isolated(lambda x: x + offset, 2, timeout=60, method="spawn") == 7


@pytest.mark.parametrize("method", METHODS)
def test_shared_map_makes_what_the_second_process_failed_on_here(method):
    got = shared_map(_Square(os.getpid()), 40, grace=30, method=method)
    assert all(got[i] == i * i for i in got)
    assert all(i in got for i in range(40) if i % 3)  # only what the second process failed on is missing


def test_shared_map_under_spawn_without_a_picklable_function_leaves_all_to_the_caller():
    assert shared_map(lambda i: i, 10, grace=30, method="spawn") == {}


@pytest.mark.parametrize("method", METHODS)
def test_a_worker_answers_jobs_on_its_state_and_fails_typed(method):
    w = Worker(np.arange(4.0), {"scaled": _scaled, "exits": _exits, "fails": _fails}, method=method)
    try:
        assert w.submit("scaled", 2.0)
        np.testing.assert_array_equal(w.get(60), [0.0, 2.0, 4.0, 6.0])
        assert w.submit("fails")
        got = w.get(60)
        assert got.kind is FailureKind.RAISED and "MemoryError: no room" in got.message and not w.alive
        assert not w.submit("scaled", 1.0)  # stopped for good
    finally:
        w.close()
    w = Worker(1.0, {"exits": _exits}, method=method)
    try:
        assert w.submit("exits")
        assert w.get(60).kind is FailureKind.CRASHED and not w.alive
    finally:
        w.close()


def _gone(pid: int, within: float) -> bool:
    """Whether process ``pid`` ended (absent, or a zombie nobody reaped) within ``within`` seconds."""
    end = time.monotonic() + within
    while time.monotonic() < end:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return True
        if state in ("Z", "X"):
            return True
        time.sleep(0.05)
    return False


_HANGING_CHILD = """
import os, sys, time
from recon._parallel import isolated

def announce_and_hang():
    print(os.getpid(), flush=True)
    time.sleep(120)

if __name__ == "__main__":
    isolated(announce_and_hang, timeout=120, method=sys.argv[1])
"""


def _run_until_child(script: Path, args, env=None):
    proc = subprocess.Popen([sys.executable, str(script), *args], stdout=subprocess.PIPE, text=True, cwd=REPO,
                            env=env)
    line = proc.stdout.readline()
    assert line.strip().isdigit(), f"no child pid, exit {proc.poll()}"
    return proc, int(line)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc to see the child end")
@pytest.mark.parametrize("method", METHODS)
def test_a_child_does_not_outlive_a_killed_parent(method, tmp_path):
    script = tmp_path / "hang.py"
    script.write_text(_HANGING_CHILD)
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc, child = _run_until_child(script, [method], env)
    proc.kill()
    proc.wait()
    assert _gone(child, 10.0)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc to see the child end")
def test_ctrl_c_stops_the_parent_and_its_child(tmp_path):
    script = tmp_path / "hang.py"
    script.write_text(_HANGING_CHILD)
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc, child = _run_until_child(script, ["fork"], env)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=30) != 0  # KeyboardInterrupt, not swallowed by the child
    assert _gone(child, 10.0)


_FACE_BUILD_KILLED = """
import os, sys, time
sys.path.insert(0, {tests!r})
import numpy as np, trimesh
from test_brep import _axis_labels, _fits_by_label
from recon.brep import _filling
from recon.network import curve_network
from recon.brep import build_solid
from recon.fit import SurfaceFit

def announce_and_hang(*args):
    print(os.getpid(), flush=True)
    time.sleep(120)

_filling.filled_face = announce_and_hang
m = trimesh.creation.box(extents=(30, 20, 10)).subdivide_to_size(1.0)
v, f = np.asarray(m.vertices), np.asarray(m.faces)
lab = _axis_labels(m)
fits = _fits_by_label(v, f, lab, 0.01)
fits[4] = SurfaceFit("bspline", {{}}, {{"max": np.nan, "rms": np.nan, "p99": np.nan}}, 0, ok=False, reason="test")
build_solid(curve_network(v, f, lab), fits, tolerance=0.01)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc to see the child end")
def test_a_face_built_in_a_child_leaves_no_file_when_the_parent_is_killed(tmp_path):
    # issue 20: SIGKILL while a face was built in the child left $TMPDIR/recon_face_*.brep behind.
    private = tmp_path / "tmp"
    private.mkdir()
    script = tmp_path / "build.py"
    script.write_text(_FACE_BUILD_KILLED.format(tests=str(REPO / "tests")))
    env = dict(os.environ, PYTHONPATH=str(REPO), TMPDIR=str(private))
    proc, child = _run_until_child(script, [], env)
    assert list(private.iterdir()) == []  # nothing while the face is being built
    proc.kill()
    proc.wait()
    assert _gone(child, 10.0)
    assert list(private.iterdir()) == []


def _square_edges_and_bump():
    """The four edges of the unit square in z = 0 and 25 points of a bump z = 0.1 sin(πx) sin(πy) inside it."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeVertex
    from OCP.gp import gp_Pnt

    corners = [BRepBuilderAPI_MakeVertex(gp_Pnt(*p)).Vertex() for p in [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]]
    edges = [BRepBuilderAPI_MakeEdge(corners[i], corners[(i + 1) % 4]).Edge() for i in range(4)]
    x, y = np.meshgrid(np.linspace(0.1, 0.9, 5), np.linspace(0.1, 0.9, 5))
    pts = np.column_stack([x.ravel(), y.ravel(), 0.1 * np.sin(np.pi * x.ravel()) * np.sin(np.pi * y.ravel())])
    return edges, pts


def test_a_filling_face_built_under_spawn_is_the_one_built_under_fork():
    """The child's OCC inputs and its face cross the pipe as BREP text (recon.brep._serial): under spawn the edges
    go to the child that way too, and the face that comes back is byte for byte the one a forked child builds."""
    from recon.brep._filling import filled_face
    from recon.brep._result import face_area
    from recon.brep._serial import shape_bytes

    edges, pts = _square_edges_and_bump()
    here = filled_face(edges, pts)
    fork = isolated(filled_face, edges, pts, timeout=120, method="fork")
    spawn = isolated(filled_face, edges, pts, timeout=120, method="spawn")
    assert shape_bytes(fork) == shape_bytes(here) == shape_bytes(spawn)
    assert face_area(spawn) > 1.0  # the bump's area is over the square's


@pytest.mark.parametrize("method", METHODS)
def test_the_decomposition_with_a_second_process_is_the_same_under_fork_and_spawn(method, monkeypatch, caplog):
    from recon import _parallel
    from recon.decompose import _regions, decompose
    from recon.fixtures import load_fixture

    fx = load_fixture("plate_holes", "noisy20")
    monkeypatch.setattr(_regions, "PARALLEL_MIN_TRIANGLES", 0)  # the fixture is below the size it pays from
    one = decompose((fx.vertices, fx.faces), jobs=1)
    monkeypatch.setattr(_parallel, "start_method", lambda: method)
    started = []
    worker = _regions._Worker.start

    def start(cls, ctx):
        started.append(worker(ctx))
        return started[-1]

    monkeypatch.setattr(_regions._Worker, "start", classmethod(start))
    two = decompose((fx.vertices, fx.faces), jobs=2)
    assert len(started) == 1 and started[0] is not None  # a second process took part
    assert "second process stopped" not in caplog.text  # and answered every job
    assert np.array_equal(one.labels, two.labels)
