"""Deviation analysis: exact distances to B-rep faces against analytic answers."""

from __future__ import annotations

import build123d as bd
import numpy as np
import pytest
import trimesh

from OCP.BRepAdaptor import BRepAdaptor_Surface
from OCP.gp import gp_Pnt, gp_Vec
from OCP.Interface import Interface_Static
from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Writer
from OCP.STEPControl import STEPControl_AsIs
from OCP.TCollection import TCollection_ExtendedString
from OCP.TDataStd import TDataStd_Name
from OCP.TDocStd import TDocStd_Document
from OCP.TopAbs import TopAbs_REVERSED
from OCP.XCAFDoc import XCAFDoc_DocumentTool

from recon.brep._distance import BrepDistance
from recon.brep._step_read import faces_of, read_step
from recon.deviation import deviation, plot_deviation
from recon.errors import InputError


def write_named_step(shape, names, path):
    """STEP with XCAF face names (None: unnamed), as recon's B-rep writer is meant to store them."""
    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    top = tool.AddShape(shape, False)
    for face, name in zip(faces_of(shape), names):
        if name is not None:
            TDataStd_Name.Set_s(tool.AddSubShape(top, face), TCollection_ExtendedString(name))
    STEPCAFControl_Controller.Init_s()
    Interface_Static.SetIVal_s("write.stepcaf.subshapes.name", 1)
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    writer.Transfer(doc, STEPControl_AsIs)
    assert writer.Write(str(path)) == 1


def tessellation(shape, tol=0.01):
    verts, tris = shape.tessellate(tol)
    return np.array([(p.X, p.Y, p.Z) for p in verts]), np.array(tris, dtype=np.int64)


def box_sdf(p, half):
    q = np.abs(p) - half
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)


def capped_cylinder_sdf(p, radius, half_height):
    d = np.stack([np.hypot(p[:, 0], p[:, 1]) - radius, np.abs(p[:, 2]) - half_height], axis=1)
    return np.minimum(d.max(axis=1), 0) + np.linalg.norm(np.maximum(d, 0), axis=1)


# ---------------------------------------------------------------- mesh → shape, analytic answers
@pytest.mark.parametrize("delta", [0.25, -0.25])
def test_sphere_offset_mesh_is_exactly_delta(tmp_path, delta):
    # Every icosphere vertex lies on the sphere of radius R + δ: its distance to the STEP sphere of
    # radius R is exactly δ. A tessellated sphere would be off by its deflection (≈1e-2 here).
    R = 10.0
    step = tmp_path / "sphere.step"
    bd.export_step(bd.Sphere(R), str(step))
    ico = trimesh.creation.icosphere(subdivisions=3)
    rep = deviation(ico.vertices * (R + delta), ico.faces, step)
    np.testing.assert_allclose(rep.signed, delta, rtol=1e-9)
    assert rep.mesh_to_shape.max == pytest.approx(abs(delta), rel=1e-9)
    assert rep.mesh_to_shape.signed_min == pytest.approx(delta, rel=1e-9)


def test_box_against_its_own_triangulation_is_zero():
    box = bd.Box(10, 20, 30)
    v, f = tessellation(box)
    rep = deviation(v, f, box)
    assert rep.mesh_to_shape.max <= 1e-9
    # The triangulation of a box is the box: the way back is 0 as well.
    assert rep.shape_to_mesh.max <= 1e-9
    # Per-face counts partition the mesh points.
    assert sum(fd.count for fd in rep.faces) == len(v)


@pytest.mark.parametrize(
    "shape, types",
    [(bd.Cylinder(5, 20), {"cylinder", "plane"}), (bd.Torus(10, 3), {"torus"}), (bd.Cone(5, 2, 10), {"cone", "plane"})],
    ids=["cylinder", "torus", "cone"],
)
def test_curved_solid_against_its_own_triangulation_is_zero(shape, types):
    # Triangulation nodes lie on the exact surfaces; only exact distances make this 0.
    v, f = tessellation(shape)
    rep = deviation(v, f, shape, samples=2000)
    assert {fd.type for fd in rep.faces} == types
    assert rep.mesh_to_shape.max <= 1e-9


