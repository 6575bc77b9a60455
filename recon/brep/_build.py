"""Curve network + one surface per part → a closed, valid OpenCascade solid.

Watertight by construction: every network vertex becomes one ``TopoDS_Vertex`` and every network edge
one ``TopoDS_Edge``, built once and used by both faces it separates (DESIGN.md, "curves"). Each face is
its surface bounded by wires of those shared edges (``BRepBuilderAPI_MakeFace(surface, wire,
Inside=False)`` + ``ShapeFix_Face`` for the p-curves, the recipe measured in shared/OCP-NOTES.md), then
``BRep_Builder`` shell → ``ShapeFix_Shell`` → ``MakeSolid`` → ``ShapeFix_Solid`` → ``OrientClosedSolid``.
A face that fails falls back to a ``BRepOffsetAPI_MakeFilling`` B-spline on its boundary edges with mesh
points as constraints; a shell that still is not closed is sewn as a last resort.
"""

from __future__ import annotations

import functools
import logging
import os
import time
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve2d
from OCP.BRepBuilderAPI import (
    BRepBuilderAPI_MakeEdge,
    BRepBuilderAPI_MakeFace,
    BRepBuilderAPI_MakeSolid,
    BRepBuilderAPI_MakeVertex,
    BRepBuilderAPI_Sewing,
)
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.BRepLib import BRepLib
from OCP.BRepOffsetAPI import BRepOffsetAPI_MakeFilling
from OCP.Geom import Geom_BSplineCurve, Geom_Circle
from OCP.GeomAbs import GeomAbs_Shape
from OCP.GProp import GProp_GProps
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
from OCP.ShapeAnalysis import ShapeAnalysis_FreeBounds
from OCP.ShapeBuild import ShapeBuild_ReShape
from OCP.ShapeFix import ShapeFix_Edge, ShapeFix_Face, ShapeFix_Shell, ShapeFix_Solid
from OCP.TColgp import TColgp_Array1OfPnt
from OCP.TColStd import TColStd_Array1OfInteger, TColStd_Array1OfReal
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED, TopAbs_SHELL, TopAbs_SOLID, TopAbs_VERTEX, TopAbs_WIRE
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopTools import TopTools_IndexedMapOfShape
from OCP.TopoDS import TopoDS, TopoDS_Compound, TopoDS_Face, TopoDS_Shell, TopoDS_Wire

from .._parallel import Failure, FailureKind, isolated
from ..curves import OUTSIDE, CurveNetwork, EdgeCurve, NetworkGeometry, network_geometry
from ..errors import BrepError, InputError
from . import _serial  # noqa: F401  (faces cross the pipe from a child as BREP bytes)
from ._surfaces import SurfaceModel, surface_model

__all__ = ["BrepResult", "FaceRecord", "Validity", "build_solid", "shape_validity"]

log = logging.getLogger(__name__)

#: Seconds one ``BRepOffsetAPI_MakeFilling`` may take before it is given up. Every one that succeeded on
#: fandisk and rocker-arm2500 (18 faces) took 0.04–0.41 s; the ones that spin do so for minutes.
FILLING_TIMEOUT = 5.0
#: Seconds all filling fallbacks of one :func:`build_solid` may take together: a mesh whose every part needs one
#: must still end in a result (with failed faces) rather than run for minutes (crank: 36 faces to fill).
FILLING_BUDGET = 30.0

#: Seconds a face on its own curves (:func:`_face_on_own_curves`) may take; each took well under 0.1 s on crank
#: and rocker-arm, where one crashed ShapeFix_Face instead.
OWN_CURVES_TIMEOUT = 5.0

#: ShapeFix_Face works at this share of the model tolerance (OCC's default is 1e-7). At the full tolerance a
#: 30 × 20 × 10 box of B-spline faces lost 0.09 % of its volume (p-curves approximated that loosely); at 0.1
#: and 0.01 the box is exact and box_fillet noisy20 gets all 26 faces on their own surfaces (25 at 1e-7).
PRECISION_SHARE = 0.1

#: Sewing tolerances tried, as multiples of the model tolerance, when the shell has free edges (the last resort:
#: it joins faces built on copies of the shared edges or on filling surfaces). More than 10×, measured up to
#: 100×, closed no more shells on fandisk-b and rocker-arm2500 and started to merge small edges.
SEWING_FACTORS = (1.0, 10.0)

#: A face whose area differs from its part's mesh area by more than this factor either way gets a warning: a
#: MakeFilling surface can balloon between its constraints (abc_00000050: a filling face of 24× its part's area,
#: 96 % of the diagonal away from the mesh, in a solid BRepCheck calls valid). Refusing such faces was measured
#: too: abc lost its validity (a hole instead), nothing else changed, so it is reported rather than refused.
AREA_RATIO_WARNING = 2.0

#: Paper §4 / Figure 4: smooth patches grey, linear parts purple, junctions yellow (terminals green, §3).
KIND_COLOURS = {
    "patch": (0.75, 0.75, 0.75),
    "linear": (0.58, 0.29, 0.78),
    "junction": (0.95, 0.85, 0.15),
    "terminal": (0.30, 0.70, 0.30),
}


@dataclass(frozen=True)
class FaceRecord:
    """One B-rep face.

    ``status`` is ``"ok"`` (its own surface), ``"poor"`` (its own surface although the fit was not within
    tolerance: nothing better could be built), ``"ok-sewn"`` / ``"poor-sewn"`` (the same, built on copies of
    its boundary edges and joined to its neighbours by sewing), ``"filled"`` (a MakeFilling B-spline through
    its boundary and mesh points, trimmed by the shared edges), ``"filled-sewn"`` (MakeFilling's own face,
    joined by sewing)
    or ``"failed"`` (no face: the shell has a hole there); ``face`` is the ``TopoDS_Face`` in the final shape.
    """

    part: int
    name: str
    kind: str
    surface_type: str
    status: str
    area: float
    face: object = field(repr=False, default=None)
    message: str = ""


@dataclass(frozen=True)
class Validity:
    """What OpenCascade says about the result: the checks a user cares about ("a valid closed solid")."""

    shape_type: str
    valid: bool
    closed: bool
    free_edges: int
    volume: float
    n_faces: int
    n_solids: int
    n_shells: int = 0

    @property
    def ok(self) -> bool:
        """One valid closed solid, or (a mesh of several bodies) a compound of them and nothing else."""
        solids = self.shape_type == "solid" or (
            self.shape_type == "compound" and self.n_solids > 0 and self.n_shells == self.n_solids)
        return self.valid and self.closed and solids and self.volume > 0


@dataclass(frozen=True)
class BrepResult:
    """The built B-rep.

    Attributes
    ----------
    occ : TopoDS_Shape
        The OCP shape: a solid, a shell, or a compound of them.
    shape : build123d Solid, Shell or Compound
        ``occ`` wrapped for the user, made on first use (importing build123d takes about 2 s, more than
        the whole B-rep stage of a 100k-triangle box; writing STEP, BREP or STL does not need it).
    faces : tuple of FaceRecord
        One per part that has a boundary, in ``network.parts`` order.
    validity : Validity
    geometry : NetworkGeometry
        Where the network's vertices and edges ended up, with their gaps to the surfaces.
    warnings : tuple of str
    """

    occ: object
    faces: tuple
    validity: Validity
    geometry: NetworkGeometry
    warnings: tuple

    @functools.cached_property
    def shape(self):
        from build123d import Compound, Shell, Solid

        return {TopAbs_SOLID: Solid, TopAbs_SHELL: Shell}.get(self.occ.ShapeType(), Compound)(self.occ)

    @property
    def ok(self) -> bool:
        """A valid closed solid in which every part got its own face (no failed face, none lost to fixing)."""
        return self.validity.ok and all(r.status != "failed" and r.face is not None for r in self.faces)

    def face_names(self) -> list[str]:
        return [f.name for f in self.faces if f.face is not None]


# --------------------------------------------------------------------------------------------------
# Checks
# --------------------------------------------------------------------------------------------------


def _count(shape, kind) -> int:
    n = 0
    exp = TopExp_Explorer(shape, kind)
    while exp.More():
        n += 1
        exp.Next()
    return n


def free_edge_count(shape) -> int:
    """Edges bounding only one face (``ShapeAnalysis_FreeBounds``, no sewing)."""
    fb = ShapeAnalysis_FreeBounds(shape, False, True, False)
    return _count(fb.GetClosedWires(), TopAbs_EDGE) + _count(fb.GetOpenWires(), TopAbs_EDGE)


