"""A STEP file reads back as the B-rep it was written from: a plane's boundary is its edges' 3D curves.

OpenCascade's STEP reader (FreeCAD's) ignores the p-curves a file gives on a plane and projects the edges' 3D
curves onto it. crank's linear_117 (bench/brep.md) had an edge whose 3D curve ran 3.8 T beside its p-curve on the
plane: valid in memory, self-intersecting once written and read back. The strip below is the same mechanism, made
small: a plane strip 4 T wide whose long edge's 3D curve bows 6 T sideways (within its tolerance) across the strip.
Read back, the strip's projected boundary crosses itself and the reader's ShapeFix cuts it into 3 faces of another
area (crank: 142 faces written, 144 read, 4 of them invalid).
"""

from __future__ import annotations

import pytest

pytest.importorskip("OCP")

from OCP.BRep import BRep_Builder, BRep_Tool  # noqa: E402
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakeWire  # noqa: E402
from OCP.BRepCheck import BRepCheck_Analyzer  # noqa: E402
from OCP.BRepLib import BRepLib  # noqa: E402
from OCP.Geom import Geom_BezierCurve, Geom_Plane  # noqa: E402
from OCP.Geom2d import Geom2d_Line  # noqa: E402
from OCP.gp import gp_Dir, gp_Dir2d, gp_Pnt, gp_Pnt2d  # noqa: E402
from OCP.STEPControl import STEPControl_StepModelType, STEPControl_Writer  # noqa: E402
from OCP.TColgp import TColgp_Array1OfPnt  # noqa: E402
from OCP.TopAbs import TopAbs_EDGE  # noqa: E402
from OCP.TopExp import TopExp, TopExp_Explorer  # noqa: E402
from OCP.TopoDS import TopoDS  # noqa: E402

from recon.brep._export import model_units  # noqa: E402
from recon.brep._planar import lift_planar_edges, planar_offsets  # noqa: E402
from recon.brep._step_read import faces_of, read_step  # noqa: E402

T = 0.01  # the model tolerance
WIDTH = 4 * T  # the strip's width
BOW = 6 * T  # how far the bottom edge's 3D curve runs beside its p-curve (across the strip)


def _strip():
    """The plane z = 0 bounded by [0, 1] x [0, WIDTH] in p-curves; the bottom edge's 3D curve is a parabola
    y = 4 BOW t (1 - t), x = t (the p-curve's parameter): BOW off its p-curve at the middle, within its tolerance."""
    plane = Geom_Plane(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1))
    corners = [(0.0, 0.0), (1.0, 0.0), (1.0, WIDTH), (0.0, WIDTH)]
    wire = BRepBuilderAPI_MakeWire()
    edges = []
    for (u0, v0), (u1, v1) in zip(corners, corners[1:] + corners[:1]):
        length = ((u1 - u0) ** 2 + (v1 - v0) ** 2) ** 0.5
        line = Geom2d_Line(gp_Pnt2d(u0, v0), gp_Dir2d(u1 - u0, v1 - v0))
        edge = BRepBuilderAPI_MakeEdge(line, plane, 0.0, length).Edge()
        BRepLib.BuildCurves3d_s(edge)
        edges.append(edge)
        wire.Add(edge)
    face = BRepBuilderAPI_MakeFace(plane, wire.Wire()).Face()
    bottom = next(e for e in _edges(face)
                  if all(abs(BRep_Tool.Pnt_s(v).Y()) < 1e-12 for v in (TopExp.FirstVertex_s(e), TopExp.LastVertex_s(e))))
    poles = TColgp_Array1OfPnt(1, 3)
    for i, p in enumerate([gp_Pnt(0, 0, 0), gp_Pnt(0.5, 2 * BOW, 0), gp_Pnt(1, 0, 0)], 1):
        poles.SetValue(i, p)
    # the bow's peak is BOW off the p-curve; its tolerance covers it (5% over)
    BRep_Builder().UpdateEdge(bottom, Geom_BezierCurve(poles), 1.05 * BOW)
    return face


def _edges(face) -> list:
    out, exp = [], TopExp_Explorer(face, TopAbs_EDGE)
    while exp.More():
        out.append(TopoDS.Edge_s(exp.Current()))
        exp.Next()
    return out


def _read_back(shape, tmp_path):
    writer = STEPControl_Writer()
    writer.Transfer(shape, STEPControl_StepModelType.STEPControl_AsIs)
    path = tmp_path / "strip.step"
    writer.Write(str(path))
    with model_units("mm"):
        back, _ = read_step(path)
    return back


def test_a_plane_reads_back_with_its_edges_projected(tmp_path):
    face = _strip()
    assert BRepCheck_Analyzer(face).IsValid()  # in memory: the bow is within the edge's tolerance
    (offset,) = [o for *_, o in planar_offsets(face) if o > T]
    assert offset == pytest.approx(BOW, rel=1e-3)
    # the reader projects the bowed curve: it crosses the strip's far edge, and the reader cuts the loops apart
    back = _read_back(face, tmp_path)
    assert len(faces_of(back)) == 3
    assert abs(_area(back) - _area(face)) > 0.5 * _area(face)


def test_lifted_edges_read_back_valid(tmp_path):
    face = _strip()
    moved = lift_planar_edges(face, T)
    assert moved == [pytest.approx(BOW, rel=1e-3)]
    assert BRepCheck_Analyzer(face).IsValid()
    assert not [o for *_, o in planar_offsets(face) if o > T]
    back = _read_back(face, tmp_path)
    assert BRepCheck_Analyzer(back).IsValid()
    assert len(faces_of(back)) == 1
    # the same face: its area to round-off (1e-9 of it)
    assert _area(back) == pytest.approx(_area(face), rel=1e-9)
    assert _area(face) == pytest.approx(WIDTH, rel=1e-9)


def _area(shape) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(shape, props)
    return props.Mass()
