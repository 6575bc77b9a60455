"""How one part gets its face: a list of strategies tried in order, the first face wins.

Which list a part runs depends on its fit (:data:`ORDERS`): a fit within tolerance, or near it, gets its own
surface first and a filling only when every way of bounding that surface failed; a fit out of tolerance (or
none) gets a filling first and keeps its poor surface only when the filling failed too. The order is data::

    >>> print(describe_orders())  # doctest: +NORMALIZE_WHITESPACE
    own surface: on_shared_edges, with_seam_split, on_copies, filling, on_own_curves, on_mesh_boundary
    filling first: filling, poor_on_shared_edges, poor_on_own_edges

Each strategy takes the part's :class:`FaceJob` and the message so far (why the strategies before it failed) and
returns an :class:`Attempt`: a face with its status and warnings, or no face and the message to hand on.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._parallel import time_limits_fired
from ..network import CurveNetwork, NetworkGeometry
from ..errors import BrepError
from ._faces import Reach, face_of_whole_surface, face_on_copies, face_on_own_curves, face_on_own_edges, face_on_surface
from ._filling import AREA_RATIO_WARNING, FILLING_TIMEOUT, FillingBudget, fallback_face
from ._result import FaceRecord, FaceStatus
from ._seam import face_with_seam_split
from ._surfaces import SurfaceModel

__all__ = ["Attempt", "FaceJob", "ORDERS", "build_face", "describe_orders"]

log = logging.getLogger(__name__)


@dataclass
class FaceJob:
    """What building one part's face needs. ``context`` and ``edges`` are shared with the other parts: a face that
    is accepted hands on to them what its repairs changed."""

    part: int
    name: str
    kind: str
    model: SurfaceModel | None
    fit: object  # the part's surface as given (a recon.fit result has ``ok`` and ``deviation``)
    fit_ok: bool  # its own surface, fitted within tolerance
    near: bool  # out of tolerance but near enough to bound its own face (see recon.brep._faces.OWN_SURFACE_RMS)
    loops: list
    points: np.ndarray
    normals: np.ndarray
    vote: int
    network: CurveNetwork
    geo: NetworkGeometry
    edges: list
    context: object
    tolerance: float
    expected_area: float | None
    fill_budget: FillingBudget  # (shared by the build's parts)
    reach: Reach | None = None  # a face reaching beyond it is refused and the next strategy tried


@dataclass(frozen=True)
class Attempt:
    """A strategy's outcome: a face (with its area, status and warnings), or none and the message so far."""

    face: object
    area: float
    status: FaceStatus
    message: str
    warnings: tuple = ()


def _join(*messages: str) -> str:
    return "; ".join(m for m in messages if m)


def _none(message: str) -> Attempt:
    return Attempt(None, 0.0, FaceStatus.FAILED, message)


def _kept_poor(job: FaceJob, message: str) -> str:
    return f"{job.name}: {message}; kept its out-of-tolerance {job.model.kind} face"


def on_shared_edges(job: FaceJob, message: str) -> Attempt:
    """Its own surface bounded by the shared edges: the face that needs no sewing."""
    try:
        face, area = face_on_surface(job.model, job.loops, job.edges, job.vote, job.context, precision=job.tolerance)
    except BrepError as err:
        return _none(_join(message, str(err)))
    warnings = (_kept_poor(job, message),) if job.near else ()
    return Attempt(face, area, FaceStatus.on_own_surface(job.fit_ok, sewn=False), message, warnings)


def with_seam_split(job: FaceJob, message: str) -> Attempt:
    """The same on a cylinder or cone with its seam moved to the middle of an edge (recon.brep._seam)."""
    got = face_with_seam_split(job.model, job.loops, job.edges, job.geo, job.vote, job.context, job.tolerance)
    if got is None:
        return _none(message)
    warnings = (f"{job.name}: {message}; built with its seam at the middle of an edge",)
    if job.near:
        warnings += (_kept_poor(job, message),)
    return Attempt(got[0], got[1], FaceStatus.on_own_surface(job.fit_ok, sewn=False), message, warnings)


def on_copies(job: FaceJob, message: str) -> Attempt:
    """Its own surface bounded by fresh copies of the shared edges, joined to its neighbours by sewing."""
    face, area = face_on_copies(job.model, job.loops, job.network, job.geo, job.vote, precision=job.tolerance)
    if face is None:
        log.info("part %d (%s): %s; trying MakeFilling", job.part, job.model.kind, message)
        return _none(message)
    warnings = (f"{job.name}: on the shared edges it failed ({message}); built on copies of them, joined by sewing",)
    return Attempt(face, area, FaceStatus.on_own_surface(job.fit_ok, sewn=True), message, warnings)