def shape_validity(shape) -> Validity:
    """Type, validity (``BRepCheck_Analyzer``), closedness (free edges), volume of a shape."""
    occ = getattr(shape, "wrapped", shape)
    type_name = {TopAbs_SOLID: "solid", TopAbs_SHELL: "shell"}.get(occ.ShapeType(), "compound")
    n_solids = _count(occ, TopAbs_SOLID)
    if type_name == "compound" and n_solids == 0:
        type_name = "compound"
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(occ, props)
    free = free_edge_count(occ)
    return Validity(
        shape_type=type_name,
        valid=bool(BRepCheck_Analyzer(occ).IsValid()),
        closed=free == 0,
        free_edges=free,
        volume=float(props.Mass()),
        n_faces=_count(occ, TopAbs_FACE),
        n_solids=n_solids,
        n_shells=_count(occ, TopAbs_SHELL),
    )


def _area(face) -> float:
    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    return float(props.Mass())


# --------------------------------------------------------------------------------------------------
# Edges
# --------------------------------------------------------------------------------------------------


def _pnt(p) -> gp_Pnt:
    return gp_Pnt(float(p[0]), float(p[1]), float(p[2]))


def _bspline_curve(params: dict) -> Geom_BSplineCurve:
    ctrl = np.asarray(params["control_points"], float)
    knots = np.asarray(params["knots"], float)
    vals, mults = np.unique(np.round(knots, 14), return_counts=True)
    poles = TColgp_Array1OfPnt(1, len(ctrl))
    for i, c in enumerate(ctrl, start=1):
        poles.SetValue(i, _pnt(c))
    kn = TColStd_Array1OfReal(1, len(vals))
    mu = TColStd_Array1OfInteger(1, len(vals))
    for i, (v, m) in enumerate(zip(vals, mults), start=1):
        kn.SetValue(i, float(v))
        mu.SetValue(i, int(m))
    return Geom_BSplineCurve(poles, kn, mu, int(params["degree"]))


def _make_edge(curve: EdgeCurve, v1, v2, builder: BRep_Builder):
    """A TopoDS_Edge on ``curve`` between the shared vertices ``v1``, ``v2``."""
    try:
        if curve.kind == "line":
            mk = BRepBuilderAPI_MakeEdge(v1, v2)
        elif curve.kind == "circle":
            p = curve.params
            ax = gp_Ax2(_pnt(p["center"]), gp_Dir(*map(float, p["normal"])), gp_Dir(*map(float, p["xdir"])))
            circ = Geom_Circle(ax, float(p["radius"]))
            # The vertices lie on the fitted circle within the fit residual: let their tolerance cover it.
            for v, t in ((v1, p["t0"]), (v2, p["t1"])):
                d = BRep_Tool.Pnt_s(v).Distance(circ.Value(float(t)))
                if d > BRep_Tool.Tolerance_s(v):
                    builder.UpdateVertex(v, 1.01 * d)
            mk = BRepBuilderAPI_MakeEdge(circ, v1, v2, float(p["t0"]), float(p["t1"]))
        else:
            # Explicit parameters: on a closed curve both ends project to the first one otherwise.
            bsc = _bspline_curve(curve.params)
            mk = BRepBuilderAPI_MakeEdge(bsc, v1, v2, bsc.FirstParameter(), bsc.LastParameter())
        if not mk.IsDone():
            raise BrepError(f"BRepBuilderAPI_MakeEdge failed ({mk.Error()}) for a {curve.kind} edge")
        return mk.Edge()
    except BrepError:
        raise
    except Exception as err:
        raise BrepError(f"could not build a {curve.kind} edge: {err}") from err


# --------------------------------------------------------------------------------------------------
# Faces
# --------------------------------------------------------------------------------------------------


def _wire(refs, edges, context=None):
    """A wire of the shared edges ``refs`` (signed ``±(edge + 1)``), as the context has them by now.

    An earlier face's ShapeFix may have replaced or split a shared edge (recorded in ``context``); this face
    must use the same replacement or the two faces stop sharing it. The edges go in as they are
    (``BRep_Builder``): ``BRepBuilderAPI_MakeWire`` joins vertices that lie within each other's tolerance by
    copying edges onto one of them, a change nobody records, so the neighbouring face keeps the old edge
    (rocker-arm2500: 4 faces with edges of their own, 15 free edges before sewing). Joining them is
    ShapeFix's job, recorded in its context.
    """
    builder = BRep_Builder()
    wire = TopoDS_Wire()
    builder.MakeWire(wire)
    n = 0
    for r in refs:
        e = edges[abs(r) - 1]
        if e is None:
            raise BrepError(f"shared edge {abs(r) - 1} could not be built")
        e = e if r > 0 else TopoDS.Edge_s(e.Reversed())
        pieces = [e]
        if context is not None:
            now = context.Apply(e)
            if now.IsNull():
                raise BrepError(f"shared edge {abs(r) - 1} was removed by an earlier repair")
            if now.ShapeType() == TopAbs_EDGE:
                pieces = [TopoDS.Edge_s(now)]
            else:
                pieces = []
                exp = TopExp_Explorer(now, TopAbs_EDGE)
                while exp.More():
                    pieces.append(TopoDS.Edge_s(exp.Current()))
                    exp.Next()
        for piece in pieces:
            builder.Add(wire, piece)
            n += 1
    if not n:
        raise BrepError("the boundary loop has no edges")
    return wire


#: A fit out of tolerance still bounds its own face ("poor") before any filling is tried when its RMS deviation
#: is within this many tolerances. Measured on fandisk, fandisk-b, casting and rocker-arm2500, faces on such fits
#: beat MakeFilling faces everywhere: fandisk 15 fillings and 13 free edges -> 39 own faces, a valid solid, mesh→shape
#: p95 3.8 % -> 0.066 % of the diagonal; fandisk-b p95 2.9 % -> 0.030 %. 1×, 2× and 4× improved step by step; with
#: no limit casting's max deviation rose from 1.9 % to 8.0 % (fits far off), so 4×.
OWN_SURFACE_RMS = 4.0


def _near_enough(fit, tolerance: float) -> bool:
    """Whether an out-of-tolerance fit is still close enough to bound its own face (:data:`OWN_SURFACE_RMS`)."""
    dev = getattr(fit, "deviation", None) or {}
    rms = dev.get("rms", np.nan)
    return bool(np.isfinite(rms) and rms <= OWN_SURFACE_RMS * tolerance)


def _face_on_copies(model: SurfaceModel, loops: list[np.ndarray], network: CurveNetwork, geo: NetworkGeometry,
                    vote: int, *, precision: float):
    """The part's face on fresh copies of its boundary edges, or ``(None, 0.0)``.

    A face that fails on the shared edges can succeed on the same curves built anew: an earlier neighbour's
    ShapeFix may have split, re-parametrised or re-toleranced a shared edge in a way this face's ShapeFix
    cannot follow (fandisk-b: a plane bounded by two lines and two circles, valid alone, NotClosed on the
    shared edges). The copies are the same curves between the same points, so sewing joins the face to its
    neighbours with no gap to bridge.
    """
    builder = BRep_Builder()
    used = {abs(int(r)) - 1 for loop in loops for r in loop}
    ends = {int(v) for e in used for v in network.edge_vertices[e]}
    vertices = {}
    for v in ends:
        vtx = BRepBuilderAPI_MakeVertex(_pnt(geo.points[v])).Vertex()
        builder.UpdateVertex(vtx, max(1e-7, 1.01 * float(geo.vertex_gap[v])))
        vertices[v] = vtx
    copies = [None] * network.n_edges
    try:
        for e in used:
            a, b = network.edge_vertices[e]
            copies[e] = _make_edge(geo.curves[e], vertices[int(a)], vertices[int(b)], builder)
        return _face_on_surface(model, loops, copies, vote, ShapeBuild_ReShape(), precision=precision)
    except BrepError as err:
        log.info("%s face on copies of its edges failed too: %s", model.kind, err)
        return None, 0.0


