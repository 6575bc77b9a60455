"""Curve network + one surface per part → a closed, valid OpenCascade solid (:func:`build_solid`).

Watertight by construction: every network vertex becomes one ``TopoDS_Vertex`` and every network edge
one ``TopoDS_Edge``, built once and used by both faces it separates (DESIGN.md, "curves";
:mod:`recon.brep._edges`). Each part's face comes from the first of its strategies that gives one
(:mod:`recon.brep._strategies`: its own surface on the shared edges, on copies of them, on its own curves, or a
``BRepOffsetAPI_MakeFilling`` B-spline); the faces go into a shell and a solid, sewn as a last resort
(:mod:`recon.brep._shell`), and each record is matched to its face in the result (:mod:`recon.brep._match`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from typing import Mapping

import numpy as np
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.ShapeBuild import ShapeBuild_ReShape
from OCP.TopAbs import TopAbs_FACE, TopAbs_SOLID
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS

from ..network import OUTSIDE, CurveNetwork, NetworkGeometry, network_geometry
from ..errors import BrepError, InputError
from ._edges import fix_edges, shared_topology
from ._faces import Reach, near_enough, orientation_vote
from ._filling import FILLING_ATTEMPTS, FillingBudget
from ._match import match_faces
from ._planar import lift_planar_edges
from ._result import KIND_COLOURS, BrepResult, FaceRecord, FaceStatus, Validity, shape_validity
from ._shell import assemble, mend_faces, whole_fixed
from ._strategies import FaceJob, build_face
from ._surfaces import SurfaceModel, surface_model
from ._tessellate import display_deflection, unmeshed_faces

#: Builds of every face at most: the first checks each face at the mesh box's display deflection, each next one
#: also at that of the solid the last one made, where a face of that solid got no triangles (FreeCAD's deflection
#: comes from the solid's own box, known only once it is built). A rebuild moves the box only by what its new faces
#: reach, so a second build meets its own deflection (bench/brep.md, stop 34); the third bounds the cost at 3×.
MESHING_ROUNDS = 3

__all__ = ["BrepResult", "FaceRecord", "FaceStatus", "KIND_COLOURS", "Validity", "build_solid", "shape_validity"]

log = logging.getLogger(__name__)


def build_solid(network: CurveNetwork, surfaces: Mapping, *, tolerance: float,
                part_kinds: Mapping[int, str] | None = None,
                part_areas: Mapping[int, float] | None = None, jobs: int | None = None,
                progress: Callable[[int, int, str], None] | None = None,
                mesh_points: np.ndarray | None = None) -> BrepResult:
    """Build a closed, valid solid from a curve network and one surface per part.

    Parameters
    ----------
    network : CurveNetwork
        From :func:`recon.network.curve_network`.
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
    progress : callable(done, total, what), optional
        Told each part's face built ("faces built").
    mesh_points : (n, 3) float, optional
        The mesh's vertices (or its bounding box's corners): a face reaching farther than :func:`._faces.reach_margin`
        outside their box is refused. Default: the network's polylines and part samples.

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
    models = _surface_models(network, surfaces)
    warnings: list[str] = []
    if len(network.nonmanifold):
        warnings.append(f"{len(network.nonmanifold)} non-manifold mesh edges were skipped")
    geo = _placed_network(network, surfaces, models, tolerance, jobs)
    if mesh_points is None:  # (a part's extremes between its samples are missed by far less than the margin)
        mesh_points = np.concatenate([network.coords.reshape(-1, 3), network.samples.reshape(-1, 3)])
    reach = Reach.of(mesh_points, tolerance)
    open_mesh = bool(np.any(network.edge_parts[:, 1] == OUTSIDE))
    given, best = list(warnings), None
    for round_ in range(MESHING_ROUNDS):
        warnings[:] = given
        records, shape, validity = _assembled(network, geo, surfaces, models, reach, tolerance, dict(part_kinds or {}),
                                              dict(part_areas or {}), open_mesh, warnings, progress)
        # The display deflection of the solid itself, which no face knew while it was built: a face that meshes at
        # the mesh's can still get no triangles at it (issue 25). Every face is built again, checked at it too.
        unmeshed, deflection = unmeshed_faces(shape), display_deflection(shape)
        if validity is None and (unmeshed or round_):  # (a rebuild is kept only if no worse: both are measured)
            validity = shape_validity(shape)
        worse = best is not None and (validity is not None and not validity.ok, len(unmeshed)) > best[0]
        if not worse:
            best = ((validity is not None and not validity.ok, len(unmeshed)), records, shape, validity,
                    list(warnings), unmeshed, deflection)
        if not unmeshed or deflection in reach.deflections or round_ == MESHING_ROUNDS - 1:
            break
        log.info("%d faces get no triangles at the solid's display deflection %.4g: the faces are built again, each "
                 "checked at it too", len(unmeshed), deflection)
        given.append(f"{_counted_faces(len(unmeshed))} got no triangles at the solid's display deflection "
                     f"{deflection:.4g} (FreeCAD's): built again, every face checked at it too")
        reach = reach.meshing_at(deflection)
    assert best is not None
    _, records, shape, validity, warnings, unmeshed, deflection = best
    if unmeshed:
        warnings.append(f"{_counted_faces(len(unmeshed))} without triangles at the solid's display deflection "
                        f"{deflection:.4g} (FreeCAD's): holes in a viewer")
    # Map records to the faces that ended up in the shape (ShapeFix may rebuild some).
    records = match_faces(records, _faces_of(shape), network)
    if validity is None:  # (the solid's was measured already: BRepCheck and the volume, a second time for nothing)
        validity = shape_validity(shape)
    if open_mesh:
        warnings.append("the mesh is open: the result is a shell, not a solid")
    elif not validity.ok:
        warnings.append(f"result is not a valid closed solid: {validity}")
    n_bad = sum(r.status == FaceStatus.FAILED or r.face is None for r in records)
    if n_bad:
        warnings.append(f"{n_bad} of {len(records)} parts have no face in the result: do not trust its volume")
    for w in warnings:
        log.warning("build_solid: %s", w)
    return BrepResult(occ=shape, faces=tuple(records), validity=validity, geometry=geo, warnings=tuple(warnings))