def test_box_signed_distance_matches_analytic_sdf():
    # Random points around the box, many projecting outside every face (onto edges and corners):
    # the analytic signed distance function of a box is the reference.
    rng = np.random.default_rng(3)
    p = rng.uniform(-25, 25, (3000, 3))
    s, _, foot = BrepDistance(bd.Box(10, 20, 30).wrapped).signed_distance(p)
    np.testing.assert_allclose(s, box_sdf(p, np.array([5.0, 10.0, 15.0])), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(p - foot, axis=1), np.abs(s), atol=1e-12)


def test_cylinder_signed_distance_matches_analytic_sdf():
    # Outside the caps the nearest point is on a circular edge (closed form), and near the seam
    # the UV wrap and the exact classifier decide: both exercised by uniform points.
    rng = np.random.default_rng(4)
    p = rng.uniform(-15, 15, (3000, 3))
    s, _, _ = BrepDistance(bd.Cylinder(5, 20).wrapped).signed_distance(p)
    np.testing.assert_allclose(s, capped_cylinder_sdf(p, 5.0, 10.0), atol=1e-12)


def test_torus_signed_distance_matches_analytic():
    rng = np.random.default_rng(5)
    p = rng.uniform(-16, 16, (3000, 3))
    s, _, _ = BrepDistance(bd.Torus(10, 3).wrapped).signed_distance(p)
    tube = np.stack([np.hypot(p[:, 0], p[:, 1]) - 10.0, p[:, 2]], axis=1)
    np.testing.assert_allclose(s, np.linalg.norm(tube, axis=1) - 3.0, atol=1e-12)


def test_bspline_face_points_offset_along_normals():
    grid = [[(x, y, 2 * np.sin(x / 5) * np.cos(y / 7)) for x in np.linspace(0, 20, 6)] for y in np.linspace(0, 20, 6)]
    face = bd.Face.make_surface_from_array_of_points(grid)
    adaptor = BRepAdaptor_Surface(face.wrapped)
    u0, u1 = adaptor.FirstUParameter(), adaptor.LastUParameter()
    v0, v1 = adaptor.FirstVParameter(), adaptor.LastVParameter()
    rng = np.random.default_rng(6)
    points, normals = [], []
    for u, v in zip(rng.uniform(u0 + 0.1 * (u1 - u0), u1 - 0.1 * (u1 - u0), 300),
                    rng.uniform(v0 + 0.1 * (v1 - v0), v1 - 0.1 * (v1 - v0), 300)):
        p, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
        adaptor.D1(u, v, p, du, dv)
        n = np.array(du.Crossed(dv).Coord())
        n *= (-1 if face.wrapped.Orientation() == TopAbs_REVERSED else 1) / np.linalg.norm(n)
        points.append(p.Coord())
        normals.append(n)
    points, normals = np.array(points), np.array(normals)
    brep = BrepDistance(face.wrapped)
    assert brep.types == ("bspline",)
    delta = 0.2  # well below the surface's radii of curvature (> 4), so the offset point projects back
    for sign in (1.0, -1.0):
        s, _, _ = brep.signed_distance(points + sign * delta * normals)
        np.testing.assert_allclose(s, sign * delta, atol=1e-6)


# ---------------------------------------------------------------- report
def test_percentages_and_face_names_from_step(tmp_path):
    box = bd.Box(10, 20, 30)
    names = [f"side_{i}" if i != 2 else None for i in range(6)]
    step = tmp_path / "named.step"
    write_named_step(box.wrapped, names, step)
    shape, read_names = read_step(step)
    assert read_names == ("side_0", "side_1", "face_2", "side_3", "side_4", "side_5")

    rng = np.random.default_rng(7)
    v, f = tessellation(box)
    v = v + rng.normal(scale=0.05, size=v.shape)
    rep = deviation(v, f, step, samples=3000)
    assert [fd.name for fd in rep.faces] == list(read_names)
    assert rep.diagonal == pytest.approx(np.linalg.norm(v.max(0) - v.min(0)))
    for stats in (rep.mesh_to_shape, rep.shape_to_mesh):
        js = stats.to_json()
        for key in ("max", "p95", "rms", "mean"):
            assert js[f"{key}_pct"] == pytest.approx(js[key] / rep.diagonal * 100)
    assert sum(fd.count for fd in rep.faces) == len(v)
    # The per-face maxima are the overall maximum's parts.
    assert max(fd.max for fd in rep.faces if fd.max is not None) == pytest.approx(rep.mesh_to_shape.max)
    js = rep.to_json()
    assert set(js) == {"diagonal", "mesh_to_shape", "shape_to_mesh", "faces"}  # no "notes": every figure is exact
    assert {"name", "type", "max", "rms", "count"} <= set(js["faces"][0])