def _uv_loop(analysis, loop, geo: NetworkGeometry, precision: float) -> list[np.ndarray]:
    """The UV points of each edge of ``loop`` on the surface, continuous along the loop.

    Consecutive edges share their meeting point's UV exactly, and in a periodic direction each point is taken
    a whole number of periods from where OCC puts it so that it lies nearest the point before (OCC keeps one
    period; the loop must not jump back across it). So the loop closes in the parameter plane, up to a period
    for a loop that goes round a periodic surface, which ShapeFix_Face gives a seam.
    """
    surface = analysis.Surface()
    periods = np.array([surface.UPeriod() if surface.IsUPeriodic() else 0.0,
                        surface.VPeriod() if surface.IsVPeriodic() else 0.0])
    out, last = [], None
    for r in loop:
        pts = geo.polyline(abs(int(r)) - 1)
        pts = pts if r > 0 else pts[::-1]
        uvs = [] if last is None else [last]
        for p in pts[len(uvs):]:
            uv = analysis.ValueOfUV(_pnt(p), precision)
            uv = np.array([uv.X(), uv.Y()])
            if last is not None:
                step = np.where(periods > 0, periods * np.round((uv - last) / np.where(periods > 0, periods, 1.0)), 0.0)
                uv = uv - step
            last = uv
            uvs.append(uv)
        out.append(np.array(uvs))
    # The loop's first point, reached again: the same UV, or the same one a whole number of periods on.
    start, end = out[0][0], out[-1][-1]
    shift = np.where(periods > 0, periods * np.round((end - start) / np.where(periods > 0, periods, 1.0)), 0.0)
    out[-1][-1] = start + shift
    return out


def _boundary_edge_count(face) -> int:
    """Edges of ``face``, each once, not counting seams."""
    found = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(face, TopAbs_EDGE, found)
    return sum(not BRep_Tool.IsClosed_s(TopoDS.Edge_s(found.FindKey(i)), face) for i in range(1, found.Extent() + 1))


def _pcurve(uv: np.ndarray):
    """A degree-1 B-spline through the UV points ``uv (k, 2)`` (chord-length parameters on [0, 1])."""
    from OCP.Geom2d import Geom2d_BSplineCurve
    from OCP.TColgp import TColgp_Array1OfPnt2d
    from OCP.gp import gp_Pnt2d

    seg = np.linalg.norm(np.diff(uv, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-12])
    keep[-1] = True
    uv = uv[keep]
    if len(uv) < 2 or np.linalg.norm(uv[-1] - uv[0]) <= 1e-12 and len(uv) < 3:
        raise BrepError("an edge is a point in the surface's parameters")
    t = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(uv, axis=0), axis=1))])
    t /= t[-1]
    poles = TColgp_Array1OfPnt2d(1, len(uv))
    for i, (u, v) in enumerate(uv, 1):
        poles.SetValue(i, gp_Pnt2d(float(u), float(v)))
    knots = TColStd_Array1OfReal(1, len(uv))
    mults = TColStd_Array1OfInteger(1, len(uv))
    for i, x in enumerate(t, 1):
        knots.SetValue(i, float(x))
        mults.SetValue(i, 2 if i in (1, len(uv)) else 1)
    return Geom2d_BSplineCurve(poles, knots, mults, 1)


def _face_on_own_curves(model: SurfaceModel, loops: list[np.ndarray], geo: NetworkGeometry, vote: int, *,
                        precision: float):
    """The part's face bounded by its edge polylines projected onto its own surface, or ``(None, 0.0)``.

    The last resort before a filling: each edge is its polyline's image in the surface's parameters (a
    p-curve) with the 3D curve built from it, so the face's edges lie on its surface exactly and its wires
    close in the parameter plane by construction. The shared network edges lie on the surface only within
    the fit's residual, and where that residual is large (a poor fit, a CAD tessellation's long chords) the
    p-curves ShapeFix projects from them can miss each other (BRepCheck NotClosed) or cross
    (SelfIntersectingWire). The face has edges of its own, up to the edge gap from its neighbours': sewing
    joins them.
    """
    try:
        face = _face_in_child(_own_curves_face, (model, loops, geo, vote, precision), "ShapeFix_Face",
                              OWN_CURVES_TIMEOUT)
        return face, abs(_area(face))
    except BrepError as err:
        log.info("%s face on its own curves failed: %s", model.kind, err)
        return None, 0.0


def _own_curves_face(model: SurfaceModel, loops: list[np.ndarray], geo: NetworkGeometry, vote: int,
                     precision: float):
    """:func:`_face_on_own_curves`' face, made in this process; raises :class:`BrepError`."""
    from OCP.ShapeAnalysis import ShapeAnalysis_Surface

    try:
        analysis = ShapeAnalysis_Surface(model.geom)
        builder = BRep_Builder()
        wires = []
        for loop in (loops if vote > 0 else [-r[::-1] for r in loops]):
            uvs = _uv_loop(analysis, loop, geo, 1e-3 * precision)
            wire = TopoDS_Wire()
            builder.MakeWire(wire)
            first = vtx = None
            for k, uv in enumerate(uvs):
                c2d = _pcurve(uv)
                if vtx is None:
                    p = model.geom.Value(*map(float, uv[0]))
                    first = vtx = BRepBuilderAPI_MakeVertex(p).Vertex()
                closing = k == len(uvs) - 1
                end = first if closing else BRepBuilderAPI_MakeVertex(model.geom.Value(*map(float, uv[-1]))).Vertex()
                mk = BRepBuilderAPI_MakeEdge(c2d, model.geom, vtx, end, c2d.FirstParameter(), c2d.LastParameter())
                if not mk.IsDone():
                    raise BrepError(f"BRepBuilderAPI_MakeEdge on the surface failed ({mk.Error()})")
                edge = mk.Edge()
                BRepLib.BuildCurves3d_s(edge, 1e-3 * precision)
                builder.Add(wire, edge)
                vtx = end
            wires.append(wire)
        fix = _face_fixer(model, wires, precision)
        fix.Perform()
        face = fix.Face()
        # ShapeFix drops a wire it cannot mend (rocker-arm: a cone left with only its hole). It may split edges
        # and join a band's two wires with a seam, but every edge it was given is still there, in pieces.
        kept, given = _boundary_edge_count(face), sum(len(loop) for loop in loops)
        if kept < given:
            raise BrepError(f"face on its own curves kept {kept} of its {given} edges")
        area = _area(face)
        if not area > 0:
            raise BrepError(f"face on its own curves has area {area:.4g}")
        flipped = TopoDS.Face_s(face.Reversed())
        problems = face_problems(face) or face_problems(flipped)
        if problems:
            raise BrepError(f"face on its own curves is not valid ({problems})")
        return flipped if vote < 0 else face
    except BrepError:
        raise
    except Exception as err:  # OCC raises Standard_Failure subclasses
        raise BrepError(f"{type(err).__name__}: {err}") from err


def _face_on_own_edges(model: SurfaceModel, loops: list[np.ndarray], network: CurveNetwork, geo: NetworkGeometry,
                       vote: int, *, precision: float):
    """A face on edges of its own, for sewing: on copies of the shared curves, else on its own p-curves.

    Returns ``(face or None, area, how it was built)``.
    """
    face, area = _face_on_copies(model, loops, network, geo, vote, precision=precision)
    if face is not None:
        return face, area, "built on copies of them"
    face, area = _face_on_own_curves(model, loops, geo, vote, precision=precision)
    return face, area, "built on its own curves"


def _orientation_vote(model: SurfaceModel, points, normals) -> int:
    """+1 if the surface's own normal agrees with the mesh's outward normals on this part, else -1."""
    if len(points) == 0:
        return 1
    sn = model.signed_normals(points)
    return 1 if float(np.sum(np.einsum("ij,ij->i", sn, normals))) >= 0 else -1


def _face_on_surface(model: SurfaceModel, loops: list[np.ndarray], edges, vote: int, context, *,
                     precision: float, both_sides: bool = True):
    """Face on the part's own surface; wires run counter-clockwise about the surface normal.

    With ``both_sides`` the face must pass BRepCheck in both orientations: a wire that BRepTools_WireExplorer
    walks one way but not the other (p-curves jumping by a period, edges ShapeFix added) is NotClosed as soon as
    ShapeFix_Shell turns the face over to agree with its neighbours (rocker-arm2500: a cone face on a wrong fit,
    the one invalid face of its solid).
    """
    try:
        return _face_on_surface_occ(model, loops, edges, vote, context, precision, both_sides)
    except BrepError:
        raise
    except Exception as err:  # OCC raises Standard_Failure subclasses
        raise BrepError(f"OpenCascade failed on the face: {type(err).__name__}: {err}") from err