def filling(job: FaceJob, message: str) -> Attempt:
    """A MakeFilling B-spline through its boundary and points (recon.brep._filling), within the build's calls."""
    face, area, status, why = fallback_face(job.loops, job.edges, job.points, job.normals, job.context,
                                            precision=job.tolerance, timeout=FILLING_TIMEOUT,
                                            expected_area=job.expected_area, budget=job.fill_budget)
    message = _join(message, why)
    if face is None:
        return _none(message)
    return Attempt(face, area, status, message, (f"{job.name}: own face failed ({message}); replaced by a filling "
                                                 "B-spline",))


def _on_own(job: FaceJob, message: str, polylines, how: str) -> Attempt:
    face, area = face_on_own_curves(job.model, job.loops, polylines, job.vote, precision=job.tolerance)
    if face is None:
        return _none(message)
    return Attempt(face, area, FaceStatus.on_own_surface(job.fit_ok, sewn=True), message,
                   (f"{job.name}: {message}; built on {how}, joined by sewing",))


def on_own_curves(job: FaceJob, message: str) -> Attempt:
    """Its own surface bounded by the placed edges' images in its parameters, joined by sewing. After the filling:
    a filling bounded by the shared edges needs no sewing."""
    return _on_own(job, message, job.geo, "its own curves")


def on_mesh_boundary(job: FaceJob, message: str) -> Attempt:
    """The same on the mesh's own boundary polylines. The network's vertices are placed on all the surfaces that
    meet there, which on a sliver between poor fits can move a corner across the opposite edge; the mesh's
    boundary does not cross itself and lies within the edge gap of the shared edges, which sewing bridges."""
    return _on_own(job, message, job.network, "its mesh boundary")


def poor_on_shared_edges(job: FaceJob, message: str) -> Attempt:
    """An out-of-tolerance surface bounded by the shared edges: it closes the solid better than a hole does."""
    if job.model is None:
        return _none(message)
    try:
        face, area = face_on_surface(job.model, job.loops, job.edges, job.vote, job.context, precision=job.tolerance)
    except BrepError as err:
        return _none(f"{message}; {err}")
    return Attempt(face, area, FaceStatus.POOR, message, (_kept_poor(job, message),))


def poor_on_own_edges(job: FaceJob, message: str) -> Attempt:
    """The same on edges of its own (copies of the shared ones, else its own curves), joined by sewing."""
    if job.model is None:
        return _none(message)
    face, area, _ = face_on_own_edges(job.model, job.loops, job.network, job.geo, job.vote, precision=job.tolerance)
    if face is None:
        return _none(message)
    return Attempt(face, area, FaceStatus.POOR_SEWN, message, (_kept_poor(job, message),))


Strategy = Callable[[FaceJob, str], Attempt]

#: The strategies each kind of part tries, in order: its own surface first when the fit is within tolerance or
#: near it, a filling first otherwise.
ORDERS: dict[str, tuple[Strategy, ...]] = {
    "own surface": (on_shared_edges, with_seam_split, on_copies, filling, on_own_curves, on_mesh_boundary),
    "filling first": (filling, poor_on_shared_edges, poor_on_own_edges),
}


def describe_orders() -> str:
    """:data:`ORDERS` as text, one line per kind of part."""
    return "\n".join(f"{k}: {', '.join(s.__name__ for s in order)}" for k, order in ORDERS.items())


def _first_message(job: FaceJob) -> str:
    if job.near:
        return f"its fit is not within tolerance (RMS {job.fit.deviation['rms']:.3g})"
    if job.fit_ok:
        return ""
    return "its fit is not within tolerance" if job.model is not None else "it has no fitted surface"


def _nearest_refused(job: FaceJob, refused: list, message: str, warnings: list) -> Attempt:
    """The last resort of a part whose every face was refused for its reach: the nearest of them when it is not wild
    (within :data:`recon.brep._faces.REACH_MESHED` diagonals, where the deviation can still mesh and judge it). A face
    past the margin closes the solid; a hole leaves it open, or a part of one face leaves the result faceless (export
    seeds 5 and 38: every face of their two parts refused, no result at all)."""
    tame = [r for r in refused if job.reach is not None and not job.reach.wild(r[0])]
    if not tame:
        warnings.append(f"{job.name}: no face ({message})")
        return _none(message)
    far, name, got = min(tame, key=lambda r: r[0])
    warnings.extend(got.warnings)
    warnings.append(f"{job.name}: every face it got reaches past the margin; kept the nearest, by {name}, which "
                    f"reaches {far:.4g} outside the mesh's bounding box: the deviation judges it")
    return got


