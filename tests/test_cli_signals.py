"""SIGINT and SIGTERM sent to a real ``recon convert`` at several moments: exit 130 / 143, one line, no
traceback, nothing left behind (output folder, private TMPDIR), the input unchanged; and a SIGKILLed run's
temporary removed by the next run."""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest

from cli_harness import cli_command, cli_env, copy_fixture, digest, snapshot

MESH = "box_fillet_clean.stl"  # 5k triangles: a few seconds, long enough to be caught in each stage
SMALL = "prism_coarse.stl"  # the quickest to convert: for the tests that wait for the write

#: Seconds a run may take to end after the signal: the handler's grace (recon._cli._signals.GRACE) plus the
#: longest kernel call that holds the interpreter (an OpenCascade import or operation), on a loaded machine.
EXIT_WITHIN = 20.0

#: Run with this, the STEP writer pauses once its temporary file is complete (``RECON_TEST_SLOW_WRITE``).
SLOW_WRITE = """
import sys, time
import recon.brep._export as export
write = export._write_step
def slow(tmp, *args):
    write(tmp, *args)
    print("writing", flush=True)
    time.sleep(30)
export._write_step = slow
from recon.cli import main
sys.exit(main(sys.argv[1:]))
"""


#: Run with this, the decomposition stage says so on stdout and then runs for minutes (the real decomposition,
#: over and over): a moment inside a stage that does not depend on how fast the machine is.
LONG_DECOMPOSE = """
import sys
import recon.pipeline as pipeline
decompose = pipeline.decompose
def long(*args, **kwargs):
    print("decomposing", flush=True)
    for _ in range(10_000):
        out = decompose(*args, **kwargs)
    return out
pipeline.decompose = long
from recon.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _handlers_installed(pid: int, timeout: float = 60.0) -> None:
    """Wait until the process catches SIGTERM: recon's handlers are in (before that, Python is still starting)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with open(f"/proc/{pid}/status") as fh:
            caught = int(next(line for line in fh if line.startswith("SigCgt:")).split()[1], 16)
        if caught >> (signal.SIGTERM - 1) & 1:
            return
        time.sleep(0.005)
    raise AssertionError("recon never installed its signal handlers")


def _start(tmp_path, *extra, script=None, mesh=MESH):
    work, tmp = tmp_path / "work", tmp_path / "tmp"
    work.mkdir()
    tmp.mkdir()
    copy_fixture(mesh, work)
    cmd = cli_command("convert", mesh, "o.step", "--report", "r.json", *extra)
    if script is not None:
        cmd = [cmd[0], "-c", script, *cmd[3:]]
    before = snapshot(work)
    proc = subprocess.Popen(cmd, cwd=work, env=cli_env(tmp), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    return proc, work, tmp, before


def _check_interrupted(proc, sig, work, tmp, before):
    t0 = time.monotonic()
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=EXIT_WITHIN + 30)
    finally:
        proc.kill()
    took = time.monotonic() - t0
    name = signal.Signals(sig).name
    assert proc.returncode == 128 + sig, (proc.returncode, err)
    assert took < EXIT_WITHIN, took
    assert "Traceback" not in err and err.strip().splitlines() == [err.strip()], err
    assert err.strip().endswith(f"interrupted ({name})"), err
    assert snapshot(work) == before, set(snapshot(work)) ^ set(before)  # input unchanged, nothing new
    assert list(tmp.iterdir()) == []


def _linux():
    if not os.path.exists("/proc/self/status"):
        pytest.skip("needs /proc to see when the handlers are in")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("delay", [0.0, 0.2, 1.0], ids=["at-once", "0.2s", "1s"])
def test_interrupt_at_a_moment(tmp_path, sig, delay):
    """From the moment the handlers are in (Python's own start-up before it is not recon's to handle): at once
    (imports), 0.2 s (numpy, trimesh), 1 s (OpenCascade's import, loading). Inside a stage: the test below."""
    _linux()
    proc, work, tmp, before = _start(tmp_path)
    _handlers_installed(proc.pid)
    time.sleep(delay)
    if proc.poll() is not None:
        pytest.fail(f"the run ended before the signal: {proc.communicate()[1]}")
    _check_interrupted(proc, sig, work, tmp, before)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupt_inside_the_decomposition(tmp_path, sig):
    """In the middle of a stage's numerical work (a fixed delay missed it on a quiet machine, where the whole
    conversion ends within 3 s): the same clean exit."""
    _linux()
    proc, work, tmp, before = _start(tmp_path, script=LONG_DECOMPOSE)
    assert proc.stdout.readline().strip() == "decomposing"
    time.sleep(0.5)  # into the decomposition's own work, past the marker's print
    _check_interrupted(proc, sig, work, tmp, before)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupt_while_writing_leaves_no_temporary(tmp_path, sig):
    """The STEP file's temporary is complete and not yet renamed: the signal removes it, OUT is not made."""
    _linux()
    proc, work, tmp, before = _start(tmp_path, "--no-deviation", script=SLOW_WRITE, mesh=SMALL)
    assert proc.stdout.readline().strip() == "writing"
    assert any(p.name.startswith(".o.recon-") for p in work.iterdir())  # the temporary, caught in the act
    _check_interrupted(proc, sig, work, tmp, before)


def test_sigkill_leftover_is_removed_by_the_next_run(tmp_path):
    """SIGKILL cannot be handled: its temporary stays, named after the dead process, and the next run that
    writes into the folder removes it."""
    _linux()
    proc, work, tmp, before = _start(tmp_path, "--no-deviation", script=SLOW_WRITE, mesh=SMALL)
    assert proc.stdout.readline().strip() == "writing"
    proc.kill()
    proc.communicate()
    left = [p for p in work.iterdir() if p.name.startswith(".o.recon-")]
    assert len(left) == 1
    again = subprocess.run(cli_command("skeleton", str(work.parent.parent / "x.json"), "--json", "s.json"),
                           cwd=work, env=cli_env(tmp), capture_output=True, text=True, timeout=120)
    assert again.returncode == 2  # (a missing input: it still sweeps only when it writes)
    assert left[0].exists()
    star = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "fixtures", "shapes",
                        "star.json")
    again = subprocess.run(cli_command("skeleton", star, "--json", "s.json"), cwd=work, env=cli_env(tmp),
                           capture_output=True, text=True, timeout=120)
    assert again.returncode == 0, again.stderr
    assert not left[0].exists()
    assert digest(work / SMALL) == before[SMALL]


#: A library that swallows the interrupt (trimesh imports its optional modules under ``except BaseException``):
#: the run goes on, as it did before to exit 0.
SWALLOWING = """
import sys, time
import recon.pipeline as pipeline
convert = pipeline.convert
def swallowing(*args, **kwargs):
    print("converting", flush=True)
    try:
        time.sleep(30)
    except BaseException:
        pass
    return convert(*args, **kwargs)
pipeline.convert = swallowing
from recon.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_swallowed_interrupt_still_ends_the_run(tmp_path, sig):
    """The signal's exception is caught by someone else: the run still ends with 130/143, writes nothing."""
    _linux()
    proc, work, tmp, before = _start(tmp_path, "--no-deviation", script=SWALLOWING, mesh=SMALL)
    assert proc.stdout.readline().strip() == "converting"
    _check_interrupted(proc, sig, work, tmp, before)
