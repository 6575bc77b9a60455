"""B-rep building blocks on small hand-made inputs: wires keep their shared edges and vertices, orientation
conflicts, projections onto closed-form and B-spline surfaces, pictures that skip unmeshable faces, filling faces,
self-crossing boundaries and seams (tests/test_brep.py has the whole solids)."""

import numpy as np
import pytest
from build123d import Box

from recon.brep import labelled_tessellation


def _vertex(x, y, tol):
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.gp import gp_Pnt

    v = BRepBuilderAPI_MakeVertex(gp_Pnt(x, y, 0)).Vertex()
    BRep_Builder().UpdateVertex(v, tol)
    return v


def test_wire_keeps_the_shared_edges_it_is_given():
    # Two distinct vertices 0.02 apart with tolerance 0.05: BRepBuilderAPI_MakeWire copies one edge onto the
    # other vertex (it kept 2 of these 3 edges), unrecorded, and the neighbouring face then holds the other edge.
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer

    from recon.brep._edges import shared_wire as _wire

    a, b1, b2, c = _vertex(0, 0, 1e-7), _vertex(10, 0, 0.05), _vertex(10, 0.02, 0.05), _vertex(0, 10, 1e-7)
    edges = [BRepBuilderAPI_MakeEdge(a, b1).Edge(), BRepBuilderAPI_MakeEdge(b2, c).Edge(),
             BRepBuilderAPI_MakeEdge(c, a).Edge()]
    wire = _wire([1, 2, 3], edges)
    exp = TopExp_Explorer(wire, TopAbs_EDGE)
    held = []
    while exp.More():
        held.append(exp.Current())
        exp.Next()
    assert len(held) == 3 and all(h.IsSame(e) for h, e in zip(held, edges))


def test_a_vertex_merged_by_one_face_reaches_the_edges_of_the_next():
    # ShapeFix merging two vertices of one face is handed on: an edge of a face not built yet that meets the
    # old vertex gets the merged one, instead of a third vertex from that face's own ShapeFix.
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.ShapeBuild import ShapeBuild_ReShape
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS

    from recon.brep._edges import hand_on as _hand_on, shared_wire as _wire, subshapes as _subshapes

    a, b, merged, c = _vertex(0, 0, 1e-7), _vertex(10, 0, 1e-3), _vertex(10, 0, 1e-2), _vertex(0, 10, 1e-7)
    mine = BRepBuilderAPI_MakeEdge(a, b).Edge()
    theirs = BRepBuilderAPI_MakeEdge(b, c).Edge()  # in another face only
    local, shared = ShapeBuild_ReShape(), ShapeBuild_ReShape()
    before = _subshapes([_wire([1], [mine])])
    local.Replace(b, merged)
    _hand_on(local, before, shared)
    now = TopoDS.Edge_s(shared.Apply(theirs))
    assert TopExp.FirstVertex_s(now).IsSame(merged)
    assert TopExp.LastVertex_s(TopoDS.Edge_s(shared.Apply(mine))).IsSame(merged)


def test_orientation_conflicts_count_the_edges_of_a_face_turned_over():
    """A closed shell uses every edge once each way; a face turned over runs all its edges with its neighbours."""
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Shell

    from recon.brep._shell import orientation_conflicts

    def shell_of(faces):
        builder, shell = BRep_Builder(), TopoDS_Shell()
        builder.MakeShell(shell)
        for f in faces:
            builder.Add(shell, f)
        return shell

    box = Box(2, 3, 4)
    faces = [f.wrapped for f in box.faces()]
    assert orientation_conflicts(shell_of(faces)) == 0
    assert orientation_conflicts(shell_of([faces[0].Reversed()] + faces[1:])) == 4  # a box face has 4 edges
    # two opposite faces turned over share no edge: 8
    opposite = next(i for i in range(1, 6) if not any(e.wrapped.IsSame(g.wrapped) for e in box.faces()[0].edges()
                                                     for g in box.faces()[i].edges()))
    turned = [f.Reversed() if i in (0, opposite) else f for i, f in enumerate(faces)]
    assert orientation_conflicts(shell_of(turned)) == 8


