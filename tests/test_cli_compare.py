"""``recon compare``: writes the report and preview; bad input is one line and exit 2, no output."""

from __future__ import annotations

import json

import build123d as bd
import numpy as np
import pytest
import trimesh

from recon.cli import main


@pytest.fixture()
def sphere_files(tmp_path):
    R, delta = 10.0, 0.1
    step = tmp_path / "sphere.step"
    bd.export_step(bd.Sphere(R), str(step))
    ico = trimesh.creation.icosphere(subdivisions=3)
    mesh = tmp_path / "ico.stl"
    trimesh.Trimesh(ico.vertices * (R + delta), ico.faces).export(mesh)
    return mesh, step, delta


def test_compare_writes_json_and_png(tmp_path, sphere_files):
    mesh, step, delta = sphere_files
    out, png = tmp_path / "r.json", tmp_path / "p.png"
    assert main(["compare", str(mesh), str(step), "--json", str(out), "--preview", str(png), "--samples", "2000"]) == 0
    report = json.loads(out.read_text())
    assert set(report) == {"diagonal", "mesh_to_shape", "shape_to_mesh", "faces"}
    m = report["mesh_to_shape"]
    assert {"max", "p95", "rms", "mean", "max_pct"} <= set(m)
    assert set(report["shape_to_mesh"]) >= {"max", "p95", "rms", "mean", "max_pct"}
    # STL stores float32 coordinates: the vertices sit on radius R + δ to ~1e-6.
    assert m["max"] == pytest.approx(delta, abs=1e-5)
    assert m["max_pct"] == pytest.approx(m["max"] / report["diagonal"] * 100)
    (face,) = report["faces"]
    assert face["name"] == "face_0" and face["type"] == "sphere"
    assert face["count"] == len(trimesh.load(mesh).vertices)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("broken", ["missing_mesh", "empty_mesh", "missing_step", "junk_step", "no_face_step"])
def test_bad_input_exit_2_one_line_no_output(tmp_path, sphere_files, capsys, broken):
    mesh, step, _ = sphere_files
    if broken == "missing_mesh":
        mesh = tmp_path / "nope.stl"
    elif broken == "empty_mesh":
        mesh = tmp_path / "empty.stl"
        mesh.write_bytes(b"")
    elif broken == "missing_step":
        step = tmp_path / "nope.step"
    elif broken == "junk_step":
        step = tmp_path / "junk.step"
        step.write_text("ISO-10303-21;\nthis is not step\n")
    else:
        step = tmp_path / "vertex.step"
        bd.export_step(bd.Edge.make_line((0, 0, 0), (1, 0, 0)), str(step))  # a wire frame: no face
    out, png = tmp_path / "r.json", tmp_path / "p.png"
    code = main(["compare", str(mesh), str(step), "--json", str(out), "--preview", str(png)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.startswith("recon compare: error:") and "\n" not in err
    assert not out.exists() and not png.exists()


def test_version_and_help_read_as_printed(capsys):
    """`recon --version` names the installed version (exit 0, on stdout); `compare --help` shows "%", not the
    "%%" argparse needs only inside an option's help."""
    from importlib.metadata import version

    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f"recon {version('recon')}"
    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    out = capsys.readouterr().out
    assert "% of the mesh" in out and "%%" not in out
