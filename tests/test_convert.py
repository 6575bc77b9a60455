"""`recon convert` end to end: ground truth on a part whose true faces are known, and bad input."""

import json
from pathlib import Path
import subprocess
import sys
import tempfile

import numpy as np
import pytest
import trimesh

from recon._freecad import inspect_step


def _recon(*args, cwd):
    return subprocess.run([sys.executable, "-m", "recon", *map(str, args)], capture_output=True, text=True, cwd=cwd)


@pytest.fixture(scope="module")
def converted_box(tmp_path_factory, box_mesh):
    """conftest's box (6 planes, volume 6000) through ``recon convert``: the folder of its outputs and the process."""
    d = tmp_path_factory.mktemp("box")
    path = d / "box.stl"
    box_mesh.export(path)
    proc = _recon("convert", path, d / "box.step", "--report", d / "box.json", "--preview", d / "box.png", cwd=d)
    return d, proc


def test_sharp_box_gives_six_planes_and_the_exact_volume(converted_box):
    d, proc = converted_box
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads((d / "box.json").read_text())
    assert report["n_faces"] == 6
    assert report["faces_by_type"] == {"plane": 6}
    v = report["validity"]
    assert v["ok"] and v["closed"] and v["free_edges"] == 0
    assert v["volume"] == pytest.approx(6000.0, rel=1e-9)
    # The mesh lies exactly on the true planes, so the deviation is round-off.
    assert report["deviation"]["mesh_to_shape"]["max"] < 1e-9 * report["mesh"]["diagonal"]
    assert set(report["seconds"]) == {"load", "decompose", "fit", "brep", "deviation"}
    assert (d / "box.png").stat().st_size > 10_000
    assert "faces: 6 (6 plane)" in proc.stdout


def test_the_deviation_both_ways_per_named_face(converted_box):
    """The report's per-face deviations carry the faces' own names, and the summary shows both directions: a face
    that reaches far from the mesh shows only from the shape's side (every mesh point lies near some face)."""
    d, proc = converted_box
    report = json.loads((d / "box.json").read_text())
    dev = report["deviation"]
    assert sorted(f["name"] for f in dev["faces"]) == sorted(f["name"] for f in report["faces"])
    # Exact planes on an exact mesh: round-off both ways, on every face.
    assert dev["shape_to_mesh"]["max"] < 1e-9 * report["mesh"]["diagonal"]
    assert all(f["shape_to_mesh_max"] < 1e-9 * report["mesh"]["diagonal"] for f in dev["faces"])
    assert "deviation mesh→shape: max" in proc.stdout
    assert "deviation shape→mesh: max" in proc.stdout
    assert "0.000" not in proc.stdout  # round-off shows its size (e-1x), not a row of zeros


def test_summary_names_the_face_farthest_from_the_mesh():
    from recon._cli.convert import summary

    stats = {"max": 1.0, "max_pct": 1.0, "p95": 0.5, "p95_pct": 0.5, "rms": 0.2, "rms_pct": 0.2}
    report = {"validity": {"ok": True, "shape_type": "solid", "valid": True, "closed": True, "free_edges": 0,
                           "volume": 1.0},
              "faces_by_type": {"plane": 2}, "n_faces": 2, "seconds": {"load": 0.1}, "warnings": [],
              "deviation": {"diagonal": 100.0, "mesh_to_shape": stats, "shape_to_mesh": {**stats, "max": 80.0},
                            "faces": [{"name": "patch_0", "shape_to_mesh_max": 0.3},
                                      {"name": "patch_1", "shape_to_mesh_max": 80.0}]}}
    back = [ln for ln in summary(report).splitlines() if ln.startswith("deviation shape→mesh: ")]
    assert len(back) == 1 and back[0].startswith("deviation shape→mesh: max 80 ") and back[0].endswith("farthest: patch_1")


def test_step_round_trip_and_face_names(converted_box):
    d, _ = converted_box
    from build123d import import_step

    from recon.brep import read_step_faces

    solid = import_step(str(d / "box.step"))
    assert solid.is_valid and solid.volume == pytest.approx(6000.0, rel=1e-9)
    names = [n for n, _ in read_step_faces(d / "box.step")]
    assert sorted(names) == sorted(f"patch_{i}" for i in range(6))


