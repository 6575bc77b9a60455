"""The bad-input corpus: every file, option and output path a user can get wrong, for every subcommand.

Each case runs ``recon`` on files made here (no committed binaries) in a fresh folder, with TMPDIR a private
empty folder, and asserts: the exit code, exactly one line on stderr saying what is wrong, no traceback, every
input byte for byte unchanged, and no file left behind, in the output folder nor in TMPDIR.
"""

from __future__ import annotations

import os
import shutil
import subprocess

import numpy as np
import pytest

from cli_harness import FIXTURES, binary_stl, cube_mesh, run_in_process, step_is_valid_solid

SMALL = "prism_coarse.stl"  # 276 triangles: the quickest fixture that converts
STEP = "box_fillet.step"  # a true solid, for compare


def _ascii_stl(v, f) -> str:
    rows = [f"facet normal 0 0 0\n outer loop\n" + "".join(f"  vertex {x!r} {y!r} {z!r}\n" for x, y, z in v[t])
            + " endloop\nendfacet\n" for t in f]
    return "solid t\n" + "".join(rows) + "endsolid t\n"


def _make_inputs(work):
    """Every input file the corpus uses, in ``work``."""
    v, f = cube_mesh()
    cube = binary_stl(v, f)
    (work / "cube.stl").write_bytes(cube)
    shutil.copyfile(FIXTURES / SMALL, work / "part.stl")
    shutil.copyfile(FIXTURES / STEP, work / "shape.step")
    shutil.copyfile(FIXTURES.parent / "shapes" / "star.json", work / "star.json")
    (work / "empty.stl").write_bytes(b"")
    (work / "truncated.stl").write_bytes(cube[: 84 + 50 * 5 + 17])
    (work / "header_only.stl").write_bytes(cube[:50])
    (work / "count_only.stl").write_bytes(cube[:84])
    (work / "trailing.stl").write_bytes(cube + b"junk")
    ascii_cube = _ascii_stl(v, f)
    (work / "ascii_cut.stl").write_text(ascii_cube[: len(ascii_cube) // 2])
    nan_v = v.copy()
    nan_v[3] = np.nan
    (work / "nan.stl").write_text(_ascii_stl(nan_v, f))
    (work / "flat.stl").write_bytes(binary_stl(np.zeros((3, 3)), np.array([[0, 1, 2]] * 4)))
    (work / "noise.stl").write_bytes(np.random.default_rng(0).bytes(3000))
    (work / "text.stl").write_text("this is not a mesh\n")
    (work / "nofaces.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    (work / "bad.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")
    (work / "bad.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nend_header\n0 0 0\n")
    (work / "mesh.xyz").write_text("0 0 0\n")
    (work / "folder.stl").mkdir()
    (work / "not_step.step").write_text("hello\n")
    vs, fs = cube_mesh(1e-6)
    (work / "tiny.stl").write_bytes(binary_stl(vs, fs))
    vl, fl = cube_mesh(1e10)
    (work / "huge.stl").write_bytes(binary_stl(vl, fl))
    (work / "a_file").write_text("x")
    (work / "protected.step").write_text("a file the user made read-only")
    (work / "protected.step").chmod(0o444)
    (work / "out_dir").mkdir()
    os.symlink("part.stl", work / "link_to_part.stl")
    os.link(work / "part.stl", work / "hard_part.stl")
    os.link(work / "shape.step", work / "hard_shape.json")


# (id, argv, exit code, words the one line must hold)
CASES = [
    # mesh files
    ("missing", ["convert", "nope.stl", "o.step"], 2, "no such file"),
    ("mesh-is-folder", ["convert", "folder.stl", "o.step"], 2, "not a file"),
    ("unknown-format", ["convert", "mesh.xyz", "o.step"], 2, "unknown mesh format"),
    ("step-as-mesh", ["convert", "shape.step", "o.step"], 2, "unknown mesh format"),
    ("empty", ["convert", "empty.stl", "o.step"], 2, "empty"),
    ("truncated-binary", ["convert", "truncated.stl", "o.step"], 2, "truncated (expected 12 triangles, found 5)"),
    ("header-only", ["convert", "header_only.stl", "o.step"], 2, "truncated"),
    ("count-only", ["convert", "count_only.stl", "o.step"], 2, "truncated (expected 12 triangles, found 0)"),
    ("trailing-bytes", ["convert", "trailing.stl", "o.step"], 2, "longer than its triangle count"),
    ("truncated-ascii", ["convert", "ascii_cut.stl", "o.step"], 2, "truncated"),
    ("nan-vertex", ["convert", "nan.stl", "o.step"], 2, "nan"),
    ("degenerate-only", ["convert", "flat.stl", "o.step"], 2, "triangles"),
    ("random-bytes", ["convert", "noise.stl", "o.step"], 2, "noise.stl"),
    ("text-as-stl", ["convert", "text.stl", "o.step"], 2, "text.stl"),
    ("obj-no-faces", ["convert", "nofaces.obj", "o.step"], 2, "no triangles"),
    ("off-cut", ["convert", "bad.off", "o.step"], 2, "bad.off"),
    ("ply-cut", ["convert", "bad.ply", "o.step"], 2, "bad.ply"),
    ("too-small", ["convert", "tiny.stl", "o.step"], 2, "units across"),
    ("too-large", ["convert", "huge.stl", "o.step"], 2, "units across"),
    # options
    ("tolerance-zero", ["convert", "part.stl", "o.step", "--tolerance", "0"], 2, "--tolerance"),
    ("tolerance-negative", ["convert", "part.stl", "o.step", "--tolerance", "-1"], 2, "--tolerance"),
    ("tolerance-nan", ["convert", "part.stl", "o.step", "--tolerance", "nan"], 2, "--tolerance"),
    ("tolerance-inf", ["convert", "part.stl", "o.step", "--tolerance", "inf"], 2, "--tolerance"),
    ("tolerance-huge", ["convert", "part.stl", "o.step", "--tolerance", "1e9"], 2, "of the part's diagonal"),
    ("tolerance-below-precision", ["convert", "part.stl", "o.step", "--tolerance", "1e-9"], 2, "precision"),
    ("tolerance-text", ["convert", "part.stl", "o.step", "--tolerance", "abc"], 2, "invalid float"),
    ("scale-zero", ["convert", "part.stl", "o.step", "--scale", "0"], 2, "--scale"),
    ("scale-nan", ["convert", "part.stl", "o.step", "--scale", "nan"], 2, "--scale"),
    ("jobs-zero", ["convert", "part.stl", "o.step", "--jobs", "0"], 2, "--jobs"),
    ("jobs-negative", ["convert", "part.stl", "o.step", "--jobs", "-2"], 2, "--jobs"),
    ("unknown-option", ["convert", "part.stl", "o.step", "--frobnicate"], 2, "unrecognized"),
    ("missing-argument", ["convert", "part.stl"], 2, "required"),
    ("out-extension", ["convert", "part.stl", "o.obj"], 2, "unknown extension"),
    # outputs that would overwrite an input or each other
    ("out-is-input", ["convert", "part.stl", "part.stl"], 2, "refusing to overwrite"),
    ("out-is-input-dotted", ["convert", "part.stl", "./out_dir/../part.stl"], 2, "refusing to overwrite"),
    ("out-symlink-to-input", ["convert", "part.stl", "link_to_part.stl"], 2, "refusing to overwrite"),
    ("out-hardlink-of-input", ["convert", "part.stl", "hard_part.stl"], 2, "refusing to overwrite"),
    ("report-is-input", ["convert", "part.stl", "o.step", "--report", "part.stl"], 2, "refusing to overwrite"),
    ("report-is-out", ["convert", "part.stl", "o.step", "--report", "o.step"], 2, "same file"),
    ("preview-is-out", ["convert", "part.stl", "o.step", "--preview", "./o.step"], 2, "same file"),
    ("preview-is-report", ["convert", "part.stl", "o.step", "--report", "r.json", "--preview", "r.json"], 2,
     "same file"),
    # output locations
    ("out-folder-missing", ["convert", "part.stl", "no/such/o.step"], 2, "does not exist"),
    ("out-parent-is-file", ["convert", "part.stl", "a_file/o.step"], 2, "is a file"),
    ("out-is-folder", ["convert", "part.stl", "out_dir.step"], 2, None),  # made a folder in the test
    ("out-read-only-file", ["convert", "part.stl", "protected.step"], 2, "read-only"),
    ("report-folder-missing", ["convert", "part.stl", "o.step", "--report", "no/r.json"], 2, "does not exist"),
    # decompose
    ("decompose-json-is-input", ["decompose", "part.stl", "--json", "part.stl"], 2, "refusing to overwrite"),
    ("decompose-preview-is-json", ["decompose", "part.stl", "--json", "d.json", "--preview", "d.json"], 2,
     "same file"),
    ("decompose-scale", ["decompose", "part.stl", "--json", "d.json", "--scale", "-1"], 2, "--scale"),
    ("decompose-omega", ["decompose", "part.stl", "--json", "d.json", "--omega-min", "0"], 2, "--omega-min"),
    ("decompose-missing", ["decompose", "nope.stl", "--json", "d.json"], 2, "no such file"),
    # compare
    ("compare-samples-zero", ["compare", "part.stl", "shape.step", "--json", "c.json", "--samples", "0"], 2,
     "--samples"),
    ("compare-samples-few", ["compare", "part.stl", "shape.step", "--json", "c.json", "--samples", "99"], 2,
     "at least 100"),
    ("compare-json-is-shape", ["compare", "part.stl", "shape.step", "--json", "shape.step"], 2,
     "refusing to overwrite"),
    ("compare-json-hardlink-of-shape", ["compare", "part.stl", "shape.step", "--json", "hard_shape.json"], 2,
     "refusing to overwrite"),
    ("compare-not-step", ["compare", "part.stl", "not_step.step", "--json", "c.json"], 2, "not a STEP file"),
    ("compare-shape-missing", ["compare", "part.stl", "nope.step", "--json", "c.json"], 2, "does not exist"),
    ("compare-truncated-mesh", ["compare", "truncated.stl", "shape.step", "--json", "c.json"], 2, "truncated"),
    # skeleton
    ("skeleton-json-is-input", ["skeleton", "star.json", "--json", "star.json"], 2, "refusing to overwrite"),
    ("skeleton-plot-is-json", ["skeleton", "star.json", "--json", "s.json", "--plot", "s.json"], 2, "same file"),
    ("skeleton-omega-nan", ["skeleton", "star.json", "--json", "s.json", "--omega-min", "nan"], 2, "positive"),
    # -v / -q after the subcommand are options like any other
    ("verbose-after-subcommand", ["convert", "-v", "nope.stl", "o.step"], 2, "no such file"),
    ("quiet-after-subcommand", ["convert", "nope.stl", "o.step", "-q"], 2, "no such file"),
]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    src = tmp_path_factory.mktemp("inputs")
    _make_inputs(src)
    return src


@pytest.fixture
def work(inputs, tmp_path):
    dst = tmp_path / "work"
    shutil.copytree(inputs, dst, symlinks=True)
    # copytree copies hard links as separate files: make them links again
    for link, target in (("hard_part.stl", "part.stl"), ("hard_shape.json", "shape.step")):
        (dst / link).unlink()
        os.link(dst / target, dst / link)
    return dst


def test_corpus_is_large_enough():
    assert len(CASES) >= 40 and len({c[0] for c in CASES}) == len(CASES)


@pytest.mark.parametrize("name, argv, code, words", CASES, ids=[c[0] for c in CASES])
def test_bad_input(name, argv, code, words, work, capfd, monkeypatch):
    if name == "out-is-folder":
        (work / "out_dir.step").mkdir()
        words = "is a folder"
    run = run_in_process(argv, work, capfd, monkeypatch)
    run.assert_one_line_error(code, words)


def test_unwritable_folder(work, capfd, monkeypatch):
    """A folder the user may not write to: refused before the work, as permission denied. (root may write
    anywhere: the folder is then a read-only mount, or the case is skipped where mounting is not allowed.)"""
    ro = work / "ro"
    ro.mkdir()
    if os.geteuid() == 0:
        if subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(ro)],
                          capture_output=True).returncode:
            pytest.skip("running as root where tmpfs cannot be mounted: no folder is unwritable")
        words = "read-only"
    else:
        ro.chmod(0o555)
        words = "permission denied"
    try:
        run = run_in_process(["convert", "part.stl", "ro/o.step"], work, capfd, monkeypatch)
        run.assert_one_line_error(2, words)
    finally:
        if os.geteuid() == 0:
            subprocess.run(["umount", str(ro)], check=True)
        else:
            ro.chmod(0o755)


def test_disk_full_while_writing(work, capfd, monkeypatch):
    """ENOSPC in the middle of writing the STEP file: "disk full while writing", exit 2, no temporary left."""
    if os.geteuid() != 0:
        pytest.skip("needs a small tmpfs mount (root)")
    full = work / "full"
    full.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16k", "tmpfs", str(full)], capture_output=True).returncode:
        pytest.skip("tmpfs cannot be mounted here")
    try:
        run = run_in_process(["convert", "part.stl", "full/o.step", "--no-deviation"], work, capfd, monkeypatch)
        assert os.listdir(full) == []
        run.assert_one_line_error(2, "disk full while writing full/o.step")
    finally:
        subprocess.run(["umount", str(full)], check=True)


def test_internal_error_is_one_line_exit_3(work, capfd, monkeypatch, caplog):
    """A bug (an exception recon did not raise on purpose): one line naming it, exit 3; its traceback with -v."""
    import recon.pipeline

    def broken(*args, **kwargs):
        raise TypeError("a bug")

    monkeypatch.setattr(recon.pipeline, "convert", broken)
    run = run_in_process(["convert", "part.stl", "o.step"], work, capfd, monkeypatch)
    run.assert_one_line_error(3, "internal error: TypeError: a bug (run with -v for the traceback)")
    run = run_in_process(["convert", "part.stl", "o.step", "-v"], work, capfd, monkeypatch)
    logged = run.stderr + caplog.text  # (pytest's log capture holds the traceback here; a real run prints it)
    assert run.code == 3 and "Traceback" in logged and "internal error: TypeError: a bug" in run.stderr


def test_memory_error_is_one_line_exit_2(work, capfd, monkeypatch):
    import recon.pipeline

    def hungry(*args, **kwargs):
        raise MemoryError("Unable to allocate 80.0 GiB")

    monkeypatch.setattr(recon.pipeline, "convert", hungry)
    run = run_in_process(["convert", "part.stl", "o.step"], work, capfd, monkeypatch)
    run.assert_one_line_error(2, "not enough memory")


def test_success_writes_a_valid_solid_and_nothing_else(work, capfd, monkeypatch):
    """The good case through the same checks: the outputs asked for and nothing else, the STEP re-read valid."""
    run = run_in_process(["convert", "part.stl", "o.step", "--report", "r.json", "--no-deviation", "-q"], work,
                         capfd, monkeypatch)
    assert run.code in (0, 1) and "Traceback" not in run.stderr, run.stderr
    run.assert_inputs_unchanged()
    assert run.new_files() == {"o.step", "r.json"}
    assert list(run.tmp.iterdir()) == []
    import json

    report = json.loads((work / "r.json").read_text())
    assert run.code == (0 if report["verdict"]["ok"] else 1)
    assert step_is_valid_solid(work / "o.step")
    assert run.stderr == ""  # -q: errors only


def test_stale_temporary_of_a_killed_run_is_swept(work, capfd, monkeypatch):
    """What a SIGKILLed run leaves (its temporary, named after its pid and start time) the next write into the
    folder removes; a live process's temporary is kept."""
    dead = subprocess.Popen(["true"])
    dead.wait()
    stale = work / f".o.recon-{dead.pid}-12345.abcdefgh.step"
    stale.write_text("half a STEP file")
    from recon._io import _start_time

    live = work / f".x.recon-{os.getpid()}-{_start_time(os.getpid())}.abcdefgh.step"
    live.write_text("being written")
    run = run_in_process(["skeleton", "star.json", "--json", "s.json"], work, capfd, monkeypatch)
    assert run.code == 0, run.stderr
    assert not stale.exists() and live.exists()