def test_preview_png(tmp_path):
    ico = trimesh.creation.icosphere(subdivisions=2)
    out = tmp_path / "p.png"
    plot_deviation(ico.vertices, ico.faces, ico.vertices[:, 0], out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["p.png"]  # no temp file left


@pytest.mark.parametrize(
    "vertices, faces",
    [(np.empty((0, 3)), np.empty((0, 3), dtype=int)), (np.zeros((3, 2)), np.array([[0, 1, 2]])),
     (np.zeros((3, 3)), np.array([[0, 1, 3]])), (np.full((3, 3), np.nan), np.array([[0, 1, 2]]))],
    ids=["empty", "2d", "index", "nan"],
)
def test_bad_mesh_arrays(vertices, faces):
    with pytest.raises(InputError):
        deviation(vertices, faces, bd.Box(1, 1, 1))


def test_bad_step(tmp_path):
    ico = trimesh.creation.icosphere(subdivisions=1)
    with pytest.raises(InputError, match="does not exist"):
        deviation(ico.vertices, ico.faces, tmp_path / "missing.step")
    junk = tmp_path / "junk.step"
    junk.write_text("not a step file\n")
    with pytest.raises(InputError):
        deviation(ico.vertices, ico.faces, junk)


@pytest.mark.parametrize(
    "make",
    [lambda: bd.fillet(bd.Box(40, 30, 20).edges(), 3) - bd.Cylinder(5, 30), lambda: bd.Cone(5, 2, 10)],
    ids=["filleted_box_with_hole", "cone"],
)
def test_matches_brep_extrema_and_solid_classifier(make):
    # Differential test against the slow, obviously correct path: BRepExtrema_DistShapeShape to
    # the faces for the value, the solid classifier for the sign (the cone's rim is an obtuse
    # edge, where one face's normal alone gives the wrong sign).
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.TopoDS import TopoDS_Compound

    shape = make()
    faces = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(faces)
    for face in faces_of(shape.wrapped):
        builder.Add(faces, face)
    box = shape.bounding_box()
    lo, hi = np.array([box.min.X, box.min.Y, box.min.Z]), np.array([box.max.X, box.max.Y, box.max.Z])
    p = np.random.default_rng(8).uniform(lo - 3, hi + 3, (150, 3))
    # Below the cone's bottom rim, 81° down from horizontal: inside the wedge where the rim is the
    # nearest point and the cone face's own normal (tilted 17° up) points away from the point.
    theta = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    p = np.vstack([p, np.column_stack([5.3 * np.cos(theta), 5.3 * np.sin(theta), np.full(12, -7.0)])])
    s, _, _ = BrepDistance(shape.wrapped).signed_distance(p)
    ref = np.array([
        BRepExtrema_DistShapeShape(BRepBuilderAPI_MakeVertex(gp_Pnt(*q)).Vertex(), faces).Value() for q in p
    ])
    np.testing.assert_allclose(np.abs(s), ref, atol=1e-7)
    inside = np.array([shape.is_inside(tuple(q)) for q in p])
    assert np.array_equal(s < 0, inside)


# ---------------------------------------------------------------- robustness: bounded cost, broken B-reps
def test_point_triangle_distance_analytic():
    from recon.deviation import _point_triangle_distance

    tri = np.array([[[0, 0, 0], [4, 0, 0], [0, 3, 0]]], dtype=float)
    cases = [((1, 1, 2), 2.0),  # above the inside: the height
             ((-3, -4, 0), 5.0),  # beyond vertex a in the plane: |p - a|
             ((2, -1, 0), 1.0),  # beside edge ab
             ((4, 3, 0), 12 / 5)]  # beside the hypotenuse 3x + 4y = 12: |12 + 12 - 12| / 5
    p = np.array([c for c, _ in cases], dtype=float)
    d = _point_triangle_distance(p, np.repeat(tri, len(p), axis=0))
    np.testing.assert_allclose(d, [x for _, x in cases], rtol=1e-15)
    # A degenerate triangle (three collinear points) is its segment: (2, 5, 0) is 5 from the x axis.
    flat = np.array([[[0, 0, 0], [2, 0, 0], [4, 0, 0]]], dtype=float)
    assert _point_triangle_distance(np.array([[2.0, 5, 0]]), flat)[0] == pytest.approx(5.0, rel=1e-15)


def _brute(points, v, f):
    from recon.deviation import _point_triangle_distance

    tri = v[f]
    return np.array([_point_triangle_distance(np.repeat(q[None], len(tri), 0), tri).min() for q in points])


def _sliver_box_beside_a_fine_one():
    """A 40 x 2 x 2 box whose sides are long slivers, next to a 2-unit box subdivided to 0.2: (vertices, faces)."""
    m = trimesh.creation.box(extents=(40, 2, 2))
    fine = trimesh.creation.box(extents=(2, 2, 2)).subdivide_to_size(0.2)
    fine.apply_translation((21, 0, 0))
    mesh = trimesh.util.concatenate([m, fine])
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def test_mesh_distance_exact_where_certified_and_bounded_far_away():
    # A box whose sides are long slivers next to a finely subdivided side: the case where the candidate
    # bound is loose. Points near it must be exact (against brute force); points 1000 diagonals away with
    # a 16-triangle cap are upper bounds (the cost is bounded, not the answer silently wrong).
    from recon.deviation import mesh_distance

    v, f = _sliver_box_beside_a_fine_one()
    rng = np.random.default_rng(7)
    near = rng.uniform((-22, -3, -3), (24, 3, 3), (300, 3))
    d, exact = mesh_distance(v, f, near)
    truth = _brute(near, v, f)
    assert exact.all()
    np.testing.assert_allclose(d, truth, rtol=0, atol=1e-12)
    far = rng.normal(size=(50, 3))
    far = 1000 * 40 * far / np.linalg.norm(far, axis=1, keepdims=True)
    d, exact = mesh_distance(v, f, far, max_candidates=16)  # 1000 diagonals away: ~all triangles qualify
    truth = _brute(far, v, f)
    assert np.all(d >= truth - 1e-9) and np.all(d <= truth + np.linalg.norm(v.max(0) - v.min(0)))
    assert (d[exact] == pytest.approx(truth[exact], abs=1e-9))


def test_mesh_distance_pruning_keeps_the_minimum_to_the_last_bit():
    # Candidates are pruned by each piece's own radius (not the largest): what is measured must still be the
    # least distance over every piece, the same float as brute force over them, near the mesh and a few
    # diagonals away (where the 16 nearest do not settle a point and step 2 measures it).
    from recon.deviation import _pieces, _point_triangle_distance, mesh_distance

    v, f = _sliver_box_beside_a_fine_one()
    rng = np.random.default_rng(11)
    points = np.vstack([rng.uniform((-22, -3, -3), (24, 3, 3), (200, 3)), rng.uniform(-80, 80, (100, 3))])
    d, exact = mesh_distance(v, f, points)
    tri = _pieces(v[f])
    truth = np.array([_point_triangle_distance(np.repeat(q[None], len(tri), 0), tri).min() for q in points])
    assert exact.all()
    np.testing.assert_array_equal(d, truth)


def test_faces_without_triangulation_are_still_measured(monkeypatch):
    # plate_holes/coarse, abc_00000050: BRepMesh left every face of a broken B-rep without triangles and the
    # candidate tree was empty ("zero-size array to reduction operation maximum"). Untriangulated faces are
    # sampled on their p-curves and a UV grid: distances to a box stay the analytic ones.
    from recon.brep import _distance

    monkeypatch.setattr(_distance.BRep_Tool, "Triangulation_s", staticmethod(lambda face, loc: None))
    rng = np.random.default_rng(8)
    p = rng.uniform(-25, 25, (500, 3))
    brep = BrepDistance(bd.Box(10, 20, 30).wrapped)
    s, _, _ = brep.signed_distance(p)
    np.testing.assert_allclose(s, box_sdf(p, np.array([5.0, 10.0, 15.0])), atol=1e-12)
    pts, face = brep.surface_samples(100)
    assert len(pts) > 0 and np.abs(box_sdf(pts, np.array([5.0, 10.0, 15.0]))).max() < 1e-9


def test_signed_distance_in_chunks_equals_one_batch(monkeypatch):
    # Million-vertex meshes are queried in chunks to bound memory; chunking must not change a single value.
    from recon.brep import _distance

    rng = np.random.default_rng(9)
    p = rng.uniform(-25, 25, (1000, 3))
    brep = BrepDistance(bd.Box(10, 20, 30).wrapped)
    whole = brep.signed_distance(p)
    monkeypatch.setattr(_distance, "_QUERY_CHUNK", 97)
    chunked = brep.signed_distance(p)
    told = []
    monkeypatch.setattr(_distance, "_PROGRESS_CHUNK", 300)  # with a progress callback: its own chunks, told
    counted = brep.signed_distance(p, progress=lambda *a: told.append(a))
    for a, b, c in zip(whole, chunked, counted):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)
    np.testing.assert_allclose(chunked[0], box_sdf(p, np.array([5.0, 10.0, 15.0])), atol=1e-12)
    assert told == [(300, 1000, "mesh points measured"), (600, 1000, "mesh points measured"),
                    (900, 1000, "mesh points measured"), (1000, 1000, "mesh points measured")]