@pytest.mark.parametrize("kind", ["plane", "sphere", "cylinder", "cone", "torus", "cone-opening-against-axis"])
def test_closed_form_projection_is_opencascades(kind):
    """The analytic surfaces project through recon's geometry model (recon.fit's Plane, Cylinder, ...) in closed
    form; OpenCascade's GeomAPI_ProjectPointOnSurf on the same surface is the slow, obviously right answer. Points
    up to 3 units off surfaces of size ~5 (1 unit off a cone's nappe, 3 from its apex: OpenCascade's cone has both
    nappes): the foot points agree to 1e-9 and the normals up to sign. The last case
    is an OpenCascade cone with a negative semi-angle (it opens against its axis), as a CAD file may hold one."""
    from OCP.Geom import Geom_ConicalSurface
    from OCP.gp import gp_Ax3, gp_Dir, gp_Pnt

    from recon.brep import surface_model
    from recon.brep._surfaces import project_occ
    from recon.fit import SurfaceFit

    c = np.array([1.0, 2.0, 3.0])
    d = np.array([0.3, -0.4, 0.866]) / np.linalg.norm([0.3, -0.4, 0.866])
    params = {
        "plane": {"origin": c.tolist(), "normal": d.tolist()},
        "sphere": {"center": c.tolist(), "radius": 4.0},
        "cylinder": {"axis_point": c.tolist(), "axis_dir": d.tolist(), "radius": 2.5},
        "cone": {"apex": c.tolist(), "axis_dir": d.tolist(), "half_angle": 0.4, "ref_point": (c + 3 * d).tolist(),
                 "ref_radius": 3 * np.tan(0.4)},
        "torus": {"center": c.tolist(), "axis_dir": d.tolist(), "major_radius": 5.0, "minor_radius": 1.5},
    }
    rng = np.random.default_rng(11)
    if kind in params:
        model = surface_model(SurfaceFit(kind, params[kind], {}, 1))
        u = rng.normal(size=(60, 3))
        near = model.project(c + 5 * u / np.linalg.norm(u, axis=1)[:, None])[0]
    else:
        model = surface_model(Geom_ConicalSurface(gp_Ax3(gp_Pnt(*c), gp_Dir(*d), gp_Dir(*np.cross(d, [1, 0, 0]))),
                                                  -0.5, 2.0))
        near = c + np.outer(rng.uniform(1.0, 6.0, 60), -d)  # on the axis, where this cone opens
        near = model.project(near + rng.normal(size=(60, 3)))[0]
        assert np.allclose(model.surface.axis_dir, -d) and model.surface.half_angle == pytest.approx(0.5)
    reach = 3.0
    if model.kind == "cone":  # one nappe in recon, both in OpenCascade: probes away from the apex, within 1
        near, reach = near[np.linalg.norm(near - model.origin, axis=1) > 3.0], 1.0
        assert len(near) >= 20
    probe = near + rng.uniform(-reach, reach, (len(near), 1)) * model.project(near)[1]
    q, n = model.project(probe)
    q_occ, n_occ = project_occ(model.geom, probe)
    np.testing.assert_allclose(q, q_occ, atol=1e-9)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", n, n_occ)), 1.0, atol=1e-9)


def test_bspline_projection_answers_a_repeated_point_from_its_memo_with_the_same_result():
    from recon.brep import surface_model
    from recon.brep._surfaces import project_occ
    from recon.fit import fit_bspline_surface

    # a saddle z = (x² − y²) / 20 over a 10 × 10 grid: a free-form surface only OCC's projection handles
    x, y = np.meshgrid(np.linspace(-5, 5, 21), np.linspace(-5, 5, 21), indexing="ij")
    pts = np.column_stack([x.ravel(), y.ravel(), ((x**2 - y**2) / 20).ravel()])
    idx = np.arange(x.size).reshape(x.shape)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    fit = fit_bspline_surface(pts, faces=np.r_[np.column_stack([a, b, c]), np.column_stack([a, c, d])], tolerance=0.01)
    model = surface_model(fit)
    assert model.kind == "bspline"
    rng = np.random.default_rng(3)
    probe = np.column_stack([rng.uniform(-4, 4, 30), rng.uniform(-4, 4, 30), rng.uniform(-1, 1, 30)])
    probe = np.vstack([probe, probe[:10]])  # ten points asked again
    q_ref, n_ref = project_occ(model.geom, probe)
    q, n = model.project(probe)
    assert len(model._memo) == 30
    q2, n2 = model.project(probe[::-1])  # all from the memo now, in another order
    assert np.array_equal(q, q_ref) and np.array_equal(n, n_ref)
    assert np.array_equal(q2, q_ref[::-1]) and np.array_equal(model.signed_normals(probe), n_ref)
    assert len(model._memo) == 30
    # and the answers are foot points: on the saddle, the offset along its normal
    assert np.abs(q_ref[:, 2] - (q_ref[:, 0] ** 2 - q_ref[:, 1] ** 2) / 20).max() < 0.01


