"""Edges on a plane whose 3D curve leaves the plane's p-curve: the curve is moved onto the p-curve.

A STEP reader does not take a plane's p-curves from the file: OpenCascade's ``StepToTopoDS_TranslateEdgeLoop``
sets ``hasPcurve = False`` on a plane and projects each edge's 3D curve onto it (FreeCAD reads through it). A
built face whose p-curve lies beside its edge's 3D curve (within the edge's tolerance: valid in memory) comes
back from the file with the projection as its boundary, which can cross a neighbouring edge or miss a vertex
(bench/brep.md: crank's linear_117, linear_89, linear_110). Lifting the plane's p-curve into 3D as the edge's
curve makes the projection the reader takes the face's own boundary; the other face of the edge keeps its
p-curve, and the edge's tolerance grows to cover it.
"""

from __future__ import annotations

import logging

import numpy as np
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Curve2d, BRepAdaptor_Surface
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.GeomAbs import GeomAbs_Plane
from OCP.GeomAPI import GeomAPI
from OCP.ShapeFix import ShapeFix_ShapeTolerance
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_VERTEX
from OCP.TopExp import TopExp
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS
from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape

__all__ = ["lift_planar_edges", "planar_offsets"]

log = logging.getLogger(__name__)

#: Samples along an edge where its curves are compared (BRepCheck compares at 23; more, to bound what it sees).
SAMPLES = 61

#: Margin over a measured curve gap when it becomes a tolerance (5%: sampling can miss the peak between samples).
TOLERANCE_SLACK = 1.05


def _points(edge, face=None, ts=None) -> np.ndarray:
    """Points of ``edge``'s 3D curve, or of its p-curve on ``face`` mapped onto the face's surface, at ``ts``."""
    if face is None:
        c = BRepAdaptor_Curve(edge)
        return np.array([[p.X(), p.Y(), p.Z()] for p in (c.Value(float(t)) for t in ts)])
    c2, s = BRepAdaptor_Curve2d(edge, face), BRepAdaptor_Surface(face)
    out = []
    for t in ts:
        uv = c2.Value(float(t))
        p = s.Value(uv.X(), uv.Y())
        out.append([p.X(), p.Y(), p.Z()])
    return np.array(out)


def _edge_faces(shape) -> list[tuple[object, list]]:
    """Each edge of ``shape`` with its distinct faces."""
    found = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, found)
    out = []
    for i in range(1, found.Extent() + 1):
        faces: list = []
        for f in found.FindFromIndex(i):
            if not any(f.IsSame(g) for g in faces):
                faces.append(TopoDS.Face_s(f))
        out.append((TopoDS.Edge_s(found.FindKey(i)), faces))
    return out


def _is_plane(face) -> bool:
    return BRepAdaptor_Surface(face).GetType() == GeomAbs_Plane


def _liftable(edge, faces) -> object | None:
    """The one plane face of ``edge`` whose p-curve can become its 3D curve, or None."""
    if BRep_Tool.Degenerated_s(edge) or not BRep_Tool.SameRange_s(edge) or not BRep_Tool.SameParameter_s(edge):
        return None
    planes = [f for f in faces if _is_plane(f)]
    # two planes: each reader projection needs the curve in its own plane; a seam has two p-curves on it
    if len(planes) != 1 or BRep_Tool.IsClosed_s(edge, planes[0]):
        return None
    if BRep_Tool.CurveOnSurface_s(edge, planes[0], 0.0, 0.0) is None:
        return None
    return planes[0]


