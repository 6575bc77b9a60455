"""Coarse primitives as mesh tools write them (trimesh's cylinders, cones and capsules: caps drawn as fans from a
centre vertex, sides as strips one quad wide): the true faces, the analytic volume, exit 0, the file read back valid.

Each was wrong on main before stop 39: the fan centres kept the mesh from the exact path (2 B-spline faces, an
invalid or negative-volume solid), and a capsule's hemispheres had their poles on their rims (invalid on read-back)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from recon.cli import main
from recon.mesh import clean_mesh, load_mesh
from recon.pipeline import _exact, roundoff
from recon.segment._exact import exact_tessellation

R, H = 10.0, 30.0


def _convert(tmp_path, mesh: trimesh.Trimesh):
    path, report = tmp_path / "in.stl", tmp_path / "report.json"
    mesh.export(path)
    rc = main(["convert", str(path), str(tmp_path / "out.step"), "--report", str(report)])
    return rc, json.loads(report.read_text())


def _exit0_and_read_back_valid(rc, report):
    assert rc == 0, [r["detail"] for r in report["verdict"]["rules"] if r["ok"] is False]
    solid = next(r for r in report["verdict"]["rules"] if r["rule"] == "solid")
    assert solid["ok"] and "the written file out.step" in solid["detail"]


@pytest.mark.parametrize("make", [lambda n: trimesh.creation.cylinder(radius=R, height=H, sections=n),
                                  lambda n: trimesh.creation.cone(radius=R, height=H, sections=n)],
                         ids=["cylinder", "cone"])
@pytest.mark.parametrize("n", [6, 16, 48])
def test_a_fan_capped_mesh_is_a_cad_tessellation(make, n):
    """One centre vertex inside each cap is a fan, not a remesher's plane: the mesh goes to the exact path."""
    m = make(n)
    mesh = clean_mesh(m.vertices, m.faces)
    assert exact_tessellation(mesh, roundoff(mesh.vertices))


@pytest.mark.parametrize("n", [12, 16, 32])
def test_a_coarse_cylinder_is_two_planes_and_one_cylinder_with_its_true_volume(tmp_path, capsys, n):
    rc, report = _convert(tmp_path, trimesh.creation.cylinder(radius=R, height=H, sections=n))
    assert report["faces_by_type"] == {"plane": 2, "cylinder": 1}
    assert report["validity"]["volume"] == pytest.approx(np.pi * R * R * H, rel=1e-6)  # the circle's, not the n-gon's
    _exit0_and_read_back_valid(rc, report)
    # the summary states what the tolerance holds between the vertices: T + the facets' chord sag r (1 − cos(π/n))
    rule = next(r for r in report["verdict"]["rules"] if r["rule"] == "shape_to_mesh_p95")
    assert rule["limit"] == pytest.approx(report["tolerance"] + R * (1 - np.cos(np.pi / n)), rel=1e-6)
    first = capsys.readouterr().out.splitlines()[0]
    assert "at the mesh's vertices" in first and f"{rule['limit']:.4g} mm between them" in first


@pytest.mark.parametrize("n", [16, 32])
def test_a_coarse_cone_is_one_plane_and_one_cone_with_its_true_volume(tmp_path, n):
    rc, report = _convert(tmp_path, trimesh.creation.cone(radius=R, height=H, sections=n))
    assert report["faces_by_type"] == {"plane": 1, "cone": 1}
    # the apex vertex pins the tip only to round-off along a generatrix (the fit's tip lies a few 1e-3 off it), so the
    # volume is the true one within T × the area: the volume between two surfaces within T of each other
    area = np.pi * R * R + np.pi * R * np.hypot(R, H)
    assert abs(report["validity"]["volume"] - np.pi * R * R * H / 3) <= report["tolerance"] * area
    _exit0_and_read_back_valid(rc, report)


@pytest.mark.parametrize("n", [16, 32])
def test_a_capsule_is_two_hemispheres_and_a_cylinder_valid_when_read_back(tmp_path, n):
    """A hemisphere reaches 90° from its centre: with the poles on the equator its rim would pass through them."""
    r, h = 5.0, 20.0
    rc, report = _convert(tmp_path, trimesh.creation.capsule(radius=r, height=h, count=[n, n]))
    assert report["faces_by_type"] == {"sphere": 2, "cylinder": 1}
    assert report["validity"]["volume"] == pytest.approx(np.pi * r * r * h + 4 / 3 * np.pi * r ** 3, rel=1e-6)
    _exit0_and_read_back_valid(rc, report)


@pytest.mark.parametrize("sections", [(16, 8), (24, 8), (32, 16), (16, 32)])
def test_a_coarse_torus_is_one_torus_face(tmp_path, sections):
    """A mesh tool draws a torus at fixed angular steps, so its chords sag most at the outer equator (16 × 8: 0.45 mm
    there, 0.30 on the rest, the exact path's sag limit 0.37): the face proven on the rest takes the outer band's quads,
    drawn at its own step, instead of leaving them as cylinders tangent to the equator that hold their six vertices."""
    Rt, rt = 10.0, 3.0
    path = tmp_path / "torus.stl"
    trimesh.creation.torus(major_radius=Rt, minor_radius=rt, major_sections=sections[0],
                           minor_sections=sections[1]).export(path)
    mesh = load_mesh(path)
    found = _exact(mesh, None)
    assert found is not None and set(found.labels.tolist()) == {0}
    fit = found.fits[0]
    assert fit.type == "torus"
    eps = roundoff(mesh.vertices)  # the float32 vertices pin the torus to their round-off
    assert fit.params["major_radius"] == pytest.approx(Rt, abs=eps)
    assert fit.params["minor_radius"] == pytest.approx(rt, abs=eps)