def _counted_faces(n: int) -> str:
    return f"{n} face" if n == 1 else f"{n} faces"


def _assembled(network: CurveNetwork, geo: NetworkGeometry, surfaces: Mapping, models: Mapping, reach: Reach,
               tolerance: float, kinds: dict, areas: dict, open_mesh: bool, warnings: list,
               progress: Callable[[int, int, str], None] | None) -> tuple[list, object, Validity | None]:
    """Every part's face on fresh shared edges, assembled, mended and healed: ``(records, shape, validity)``, the
    validity where it was measured (None when a later step changed the shape)."""
    edges = shared_topology(network, geo, warnings)
    context = ShapeBuild_ReShape()
    fill_budget = FillingBudget(FILLING_ATTEMPTS)  # (counted, not timed: the same on every machine, issue 25)
    records = []
    for p in network.parts.tolist():
        job = _face_job(p, network, geo, surfaces, models, edges, context, tolerance=tolerance,
                        kind=kinds.get(p, "patch"), expected_area=areas.get(p), fill_budget=fill_budget)
        job.reach = reach
        records.append(build_face(job, warnings))
        if progress is not None:
            progress(len(records), len(network.parts), "faces built")
    records, faces = _faces_now(records, context)
    if not records:
        raise BrepError("the curve network has no part with a boundary (one part covers the whole mesh): "
                        "no face can be bounded")
    if not faces:
        first = next((r.message for r in records if r.message), "")
        raise BrepError(f"none of the {len(records)} parts got a face (first: {first})")
    shape = assemble(faces, tolerance, open_mesh, warnings)
    mend_faces(shape, tolerance, warnings)
    shape, validity = _healed(shape, tolerance, warnings)
    if lift_planar_edges(shape, tolerance):  # (what a STEP reader makes of a plane: bench/brep.md, read-back)
        validity = None
    return records, shape, validity


def _surface_models(network: CurveNetwork, surfaces: Mapping) -> dict[int, SurfaceModel | None]:
    """Each part's surface as a :class:`SurfaceModel` turned to its samples; None for a fit without a usable one."""
    models: dict[int, SurfaceModel | None] = {}
    for p in network.parts.tolist():
        try:
            s = surfaces[p]
        except (KeyError, IndexError) as err:
            raise InputError(f"build_solid: `surfaces` has no surface for part {p}") from err
        try:
            models[p] = surface_model(s).reframed(network.part_samples(p)[0], _rim(network, p))
        except Exception as err:  # noqa: BLE001  (ReconError, or OCC refusing the parameters)
            if not hasattr(s, "params"):
                raise  # not a fit: the caller passed something else (misuse)
            # A fit without usable parameters (empty, or ones OCC refuses): the part gets a filling face, or
            # none. Reported as "prism/coarse: plane surface fit: params need [...], got keys []".
            log.info("part %d: no surface from its fit (%s: %s)", p, type(err).__name__, err)
            models[p] = None
    return models


