"""A sewn shell mended into faces with no area, and a result no STEP file can hold (export seed 5: a filling whose
loose edge sewing widened to tens of mm was made degenerate by ShapeFix_Face, the solid split in two bodies of one
face each, and STEPCAFControl_Writer wrote a file with no face: exit 3 after the file was written)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
from OCP.BRep import BRep_Builder
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
from OCP.Geom import Geom_Plane, Geom_RectangularTrimmedSurface, Geom_SphericalSurface
from OCP.Geom2d import Geom2d_Line
from OCP.GeomConvert import GeomConvert
from OCP.gp import gp_Ax3, gp_Dir, gp_Dir2d, gp_Pnt, gp_Pnt2d
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FORWARD, TopAbs_REVERSED, TopAbs_VERTEX
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Edge, TopoDS_Face, TopoDS_Shell, TopoDS_Vertex, TopoDS_Wire

from recon.brep import shape_validity, write_shape
from recon.brep._result import BrepResult, collapsed_face_count
from recon.brep._shell import assemble
from recon.errors import UnwritableError

R = 10.0


def _cap(v0: float, v1: float, tol: float) -> TopoDS_Face:
    """A spherical cap of radius R (as a B-spline: its pole row is a singular side) bounded by its natural edges,
    every edge and vertex widened to ``tol`` (what sewing a filling's loose edge leaves)."""
    sphere = Geom_SphericalSurface(gp_Ax3(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), R)
    bs = GeomConvert.SurfaceToBSplineSurface_s(Geom_RectangularTrimmedSurface(sphere, 0, 2 * math.pi, v0, v1))
    face = BRepBuilderAPI_MakeFace(bs, 1e-7).Face()
    b = BRep_Builder()
    edges = TopExp_Explorer(face, TopAbs_EDGE)
    while edges.More():
        edge = TopoDS.Edge_s(edges.Current())
        b.UpdateEdge(edge, tol)
        vertices = TopExp_Explorer(edge, TopAbs_VERTEX)
        while vertices.More():
            b.UpdateVertex(TopoDS.Vertex_s(vertices.Current()), tol)
            vertices.Next()
        edges.Next()
    return face


def _ball(tol: float):
    warnings: list[str] = []
    shape = assemble([_cap(0, math.pi / 2, tol), _cap(-math.pi / 2, 0, tol)], 0.01, False, warnings)
    return shape, warnings


def test_mending_a_sewn_shell_does_not_split_it():
    # The equator's vertex lies R·√2 from each pole, the caps' singular sides: edges wider than that look to
    # ShapeFix_Face as if they lay on the singularity, and it made the shared equator degenerate (two bodies).
    exact, _ = _ball(1e-7)
    assert shape_validity(exact).ok
    shape, warnings = _ball(1.5 * R)
    validity = shape_validity(shape)
    assert (validity.shape_type, validity.n_solids, validity.n_faces) == ("solid", 1, 2), warnings
    assert validity.closed and collapsed_face_count(shape) == 0
    # widening the tolerances does not change the solid: the same volume as the tight caps' (to float rounding)
    assert validity.volume == pytest.approx(shape_validity(exact).volume, rel=1e-9)


def _face_with_no_area() -> TopoDS_Face:
    """A plane face whose one wire is a single degenerate edge (a point): what ShapeFix_Face left of seed 5's faces."""
    b = BRep_Builder()
    face = TopoDS_Face()
    b.MakeFace(face, Geom_Plane(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 1e-7)
    vertex = TopoDS_Vertex()
    b.MakeVertex(vertex, gp_Pnt(0, 0, 0), 1e-7)
    edge = TopoDS_Edge()
    b.MakeEdge(edge)
    b.UpdateEdge(edge, Geom2d_Line(gp_Pnt2d(0, 0), gp_Dir2d(1, 0)), face, 1e-7)
    b.Range(edge, 0.0, 1.0)
    b.Degenerated(edge, True)
    b.Add(edge, vertex.Oriented(TopAbs_FORWARD))
    b.Add(edge, vertex.Oriented(TopAbs_REVERSED))
    wire = TopoDS_Wire()
    b.MakeWire(wire)
    b.Add(wire, edge)
    b.Add(face, wire)
    return face


def test_a_result_with_no_face_of_area_is_not_written(tmp_path):
    b = BRep_Builder()
    shell = TopoDS_Shell()
    b.MakeShell(shell)
    b.Add(shell, _face_with_no_area())
    assert collapsed_face_count(shell) == 1
    result = BrepResult(shell, (), shape_validity(shell), None, ())
    out = tmp_path / "o.step"
    with pytest.raises(UnwritableError, match="took none of the 1 faces"):
        write_shape(out, result)
    assert list(tmp_path.iterdir()) == []  # nothing written, not even the temporary


def test_an_unwritable_result_is_exit_1_in_one_line():
    from recon.cli import EXIT_NOT_GOOD, _one_line

    guard = SimpleNamespace(signum=None)
    code, line = _one_line(UnwritableError("the B-rep holds no face"), guard, False, "recon convert")
    assert (code, line) == (EXIT_NOT_GOOD, "error: no result: the B-rep holds no face")