def _face_on_surface_occ(model: SurfaceModel, loops: list[np.ndarray], edges, vote: int, context, precision: float,
                         both_sides: bool):
    if vote < 0:
        loops = [-r[::-1] for r in loops]
    wires = [_wire(r, edges, context) for r in loops]
    fix = _face_fixer(model, wires, precision)
    # ShapeFix may split a shared edge (a hole's circle at a cylinder's seam): the neighbouring faces must get
    # the same pieces. It records into a context of this face's own, handed on to the shared one only when
    # the face is accepted: a face that fails must not leave its neighbours with edges split for nothing.
    local = ShapeBuild_ReShape()
    fix.SetContext(local)
    # ShapeFix edits the wires in place: what they held before is what the shared context must map.
    before = _subshapes(wires)
    tolerances = [_tolerance(s) for s in before]
    try:
        fix.Perform()
        # A wire that crosses itself on the surface is cut into loops and the face split into pieces
        # (ShapeFix_Face's FixLoopWire / FixSplitFace); fix.Face() is one of them, the others are lost with
        # their edges, which the neighbours still use (crank: 5 faces kept 0.01-50 % of their part's area, 27
        # free edges). Such a face failed on its surface: its fallbacks follow.
        pieces = _count(fix.Result(), TopAbs_FACE)
        if pieces > 1:
            raise BrepError(f"face on its surface was split into {pieces} pieces (its boundary crosses itself)")
        face = TopoDS.Face_s(local.Apply(fix.Face()))
        area = _area(face)
        if not area > 0:
            raise BrepError(f"face on its surface has area {area:.4g}")
        flipped = TopoDS.Face_s(face.Reversed())
        if not (BRepCheck_Analyzer(face).IsValid() and (not both_sides or BRepCheck_Analyzer(flipped).IsValid())):
            _fix_edges(face)
            problems = face_problems(face) or (face_problems(flipped) if both_sides else "")
            if problems:
                raise BrepError(f"face on its surface is not valid ({problems})")
    except Exception:
        # ShapeFix and the edge repair raise the shared edges' and vertices' tolerances in place to fit this
        # face: one that fails must not leave them raised (rocker-arm: a B-spline face that failed took two
        # shared edges to 0.10 and 0.15, 60× the tolerance, and the filling bounded by them then failed too)
        for shape, tol in zip(before, tolerances):
            _set_tolerance(shape, tol)
        raise
    _hand_on(local, before, context)
    return (TopoDS.Face_s(face.Reversed()) if vote < 0 else face), area


#: A face on a cylinder or cone whose two boundary loops each wind once round the axis gets its seam from
#: ShapeFix_Face (FixMissingSeam) through the edge end nearest to the surface's u = 0. Where every vertex sits
#: beside an edge that runs along the axis (crank's journal: both ends of two pins that cross it) the seam runs
#: along that edge, and the face is cut into a sliver and the rest. On such a failure the face is tried again
#: with its longest edge across the turn split at its middle and the surface's u = 0 put there.
SEAM_SURFACES = ("cylinder", "cone")


def _winding(model: SurfaceModel, pts: np.ndarray) -> float:
    """How many times the closed polyline ``pts`` winds round ``model``'s axis."""
    rel = pts - model.origin
    d = _unit_np(model.axis)
    x = _unit_np(np.cross(d, [1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.cross(d, [0.0, 1.0, 0.0]))
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


def _seam_split(model: SurfaceModel, loops: list[np.ndarray], edges, geo: NetworkGeometry, context):
    """For a face whose two loops wind once round ``model``'s axis: the longest shared edge across the turn split
    at its middle (recorded in ``context``), and the model turned so that u = 0 lies at the split; else None."""
    from OCP.GeomAPI import GeomAPI_ProjectPointOnCurve

    if model is None or model.kind not in SEAM_SURFACES or len(loops) != 2:
        return None
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
    proj = GeomAPI_ProjectPointOnCurve(_pnt(p), curve, first, last)
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
    q = _vec3(curve.Value(t))
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


def _face_with_seam_split(model, loops, edges, geo, vote, context, tolerance):
    """``(face, area)`` on ``model``'s surface with its seam placed by :func:`_seam_split`, or None."""
    try:
        split = _seam_split(model, loops, edges, geo, context)
    except Exception as err:  # noqa: BLE001  (OCC raising on an edge: no retry)
        log.info("seam split failed: %s", err)
        return None
    if split is None:
        return None
    turned, edge, pieces = split
    trial = _SplitContext(context, edge, pieces)
    try:
        got = _face_on_surface(turned, loops, edges, vote, trial, precision=tolerance)
    except BrepError as err:
        log.info("face with its seam at the middle of an edge: %s", err)
        return None
    trial.replay()
    return got


def _vec3(p) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()])


def _tolerance(shape) -> float:
    if shape.ShapeType() == TopAbs_VERTEX:
        return BRep_Tool.Tolerance_s(TopoDS.Vertex_s(shape))
    return BRep_Tool.Tolerance_s(TopoDS.Edge_s(shape))


def _set_tolerance(shape, tol: float) -> None:
    """Set the tolerance of one vertex or edge, down as well as up (BRep_Builder only raises it)."""
    from OCP.ShapeFix import ShapeFix_ShapeTolerance

    if _tolerance(shape) != tol:
        ShapeFix_ShapeTolerance().SetTolerance(shape, tol, shape.ShapeType())


def _face_fixer(model: SurfaceModel, wires, precision: float):
    """``ShapeFix_Face`` (not yet performed) of the face on ``model``'s surface bounded by ``wires``."""
    mk = BRepBuilderAPI_MakeFace(model.geom, wires[0], False)
    if not mk.IsDone():
        raise BrepError(f"BRepBuilderAPI_MakeFace failed ({mk.Error()})")
    for w in wires[1:]:
        mk.Add(w)
    fix = ShapeFix_Face(mk.Face())
    # Near the model's tolerance, not at OCC's 1e-7: a p-curve end that misses its neighbour's by less than the
    # vertices' tolerance is not a gap to fill with a new edge (ShapeFix_Wire's FixLacking), an edge that the
    # neighbouring face never sees (see PRECISION_SHARE).
    fix.SetPrecision(PRECISION_SHARE * precision)
    fix.SetMaxTolerance(10.0 * precision)
    return fix


def _subshapes(wires) -> list:
    """The vertices, then the edges, of ``wires`` (each once)."""
    out = []
    for kind in (TopAbs_VERTEX, TopAbs_EDGE):
        found = TopTools_IndexedMapOfShape()
        for wire in wires:
            TopExp.MapShapes_s(wire, kind, found)
        out.extend(found.FindKey(i) for i in range(1, found.Extent() + 1))
    return out


def _hand_on(local, shapes, context) -> None:
    """Record in the shared ``context`` what the face's own ``local`` context did to ``shapes``.

    ``shapes`` are the wires' vertices and edges as they were before ShapeFix: ShapeFix edits the wires
    themselves (their edges after it are its own), and a vertex it merged with a neighbour must reach the
    other edges that meet there, in faces not built yet, or the next face finds two vertices and merges
    them again into a third (rocker-arm2500: 64 free edges before sewing, 15 with vertices handed on).
    """
    for s in shapes:
        now = local.Apply(s)
        if now.IsNull():
            context.Remove(s)
        elif not now.IsSame(s):
            context.Replace(s, now)


def _fix_edges(face) -> None:
    """Make every edge of ``face`` same-parameter with a tolerance that covers its measured gap.

    The network's edges lie on a fitted surface only within the fit's residual, and the pieces of an edge
    that ShapeFix split at a seam lose their same-range flag; ``ShapeFix_Edge`` re-projects the p-curve,
    measures the 3D/2D deviation and raises the edge (and vertex) tolerance to it.
    """
    sfe = ShapeFix_Edge()
    surface = BRep_Tool.Surface_s(face)
    exp = TopExp_Explorer(face, TopAbs_EDGE)
    while exp.More():
        edge = TopoDS.Edge_s(exp.Current())
        sfe.FixSameParameter(edge, face)
        sfe.FixVertexTolerance(edge, face)
        _cover_pcurve_ends(edge, face, surface)
        exp.Next()