def test_model_deviation_of_shifted_box_and_grown_sphere():
    """Analytic answers: a 10 mm box against itself moved 0.1 along x lies 0.1 from it on the two x faces (a third
    of its area, so the p95 too) and nowhere farther; a sphere of radius 10 lies 0.05 from one of 10.05 everywhere,
    both ways. A shape in other units is taken into the reference's by ``shape_scale``."""
    import build123d as bd

    from recon.deviation import model_deviation

    box = bd.Box(10, 10, 10)
    moved = model_deviation(box, bd.Pos(0.1, 0, 0) * bd.Box(10, 10, 10), samples=4000)
    for stats in (moved.to_reference, moved.from_reference):
        assert stats.max == pytest.approx(0.1, rel=1e-9)
        assert stats.p95 == pytest.approx(0.1, rel=1e-9)
        assert 0.1 / 3 - 0.01 < stats.mean < 0.1 / 3 + 0.01
    assert model_deviation(box, box, samples=2000).to_reference.max < 1e-12
    grown = model_deviation(bd.Sphere(10), bd.Sphere(10.05), samples=4000)
    for stats in (grown.to_reference, grown.from_reference):
        assert stats.max == pytest.approx(0.05, rel=1e-9) and stats.rms == pytest.approx(0.05, rel=1e-9)
    assert grown.to_json()["to_reference"]["max_pct"] == pytest.approx(100 * 0.05 / grown.to_reference.diagonal)
    # the box in cm against the moved box in mm: the same distances, in mm
    cm = model_deviation(bd.Box(1, 1, 1), bd.Pos(0.1, 0, 0) * bd.Box(10, 10, 10), samples=4000, shape_scale=10.0)
    assert cm.to_reference.max == pytest.approx(0.1, rel=1e-9) and cm.from_reference.max == pytest.approx(0.1, rel=1e-9)