def test_tessellation_for_pictures_leaves_out_a_face_the_mesher_cannot_mesh(monkeypatch, caplog):
    """OpenCascade's mesher gives some valid faces no triangles (a B-spline face of the ABC model did): ground
    truth must raise, a picture leaves that face out and keeps the others with their labels."""
    from recon.brep import _tessellate
    from recon.errors import BrepError

    shape = Box(2, 3, 4)
    v0, f0, lab0, _ = labelled_tessellation(shape, deflection=0.05)
    real = _tessellate.BRep_Tool

    class NoTriangulationForFace2:
        calls = 0

        @classmethod
        def Triangulation_s(cls, face, loc):
            cls.calls += 1
            return None if cls.calls == 3 else real.Triangulation_s(face, loc)

        Surface_s = staticmethod(real.Surface_s)

    monkeypatch.setattr(_tessellate, "BRep_Tool", NoTriangulationForFace2)
    with pytest.raises(BrepError, match="face 2 has no triangulation"):
        labelled_tessellation(shape, deflection=0.05)
    NoTriangulationForFace2.calls = 0
    v, f, lab, surfaces = labelled_tessellation(shape, deflection=0.05, skip_unmeshed=True)
    assert len(surfaces) == 6  # still indexed by face
    assert sorted(set(lab.tolist())) == [0, 1, 3, 4, 5]
    assert len(f) == int((lab0 != 2).sum())  # every other face's triangles, as without the failure
    assert "face 2 could not be meshed" in caplog.text



def test_filling_through_every_sample_only_where_every_third_is_off(monkeypatch):
    """The filling fallback's point sets (recon.brep._filling.FILLING_POINTS): every 3rd of 48 samples first; all
    of them when that gives no face, or a face off the part's area by more than AREA_RATIO_WARNING, and then
    the face whose area is nearer; 10 samples (fewer than 16) are all of them, once."""
    from recon.brep import _filling

    calls = []
    areas = {}

    def through(loops, edges, points, normals, context, *, precision, timeout):
        calls.append(len(points))
        a = areas.get(len(points))
        return (f"face{len(points)}", a, "filled", "") if a else (None, 0.0, "failed", f"no face from {len(points)}")

    monkeypatch.setattr(_filling, "fallback_face_through", through)
    pts = np.zeros((48, 3))
    cases = [  # areas by point count, the part's area, the calls expected, the face expected
        ({16: 1.5, 48: 1.0}, 1.0, [16], "face16"),     # within 2× of the part's: kept
        ({16: 3.75, 48: 1.2}, 1.0, [16, 48], "face48"),  # 3.75× off: all samples, nearer
        ({16: 3.75, 48: 5.0}, 1.0, [16, 48], "face16"),  # all samples farther off: the first stands
        ({48: 1.0}, 1.0, [16, 48], "face48"),           # no face from every 3rd
        ({16: 3.75}, None, [16], "face16"),            # no part area to compare with: the first face
    ]
    for got_areas, expected_area, expected_calls, expected_face in cases:
        calls.clear()
        areas.clear()
        areas.update(got_areas)
        face, _, _, _ = _filling.fallback_face([], [], pts, pts, None, precision=1e-3, timeout=5.0,
                                                expected_area=expected_area)
        assert (calls, face) == (expected_calls, expected_face)
    calls.clear()
    areas.clear()
    face, _, status, msg = _filling.fallback_face([], [], pts[:10], pts[:10], None, precision=1e-3, timeout=5.0,
                                                   expected_area=1.0)
    assert calls == [10] and (face, status, msg) == (None, "failed", "no face from 10")