@pytest.mark.freecad
def test_freecad_opens_one_valid_solid(converted_box):
    d, _ = converted_box
    (obj,) = inspect_step(d / "box.step")["objects"]
    assert obj["type"] == "Solid" and obj["valid"] and obj["closed"]
    assert obj["faces"] == 6 and obj["volume"] == pytest.approx(6000.0, rel=1e-9)


def test_python_api_returns_a_build123d_solid_to_keep_modelling(box_mesh):
    import build123d as bd

    from recon import convert

    result = convert((box_mesh.vertices, box_mesh.faces), deviation=False)
    assert isinstance(result.shape, bd.Solid)
    # Drill a through hole in the reconstruction: the volume drops by exactly the cylinder's.
    drilled = result.shape - bd.Cylinder(3, 40)
    assert drilled.volume == pytest.approx(6000.0 - np.pi * 9 * 10, rel=1e-6)



# -- ground truth under noise, and real meshes ------------------------------------------------------------------



@pytest.mark.parametrize("part", ["box_chamfer", "box_fillet", "plate_holes", "pocket", "prism", "lofted", "revolved"])
def test_noisy_fixture_converts_to_a_valid_solid_with_about_its_true_faces(part):
    """Issue 5's noisy target, σ = 0.2 % of the diagonal: a valid closed solid, face count within 15 % of the
    truth."""
    from recon import convert
    from recon.fixtures import load_fixture

    fx = load_fixture(part, "noisy20")
    result = convert((fx.vertices, fx.faces), deviation=False)
    assert result.brep.validity.ok, result.report["validity"]
    n_true = len(fx.true_faces)
    assert abs(result.report["n_faces"] - n_true) <= 0.15 * n_true
    # The solid is the part within the noise: σ on a part of area A moves the volume by ~σ·A/√n, far below 1 %.
    assert result.brep.validity.volume == pytest.approx(fx.volume, rel=1e-2)


@pytest.mark.parametrize("moved", [False, True])
def test_lofted_fixture_is_two_planes_and_one_closed_bspline(moved):
    """Issue #4: the lofted side wraps all the way round. It is one face on a B-spline periodic about the loft's
    axis, bounded by its two loops; with the two planes it closes into a valid solid of the true 3 faces. The
    same after a rigid motion and a permutation of the triangles: the axis comes from the loops, not the frame."""
    from recon import convert
    from bench.synthetic import random_rotation
    from recon.fixtures import load_fixture

    fx = load_fixture("lofted", "clean")
    vertices, faces = fx.vertices, fx.faces
    if moved:
        rng = np.random.default_rng(7)
        vertices = vertices @ random_rotation(rng).T + np.array([100.0, -50.0, 20.0])
        faces = faces[rng.permutation(len(faces))]
    result = convert((vertices, faces))
    assert result.brep.validity.ok, result.report["validity"]
    assert result.report["faces_by_type"] == {"bspline": 1, "plane": 2}
    (side,) = [f for f in result.fits.values() if f.type == "bspline"]
    assert side and side.params["periodic_u"]
    assert side.deviation["p99"] <= result.report["tolerance"]
    # The clean mesh's vertices lie on the true surface and its chords cut inside it: the mesh's own volume is
    # 0.15 % short (lofted.json, volume_error). A surface through the vertices recovers what the chords cut off,
    # so the solid is closer to the truth than the mesh: within a tenth of the mesh's error (measured 1.1e-5,
    # moved 4.7e-5).
    assert result.brep.validity.volume == pytest.approx(fx.volume, rel=1.5e-4)
    assert result.report["deviation"]["mesh_to_shape"]["p95_pct"] <= 0.05


def test_chamfered_box_keeps_its_corner_triangles():
    """box_chamfer: 6 faces, 12 chamfers and 8 corner triangles of 4 mesh triangles each, all planes. A corner
    is too small for a surface fit of its own; joined to a chamfer it bent the chamfer into a B-spline (18
    faces, 11 B-splines). The mesh lies exactly on the true planes, so the solid's volume is the true one up
    to the B-rep's vertex tolerance (1e-7 of the part's size: 1e-6 relative is generous)."""
    from recon import convert
    from recon.fixtures import load_fixture

    fx = load_fixture("box_chamfer", "clean")
    result = convert((fx.vertices, fx.faces), deviation=False)
    assert result.brep.validity.ok, result.report["validity"]
    assert result.report["n_faces"] == len(fx.true_faces) == 26
    assert result.report["faces_by_type"] == {"plane": 26}
    assert result.brep.validity.volume == pytest.approx(fx.volume, rel=1e-6)