def _cover_pcurve_ends(edge, face, surface) -> None:
    """Raise each vertex's tolerance to reach the ends of the edge's p-curve mapped onto the surface.

    The vertex is the surfaces' least-squares meeting point, off a fitted surface by up to the fit residual;
    the p-curve ends lie on the surface. Without this the wire is open in the face's parameter space
    (BRepCheck NotClosed) although it is closed in 3D.
    """
    first, last = TopExp.FirstVertex_s(edge), TopExp.LastVertex_s(edge)
    if first.IsNull() or last.IsNull():
        return
    if not BRep_Tool.IsGeometric_s(edge) or BRep_Tool.CurveOnSurface_s(edge, face, 0.0, 0.0) is None:
        return
    c2d = BRepAdaptor_Curve2d(edge, face)
    t0, t1 = c2d.FirstParameter(), c2d.LastParameter()
    builder = BRep_Builder()
    for vtx, t in ((first, t0), (last, t1)):
        uv = c2d.Value(t)
        d = surface.Value(uv.X(), uv.Y()).Distance(BRep_Tool.Pnt_s(vtx))
        if d > BRep_Tool.Tolerance_s(vtx):
            builder.UpdateVertex(vtx, 1.05 * d)


def face_problems(face) -> str:
    """``BRepCheck_Analyzer``'s complaints about ``face`` and its wires, edges and vertices, counted; "" if valid."""
    analyzer = BRepCheck_Analyzer(face)
    if analyzer.IsValid():
        return ""
    counts: dict[str, int] = {}

    def note(result):
        if result is None:
            return
        try:
            items = [result.Status()]
            result.InitContextIterator()
            while result.MoreShapeInContext():
                items.append(result.StatusOnShape())
                result.NextShapeInContext()
        except Exception:  # noqa: BLE001  (the list wrapper differs between OCP builds)
            return
        for lst in items:
            for st in lst:
                name = str(st).rsplit(".", 1)[-1].replace("BRepCheck_", "")
                if name != "NoError":
                    counts[name] = counts.get(name, 0) + 1

    note(analyzer.Result(face))
    for kind in (TopAbs_WIRE, TopAbs_EDGE, TopAbs_VERTEX):
        exp = TopExp_Explorer(face, kind)
        while exp.More():
            note(analyzer.Result(exp.Current()))
            exp.Next()
    return "BRepCheck: " + (", ".join(f"{k} ×{v}" for k, v in sorted(counts.items())) or "invalid")


def _checked_edges(loop, edges, context) -> list:
    """The loop's current shared edges, each checked to have a 3D curve and two non-null vertices.

    ``BRepOffsetAPI_MakeFilling`` dereferences edge vertices without checks: a null one there has killed
    the whole process ("BRep_Tool:: TopoDS_Vertex hasn't gp_Pnt", then a segfault). Nothing unchecked
    goes in.
    """
    out = []
    wire = _wire(loop, edges, context)
    exp = TopExp_Explorer(wire, TopAbs_EDGE)
    while exp.More():
        edge = TopoDS.Edge_s(exp.Current())
        if edge.IsNull() or BRep_Tool.Degenerated_s(edge):
            raise BrepError("a boundary edge is null or degenerate")
        if not BRep_Tool.IsGeometric_s(edge):
            raise BrepError("a boundary edge has no 3D curve")
        for vtx in (TopExp.FirstVertex_s(edge), TopExp.LastVertex_s(edge)):
            if vtx.IsNull() or vtx.TShape() is None:
                raise BrepError("a boundary edge has a null vertex")
        out.append(edge)
        exp.Next()
    if not out:
        raise BrepError("the boundary loop has no edges")
    return out


