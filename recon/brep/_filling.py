"""The fallback face: a ``BRepOffsetAPI_MakeFilling`` B-spline through a part's boundary and mesh points, built
in a child process (it can crash or spin), then trimmed by the shared edges where it can be."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from OCP.BRep import BRep_Tool
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepOffsetAPI import BRepOffsetAPI_MakeFilling
from OCP.GeomAbs import GeomAbs_Shape
from OCP.TopAbs import TopAbs_FACE
from OCP.TopExp import TopExp
from OCP.TopoDS import TopoDS

from .._parallel import time_limits_fired
from ..errors import BrepError
from ._edges import checked_edges, pnt
from ._faces import face_in_child, face_on_surface, orientation_vote
from ._result import FaceStatus, face_area
from ..fit import SurfaceKind
from ._surfaces import SurfaceModel


#: Seconds one ``BRepOffsetAPI_MakeFilling`` may take: a safety net against one that spins, not a budget (issue 25):
#: 7× the slowest seen, 16.5 s on 2 cores under a load of 12 (2 s unloaded). Where it fires the part fails
#: (:func:`recon._parallel.time_limits_fired`): never a result that depends on the machine's speed.
FILLING_TIMEOUT = 120.0


#: MakeFilling calls one build may make, a count so that every machine stops at the same one (it replaces a 30 s
#: budget): both point sets (FILLING_POINTS) for 36 parts, the most a real mesh needed filled: 30 s at 0.41 s each.
FILLING_ATTEMPTS = 72


@dataclass
class FillingBudget:
    """The MakeFilling calls a build has left (:data:`FILLING_ATTEMPTS`), taken by its parts in their order."""

    left: int = FILLING_ATTEMPTS

    def take(self) -> bool:
        """One call, if one is left."""
        if self.left <= 0:
            return False
        self.left -= 1
        return True


#: A face whose area is off its part's mesh area by more than this factor either way is named in the warnings: a
#: MakeFilling surface can balloon between its constraints (reported, not refused: bench/brep.md).
AREA_RATIO_WARNING = 2.0


#: The filling's point sets, in turn: every ``len // 16``-th sample of the part (of the 48 the network keeps, every
#: 3rd), then every one (0) when the first face is missing or off the part's area by more than AREA_RATIO_WARNING:
#: few points let the surface balloon, all of them alone over-constrain it (bench/brep.md).
FILLING_POINTS = (16, 0)


#: MakeFilling's approximation of its plate: highest degree, most segments. OCC's default (8, 9) lets a high-degree
#: net swing far outside the face (poles 14 part diagonals away, bench/editability.md), swelling the solid's box;
#: degree 5 over up to 30 segments keeps the control net within 3× the face's own box.
FILLING_APPROX = (5, 30)


def filled_face(checked: list, points):
    """Fallback: a B-spline face through the boundary edges ``checked`` (:func:`checked_edges`) and mesh points
    (BRepOffsetAPI_MakeFilling).

    The caller trims the face's surface with the shared wires again (so that the face keeps the network's edges)
    and keeps the filled face itself only if that fails.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    try:
        fill = BRepOffsetAPI_MakeFilling()
        fill.SetApproxParam(*FILLING_APPROX)
        for edge in checked:
            fill.Add(edge, GeomAbs_Shape.GeomAbs_C0, True)
        for p in pts:
            fill.Add(pnt(p))
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


def wire_joins(checked: list) -> str:
    """Why ``BRepOffsetAPI_MakeFilling`` would fail to make its wire of the loop ``checked``, or "".

    MakeFilling first makes wires of its boundary edges (``BRepFill_Filling::BuildWires``): from the first edge on,
    it adds the first edge left that shares a vertex with the wire's two ends (``TopExp::Vertices``), else one with
    a vertex within both tolerances of an end, through ``BRepLib_MakeWire``, which joins a new edge's end to any
    vertex of the wire so far within either one's tolerance. Vertex tolerances that neighbours' repairs grew past
    the distance to another vertex of the loop (bench/brep.md, 2026-12-04) make such a join; the wire
    then has no two ends (null vertices) and MakeFilling raises "BRep_Tool:: TopoDS_Vertex hasn't gp_Pnt". The same
    steps are taken here on copies of the edges (the joins change vertices in place) and the loop refused there.
    """
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
    from OCP.BRepLib import BRepLib_MakeWire
    from OCP.TopoDS import TopoDS_Compound, TopoDS_Iterator, TopoDS_Vertex

    builder = BRep_Builder()
    group = TopoDS_Compound()
    builder.MakeCompound(group)
    for edge in checked:
        builder.Add(group, edge)
    copied = BRepBuilderAPI_Copy(group, True, False).Shape()  # (held: the iterator keeps a reference only)
    it = TopoDS_Iterator(copied)
    rest = []
    while it.More():
        rest.append(TopoDS.Edge_s(it.Value()))
        it.Next()

    def ends(shape):
        a, b = TopoDS_Vertex(), TopoDS_Vertex()
        TopExp.Vertices_s(shape, a, b)
        return a, b

    def close(v, w):
        d = BRep_Tool.Pnt_s(v).Distance(BRep_Tool.Pnt_s(w))
        return d < BRep_Tool.Tolerance_s(v) and d < BRep_Tool.Tolerance_s(w)

    total = len(rest)
    while rest:
        wire = BRepLib_MakeWire()
        wire.Add(rest.pop(0))
        while True:
            wire_ends = ends(wire.Wire())
            if any(v.IsNull() for v in wire_ends):
                return (f"after {total - len(rest)} of its {total} edges MakeFilling's wire has no ends: vertex "
                        "tolerances reach other vertices of the loop, which it joins (BRep_Tool:: TopoDS_Vertex "
                        "hasn't gp_Pnt)")
            pick = next((k for k, e in enumerate(rest) if any(v.IsSame(w) for v in wire_ends for w in ends(e))), None)
            if pick is None:
                pick = next((k for k, e in enumerate(rest) if any(close(v, w) for v in wire_ends for w in ends(e))),
                            None)
            if pick is None:
                break
            wire.Add(rest.pop(pick))
    return ""