def test_distance_does_not_depend_on_an_earlier_tessellation():
    """BRepMesh refines a triangulation a shape already has instead of starting afresh: measured on the shape
    itself, a part meshed finely before (here at 0.001) gave 4x the nodes of a fresh one, and a B-rep with a
    face BRepMesh cannot mesh took minutes and gigabytes. BrepDistance measures a copy without it."""
    import build123d as bd
    from OCP.BRepMesh import BRepMesh_IncrementalMesh

    from recon.brep._distance import BrepDistance

    fresh = BrepDistance((bd.Box(20, 20, 10) - bd.Cylinder(4, 10)).wrapped)
    part = bd.Box(20, 20, 10) - bd.Cylinder(4, 10)
    BRepMesh_IncrementalMesh(part.wrapped, 0.001, False, 0.1, True)
    again = BrepDistance(part.wrapped)
    assert [len(f.nodes) for f in again._faces] == [len(f.nodes) for f in fresh._faces]
    p = np.array([[0.0, 0.0, 8.0], [3.0, 0.0, 0.0], [12.0, 3.0, 1.0]])
    assert np.allclose(again.signed_distance(p)[0], fresh.signed_distance(p)[0], atol=1e-12)




def test_names_for_a_shape_follow_its_face_order(tmp_path):
    """A box moved 0.1 along +z against its own dense mesh: the points of its top and bottom lie 0.1 from the
    moved top and bottom faces, the points of its sides slide along the sides (distance 0). The names given in
    ``faces_of`` order carry those figures."""
    box = bd.Box(10, 20, 30)
    mesh = trimesh.creation.box(extents=(10, 20, 30)).subdivide_to_size(1.0)
    moved = box.moved(bd.Location((0, 0, 0.1)))
    z = [bd.Face(face).center().Z for face in faces_of(moved.wrapped)]
    names = ["top" if c > 15 else "bottom" if c < -14 else f"side_{i}" for i, c in enumerate(z)]
    rep = deviation(mesh.vertices, mesh.faces, moved, samples=2000, names=names)
    assert [fd.name for fd in rep.faces] == names
    by_name = {fd.name: fd for fd in rep.faces}
    for end in ("top", "bottom"):
        assert by_name[end].rms == pytest.approx(0.1, abs=1e-6)
    for fd in rep.faces:
        if fd.name.startswith("side_"):
            assert fd.rms < 0.02
    with pytest.raises(InputError, match="5 names for a shape of 6 faces"):
        deviation(mesh.vertices, mesh.faces, moved, names=names[:5])
    step = tmp_path / "box.step"
    write_named_step(box.wrapped, [None] * 6, step)
    with pytest.raises(InputError, match="read from it"):
        deviation(mesh.vertices, mesh.faces, step, names=names)