def planar_offsets(shape) -> list[tuple[object, object, list, float]]:
    """``(edge, plane face, its faces, offset)`` for each edge with one plane face: the largest distance, along the plane,
    between its 3D curve and its p-curve there (what a STEP reader's projection moves that boundary by)."""
    out = []
    for edge, faces in _edge_faces(shape):
        face = _liftable(edge, faces)
        if face is None:
            continue
        a, b = BRep_Tool.Range_s(edge)
        ts = np.linspace(a, b, SAMPLES)
        n = BRepAdaptor_Surface(face).Plane().Axis().Direction()
        normal = np.array([n.X(), n.Y(), n.Z()])
        d = _points(edge, None, ts) - _points(edge, face, ts)
        along = d - np.outer(d @ normal, normal)
        out.append((edge, face, faces, float(np.linalg.norm(along, axis=1).max())))
    return out


def _lift(edge, face, others: list) -> tuple[object, TopLoc_Location, float, list] | None:
    """Give ``edge`` its p-curve on the plane ``face`` as its 3D curve; returns what undoes it."""
    loc = TopLoc_Location()
    old_curve = BRep_Tool.Curve_s(edge, loc, 0.0, 0.0)
    if old_curve is None:
        return None
    old_tol = BRep_Tool.Tolerance_s(edge)
    vertices = [TopExp.FirstVertex_s(edge), TopExp.LastVertex_s(edge)]
    old_vtol = [BRep_Tool.Tolerance_s(v) for v in vertices]
    c2d = BRep_Tool.CurveOnSurface_s(edge, face, 0.0, 0.0)
    lifted = GeomAPI.To3d_s(c2d, BRepAdaptor_Surface(face).Plane())
    builder = BRep_Builder()
    # (global coordinates with an identity location: UpdateEdge expresses it in the edge's own location)
    builder.UpdateEdge(edge, lifted, TopLoc_Location(), old_tol)
    a, b = BRep_Tool.Range_s(edge)
    ts = np.linspace(a, b, SAMPLES)
    curve = _points(edge, None, ts)
    gap = max(float(np.linalg.norm(curve - _points(edge, f, ts), axis=1).max()) for f in others + [face])
    builder.UpdateEdge(edge, max(old_tol, TOLERANCE_SLACK * gap))
    for v, end in zip(vertices, (curve[0], curve[-1])):
        p = BRep_Tool.Pnt_s(v)
        d = float(np.linalg.norm(end - np.array([p.X(), p.Y(), p.Z()])))
        builder.UpdateVertex(v, max(BRep_Tool.Tolerance_s(edge), TOLERANCE_SLACK * d))
    return old_curve, loc, old_tol, list(zip(vertices, old_vtol))


def _undo(edge, undo) -> None:
    old_curve, loc, old_tol, vtols = undo
    BRep_Builder().UpdateEdge(edge, old_curve, loc, old_tol)
    fix = ShapeFix_ShapeTolerance()
    fix.SetTolerance(edge, old_tol, TopAbs_EDGE)
    for v, t in vtols:
        fix.SetTolerance(v, t, TopAbs_VERTEX)


def lift_planar_edges(shape, tolerance: float) -> list[float]:
    """Move onto its plane's p-curve the 3D curve of each edge whose p-curve on its one plane face lies more than
    ``tolerance`` beside it (:func:`planar_offsets`), in place, where its faces stay valid.

    ``tolerance`` is the model's: a reader's boundary moved by less stays within what the model is accurate to.
    Returns the offsets (model units) of the edges moved.
    """
    moved = []
    for edge, face, faces, offset in planar_offsets(shape):
        if offset <= tolerance:
            continue
        others = [f for f in faces if not f.IsSame(face)]
        before = [BRepCheck_Analyzer(f).IsValid() for f in faces]
        undo = _lift(edge, face, others)
        if undo is None:
            continue
        after = [BRepCheck_Analyzer(f).IsValid() for f in faces]
        if any(b and not a for b, a in zip(before, after)):
            _undo(edge, undo)
            log.info("lift_planar_edges: an edge %.3g off its plane's p-curve kept: its faces would not be valid",
                     offset)
            continue
        moved.append(offset)
    if moved:
        log.info("lift_planar_edges: %d edges moved onto their plane's p-curve (up to %.3g beside it)", len(moved),
                 max(moved))
    return moved
