"""A face on a cylinder or cone whose seam ShapeFix put in the wrong place, tried again with the seam moved."""

from __future__ import annotations

import logging

import numpy as np
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeVertex
from OCP.TopAbs import TopAbs_REVERSED
from OCP.TopExp import TopExp
from OCP.TopoDS import TopoDS_Wire

from .._array import x_or_y_helper
from ..network import NetworkGeometry
from ..errors import BrepError
from ._edges import pnt, vec3
from ._faces import face_on_surface
from ._surfaces import SurfaceModel

log = logging.getLogger(__name__)


#: Surfaces whose band between two loops that each wind once round the axis may need its seam moved: ShapeFix_Face
#: puts the seam through the vertex nearest u = 0, and where that vertex sits beside an edge along the axis the seam
#: runs along it and cuts the face in two; the face is then tried again with its seam at the middle of its longest
#: edge across the turn (bench/brep.md).
SEAM_SURFACES = ("cylinder", "cone")


def _winding(model: SurfaceModel, pts: np.ndarray) -> float:
    """How many times the closed polyline ``pts`` winds round ``model``'s axis."""
    rel = pts - model.origin
    d = _unit_np(model.axis)
    x = _unit_np(np.cross(d, x_or_y_helper(d)))
    y = np.cross(d, x)
    ang = np.unwrap(np.arctan2(rel @ y, rel @ x))
    return float((ang[-1] - ang[0]) / (2 * np.pi))


def _unit_np(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _loop_points(loop, geo: NetworkGeometry) -> np.ndarray:
    out = []
    for r in loop:
        e = abs(int(r)) - 1
        c = geo.coords[geo.offsets[e]:geo.offsets[e + 1]]
        out.append(c if r > 0 else c[::-1])
    return np.concatenate(out)


def seam_split(model: SurfaceModel, loops: list[np.ndarray], edges, geo: NetworkGeometry, context):
    """For a face whose two loops wind once round ``model``'s axis: the longest shared edge across the turn split
    at its middle (recorded in ``context``), and the model turned so that u = 0 lies at the split; else None."""
    from OCP.GeomAPI import GeomAPI_ProjectPointOnCurve

    if model is None or model.kind not in SEAM_SURFACES or len(loops) != 2:
        return None
    # a loop winds once about the axis within 5% of a turn (scale-free: sampled loops miss a little)
    if not all(abs(abs(_winding(model, _loop_points(l, geo))) - 1.0) < 0.05 for l in loops):
        return None
    d = _unit_np(model.axis)
    best = None
    for loop in loops:
        for r in loop:
            e = abs(int(r)) - 1
            edge = edges[e]
            if edge is None or not context.Apply(edge).IsSame(edge):
                continue  # split or replaced already
            c = geo.coords[geo.offsets[e]:geo.offsets[e + 1]]
            rel = c - model.origin
            radial = rel - np.outer(rel @ d, d)
            ang = np.unwrap(np.arctan2(np.cross(radial[:-1], radial[1:]) @ d,
                                       np.einsum("ij,ij->i", radial[:-1], radial[1:])))
            turn = np.concatenate([[0.0], np.cumsum(ang)])
            span = abs(turn[-1])
            if best is None or span > best[0]:
                best = (span, e, c[int(np.argmin(np.abs(turn - 0.5 * turn[-1])))])
    if best is None or best[0] < np.pi / 2:
        return None
    _, e, p = best
    edge = edges[e]
    curve = BRep_Tool.Curve_s(edge, 0.0, 0.0)  # (OCP does not hand the range back: BRep_Tool.Range_s)
    first, last = BRep_Tool.Range_s(edge)
    proj = GeomAPI_ProjectPointOnCurve(pnt(p), curve, first, last)
    if proj.NbPoints() == 0:
        return None
    t = proj.LowerDistanceParameter()
    if not first < t < last:
        return None
    v1, v2 = TopExp.FirstVertex_s(edge), TopExp.LastVertex_s(edge)
    vmid = BRepBuilderAPI_MakeVertex(curve.Value(t)).Vertex()
    builder = BRep_Builder()
    builder.UpdateVertex(vmid, BRep_Tool.Tolerance_s(edge))
    pieces = []
    for a, b, t0, t1 in ((v1, vmid, first, t), (vmid, v2, t, last)):
        mk = BRepBuilderAPI_MakeEdge(curve, a, b, t0, t1)
        if not mk.IsDone():
            return None
        pieces.append(mk.Edge())
    wire = TopoDS_Wire()
    builder.MakeWire(wire)
    for piece in pieces:
        builder.Add(wire, piece)
    if edge.Orientation() == TopAbs_REVERSED:
        wire.Reverse()
    q = vec3(curve.Value(t))
    rel = q - model.origin
    radial = rel - (rel @ d) * d
    # reframed() turns u = 0 away from the points it is given: give it the point opposite the split.
    turned = model.reframed((model.origin - radial)[None])
    return turned, edge, wire


class _SplitContext:
    """The shared context as a face under trial sees it: one edge already split, every change kept back.

    ``replay()`` hands the split and the face's own changes to the shared context once the face is accepted.
    """

    def __init__(self, context, edge, pieces):
        self.context, self.edge, self.pieces, self.changes = context, edge, pieces, []

    def Apply(self, shape):
        if shape.IsSame(self.edge):
            w = self.pieces
            return w if shape.Orientation() == self.edge.Orientation() else w.Reversed()
        return self.context.Apply(shape)

    def Replace(self, shape, new):
        self.changes.append(("replace", shape, new))

    def Remove(self, shape):
        self.changes.append(("remove", shape, None))

    def replay(self):
        self.context.Replace(self.edge, self.pieces)
        for what, shape, new in self.changes:
            if what == "replace":
                self.context.Replace(shape, new)
            else:
                self.context.Remove(shape)


def face_with_seam_split(model, loops, edges, geo, vote, context, tolerance):
    """``(face, area)`` on ``model``'s surface with its seam placed by :func:`seam_split`, or None."""
    try:
        split = seam_split(model, loops, edges, geo, context)
    except Exception as err:  # noqa: BLE001  (OCC raising on an edge: no retry)
        log.info("seam split failed: %s", err)
        return None
    if split is None:
        return None
    turned, edge, pieces = split
    trial = _SplitContext(context, edge, pieces)
    try:
        got = face_on_surface(turned, loops, edges, vote, trial, precision=tolerance)
    except BrepError as err:
        log.info("face with its seam at the middle of an edge: %s", err)
        return None
    trial.replay()
    return got