def test_pocket_floor_fillets_are_four_cylinders():
    """pocket: 11 planes and the 4 floor fillets (radius 3), which meet at the pocket's sharp corners. The
    decomposition gives the fillets as one ring no surface fits (it was one bad plane face: 12 faces);
    split by fitting, the ring is the 4 true cylinders. The faces are the true surfaces, so the volume is the
    true one far closer than the mesh's own (the chords of the fillets lose 1.4e-3 of it)."""
    from recon import convert
    from recon.fixtures import load_fixture

    fx = load_fixture("pocket", "clean")
    result = convert((fx.vertices, fx.faces), deviation=False)
    assert result.brep.validity.ok, result.report["validity"]
    assert result.report["faces_by_type"] == {"plane": 11, "cylinder": 4}
    radii = [f.params["radius"] for f in result.fits.values() if f.type == "cylinder"]
    assert radii == pytest.approx([3.0] * 4, rel=1e-6)
    assert result.brep.validity.volume == pytest.approx(fx.volume, rel=3e-4)


def test_revolved_part_under_noise_has_its_six_true_faces():
    """revolved at σ = 0.05 % of the diagonal: 2 cylinders, 2 planes, a cone and a torus. Under noise a small
    region of the r = 20 cylinder fits a plane within tolerance and stopped growing where the curvature
    showed, leaving the cylinder in pieces (8 faces); the stalled region now tries the curved types."""
    from recon import convert
    from recon.fixtures import load_fixture

    fx = load_fixture("revolved", "noisy05")
    result = convert((fx.vertices, fx.faces), deviation=False)
    assert result.brep.validity.ok, result.report["validity"]
    assert result.report["faces_by_type"] == {"cylinder": 2, "plane": 2, "cone": 1, "torus": 1}
    (big,) = [f for f in result.fits.values() if f.type == "cylinder" and f.params["radius"] > 17]
    # σ ≈ 0.04 mm over ~900 vertices: the radius is known to far better than σ; 0.1 mm is 2.5 σ
    assert big.params["radius"] == pytest.approx(20.0, abs=0.1)


@pytest.mark.parametrize(
    "name", ["block.off", "joint.off", "abc_00000050.stl", "fandisk-b_noisy0.1.off", "casting.off"])
def test_real_mesh_converts_to_valid_solids(shared_meshes, name):
    """Meshes nobody here made: block (one body), joint (genus 2), the ABC model (three bodies → three solids),
    fandisk-b with synthetic noise on the same connectivity, casting (69 faces)."""
    from recon import convert

    result = convert(shared_meshes / name, deviation=False)
    val = result.brep.validity
    assert val.ok, result.report["validity"]
    assert val.n_solids == (3 if name.startswith("abc") else 1)


