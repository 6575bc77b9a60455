"""What the command line prints, and where: the result's summary on stdout (``> summary.txt`` keeps it),
warnings, progress and errors on stderr, ``-q`` errors only; lengths with their unit."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from cli_harness import FIXTURES, cli_command, cli_env

SMALL = "prism_coarse.stl"  # 264 triangles: the quickest fixture that converts
SUMMARY_HEADS = ("result: ", "faces: ", "solid: ", "deviation mesh→shape: ", "deviation shape→mesh: ", "time: ")


def _run(work, *args, timeout=300):
    tmp = work / "tmp"
    tmp.mkdir(exist_ok=True)
    return subprocess.run(cli_command(*args), cwd=work, env=cli_env(tmp), capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture()
def work(tmp_path):
    shutil.copyfile(FIXTURES / SMALL, tmp_path / "part.stl")
    shutil.copyfile(FIXTURES / "prism.step", tmp_path / "shape.step")
    return tmp_path


def test_convert_summary_on_stdout_nothing_on_stderr(work):
    """Piped (no terminal): the summary lines, in order, and "wrote" on stdout; stderr holds none of them (a clean
    fixture has no warning, and off a terminal a run this short prints no progress)."""
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