def isolated_filled_face(loops, edges, points, context, *, timeout: float = FILLING_TIMEOUT):
    """:func:`filled_face` in a child process (:func:`face_in_child`); returns the face and its surface."""
    if len(loops) != 1:
        raise BrepError(f"MakeFilling fallback needs a single boundary loop, the part has {len(loops)}")
    checked = checked_edges(loops[0], edges, context)
    joined = wire_joins(checked)
    if joined:
        raise BrepError(f"MakeFilling refused: {joined}")
    face = face_in_child(filled_face, (checked, points), "BRepOffsetAPI_MakeFilling", timeout)
    return face, BRep_Tool.Surface_s(face)


def fallback_face(loops, edges, points, normals, context, *, precision: float, timeout: float = FILLING_TIMEOUT,
                   expected_area: float | None = None, budget: FillingBudget | None = None):
    """A filling surface through the part's boundary and points, trimmed by the shared wires if possible.

    Through every ``len // 16``-th point first; through every point when that gives no face, or one whose area
    is off ``expected_area`` (the part's mesh area) by more than :data:`AREA_RATIO_WARNING` either way, and then
    the face of the two whose area is nearer (see :data:`FILLING_POINTS`). Each MakeFilling call takes one of
    ``budget`` (none left: no call) and may take ``timeout`` seconds; one that runs out of time ends the attempts.
    Returns ``(face or None, area, status, message)``; ``status`` is ``FILLED`` for a face on the filling
    surface bounded by the network's own edges, ``FILLED_SEWN`` for MakeFilling's own face (new edges,
    joined to its neighbours by sewing), ``FAILED`` otherwise (a :class:`FaceStatus`).
    """
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
        if budget is not None and not budget.take():
            spent = f"no filling tried: this build's {FILLING_ATTEMPTS} MakeFilling calls are spent"
            best = (None, 0.0, FaceStatus.FAILED, spent) if best is None else best
            break
        fired = time_limits_fired()
        got = fallback_face_through(loops, edges, pts[::every], nrm[::every], context, precision=precision,
                                     timeout=timeout)
        if best is None or off(got) < off(best):
            best = got
        if off(best) <= AREA_RATIO_WARNING or time_limits_fired() > fired:
            break
    return best


def fallback_face_through(loops, edges, points, normals, context, *, precision: float, timeout: float):
    """:func:`fallback_face` through the given points."""
    try:
        filled, surface = isolated_filled_face(loops, edges, points, context, timeout=timeout)
    except BrepError as err:
        return None, 0.0, FaceStatus.FAILED, str(err)
    except Exception as err:  # noqa: BLE001  (an OCC failure outside the checked calls is still a record)
        return None, 0.0, FaceStatus.FAILED, f"filling failed: {type(err).__name__}: {err}"
    filling = SurfaceModel(SurfaceKind.BSPLINE, surface)
    fvote = 1
    try:
        fvote = orientation_vote(filling, points, normals)
        face, area = face_on_surface(filling, loops, edges, fvote, context, precision=precision)
        return face, area, FaceStatus.FILLED, ""
    except Exception as err:  # noqa: BLE001  (BrepError or an OCC failure: fall back to the filled face)
        first = str(err)
    area = abs(face_area(filled))
    if area > 0 and BRepCheck_Analyzer(filled).IsValid():
        return filled, area, FaceStatus.FILLED_SEWN, f"filling surface trimmed by the shared edges failed ({first})"
    try:
        # Last resort: a face valid one way round still closes the shell, where no face leaves a hole.
        face, area = face_on_surface(filling, loops, edges, fvote, context, precision=precision, both_sides=False)
        return face, area, FaceStatus.FILLED, f"the filling face is valid one way round only ({first})"
    except Exception:  # noqa: BLE001
        return None, 0.0, FaceStatus.FAILED, f"the filling face is not valid either ({first})"