@pytest.mark.parametrize(
    "make_args, message",
    [
        (lambda d: ("convert", d / "missing.stl", d / "o.step"), "no such file"),
        (lambda d: ("convert", d / "empty.stl", d / "o.step"), "empty"),
        (lambda d: ("convert", d / "cube.stl", d / "o.obj"), "unknown extension"),
        (lambda d: ("convert", d / "cube.stl", d / "o.step", "--tolerance", "-1"), "--tolerance"),
        (lambda d: ("convert", d / "cube.stl", d / "o.step", "--jobs", "0"), "--jobs"),
        (lambda d: ("convert", d / "cube.stl", d / "nofolder" / "o.step"), "does not exist"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(tmp_path, make_args, message):
    (tmp_path / "empty.stl").write_bytes(b"")
    trimesh.creation.box().export(tmp_path / "cube.stl")
    before = set(tmp_path.iterdir())
    proc = _recon(*make_args(tmp_path), cwd=tmp_path)
    assert proc.returncode == 2
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("recon convert: error:") and message in err[0], proc.stderr
    assert set(tmp_path.iterdir()) == before


def test_sphere_one_smooth_part_becomes_one_sphere_face():
    """A closed body that one smooth part covers has no edge to bound a face with. A sphere bounds itself (its seam
    and poles, as OpenCascade's own sphere): one face, as the true part has; the vertices lie on the sphere, so the
    volume is 4/3 π r³."""
    from recon import convert

    mesh = trimesh.creation.icosphere(subdivisions=4, radius=10.0)
    result = convert((mesh.vertices, mesh.faces), deviation=False)
    assert result.brep.validity.ok
    assert result.report["faces_by_type"] == {"sphere": 1}
    assert result.brep.validity.volume == pytest.approx(4 / 3 * np.pi * 1000.0, rel=1e-5)


def test_closed_torus_becomes_one_torus_face():
    """A torus wraps around both ways: one smooth part with no boundary, one face bounded by its own two seams.
    The vertices lie on the torus, so the volume is the torus's 2π² R r², not the polyhedron's."""
    from recon import convert

    R, r = 10.0, 3.0
    mesh = trimesh.creation.torus(major_radius=R, minor_radius=r, major_sections=64, minor_sections=24)
    result = convert((mesh.vertices, mesh.faces), deviation=False)
    assert result.brep.validity.ok
    assert result.report["faces_by_type"] == {"torus": 1}
    assert result.brep.validity.volume == pytest.approx(2 * np.pi**2 * R * r**2, rel=1e-5)
    assert abs(mesh.volume / (2 * np.pi**2 * R * r**2) - 1) > 1e-3  # (the polyhedron's volume would fail)


def test_noisy_sphere_is_one_sphere_face():
    """The same under noise (σ = 0.1 % of the diameter along the normals), through the decomposition rather than the
    exact-vertex path: the one part's sphere fit is within tolerance, so the body is not cut; one sphere face whose
    radius is the true one to well within σ."""
    from recon import convert

    mesh = trimesh.creation.icosphere(subdivisions=4, radius=10.0)
    rng = np.random.default_rng(0)
    sigma = 0.02
    noisy = mesh.vertices + mesh.vertex_normals * rng.normal(0.0, sigma, (len(mesh.vertices), 1))
    result = convert((noisy, mesh.faces), deviation=False)
    assert result.brep.validity.ok
    assert result.report["faces_by_type"] == {"sphere": 1}
    (fit,) = result.fits.values()
    assert abs(fit.params["radius"] - 10.0) < sigma / 4


def test_sphere_meshed_inside_out_is_one_outward_face():
    """A sphere meshed inside out (every triangle wound the wrong way) is turned round with the mesh: one sphere face
    whose normal points out, a valid solid of volume +4/3 π r³ (a face left facing inward would give −)."""
    from recon import convert

    mesh = trimesh.creation.icosphere(subdivisions=3, radius=5.0)
    result = convert((mesh.vertices, mesh.faces[:, ::-1]), deviation=False)
    assert result.report["faces_by_type"] == {"sphere": 1}
    assert result.brep.validity.ok
    assert result.brep.validity.volume == pytest.approx(4 / 3 * np.pi * 125.0, rel=1e-5)


def test_filleted_box_under_light_noise_has_its_true_faces():
    """box_fillet at σ = 0.05 % of the diagonal: 6 planes, 12 fillet cylinders, 8 corner spheres. The
    decomposition's borders left pieces of fillets in B-spline faces (30 faces, 7 B-splines); grown over their
    borders, the faces take back the triangles that lie on their surfaces and are the true 26."""
    from recon import convert
    from recon.fixtures import load_fixture

    fx = load_fixture("box_fillet", "noisy05")
    result = convert((fx.vertices, fx.faces), deviation=False)
    assert result.brep.validity.ok, result.report["validity"]
    assert result.report["faces_by_type"] == {"plane": 6, "cylinder": 12, "sphere": 8}


def test_revolved_part_under_heavy_noise_recovers_every_face_with_its_type():
    """revolved at σ = 0.2 % of the diagonal. The decomposition leaves the cone in eleven parts, whose pieces
    fit planes, spheres and cylinders within tolerance (19 faces, the cone recovered nowhere). A sphere fits
    the cone's pieces only with a systematic misfit, and merged with their neighbours they are one cone: the
    solid has the true six faces, each recovering a true face (area IoU ≥ 0.5) with that face's type."""
    from recon import convert
    from recon.decompose import face_recovery
    from recon.fixtures import load_fixture

    fx = load_fixture("revolved", "noisy20")
    result = convert((fx.vertices, fx.faces), deviation=False)
    assert result.brep.validity.ok, result.report["validity"]
    assert result.report["faces_by_type"] == {"cylinder": 2, "plane": 2, "cone": 1, "torus": 1}
    rec = face_recovery(result.labels, fx.labels[result.mesh.source_face], result.mesh.face_areas)
    assert (rec.iou >= 0.5).all(), rec.iou
    ours = [result.fits[int(p)].type for p in rec.best_part]
    assert ours == [fx.true_faces[int(t)].type for t in rec.true_ids]


@pytest.fixture(scope="module")
def chamfer_noisy20():
    """box_chamfer at σ = 0.2 % of the diagonal, converted once for the tests below (~40 s each)."""
    from recon import convert
    from recon.fixtures import load_fixture

    fx = load_fixture("box_chamfer", "noisy20")
    return fx, convert((fx.vertices, fx.faces), deviation=False)


def test_chamfered_box_under_heavy_noise_has_no_face_in_two_pieces(chamfer_noisy20):
    """box_chamfer at σ = 0.2 %: the decomposition leaves several of its planes in two pieces, and one plane
    fits each pair. The fit stage keeps every merge, not only those that free the highest label
    (merge_same_surface does not renumber; with the check on the labels' max the solid kept 5 such pairs). By
    the ground truth: no two neighbouring faces of ours are both (≥ 90 % of their area) pieces of one true face."""
    fx, result = chamfer_noisy20
    labels, truth, area = result.labels, fx.labels[result.mesh.source_face], result.mesh.face_areas
    share = np.zeros((labels.max() + 1, truth.max() + 1))
    np.add.at(share, (labels, truth), area)
    share /= share.sum(axis=1, keepdims=True)
    piece_of = np.where(share.max(axis=1) >= 0.9, share.argmax(axis=1), -1)
    pairs = np.asarray(result.mesh.face_adjacency).reshape(-1, 2)
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    two = (a != b) & (piece_of[a] >= 0) & (piece_of[a] == piece_of[b])
    assert not two.any(), sorted({(int(p), int(q)) for p, q in zip(a[two], b[two])})


def test_chamfered_box_under_heavy_noise_is_planes(chamfer_noisy20):
    """box_chamfer at σ = 0.2 %: the chamfers are ~1.5 triangles wide, and a cylinder or cone covered a
    chamfer with strips of both its planes within tolerance (30 faces, 45 % of the area of a true type).
    Grown back over their borders and cut back to the planes inside them, the faces are planes again: the
    issue's target of 90 % of the true area in faces of its type (all planes), and at most the truth's 26
    faces + 15 %."""
    from bench.measure import type_agreement

    fx, result = chamfer_noisy20
    assert result.brep.validity.ok, result.report["validity"]
    assert result.report["n_faces"] <= 1.15 * len(fx.true_faces)
    agreement = type_agreement(result.labels, fx.labels[result.mesh.source_face], result.mesh.face_areas,
                               {p: f.type for p, f in result.fits.items()}, [f.type for f in fx.true_faces])
    assert agreement >= 0.9


def test_chamfered_box_under_heavy_noise_keeps_corner_triangles_as_faces(chamfer_noisy20):
    """box_chamfer at σ = 0.2 %: its 8 corner triangles are 4 mesh triangles (6 vertices) each, and the
    decomposition leaves each inside a chamfer's part. Joined to a chamfer, a corner bends it into a B-spline or
    a compromise cone or cylinder; cut back to the chamfer's plane, the corner went to a neighbour that no plane
    then held, or stayed (no corner recovered, 16 of the 26 true faces). A planar piece that no surface around it
    holds is a face of its own, whether a trim or a compromise surface's giving its triangles back leaves it: by
    the ground truth, corners are recovered (area IoU >= 0.5) as planes, and so are the chamfers they had bent."""
    from recon.decompose import face_recovery

    fx, result = chamfer_noisy20
    assert result.brep.validity.ok, result.report["validity"]
    rec = face_recovery(result.labels, fx.labels[result.mesh.source_face], result.mesh.face_areas)
    corners = [i for i, t in enumerate(rec.true_ids) if fx.true_faces[int(t)].area < 20.0]
    assert len(corners) == 8
    found = [i for i in corners if rec.iou[i] >= 0.5]
    assert len(found) >= 2, rec.iou[corners]
    assert all(result.fits[int(rec.best_part[i])].type == "plane" for i in found)
    assert (rec.iou >= 0.5).sum() >= 20, rec.iou


def test_each_warning_is_printed_once_and_the_report_has_them_all(tmp_path):
    # plate_holes/coarse: its few large triangles leave three faces out of tolerance and a shell to sew
    from recon.fixtures import FIXTURE_DIR

    proc = _recon("convert", Path(FIXTURE_DIR) / "plate_holes_coarse.stl", tmp_path / "p.step", "--no-deviation",
                  "--report", tmp_path / "p.json", cwd=tmp_path)
    assert proc.returncode in (0, 1), proc.stderr[-2000:]
    warnings = json.loads((tmp_path / "p.json").read_text())["warnings"]
    assert warnings
    lines = (proc.stdout + proc.stderr).splitlines()  # the summary (stdout) and the log (stderr)
    shown = [w for w in warnings if f"warning: {w}" in lines]
    assert len(shown) == min(len(warnings), 5)
    for w in warnings:  # not also as a log line of build_solid
        assert sum(w in line for line in lines) == (1 if w in shown else 0), w
    if len(warnings) > 5:
        assert f"… and {len(warnings) - 5} more warnings" in proc.stdout


def test_summary_names_how_many_warnings_it_left_out():
    from recon._cli.convert import SUMMARY_WARNINGS, summary

    report = {"validity": {"ok": True, "shape_type": "solid", "valid": True, "closed": True, "free_edges": 0,
                           "volume": 1.0},
              "faces_by_type": {"plane": 6}, "n_faces": 6, "seconds": {"load": 0.1},
              "warnings": [f"w{i}" for i in range(SUMMARY_WARNINGS + 3)]}
    text = summary(report).splitlines()
    assert [ln for ln in text if ln.startswith("warning: ")] == [f"warning: w{i}" for i in range(SUMMARY_WARNINGS)]
    assert text[-1].startswith("… and 3 more warnings")
    report["warnings"] = report["warnings"][:SUMMARY_WARNINGS]
    assert not summary(report).splitlines()[-1].startswith("…")


def test_cad_export_with_two_triangle_faces_gives_back_its_faces(tmp_path):
    """A CAD export's tessellation, as OpenCascade makes it: a 40 × 30 × 3 plate with a round hole and a
    rectangular slot, 204 triangles; each of its 8 walls is 2 triangles (4 vertices), the hole's 84 triangles
    have their vertices on its two rims only (a sphere holds those too). The 11 true faces come back: 10 planes
    and the hole's cylinder, a valid solid within 10⁻⁶ % of the mesh."""
    from collections import Counter

    from build123d import Box, Cylinder, Pos

    from recon import convert
    from recon.brep import labelled_tessellation

    shape = Box(40, 30, 3) - Pos(-8, 0, 0) * Cylinder(4, 3) - Pos(10, 0, 0) * Box(8, 12, 3)
    v, f, lab, _ = labelled_tessellation(shape, deflection=0.05)
    assert sorted(np.bincount(lab).tolist()) == [2] * 8 + [52, 52, 84]
    path = tmp_path / "plate.stl"
    trimesh.Trimesh(v, f, process=False).export(path)
    rep = convert(path).report
    assert rep["validity"]["ok"]
    assert rep["n_faces"] == len(shape.faces()) == 11
    assert Counter(rep["faces_by_type"]) == Counter({"plane": 10, "cylinder": 1})
    assert rep["deviation"]["mesh_to_shape"]["p95_pct"] < 1e-6


@pytest.mark.parametrize("thickness", [0.5, 1.0])
def test_a_thin_plate_s_holes_are_cylinders(thickness):
    """A 60 × 40 plate 0.5 (1.0) thick with holes of radius 5 and 3, exported as STL like any CAD part: each hole's
    wall is a band whose vertices are its two end circles, which a sphere also holds (the 5 mm hole of the 0.5 plate
    came out a sphere). It converts to its 8 true faces — 6 planes and 2 cylinders of the holes' radii — in a valid
    solid of the plate's volume."""
    from build123d import Box, Cylinder, Pos, export_stl

    from recon import convert

    part = Box(60, 40, thickness) - Pos(-15, 0, 0) * Cylinder(5, 10) - Pos(15, 0, 0) * Cylinder(3, 10)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "plate.stl"
        export_stl(part, str(path), tolerance=0.01, angular_tolerance=0.2)
        result = convert(path, deviation=False)
    assert result.report["faces_by_type"] == {"plane": 6, "cylinder": 2}
    radii = sorted(f.params["radius"] for f in result.fits.values() if f.type == "cylinder")
    assert radii == pytest.approx([3.0, 5.0], rel=1e-4)
    assert result.brep.validity.ok
    assert result.brep.validity.volume == pytest.approx(thickness * (60 * 40 - np.pi * (25 + 9)), rel=1e-3)
