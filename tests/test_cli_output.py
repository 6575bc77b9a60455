"""What the command line prints, and where: the result's summary on stdout (``> summary.txt`` keeps it),
warnings, progress and errors on stderr, ``-q`` errors only; lengths with their unit."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import pytest

from cli_harness import FIXTURES, cli_command, cli_env
from test_export import occ_prints_warnings  # noqa: F401  (a fixture)

SMALL = "prism_coarse.stl"  # 264 triangles: the quickest fixture that converts
SUMMARY_HEADS = ("result: ", "faces: ", "solid: ", "deviation mesh→shape: ", "deviation shape→mesh: ", "time: ")


def _run(work, *args, timeout=300, interval=3600):
    """The CLI in a subprocess, stdout and stderr pipes (not terminals); progress lines every ``interval`` s."""
    tmp = work / "tmp"
    tmp.mkdir(exist_ok=True)
    env = {**cli_env(tmp), "RECON_PROGRESS_INTERVAL": str(interval)}
    return subprocess.run(cli_command(*args), cwd=work, env=env, capture_output=True, text=True, timeout=timeout)


@pytest.fixture()
def work(tmp_path):
    shutil.copyfile(FIXTURES / SMALL, tmp_path / "part.stl")
    shutil.copyfile(FIXTURES / "prism.step", tmp_path / "shape.step")
    return tmp_path


def test_convert_summary_on_stdout_nothing_on_stderr(work):
    """Piped (no terminal): the summary lines, in order, and "wrote" on stdout; stderr holds none of them (a clean
    fixture has no warning, and off a terminal a run shorter than the progress interval prints no progress: the
    interval is an hour here, so that a loaded machine cannot make the run longer than it)."""
    proc = _run(work, "convert", "part.stl", "out.step")
    assert proc.returncode == 0, proc.stderr
    heads = [next(h for h in SUMMARY_HEADS if ln.startswith(h)) for ln in proc.stdout.splitlines()
             if ln.startswith(SUMMARY_HEADS)]
    assert heads == list(SUMMARY_HEADS), proc.stdout
    assert proc.stdout.splitlines()[-1] == "wrote out.step"
    assert proc.stderr == "", proc.stderr


def test_quiet_prints_nothing_and_errors_stay_one_line_on_stderr(work):
    proc = _run(work, "convert", "part.stl", "out.step", "-q")
    assert (proc.returncode, proc.stdout, proc.stderr) == (0, "", "")
    assert (work / "out.step").is_file()  # -q silences the summary, not the work
    proc = _run(work, "convert", "missing.stl", "out2.step")
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("recon convert: error: "), proc.stderr
    proc = _run(work, "-q", "convert", "missing.stl", "out2.step")  # -q keeps the error line
    assert proc.returncode == 2 and proc.stdout == "" and proc.stderr.count("\n") == 1


def test_compare_summary_on_stdout(work):
    proc = _run(work, "compare", "part.stl", "shape.step", "--json", "r.json", "--samples", "500")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert [ln.split(":")[0] for ln in lines] == ["deviation mesh→shape", "deviation shape→mesh", "wrote r.json"]
    assert proc.stderr == ""
    proc = _run(work, "compare", "part.stl", "shape.step", "--json", "r.json", "-q")
    assert (proc.returncode, proc.stdout, proc.stderr) == (0, "", "")


def test_help_says_where_the_output_goes(capsys):
    from recon.cli import main

    with pytest.raises(SystemExit):
        main(["convert", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "summary on stdout" in out and "errors only" in out and "exit codes: 0" in out


def test_figures_keep_their_size_and_unit():
    """A tiny deviation (an exact CAD export's round-off) shows its size, never "0.000"; lengths carry the unit."""
    from recon._cli._format import deviation_line, length, number, percent

    assert length(1.04e-6) == "1.0e-06 mm" and percent(1.34e-6) == "1.3e-06 %"
    assert length(0.012345) == "0.01235 mm" and percent(0.0617) == "0.0617 %" and length(25.4, "in") == "25.4 in"
    assert number(0.0) == "0" and number(float("nan")) == "n/a" and length(None) == "n/a"
    stats = {"max": 1e-6, "p95": 5e-7, "rms": 2e-7, "max_pct": 1.3e-6, "p95_pct": 6.5e-7, "rms_pct": 2.6e-7}
    line = deviation_line("mesh→shape", stats, 77.0)
    assert line == ("deviation mesh→shape: max 1.0e-06 mm (1.3e-06 % of diagonal), p95 5.0e-07 mm (6.5e-07 % of "
                    "diagonal), rms 2.0e-07 mm (2.6e-07 % of diagonal); diagonal 77 mm")


def test_printed_deviations_have_units_and_no_zero_percent(work):
    proc = _run(work, "convert", "part.stl", "out.step")
    dev = [ln for ln in proc.stdout.splitlines() if ln.startswith("deviation ")]
    assert len(dev) == 2, proc.stdout
    for line in dev:
        assert line.count(" mm (") == 3 and line.count(" % of diagonal)") == 3, line
        assert "0.000" not in line, line
    assert re.search(r"\(tolerance [0-9.e+-]+ mm\)", proc.stdout.splitlines()[0]), proc.stdout


PROGRESS = re.compile(r"^recon: (fit|brep|deviation): (parts fitted|refinement passes|faces built|samples measured|mesh points measured|far samples' triangles measured) "
                      r"([0-9,]+)/([0-9,]+) \(\d+ %\)(, (about \d+ (s|min)|under 1 s) left)?$")


def test_progress_lines_off_a_terminal_count_the_items(work):
    """stderr a pipe, the interval 0 (a stand-in for a run longer than 5 s: every count is printed): plain lines with
    the parts fitted, the faces built and the B-rep's samples measured, counting up to below their totals; the
    faces' total is the number of parts, the samples' at least the 20,000 area-uniform ones. stdout holds the summary
    alone."""
    shutil.copyfile(FIXTURES / "box_fillet_coarse.stl", work / "fillet.stl")  # through the fit stage (no exact path)
    proc = _run(work, "convert", "fillet.stl", "out.step", "--report", "r.json", interval=0)
    assert proc.returncode in (0, 1), proc.stderr
    counts: dict = {}
    for line in proc.stderr.splitlines():
        m = PROGRESS.match(line)
        assert m, line  # nothing else on stderr: no warning is logged that the summary repeats
        done, total = int(m[3].replace(",", "")), int(m[4].replace(",", ""))
        assert 0 < done < total, line
        counts.setdefault((m[1], m[2]), []).append((done, total))
    assert {"fit", "brep", "deviation"} == {stage for stage, _ in counts}
    assert ("fit", "parts fitted") in counts and ("fit", "refinement passes") in counts
    report = json.loads((work / "r.json").read_text())
    for seq in counts.values():
        assert len({t for _, t in seq}) == 1 and [d for d, _ in seq] == sorted({d for d, _ in seq}), seq
    assert counts[("brep", "faces built")] == [(k, len(report["faces"])) for k in range(1, len(report["faces"]))]
    assert counts[("deviation", "samples measured")][0][1] >= 20_000  # DEFAULT_SAMPLES, and the tessellation's nodes
    assert not any(PROGRESS.match(ln) for ln in proc.stdout.splitlines())
    assert proc.stdout.splitlines()[-1] == "wrote out.step"


class _Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_plain_progress_waits_for_the_interval_and_a_terminal_redraws_one_line():
    import io

    from recon._progress import Count, StageProgress

    clock, out = _Clock(), io.StringIO()
    shown = StageProgress(out, tty=False, interval=5.0, clock=clock)
    shown("fit", 0.0)
    for k, t in enumerate([1.0, 4.9, 5.1, 7.0, 10.0, 10.2], 1):  # seconds since the run began
        clock.t = 100.0 + t
        shown("fit", Count(k, 10, "parts fitted"))
    shown("fit", 1.0)
    # none before 5 s (a shorter run prints nothing), then at most one per 5 s
    assert out.getvalue().splitlines() == ["recon: fit: parts fitted 3/10 (30 %), about 12 s left",
                                           "recon: fit: parts fitted 6/10 (60 %), about 7 s left"]
    clock.t, tty = 0.0, io.StringIO()
    shown = StageProgress(tty, tty=True, clock=clock)
    shown("brep", 0.0)
    clock.t = 1.0
    shown("brep", Count(1, 4, "faces built"))
    clock.t = 1.05  # within a tenth of a second of the last redraw: not drawn
    shown("brep", Count(2, 4, "faces built"))
    clock.t = 2.0
    shown("brep", 1.0)
    assert tty.getvalue() == ("\r\x1b[K  brep       …" "\r\x1b[K  brep       faces built 1/4 (25 %), about 3 s left"
                              "\r\x1b[K  brep         2.00 s\n")
    assert Count(1, 4, "x") == 0.25 and isinstance(Count(1, 4, "x"), float)  # a plain callback reads a fraction


def test_occ_warnings_stay_out_of_the_summary_and_stderr(work, capfd, monkeypatch, occ_prints_warnings):
    """An OpenCascade warning during the B-rep stage (a filling's broken wire, see test_export) is neither in the
    summary on stdout nor on stderr: it goes to the debug log."""
    import recon.brep
    from recon.cli import main
    from test_export import WIRE_WARNING, _filling_of_a_broken_wire

    real, calls = recon.brep.build_solid, []

    def noisy(*args, **kwargs):
        calls.append(_filling_of_a_broken_wire())
        return real(*args, **kwargs)

    monkeypatch.setattr(recon.brep, "build_solid", noisy)
    monkeypatch.chdir(work)
    capfd.readouterr()
    assert main(["convert", "part.stl", "out.step"]) == 0 and calls == [True]
    captured = capfd.readouterr()
    assert WIRE_WARNING not in captured.out + captured.err
    assert captured.out.startswith("result: within tolerance") and captured.err == "", captured


def test_units_inch_declared_in_the_step_and_the_summary(work):
    """--units inch: the summary's lengths in inches, and the STEP read back by OpenCascade in mm is 25.4 times
    larger (volume × 25.4³) than the report's volume, which is in the mesh's numbers."""
    from recon.brep._result import shape_validity
    from recon.brep._step_read import read_step

    proc = _run(work, "convert", "part.stl", "out.step", "--units", "inch", "--report", "r.json")
    assert proc.returncode == 0, proc.stderr
    report = json.loads((work / "r.json").read_text())
    assert re.search(r"\(tolerance [0-9.e+-]+ in\)", proc.stdout) and " in³)" in proc.stdout, proc.stdout
    assert all(line.count(" in (") == 3 for line in proc.stdout.splitlines() if line.startswith("deviation "))
    shape, _ = read_step(work / "out.step")
    assert shape_validity(shape).volume == pytest.approx(report["validity"]["volume"] * 25.4 ** 3, rel=1e-9)
    # compare --units inch reads the file in the mesh's unit: the deviation convert reported, lengths in inches
    proc = _run(work, "compare", "part.stl", "out.step", "--units", "inch", "--json", "c.json")
    assert proc.returncode == 0, proc.stderr
    inch = json.loads((work / "c.json").read_text())
    assert inch["diagonal"] == pytest.approx(report["deviation"]["diagonal"], rel=1e-12)
    assert inch["mesh_to_shape"]["max"] == pytest.approx(report["deviation"]["mesh_to_shape"]["max"], rel=1e-6)
    assert all(line.count(" in (") == 3 for line in proc.stdout.splitlines() if line.startswith("deviation "))
    # read in mm (the default) the shape is 25.4 times the mesh: most of it lies farther from the mesh than the
    # part is long
    assert _run(work, "compare", "part.stl", "out.step", "--json", "mm.json").returncode == 0
    assert json.loads((work / "mm.json").read_text())["shape_to_mesh"]["p95"] > inch["diagonal"]


def test_iges_output_and_schema_option(work):
    proc = _run(work, "convert", "part.stl", "out.igs", "--report", "r.json", "--no-deviation")
    assert proc.returncode == 0, proc.stderr
    solid = next(r for r in json.loads((work / "r.json").read_text())["verdict"]["rules"] if r["rule"] == "solid")
    assert solid["ok"] and "out.igs" in solid["detail"]  # read back from the IGES file: one valid closed solid
    proc = _run(work, "convert", "part.stl", "out.stl", "--schema", "AP214")
    assert proc.returncode == 2 and proc.stdout == "" and proc.stderr.count("\n") == 1, proc.stderr
    assert "--schema AP214: a STEP option" in proc.stderr and not (work / "out.stl").exists()
    proc = _run(work, "convert", "part.stl", "out.step", "--schema", "AP214", "-q")
    assert proc.returncode == 0 and "AUTOMOTIVE_DESIGN" in (work / "out.step").read_text()[:2000]


@pytest.mark.parametrize("verbose", [False, True])
def test_a_closed_pipe_ends_the_run_quietly_with_141(work, verbose):
    """`recon convert … | true`: the reader is gone before the summary is printed. As a Unix tool killed by SIGPIPE:
    exit 141, nothing on stderr (no traceback, no "Exception ignored", no "Broken pipe"); the output file, written
    before the summary, is complete."""
    from cli_harness import step_is_valid_solid

    tmp = work / "tmp"
    tmp.mkdir(exist_ok=True)
    args = ["convert", "part.stl", "out.step", *(["-v"] if verbose else [])]
    proc = subprocess.Popen(cli_command(*args), cwd=work, env={**cli_env(tmp), "RECON_PROGRESS_INTERVAL": "3600"},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdout.close()  # the reader goes away at once
    err = proc.stderr.read()
    assert proc.wait(timeout=300) == 141, err
    assert "Traceback" not in err and "Exception ignored" not in err and "Broken pipe" not in err, err
    assert step_is_valid_solid(work / "out.step") and list(tmp.iterdir()) == []
    if not verbose:
        assert err == ""