def test_shape_to_mesh_percentiles_are_shares_of_the_area():
    """A 10-unit box with a hemispherical bump of radius 1 on top, against the plain box's 12 triangles: the bump
    is 1 % of the area (2π of 606), every other point of the shape lies on the mesh. So 95 % of the area is at
    distance 0 — the p95 is 0 — and the farthest point, the bump's apex, is 1 from the top. The bump's
    tessellation nodes (a few hundred, where the planes have their corners only) are not to outweigh the
    area-uniform samples: with 500 of those they did (p95 0.9)."""
    shape = bd.Box(10, 10, 10) + bd.Pos(0, 0, 5) * bd.Sphere(1)
    box = trimesh.creation.box(extents=(10, 10, 10))
    rep = deviation(np.asarray(box.vertices), np.asarray(box.faces), shape, samples=500)
    assert rep.shape_to_mesh.p95 <= 1e-9
    assert rep.shape_to_mesh.max == pytest.approx(1.0, abs=1e-6)


def test_signed_distance_defers_boundary_normals_without_changing_a_bit(monkeypatch):
    # signed_distance computes a boundary foot's normal (a surface projection on a B-spline face) only where it
    # counts for the sign: the result must be the same floats as with every face's normals computed up front.
    from pathlib import Path

    from OCP.BRepBuilderAPI import BRepBuilderAPI_NurbsConvert

    # the plate with holes as B-spline faces: points over a hole project into it and take the hole's edge
    shape, _ = read_step(Path(__file__).resolve().parents[1] / "fixtures" / "data" / "plate_holes.step")
    brep = BrepDistance(BRepBuilderAPI_NurbsConvert(shape, True).Shape())
    assert set(brep.types) == {"bspline"}
    rng = np.random.default_rng(12)
    lo, hi = brep._sample_points.min(axis=0), brep._sample_points.max(axis=0)
    p = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), (600, 3))
    computed = []
    monkeypatch.setattr(BrepDistance, "_edge_normals",
                        lambda self, i, f, _o=BrepDistance._edge_normals: computed.append(len(f)) or _o(self, i, f))
    deferred = brep.signed_distance(p)
    assert sum(computed) > 0  # some boundary normals did count
    up_front = BrepDistance._face_query_deferred

    def all_normals(self, index, q, *, uv0=None):
        best, foot, nrm, later = up_front(self, index, q, uv0=uv0)
        nrm[later] = self._edge_normals(index, foot[later])
        return best, foot, nrm, later[:0]

    monkeypatch.setattr(BrepDistance, "_face_query_deferred", all_normals)
    for got, want in zip(deferred, brep.signed_distance(p)):
        np.testing.assert_array_equal(got, want)
    assert (np.sign(deferred[0]) < 0).any() and (np.sign(deferred[0]) > 0).any()