def _whole(job: FaceJob, warnings: list) -> FaceRecord:
    """The face of a part with no loop: a closed body it covers alone, which only its own closed surface bounds (no
    edge to fill between, none to sew to)."""
    message = _first_message(job)
    try:
        if job.model is None:
            raise BrepError("it has no fitted surface")
        face, area = face_of_whole_surface(job.model, job.vote, precision=job.tolerance)
    except BrepError as err:
        message = _join(message, str(err))
        warnings.append(f"{job.name}: no face ({message})")
        kind = job.model.kind if job.model is not None else "none"
        return FaceRecord(job.part, job.name, job.kind, kind, FaceStatus.FAILED, 0.0, None, message)
    if job.near:
        warnings.append(_kept_poor(job, message))
    status = FaceStatus.on_own_surface(job.fit_ok, sewn=False)
    return FaceRecord(job.part, job.name, job.kind, job.model.kind, status, area, face, message)


def _kept_unmeshable(job: FaceJob, unmeshable: list, warnings: list) -> Attempt:
    """The last resort of a part whose every face within reach gets no triangles from the mesher: the first of them
    (valid, and it closes the solid; the verdict names it as a face no viewer shows)."""
    name, got = unmeshable[0]
    warnings.extend(got.warnings)
    warnings.append(f"{job.name}: no way of building it gave a face OpenCascade's mesher triangulates; kept the one "
                    f"by {name}")
    return got


def build_face(job: FaceJob, warnings: list) -> FaceRecord:
    """The part's face by the first strategy of its order that gives one (``FAILED`` and no face if none does);
    what each says about the face is appended to ``warnings``."""
    if not job.loops:
        return _whole(job, warnings)
    order = ORDERS["own surface" if job.fit_ok or job.near else "filling first"]
    message = _first_message(job)
    got = _none(message)
    refused: list[tuple[float, str, Attempt]] = []  # (how far out, by which strategy, its face): the last resort
    unmeshable: list[tuple[str, Attempt]] = []  # (by which strategy, its face): valid faces no mesher triangulates
    for strategy in order:
        fired = time_limits_fired()
        got = strategy(job, message)
        message = got.message
        if time_limits_fired() > fired:  # a safety net fired: what would come next depends on the machine's speed
            got = _none(_join(message, "a time limit (a safety net against a hang) fired: the part fails rather "
                                       "than take a face another machine might not"))
            message = got.message
            job.fill_budget.left = 0  # (the build has failed: no more fillings, each of which could hang as long)
            warnings.append(f"{job.name}: no face ({message})")
            break
        far = job.reach.outside(got.face) if got.face is not None and job.reach is not None else 0.0
        if job.reach is not None and far > job.reach.margin:
            refused.append((far, strategy.__name__, got))
            got = _none(_join(message, f"{strategy.__name__}: {job.reach.why(far)}"))
            message = got.message
        elif got.face is not None and job.reach is not None and job.reach.unmeshable(got.face):
            unmeshable.append((strategy.__name__, got))
            got = _none(_join(message, f"{strategy.__name__}: its face gets no triangles from OpenCascade's mesher "
                                       "(a hole in every viewer)"))
            message = got.message
        if got.face is not None:
            warnings.extend(got.warnings)
            break
    else:
        got = _kept_unmeshable(job, unmeshable, warnings) if unmeshable else _nearest_refused(job, refused, message,
                                                                                               warnings)
    if got.status.own:
        surface_type = job.model.kind
    else:
        surface_type = "bspline" if got.face is not None else (job.model.kind if job.model is not None else "none")
    expected = job.expected_area
    if got.face is not None and expected and not 1 / AREA_RATIO_WARNING <= got.area / expected <= AREA_RATIO_WARNING:
        warnings.append(f"{job.name}: its {surface_type} face has {got.area / expected:.3g}× the area of its part of "
                        "the mesh: it may reach far from the mesh (see the deviation)")
    return FaceRecord(job.part, job.name, job.kind, surface_type, got.status, got.area, got.face, message)