def test_a_boundary_that_crosses_itself_is_no_face_on_its_surface():
    """A bowtie on a plane: A(0,0) → B(1,1) → C(1,0) → D(0,1) → A crosses itself at (½, ½). ShapeFix cuts it into
    its two triangles (¼ each) and hands back one: that face held half the part's area, and the other half's
    edges were lost to the neighbours that share them (crank: 27 free edges). It is a failure, so that the
    part's fallbacks run."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeVertex
    from OCP.gp import gp_Pnt
    from OCP.ShapeBuild import ShapeBuild_ReShape

    from recon.brep import _faces
    from recon.brep._surfaces import surface_model
    from recon.errors import BrepError
    from recon.fit import SurfaceFit

    plane = SurfaceFit("plane", {"origin": [0.5, 0.5, 0.0], "normal": [0.0, 0.0, 1.0]},
                       {"max": 0.0, "rms": 0.0, "p99": 0.0}, 4)
    corners = [BRepBuilderAPI_MakeVertex(gp_Pnt(*p)).Vertex() for p in [(0, 0, 0), (1, 1, 0), (1, 0, 0), (0, 1, 0)]]
    edges = [BRepBuilderAPI_MakeEdge(corners[i], corners[(i + 1) % 4]).Edge() for i in range(4)]
    with pytest.raises(BrepError, match="split into 2 pieces"):
        _faces.face_on_surface(surface_model(plane), [np.array([1, 2, 3, 4])], edges, 1, ShapeBuild_ReShape(),
                               precision=1e-3)


def test_a_band_round_a_cylinder_gets_its_seam_at_the_middle_of_its_longest_edge():
    """A band of a unit cylinder (z = 0 to 1) bounded by two loops that each wind once round the axis: the bottom
    one of arcs 0°–250° and 250°–360°, the top one of two half circles. The retry for such a face puts the seam
    through the middle of the edge that turns furthest round the axis (the 250° arc, at 125°): that edge is
    split there in two arcs of 125°, and the surface's u = 0 turned to the split point."""
    from types import SimpleNamespace

    from OCP.BRep import BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeVertex
    from OCP.GC import GC_MakeArcOfCircle
    from OCP.gp import gp_Pnt
    from OCP.ShapeBuild import ShapeBuild_ReShape
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    from recon.brep import _seam
    from recon.brep._surfaces import surface_model
    from recon.fit import SurfaceFit

    def at(deg, z):
        a = np.deg2rad(deg)
        return np.array([np.cos(a), np.sin(a), z])

    arcs = [(0, 250, 0.0), (250, 360, 0.0), (0, 180, 1.0), (180, 360, 1.0)]
    vertices = {key: BRepBuilderAPI_MakeVertex(gp_Pnt(*at(*key))).Vertex() for key in [(0, 0.0), (250, 0.0),
                                                                                         (0, 1.0), (180, 1.0)]}
    edges, coords = [], []
    for a, b, z in arcs:
        curve = GC_MakeArcOfCircle(gp_Pnt(*at(a, z)), gp_Pnt(*at((a + b) / 2, z)), gp_Pnt(*at(b, z))).Value()
        edges.append(BRepBuilderAPI_MakeEdge(curve, vertices[(a, z)], vertices[(b % 360, z)]).Edge())
        coords.append(np.array([at(t, z) for t in np.linspace(a, b, 60)]))
    geo = SimpleNamespace(coords=np.concatenate(coords), offsets=np.arange(0, 61 * 4, 60)[:5])
    cylinder = SurfaceFit("cylinder", {"axis_point": [0.0, 0.0, 0.0], "axis_dir": [0.0, 0.0, 1.0], "radius": 1.0},
                          {"max": 0.0, "rms": 0.0, "p99": 0.0}, 100)
    split = _seam.seam_split(surface_model(cylinder), [np.array([1, 2]), np.array([3, 4])], edges, geo,
                             ShapeBuild_ReShape())
    assert split is not None
    turned, edge, pieces = split
    assert edge.IsSame(edges[0])
    ends = []
    exp = TopExp_Explorer(pieces, TopAbs_EDGE)
    while exp.More():
        first, last = BRep_Tool.Range_s(TopoDS.Edge_s(exp.Current()))
        ends.append(abs(last - first))
        exp.Next()
    np.testing.assert_allclose(ends, [np.deg2rad(125.0)] * 2, atol=np.deg2rad(3.0))  # the polyline's 60 points
    u0 = turned.geom.Value(0.0, 0.0)
    assert np.rad2deg(np.arctan2(u0.Y(), u0.X())) == pytest.approx(125.0, abs=3.0)
    assert turned.surface.radius == pytest.approx(1.0)


def test_a_face_on_its_mesh_boundary_where_the_placed_corners_cross():
    """Crank's linear_138: a plane sliver of 4 triangles between poor fits. The network puts each corner on all
    the surfaces that meet there, and that moved one corner 1.2 tolerances across the opposite edge: the
    plane's wire through the placed corners crosses itself, and no face bounded by it exists. The mesh's own
    boundary does not cross itself. Here A(0,0) B(10,0) C(10,1) D(-1,0.5) is the mesh's quadrilateral (area 8);
    D placed at (1,-0.5) puts C→D across A→B at (4, 0)."""
    from recon.brep import _faces
    from recon.brep._surfaces import surface_model
    from recon.fit import SurfaceFit

    plane = surface_model(SurfaceFit("plane", {"origin": [5.0, 0.5, 0.0], "normal": [0.0, 0.0, 1.0]},
                                     {"max": 0.0, "rms": 0.0, "p99": 0.0}, 4))

    class Polylines:  # what `face_on_own_curves` reads of a NetworkGeometry or a CurveNetwork
        def __init__(self, corners):
            c = np.column_stack([np.asarray(corners, dtype=float), np.zeros(4)])
            self.lines = [c[[i, (i + 1) % 4]] for i in range(4)]

        def polyline(self, e):
            return self.lines[e]

    loops = [np.array([1, 2, 3, 4])]
    placed = Polylines([(0, 0), (10, 0), (10, 1), (1, -0.5)])
    mesh = Polylines([(0, 0), (10, 0), (10, 1), (-1, 0.5)])
    assert _faces.face_on_own_curves(plane, loops, placed, 1, precision=1e-3) == (None, 0.0)
    face, area = _faces.face_on_own_curves(plane, loops, mesh, 1, precision=1e-3)
    assert face is not None and area == pytest.approx(8.0, rel=1e-9)