def test_surface_samples_of_faces_without_triangles_are_empty():
    """A result whose faces all failed to triangulate has nothing to sample: empty arrays, not a crash (an export
    part once ended recon with exit 3 here instead of exit 1 with its verdict)."""
    brep = BrepDistance(bd.Box(10, 10, 10).wrapped)
    brep._faces = []  # what BrepDistance holds when no face could be triangulated or sampled
    points, face = brep.surface_samples(100)
    assert points.shape == (0, 3) and face.shape == (0,) and face.dtype == np.int64


def test_pieces_cover_the_same_area_with_the_largest_cut_first():
    # The slivers are cut (the surface and its area unchanged) until no piece's radius exceeds twice the side of the
    # median triangle's square, the budget allowing: the largest radius is what loosens mesh_distance's bounds.
    from recon.deviation import _pieces

    v, f = _sliver_box_beside_a_fine_one()
    tri = v[f]

    def areas(t):
        return 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)

    pieces = _pieces(tri)
    assert areas(pieces).sum() == pytest.approx(areas(tri).sum(), rel=1e-12)
    def radius(t):
        return np.linalg.norm(t - t.mean(axis=1, keepdims=True), axis=2).max(axis=1)

    r, budget, target = radius(pieces), 4 * len(tri) + 10_000, 2.0 * np.sqrt(np.median(areas(tri)))
    assert len(pieces) <= budget
    assert r.max() <= radius(tri).max() / 4  # the box's 40-long slivers are cut
    # stopped at the target, or where cutting the next largest (within 1/√2 of the largest) would pass the budget
    assert r.max() <= target or len(pieces) + (r > max(target, r.max() / np.sqrt(2))).sum() > budget


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mesh_distance_is_the_all_pairs_minimum_to_the_last_bit(seed):
    """The box hierarchy and the box bounds only rule pieces out: the distance is the least over every piece
    (:func:`recon.deviation._pieces`) of the same point–triangle distance, bit for bit, on slivers (a CAD export's
    fans, long and thin) with points on, near and far from them."""
    import sys

    dev = sys.modules["recon.deviation"]
    rng = np.random.default_rng(seed)
    m = 300
    base = rng.uniform(-10, 10, (m, 3))
    long = rng.normal(size=(m, 3)) * rng.uniform(2, 20, (m, 1))
    thin = rng.normal(size=(m, 3)) * 0.01
    v = np.concatenate([base, base + long, base + long / 2 + thin])
    f = np.arange(3 * m).reshape(3, m).T
    tri = v[f]
    w = rng.dirichlet(np.ones(3), 400)
    on = np.einsum("nk,nkd->nd", w, tri[rng.integers(0, m, 400)])
    pts = np.concatenate([on, on + rng.normal(size=on.shape) * 1e-3, rng.uniform(-40, 40, (400, 3))])
    got, exact = dev.mesh_distance(v, f, pts)
    pieces = dev._pieces(tri)
    want = np.array([dev._point_triangle_distance(np.repeat(q[None], len(pieces), 0), pieces).min() for q in pts])
    assert exact.all()
    assert np.array_equal(got, want)


def test_mesh_distance_one_pass_and_stepwise_paths_agree_to_the_last_bit():
    """Within the budgets every sample is measured in one pass down the box hierarchy; past them (a cap of one piece
    here) the stepwise path runs. Wherever the stepwise path calls a distance exact it is the same float as the one
    pass's, near the slivers and a few diagonals away: the two paths are one minimum, found two ways."""
    from recon.deviation import mesh_distance

    v, f = _sliver_box_beside_a_fine_one()
    rng = np.random.default_rng(13)
    points = np.vstack([rng.uniform((-22, -3, -3), (24, 3, 3), (300, 3)), rng.uniform(-80, 80, (100, 3))])
    one, exact_one = mesh_distance(v, f, points)
    step, exact_step = mesh_distance(v, f, points, max_candidates=1)
    assert exact_one.all()
    assert 0 < exact_step.sum() < len(points)  # both of the stepwise path's outcomes are exercised
    assert np.array_equal(one[exact_step], step[exact_step])
    assert np.all(step[~exact_step] >= one[~exact_step])  # the others are upper bounds
