"""Edges within the sewing tolerance of their surfaces at a grazing meeting (crank's tongue), and the filling's input
check for vertex tolerances grown past the distance to other vertices (crank's linear_138): bench/brep.md, 2026-12-04."""

import numpy as np
import pytest


def _pentagon(tolerances):
    """Crank's linear_138 boundary, scaled by 100 and straightened: five straight edges in the plane y = 0 on shared
    vertices with the given tolerances (crank's, scaled: 2, 2, 0.01, 1.1, 1.1)."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeVertex
    from OCP.gp import gp_Pnt

    builder = BRep_Builder()
    vertices = []
    for (x, z), tol in zip([(0, 0), (0, 3.5), (1.5, 5), (0.85, 4.5), (0.9, 0.1)], tolerances):
        v = BRepBuilderAPI_MakeVertex(gp_Pnt(float(x), 0.0, float(z))).Vertex()
        builder.UpdateVertex(v, float(tol))
        vertices.append(v)
    return [BRepBuilderAPI_MakeEdge(vertices[i], vertices[(i + 1) % 5]).Edge() for i in range(5)]


@pytest.mark.parametrize("tolerances, refused", [
    ([2, 2, 0.01, 1.1, 1.1], True),  # crank's: vertex 4 lies 1.31 from vertex 2, within its 2
    ([1e-7] * 5, False),
    ([0.5] * 5, False),
    ([1.2, 1.2, 0.01, 0.6, 0.6], False),  # vertex 2's tolerance now short of vertex 4
])
def test_filling_check_refuses_exactly_the_loops_makefilling_fails_on(tolerances, refused):
    """MakeFilling joins a new edge's end to any vertex of its wire so far within either one's tolerance; where that
    leaves its wire without two ends it raises "TopoDS_Vertex hasn't gp_Pnt" (shown here in a child process: such
    calls have crashed). :func:`wire_joins` takes MakeFilling's steps on copies and says so before the call; where
    it says nothing MakeFilling makes a face."""
    from recon.brep._faces import face_in_child
    from recon.brep._filling import filled_face, wire_joins
    from recon.errors import BrepError

    why = wire_joins(_pentagon(tolerances))
    inner = np.array([[0.5, 0.0, 2.0]])
    if refused:
        assert "no ends" in why
        with pytest.raises(BrepError, match="gp_Pnt"):
            face_in_child(filled_face, (_pentagon(tolerances), inner), "BRepOffsetAPI_MakeFilling", 60.0)
    else:
        assert why == ""
        assert not face_in_child(filled_face, (_pentagon(tolerances), inner), "BRepOffsetAPI_MakeFilling", 60.0).IsNull()


def test_a_long_last_chord_into_a_tip_is_placed_within_the_sewing_tolerance_of_both_surfaces():
    """Crank's tongue (e63, e68): an edge runs along the line where a cylinder (part 0, radius 1 about the z axis) and
    a plane (part 1) cut each other, in short chords, then turns and ends in one long chord to the tip, where the plane
    meets the cylinder again but nowhere between: the plane holds the chord, 12 tolerances inside the cylinder at its
    middle. Fitted through those points the curve lies farther off the cylinder than the sewing tolerance (crank's
    bowed 10.4 T off its cylinder, and its neighbour's 30 T sideways across it). Placed, every point of the edge is
    within the sewing tolerance of both surfaces and of its points, and its new points lie on the chord's normal
    plane through the axis, not sideways along the chord."""
    from recon.fit import fit_edge_curve
    from recon.network._placement import STRAY_FACTOR, _curve_points, _within_sewing

    tol = 1e-3
    sag = 12 * tol
    half = np.arccos(1 - sag)  # the chord from angle -half to +half at z = 0 lies `sag` inside the unit circle
    normal = np.array([1.0, 0.0, 0.0])  # the plane x = cos(half): it holds the chord and cuts the cylinder twice

    def project(part, pts):
        if part == 0:
            r = np.linalg.norm(pts[:, :2], axis=1)[:, None]
            e = np.column_stack([pts[:, :2] / r, np.zeros(len(pts))])
            return np.column_stack([e[:, :2], pts[:, 2]]), e
        d = pts @ normal - np.cos(half)
        return pts - d[:, None] * normal, np.tile(normal, (len(pts), 1))

    c, s = np.cos(half), np.sin(half)
    along = np.column_stack([np.full(6, c), np.full(6, -s), np.linspace(-0.05, 0.0, 6)])  # on both: their line
    pts = np.vstack([along, [[c, s, 0.0]]])  # then the long chord (sin(half) × 2 = 0.31, 245 T) to the tip
    curve = fit_edge_curve(pts, closed=False, tolerance=tol)
    sewing = STRAY_FACTOR * tol

    def worst(c_, p_):
        x = _curve_points(c_, 400)
        off = max(float(np.max(np.linalg.norm(project(k, x)[0] - x, axis=1))) for k in (0, 1))
        s_ = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p_, axis=0), axis=1))])
        t = np.linspace(0.0, s_[-1], 4000)
        poly = np.column_stack([np.interp(t, s_, p_[:, j]) for j in range(3)])
        return off, float(np.max(np.min(np.linalg.norm(x[:, None] - poly[None], axis=2), axis=1)))

    assert max(worst(curve, pts)) > sewing  # the failing edge: farther off than sewing bridges
    placed, edge = _within_sewing(pts, curve, 0, 1, project, tolerance=tol, max_points=64, fit_curve=fit_edge_curve)
    assert len(placed) > len(pts)
    off, from_points = worst(edge, placed)
    assert off <= sewing and from_points <= sewing
    new = placed[6:-1]  # the points put on the chord: moved only along x (the normals of both surfaces there)
    assert np.all(np.abs(new[:, 2]) <= 1e-12) and np.all(np.abs(new[:, 1]) <= s + 1e-12)
