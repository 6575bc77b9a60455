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