def _rim(network: CurveNetwork, part: int) -> list[np.ndarray]:
    """The polylines of the edges of the part's loops."""
    return [network.polyline(abs(int(ref)) - 1) for j in network.part_loops(part) for ref in network.loop(j)]


def _fit_ok(surfaces: Mapping, models: Mapping, part: int) -> bool:
    """Whether the part has its own surface, fitted within tolerance (a surface that is no fit counts as one)."""
    return models[part] is not None and bool(getattr(surfaces[part], "ok", True))


def _placed_network(network: CurveNetwork, surfaces: Mapping, models: Mapping, tolerance: float,
                    jobs: int | None) -> NetworkGeometry:
    """The network's vertices and edges placed on the surfaces (:func:`recon.network.network_geometry`)."""
    def project(part, pts):
        if models[part] is None:  # no surface: the other surfaces place the network alone
            return np.array(pts, dtype=np.float64), np.zeros_like(pts, dtype=np.float64)
        return models[part].project(pts)

    # Chords are refined onto the edge only between surfaces fitted within tolerance: a poor fit can cross its
    # neighbour well away from the mesh, where the mesh's own boundary is the better guess.
    trusted = {p for p in network.parts.tolist() if _fit_ok(surfaces, models, p)}
    if jobs is None:
        jobs = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return network_geometry(network, project, tolerance=tolerance, refine=trusted, jobs=jobs)


def _face_job(p: int, network: CurveNetwork, geo: NetworkGeometry, surfaces: Mapping, models: Mapping, edges: list,
              context, *, tolerance: float, kind: str, expected_area: float | None,
              fill_budget: FillingBudget) -> FaceJob:
    model = models[p]
    pts, nrm = network.part_samples(p)
    fit_ok = _fit_ok(surfaces, models, p)
    return FaceJob(
        part=p, name=f"{kind}_{p}", kind=kind, model=model, fit=surfaces[p], fit_ok=fit_ok,
        # out of tolerance but near: its own surface still beats a filling (see recon.brep._faces.OWN_SURFACE_RMS)
        near=model is not None and not fit_ok and near_enough(surfaces[p], tolerance),
        loops=[network.loop(j) for j in network.part_loops(p)], points=pts, normals=nrm,
        vote=orientation_vote(model, pts, nrm) if model is not None else 1,
        network=network, geo=geo, edges=edges, context=context, tolerance=tolerance, expected_area=expected_area,
        fill_budget=fill_budget,
    )


def _faces_now(records: list, context) -> tuple[list, list]:
    """The records with their faces as the shared ``context`` has them now, and those faces.

    Faces built before a later ShapeFix split one of their edges get the pieces now. A later neighbour's ShapeFix
    re-projects or re-tolerances a shared edge in place, which can leave an earlier face with a p-curve off its
    edge (valid when built): the same edge repair as for a face of its own (in place, so neighbours keep
    sharing).
    """
    faces = [TopoDS.Face_s(context.Apply(r.face)) for r in records if r.face is not None]
    for f in faces:
        if not BRepCheck_Analyzer(f).IsValid():
            fix_edges(f)
    records = [FaceRecord(r.part, r.name, r.kind, r.surface_type, r.status, r.area,
                          None if r.face is None else TopoDS.Face_s(context.Apply(r.face)), r.message) for r in records]
    return records, faces


def _healed(shape, tolerance: float, warnings: list) -> tuple[object, Validity | None]:
    """``shape``, mended whole when it is a solid BRepCheck refuses; and its validity where it was measured."""
    if shape.ShapeType() != TopAbs_SOLID:
        return shape, None
    validity = shape_validity(shape)
    if not validity.ok:
        fixed = whole_fixed(shape, tolerance, warnings)
        if fixed is not shape:
            return fixed, None
    return shape, validity


def _faces_of(shape) -> list:
    out = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        out.append(TopoDS.Face_s(exp.Current()))
        exp.Next()
    return out