def _filled_face(checked: list, points):
    """Fallback: a B-spline face through the boundary edges ``checked`` (:func:`_checked_edges`) and mesh points
    (BRepOffsetAPI_MakeFilling).

    The caller trims the face's surface with the shared wires again (so that the face keeps the network's edges)
    and keeps the filled face itself only if that fails.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    try:
        fill = BRepOffsetAPI_MakeFilling()
        for edge in checked:
            fill.Add(edge, GeomAbs_Shape.GeomAbs_C0, True)
        for p in pts:
            fill.Add(_pnt(p))
        fill.Build()
        if not fill.IsDone():
            raise BrepError("BRepOffsetAPI_MakeFilling failed")
        shape = fill.Shape()
        if shape.IsNull() or shape.ShapeType() != TopAbs_FACE:
            raise BrepError("BRepOffsetAPI_MakeFilling returned no face")
        face = TopoDS.Face_s(shape)
    except BrepError:
        raise
    except Exception as err:  # OCC raises Standard_Failure subclasses
        raise BrepError(f"BRepOffsetAPI_MakeFilling failed: {type(err).__name__}: {err}") from err
    return face


def _face_in_child(build, args: tuple, what: str, timeout: float):
    """The face ``build(*args)`` returns, computed in a child process killed after ``timeout`` seconds
    (:func:`recon._parallel.isolated`).

    Some OCC calls can crash the whole process where no exception can be caught (a segmentation fault inside
    GeomPlate on noisy boundaries, box_fillet noisy20; inside ShapeFix_Face on a rocker-arm cone's own curves)
    or spin for minutes (``ProjLib_CompProjectedCurve`` inside ``GeomPlate_BuildPlateSurface``, box_fillet
    noisy05). In a child the crash or the hang costs one face, not the user's session: the face comes back
    pickled through the pipe as BREP bytes (:mod:`._serial`). ``build`` raises :class:`BrepError` for a face it
    cannot make.
    """
    got = isolated(build, *args, timeout=timeout, what=what)
    if isinstance(got, Failure):
        if got.kind is FailureKind.TIMED_OUT:
            raise BrepError(f"{what} did not finish within {timeout:g} s; the part has no face")
        if got.kind is FailureKind.CRASHED and got.signal is not None:
            raise BrepError(f"{what} crashed (signal {got.signal}); the part has no face")
        if got.error_type == "BrepError":
            raise BrepError(got.message)
        raise BrepError(f"{what} failed")
    if not isinstance(got, TopoDS_Face) or got.IsNull():
        raise BrepError(f"{what} returned no face")
    return got


def _isolated_filled_face(loops, edges, points, context, *, timeout: float = FILLING_TIMEOUT):
    """:func:`_filled_face` in a child process (:func:`_face_in_child`); returns the face and its surface."""
    if len(loops) != 1:
        raise BrepError(f"MakeFilling fallback needs a single boundary loop, the part has {len(loops)}")
    checked = _checked_edges(loops[0], edges, context)
    face = _face_in_child(_filled_face, (checked, points), "BRepOffsetAPI_MakeFilling", timeout)
    return face, BRep_Tool.Surface_s(face)


# --------------------------------------------------------------------------------------------------
# Solid
# --------------------------------------------------------------------------------------------------


def _fallback_face(loops, edges, points, normals, context, *, precision: float, timeout: float = FILLING_TIMEOUT,
                   expected_area: float | None = None):
    """A filling surface through the part's boundary and points, trimmed by the shared wires if possible.

    Through every ``len // 16``-th point first; through every point when that gives no face, or one whose area
    is off ``expected_area`` (the part's mesh area) by more than :data:`AREA_RATIO_WARNING` either way, and then
    the face of the two whose area is nearer (see :data:`FILLING_POINTS`).
    Returns ``(face or None, area, status, message)``; ``status`` is ``"filled"`` for a face on the filling
    surface bounded by the network's own edges, ``"filled-sewn"`` for MakeFilling's own face (new edges,
    joined to its neighbours by sewing), ``"failed"`` otherwise.
    """
    deadline = time.monotonic() + timeout
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)

    def off(got):  # how far the face's area is from the part's, as a factor either way (inf: no face)
        if got[0] is None:
            return np.inf
        if not expected_area or not expected_area > 0:
            return 1.0
        return float(np.exp(abs(np.log(max(got[1], 1e-300) / expected_area))))

    best, tried = None, set()
    for step in FILLING_POINTS:
        every = max(1, len(pts) // step) if step else 1
        if every in tried:  # (fewer samples than the step: the same points again)
            continue
        tried.add(every)
        got = _fallback_face_through(loops, edges, pts[::every], nrm[::every], context, precision=precision,
                                     timeout=min(timeout, deadline - time.monotonic()))
        if best is None or off(got) < off(best):
            best = got
        if off(best) <= AREA_RATIO_WARNING:
            break
    return best


#: The filling fallback's point sets, in turn: every ``len // 16``-th sample of the part (of the 48 the network
#: keeps, every 3rd), then every one (0) when the first face is missing or far off the part's area. Through every
#: 3rd, box_fillet coarse's filling of a part that wraps a corner had 3.75× the part's area and reached 82 units
#: (105 % of the diagonal) from the mesh; through every sample, 24. Through every sample alone, casting and
#: rocker-arm were no longer solids (casting's patch_58: its filling not valid bounded by the shared edges).
FILLING_POINTS = (16, 0)


def _fallback_face_through(loops, edges, points, normals, context, *, precision: float, timeout: float):
    """:func:`_fallback_face` through the given points."""
    if not timeout > 0:
        return None, 0.0, "failed", f"no filling tried: the {FILLING_BUDGET:g} s budget for filling faces is spent"
    try:
        filled, surface = _isolated_filled_face(loops, edges, points, context, timeout=timeout)
    except BrepError as err:
        return None, 0.0, "failed", str(err)
    except Exception as err:  # noqa: BLE001  (an OCC failure outside the checked calls is still a record)
        return None, 0.0, "failed", f"filling failed: {type(err).__name__}: {err}"
    filling = SurfaceModel("bspline", surface)
    fvote = 1
    try:
        fvote = _orientation_vote(filling, points, normals)
        face, area = _face_on_surface(filling, loops, edges, fvote, context, precision=precision)
        return face, area, "filled", ""
    except Exception as err:  # noqa: BLE001  (BrepError or an OCC failure: fall back to the filled face)
        first = str(err)
    area = abs(_area(filled))
    if area > 0 and BRepCheck_Analyzer(filled).IsValid():
        return filled, area, "filled-sewn", f"filling surface trimmed by the shared edges failed ({first})"
    try:
        # Last resort: a face valid one way round still closes the shell, where no face leaves a hole (casting: a
        # closed solid with this one face invalid, against an open shell with 6 free edges).
        face, area = _face_on_surface(filling, loops, edges, fvote, context, precision=precision, both_sides=False)
        return face, area, "filled", f"the filling face is valid one way round only ({first})"
    except Exception:  # noqa: BLE001
        return None, 0.0, "failed", f"the filling face is not valid either ({first})"


def build_solid(network: CurveNetwork, surfaces: Mapping, *, tolerance: float,
                part_kinds: Mapping[int, str] | None = None,
                part_areas: Mapping[int, float] | None = None, jobs: int | None = None) -> BrepResult:
    """Build a closed, valid solid from a curve network and one surface per part.

    Parameters
    ----------
    network : CurveNetwork
        From :func:`recon.curves.curve_network`.
    surfaces : mapping part id → surface
        ``Geom_Surface`` (e.g. a true CAD surface), a ``recon.fit`` result (``.type``, ``.params``) or a
        :class:`SurfaceModel`; a sequence indexed by part id works too.
    tolerance : float
        Model tolerance (model units): lines/circles are kept for edges within it; sewing uses 10× it.
    part_kinds : mapping part id → "patch" | "linear" | "junction" | "terminal", optional
        Names and colours faces as in the paper (``"patch_3"``, ``"linear_7"``); default ``"patch"``.
    part_areas : mapping part id → float, optional
        The mesh area of each part. A face whose area is off it by more than :data:`AREA_RATIO_WARNING` either
        way is named in the warnings.
    jobs : int, optional
        Processes to place the curve network with (at most two are used; default: the cores available). The
        result does not depend on it.

    Returns
    -------
    BrepResult
        A build123d ``Solid`` when closed (a ``Compound`` of solids for several bodies), a ``Shell``
        with a warning for an open mesh. Per-face failures are records, not exceptions.
    """
    if not tolerance > 0:
        raise InputError(f"build_solid: `tolerance` must be > 0, got {tolerance!r}")
    if not isinstance(network, CurveNetwork):
        raise InputError(f"build_solid: `network` must be a CurveNetwork, got {type(network).__name__}")
    part_kinds = dict(part_kinds or {})
    models: dict[int, SurfaceModel] = {}
    for p in network.parts.tolist():
        try:
            s = surfaces[p]
        except (KeyError, IndexError) as err:
            raise InputError(f"build_solid: `surfaces` has no surface for part {p}") from err
        try:
            models[p] = surface_model(s).reframed(network.part_samples(p)[0])
        except Exception as err:  # noqa: BLE001  (ReconError, or OCC refusing the parameters)
            if not hasattr(s, "params"):
                raise  # not a fit: the caller passed something else (misuse)
            # A fit without usable parameters (empty, or ones OCC refuses): the part gets a filling face, or
            # none. Reported as "prism/coarse: surface fit params: expected one of (...), got keys []".
            log.info("part %d: no surface from its fit (%s: %s)", p, type(err).__name__, err)
            models[p] = None
    warnings: list[str] = []
    if len(network.nonmanifold):
        warnings.append(f"{len(network.nonmanifold)} non-manifold mesh edges were skipped")

    def project(part, pts):
        if models[part] is None:  # no surface: the other surfaces place the network alone
            return np.array(pts, dtype=np.float64), np.zeros_like(pts, dtype=np.float64)
        return models[part].project(pts)

    # Chords are refined onto the edge only between surfaces fitted within tolerance: a poor fit can cross its
    # neighbour well away from the mesh (pocket coarse: the fillet ring's B-spline, its face then
    # self-intersecting), where the mesh's own boundary is the better guess.
    trusted = {p for p in network.parts.tolist() if models[p] is not None and bool(getattr(surfaces[p], "ok", True))}
    if jobs is None:
        jobs = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    geo = network_geometry(network, project, tolerance=tolerance, refine=trusted, jobs=jobs)
    builder = BRep_Builder()

    # Shared vertices and edges: each made once.
    vertices = []
    for v, (p, gap) in enumerate(zip(geo.points, geo.vertex_gap)):
        mk = BRepBuilderAPI_MakeVertex(_pnt(p))
        vtx = mk.Vertex()
        builder.UpdateVertex(vtx, max(1e-7, 1.01 * float(gap)))
        vertices.append(vtx)
    edges = []
    for e in range(network.n_edges):
        a, b = network.edge_vertices[e]
        try:
            edges.append(_make_edge(geo.curves[e], vertices[a], vertices[b], builder))
        except BrepError as err:
            # The faces that use it fail (as records); the rest of the solid is still built.
            warnings.append(f"edge {e} between parts {network.edge_parts[e].tolist()}: {err}")
            edges.append(None)

    open_mesh = bool(np.any(network.edge_parts[:, 1] == OUTSIDE))
    fill_deadline = time.monotonic() + FILLING_BUDGET
    context = ShapeBuild_ReShape()
    records: list[FaceRecord] = []
    faces = []
    for p in network.parts.tolist():
        model = models[p]
        kind = part_kinds.get(p, "patch")
        name = f"{kind}_{p}"
        loops = [network.loop(j) for j in network.part_loops(p)]
        pts, nrm = network.part_samples(p)
        fit_ok = model is not None and bool(getattr(surfaces[p], "ok", True))
        # Out of tolerance but near: its own surface still beats a filling (see OWN_SURFACE_RMS); status "poor".
        near = model is not None and not fit_ok and _near_enough(surfaces[p], tolerance)
        vote = _orientation_vote(model, pts, nrm) if model is not None else 1
        face, area, status, msg = None, 0.0, "failed", ""
        if fit_ok or near:
            own_status = "ok" if fit_ok else "poor"
            if near:
                msg = f"its fit is not within tolerance (RMS {surfaces[p].deviation['rms']:.3g})"
            try:
                face, area = _face_on_surface(model, loops, edges, vote, context, precision=tolerance)
                status = own_status
            except BrepError as err:
                msg = "; ".join(m for m in (msg, str(err)) if m)
                face = _face_with_seam_split(model, loops, edges, geo, vote, context, tolerance)
                if face is not None:
                    face, area = face
                    status = own_status
                    warnings.append(f"{name}: {msg}; built with its seam at the middle of an edge")
            if face is None and status == "failed":
                face, area = _face_on_copies(model, loops, network, geo, vote, precision=tolerance)
                if face is not None:
                    status = f"{own_status}-sewn"
                    warnings.append(f"{name}: on the shared edges it failed ({msg}); built on copies of them, "
                                    "joined by sewing")
                else:
                    log.info("part %d (%s): %s; trying MakeFilling", p, model.kind, msg)
        else:
            msg = "its fit is not within tolerance" if model is not None else "it has no fitted surface"
        if face is None:
            left = min(FILLING_TIMEOUT, fill_deadline - time.monotonic())
            face, area, status, msg2 = _fallback_face(loops, edges, pts, nrm, context, precision=tolerance,
                                                      timeout=left, expected_area=(part_areas or {}).get(p))
            msg = "; ".join(m for m in (msg, msg2) if m)
            if face is None and (fit_ok or near):
                # Its own surface after all, on curves of its own: a filling bounded by the shared edges needs no
                # sewing and goes first (casting: a filling closes the solid, a face on own curves left 2 free
                # edges after sewing).
                face, area = _face_on_own_curves(model, loops, geo, vote, precision=tolerance)
                how = "its own curves"
                if face is None:
                    # The network's vertices are placed on all the surfaces that meet there; on a sliver
                    # between poor fits that can move a corner across the opposite edge (crank's linear_138:
                    # 1.2 tolerances, the plane's wire crossed itself). The mesh's own boundary does not cross
                    # itself; it lies within the edge gap of the shared edges, which sewing bridges.
                    face, area = _face_on_own_curves(model, loops, network, vote, precision=tolerance)
                    how = "its mesh boundary"
                if face is not None:
                    status = f"{own_status}-sewn"
                    warnings.append(f"{name}: {msg}; built on {how}, joined by sewing")
            if face is None:
                if fit_ok or near or model is None:  # (a near fit's own face was tried first)
                    warnings.append(f"{name}: no face ({msg})")
                else:
                    # A poor surface still closes the solid better than a hole does.
                    try:
                        face, area = _face_on_surface(model, loops, edges, vote, context, precision=tolerance)
                        status = "poor"
                    except BrepError as err:
                        msg = f"{msg}; {err}"
                        face, area, _ = _face_on_own_edges(model, loops, network, geo, vote, precision=tolerance)
                        status = "poor-sewn"
                    if face is not None:
                        warnings.append(f"{name}: {msg}; kept its out-of-tolerance {model.kind} face")
                    else:
                        status = "failed"
                        warnings.append(f"{name}: no face ({msg})")
            elif status.startswith("filled"):
                warnings.append(f"{name}: own face failed ({msg}); replaced by a filling B-spline")
        elif near and status == "poor":  # (a face on copies was named above, with `msg`)
            warnings.append(f"{name}: {msg}; kept its out-of-tolerance {model.kind} face")
        own = status in ("ok", "ok-sewn", "poor", "poor-sewn")
        surface_type = model.kind if own else "bspline" if face is not None else (
            model.kind if model is not None else "none")
        expected = (part_areas or {}).get(p)
        if face is not None and expected and not 1 / AREA_RATIO_WARNING <= area / expected <= AREA_RATIO_WARNING:
            warnings.append(f"{name}: its {surface_type} face has {area / expected:.3g}× the area of its part of "
                            "the mesh: it may reach far from the mesh (see the deviation)")
        records.append(FaceRecord(p, name, kind, surface_type, status, area, face, msg))
        if face is not None:
            faces.append(face)

    # Faces built before a later ShapeFix split one of their edges get the pieces now.
    faces = [TopoDS.Face_s(context.Apply(f)) for f in faces]
    # A later neighbour's ShapeFix re-projects or re-tolerances a shared edge in place, which can leave an
    # earlier face with a p-curve off its edge (rocker-arm2500: one face InvalidCurveOnSurface at this point,
    # valid when built): the same edge repair as for a face of its own (in place, so neighbours keep sharing).
    for f in faces:
        if not BRepCheck_Analyzer(f).IsValid():
            _fix_edges(f)
    records = [FaceRecord(r.part, r.name, r.kind, r.surface_type, r.status, r.area,
                          None if r.face is None else TopoDS.Face_s(context.Apply(r.face)), r.message) for r in records]
    if not records:
        raise BrepError("the curve network has no part with a boundary (one part covers the whole mesh): "
                        "no face can be bounded")
    if not faces:
        first = next((r.message for r in records if r.message), "")
        raise BrepError(f"none of the {len(records)} parts got a face (first: {first})")
    shape = _assemble(faces, tolerance, open_mesh, warnings)
    _mend_faces(shape, tolerance, warnings)
    validity = None
    if shape.ShapeType() == TopAbs_SOLID:
        validity = shape_validity(shape)
        if not validity.ok:
            fixed = _whole_fixed(shape, tolerance, warnings)
            if fixed is not shape:
                shape, validity = fixed, None
    # Map records to the faces that ended up in the shape (ShapeFix may rebuild some).
    final_faces = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        final_faces.append(TopoDS.Face_s(exp.Current()))
        exp.Next()
    records = _match_faces(records, final_faces, network)

    if validity is None:  # (the solid's was measured above: BRepCheck and the volume, a second time for nothing)
        validity = shape_validity(shape)
    if open_mesh:
        warnings.append("the mesh is open: the result is a shell, not a solid")
    elif not validity.ok:
        warnings.append(f"result is not a valid closed solid: {validity}")
    n_bad = sum(r.status == "failed" or r.face is None for r in records)
    if n_bad:
        warnings.append(f"{n_bad} of {len(records)} parts have no face in the result: do not trust its volume")
    for w in warnings:
        log.warning("build_solid: %s", w)

    return BrepResult(occ=shape, faces=tuple(records), validity=validity, geometry=geo,
                      warnings=tuple(warnings))


def _assemble(faces, tolerance, open_mesh, warnings):
    builder = BRep_Builder()
    shell = TopoDS_Shell()
    builder.MakeShell(shell)
    for f in faces:
        builder.Add(shell, f)
    sewn_shell = False
    if free_edge_count(shell) > 0 and not open_mesh:
        # Faces that did not use the shared edges (copies, fillings, failures): sew as the last resort, at the
        # smallest tolerance that closes the shell (copies of shared edges need almost none; a wide sewing
        # merges the small edges of small faces). A mesh of several bodies sews into several shells: their
        # faces go back into one shell, which ShapeFix_Shell splits by connection below.
        best = None
        for factor in SEWING_FACTORS:
            sewn = _sewn(faces, factor * tolerance)
            if sewn is None:
                continue
            free = free_edge_count(sewn)
            if best is None or free < best[0]:
                best = (free, factor, sewn)
            if free == 0:
                break
        if best is not None:
            shell = best[2]
            sewn_shell = True
            warnings.append(f"shell had free edges; sewn at {best[1] * tolerance:g} ({best[1]:g}× the tolerance)")
            if best[0] == 0 and orientation_conflicts(shell):
                shell = _without_small_edges(shell, tolerance, warnings)
        else:
            warnings.append("shell had free edges; sewing returned no face")
    fix = ShapeFix_Shell(shell)
    # A shell as built needs orientation only: every face was mended (and checked) on its own already, and
    # ShapeFix_Shell's own pass of ShapeFix_Face works at OCC's 1e-7 and re-merges what the faces share (on
    # abc_00000050 it turned a closed manifold shell of 13 valid faces into 4 shells, two of them with 11 free
    # edges). Sewing re-cuts edges: that pass mends what it leaves (plate_holes/coarse is invalid without it).
    fix.FixFaceMode = -1 if sewn_shell else 0  # -1: its default
    fix.Perform()
    fixed = fix.Shape()
    shells = []
    exp = TopExp_Explorer(fixed, TopAbs_SHELL)
    while exp.More():
        shells.append(TopoDS.Shell_s(exp.Current()))
        exp.Next()
    if not shells:
        warnings.append("ShapeFix_Shell returned no shell: the result is the loose faces")
        comp = TopoDS_Compound()
        builder.MakeCompound(comp)
        for f in faces:
            builder.Add(comp, f)
        return comp
    if open_mesh:
        return shells[0] if len(shells) == 1 else fixed
    solids = []
    for sh in shells:
        if free_edge_count(sh) > 0:
            warnings.append(f"a shell with {free_edge_count(sh)} free edges is left as a shell")
            solids.append(sh)
            continue
        mk = BRepBuilderAPI_MakeSolid(sh)
        if not mk.IsDone():
            warnings.append("BRepBuilderAPI_MakeSolid failed: a closed shell is left as a shell")
            solids.append(sh)
            continue
        sf = ShapeFix_Solid(mk.Solid())
        sf.FixShellTool().FixFaceMode = -1 if sewn_shell else 0  # (as for the shell above)
        sf.Perform()
        fixed_solid = sf.Solid()
        if fixed_solid.IsNull() or fixed_solid.ShapeType() != TopAbs_SOLID:
            warnings.append("ShapeFix_Solid returned no solid: a closed shell is left as a shell")
            solids.append(sh)
            continue
        solid = TopoDS.Solid_s(fixed_solid)
        if not BRepLib.OrientClosedSolid_s(solid):
            warnings.append("BRepLib.OrientClosedSolid could not orient the solid")
        solids.append(solid)
    if len(solids) == 1:
        return solids[0]
    comp = TopoDS_Compound()
    builder.MakeCompound(comp)
    for s in solids:
        builder.Add(comp, s)
    warnings.append(f"{len(solids)} bodies: the result is a compound")
    return comp


#: Small edges that make a sewn shell unorientable are dropped at these multiples of the tolerance, the least first.
SMALL_EDGE_FACTORS = (2.0, 4.0)


def orientation_conflicts(shell) -> int:
    """Edges that two faces of ``shell`` run in the same direction: where no orientation of the faces agrees.

    In a closed orientable shell every edge is used once forward and once reversed. Faces are built oriented by
    the mesh normals, so a conflict is not a face the wrong way round but an edge sewing joined wrongly: a short
    edge cut where the sewing tolerance spans more than it (rocker-arm: one edge of 0.1 × the tolerance at 10×
    it, along which ShapeFix_Shell split the closed shell in two).
    """
    emap = TopTools_IndexedMapOfShape()
    uses: dict[int, list] = {}
    faces = TopExp_Explorer(shell, TopAbs_FACE)
    i = 0
    while faces.More():
        edges = TopExp_Explorer(faces.Current(), TopAbs_EDGE)  # orientations composed with the face's
        while edges.More():
            edge = edges.Current()
            if not BRep_Tool.Degenerated_s(TopoDS.Edge_s(edge)):
                uses.setdefault(emap.Add(edge), []).append((i, edge.Orientation()))
            edges.Next()
        faces.Next()
        i += 1
    return sum(len(u) == 2 and u[0][0] != u[1][0] and u[0][1] == u[1][1] for u in uses.values())


def _without_small_edges(shell, tolerance: float, warnings):
    """``shell`` with its small edges dropped (vertices merged, in every face that shares them) at the least of
    :data:`SMALL_EDGE_FACTORS` × ``tolerance`` that leaves no orientation conflict and every face; else ``shell``.
    """
    from OCP.ShapeFix import ShapeFix_Wireframe

    n_faces = _count(shell, TopAbs_FACE)
    for factor in SMALL_EDGE_FACTORS:
        fix = ShapeFix_Wireframe(shell)
        fix.SetPrecision(factor * tolerance)
        fix.ModeDropSmallEdges = True
        if not fix.FixSmallEdges():
            continue
        out = fix.Shape()
        if out.ShapeType() == TopAbs_SHELL and _count(out, TopAbs_FACE) == n_faces and not orientation_conflicts(out):
            warnings.append(f"sewing left {orientation_conflicts(shell)} edges no orientation agrees on: edges under "
                            f"{factor:g}× the tolerance were dropped")
            return TopoDS.Shell_s(out)
    warnings.append(f"sewing left {orientation_conflicts(shell)} edges no orientation agrees on")
    return shell


def _whole_fixed(shape, tolerance: float, warnings):
    """A closed solid BRepCheck refuses, after ShapeFix_Shape on the whole of it; ``shape`` if that is no better.

    The last resort, kept only when the result is one valid closed solid with every face: ShapeFix_Shape mends
    the faces and their shared edges together, where :func:`_mend_faces` mends each face alone (rocker-arm after
    its small edges were dropped: two faces NotClosed / InvalidCurveOnSurface, valid after this, volume −0.1 %).
    """
    from OCP.ShapeFix import ShapeFix_Shape

    fix = ShapeFix_Shape(shape)
    fix.SetPrecision(PRECISION_SHARE * tolerance)
    fix.SetMaxTolerance(SEWING_FACTORS[-1] * tolerance)
    fix.Perform()
    out = fix.Shape()
    if (out.ShapeType() == TopAbs_SOLID and _count(out, TopAbs_FACE) == _count(shape, TopAbs_FACE)
            and shape_validity(out).ok):
        warnings.append("the solid was invalid after assembly: mended whole by ShapeFix_Shape")
        return TopoDS.Solid_s(out)
    return shape


def _mend_faces(shape, tolerance: float, warnings) -> None:
    """Mend, in place, faces of the assembled ``shape`` that BRepCheck refuses: edges made same-parameter, then
    ShapeFix_Wire's self-intersection fix.

    Every face was valid when it was built; sewing at a tolerance above the edges' own re-cuts and re-tolerances
    them (rocker-arm: one valid B-spline face self-intersecting after sewing at 10× the tolerance, the one
    fault of a closed solid of 112 faces; valid after this, volume changed by 7e-6).
    """
    from OCP.ShapeFix import ShapeFix_Wire

    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        face = TopoDS.Face_s(exp.Current())
        exp.Next()
        if BRepCheck_Analyzer(face).IsValid():
            continue
        _fix_edges(face)
        if not BRepCheck_Analyzer(face).IsValid():
            wires = TopExp_Explorer(face, TopAbs_WIRE)
            while wires.More():
                ShapeFix_Wire(TopoDS.Wire_s(wires.Current()), face, PRECISION_SHARE * tolerance).FixSelfIntersection()
                wires.Next()
        problems = face_problems(face)
        warnings.append(f"a face invalid after assembly was mended in place{f'; still: {problems}' if problems else ''}")


def _face_boxes(faces) -> np.ndarray:
    """(k, 6) float: (xmin, ymin, zmin, xmax, ymax, zmax) of each face's bounding box from its geometry (not its
    triangulation, which can lie inside the surface), widened by a thousandth of the whole's diagonal so that
    round-off cannot put a face outside its box."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    out = np.empty((len(faces), 6))
    for i, f in enumerate(faces):
        box = Bnd_Box()
        BRepBndLib.Add_s(f, box, False)
        out[i] = (-np.inf,) * 3 + (np.inf,) * 3 if box.IsVoid() or box.IsOpen() else box.Get()
    finite = np.all(np.isfinite(out), axis=1)
    if finite.any():
        margin = 1e-3 * float(np.linalg.norm(out[finite, 3:].max(axis=0) - out[finite, :3].min(axis=0)))
        out[:, :3] -= margin
        out[:, 3:] += margin
    return out


def _box_distances(boxes: np.ndarray, p) -> np.ndarray:
    """Distance of the point ``p`` (3,) to each box of ``boxes`` (k, 6) (0 inside)."""
    gap = np.maximum(np.maximum(boxes[:, :3] - p, p - boxes[:, 3:]), 0.0)
    return np.linalg.norm(gap, axis=1)


def _sewn(faces, tolerance: float):
    """All ``faces`` sewn at ``tolerance``, back in one shell (``None`` if sewing returned no face)."""
    sew = BRepBuilderAPI_Sewing(tolerance)
    for f in faces:
        sew.Add(f)
    sew.Perform()
    builder = BRep_Builder()
    shell = TopoDS_Shell()
    builder.MakeShell(shell)
    n_faces = 0
    exp = TopExp_Explorer(sew.SewedShape(), TopAbs_FACE)
    while exp.More():
        builder.Add(shell, exp.Current())
        n_faces += 1
        exp.Next()
    return shell if n_faces else None


def _match_faces(records, final_faces, network):
    """Attach each record to its face in the final shape: same TShape first, else nearest sample point (the first
    face in ``final_faces`` at the least distance)."""
    out = []
    taken = set()
    boxes = None
    for rec in records:
        match = None
        if rec.face is not None:
            for i, f in enumerate(final_faces):
                if i not in taken and f.IsSame(rec.face):
                    match = i
                    break
        if match is None and rec.face is not None:
            from OCP.BRepExtrema import BRepExtrema_DistShapeShape

            pts, _ = network.part_samples(rec.part)
            if len(pts):
                p = pts[len(pts) // 2]
                vtx = BRepBuilderAPI_MakeVertex(_pnt(p)).Vertex()
                # A face's box bounds its distance from below: the faces are measured nearest box first, and none
                # whose box is farther than the least distance found can be nearer (a sewn shell rebuilds every
                # face, and measuring each against all took rocker-arm's 112 faces ~0.6 s).
                if boxes is None:
                    boxes = _face_boxes(final_faces)
                free = [i for i in range(len(final_faces)) if i not in taken]
                lower = dict(zip(free, _box_distances(boxes[free], p)))
                best = None
                for i in sorted(free, key=lambda i: (lower[i], i)):
                    if best is not None and lower[i] > best[0]:
                        break
                    d = BRepExtrema_DistShapeShape(vtx, final_faces[i])
                    if d.IsDone() and (best is None or (d.Value(), i) < best):
                        best = (d.Value(), i)
                match = best[1] if best else None
        if match is not None:
            taken.add(match)
        face = final_faces[match] if match is not None else None
        out.append(FaceRecord(rec.part, rec.name, rec.kind, rec.surface_type, rec.status, rec.area, face, rec.message))
    return out
