"""The main job: mesh → decomposition → fitted surfaces → curve network → B-rep solid → report.

Every stage is its own module; this one only chains them, times them and gathers the figures a user
judges a reconstruction by (faces by type, deviation from the mesh, validity, time per stage).
"""

from __future__ import annotations

import logging
import os
import time
from collections import Counter
from dataclasses import dataclass, field, replace
from functools import partial
from typing import TYPE_CHECKING, Any, Callable

import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from .decompose import Decomposition, decompose
from .errors import InputError, ReconError
from ._progress import Count
from ._tolerance import tolerance_for
from .mesh import HoleReport, Mesh, SpikeReport, clean_mesh, close_holes, load_mesh, move_spikes
from ._working import working_copy
from .segment import as_decomposition, coplanar_pairs, exact_faces, exact_tessellation, plane_atoms, roundoff, segment

if TYPE_CHECKING:  # (build123d loads on first use of a result's shape; see Conversion.shape)
    import build123d as bd

    from .verdict import Verdict

__all__ = ["Conversion", "convert", "STAGES"]

log = logging.getLogger(__name__)

#: The stages in the order they run; progress callbacks receive these names.
STAGES = ("load", "decompose", "fit", "brep", "deviation")

Progress = Callable[[str, float], None]


@dataclass(frozen=True)
class Conversion:
    """Result of :func:`convert`.

    Attributes
    ----------
    shape : build123d Solid, Shell or Compound
        The B-rep: keep modelling on it in build123d, or in CadQuery with :func:`recon.to_cadquery`. Made on
        first use (``brep.shape``): the command line writes the STEP without importing build123d.
    report : dict
        Strict-JSON figures: faces by type, deviation, validity, time per stage, per-face records, and the
        ``verdict`` of the acceptance rules (:mod:`recon.verdict`).
    mesh : Mesh
        The cleaned mesh, with its small holes closed over when it had some (``extra["holes"]``, a
        :class:`recon.mesh.HoleReport`, marks the added triangles: they come after the input's).
    decomposition : Decomposition
    labels : (m,) int
        The face label of every triangle of ``mesh`` (the decomposition with sharp features dissolved).
    fits : dict of int → SurfaceFit
    brep : recon.brep.BrepResult
    """

    report: dict
    mesh: Mesh
    decomposition: Decomposition
    labels: np.ndarray
    fits: dict
    brep: Any
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def shape(self) -> bd.Shape:
        return self.brep.shape

    @property
    def verdict(self) -> Verdict:
        """The acceptance rules on this result (:class:`recon.verdict.Verdict`, from ``report["verdict"]``): judged
        on the shape in memory, and on the written file once :func:`recon.verdict.write_checked` wrote it."""
        from .verdict import Verdict

        return Verdict.from_json(self.report["verdict"])


# BLAS on one thread throughout (issue 25): a reduction split over threads sums in another order, and the result must
# not depend on the machine's core count (bench/determinism.md).
@threadpool_limits.wrap(limits=1, user_api="blas")
def convert(
    mesh: Mesh | str | os.PathLike | tuple[npt.ArrayLike, npt.ArrayLike],
    *,
    tolerance: float | None = None,
    scale: float | None = None,
    deviation: bool = True,
    progress: Progress | None = None,
    jobs: int | None = None,
) -> Conversion:
    """Reconstruct a B-rep from a triangle mesh.

    Parameters
    ----------
    mesh : Mesh or path
        A cleaned :class:`recon.mesh.Mesh`, a mesh file (STL, OBJ, PLY, OFF, 3MF, GLB), or ``(vertices, faces)``
        arrays (cleaned here).
    tolerance : float, optional
        Model units. A surface type is accepted for a part when its points lie within it (99th percentile,
        max within twice it); edges are kept as lines/circles within it. Default: max(4σ, 10⁻⁴ · diagonal)
        with σ the mesh's estimated noise (:func:`recon.fit.default_tolerance`).
    scale : float, optional
        Feature scale of the decomposition (model units); default estimated from the mesh.
    deviation : bool
        Measure the deviation between the mesh and the result (both ways) for the report.
    progress : callable(stage, fraction), optional
        Called with a stage name from :data:`STAGES` and 0.0 when it starts, 1.0 when it ends. The fit, brep and
        deviation stages also call it as their items complete, with a :class:`recon._progress.Count`: a float
        ``done / total`` (0 < it < 1) of the current step's items that carries ``done``, ``total`` and ``what``
        ("parts fitted", "faces built", "samples measured").
    jobs : int, optional
        Processes the decomposition and the curve network's placement may use (default: the cores available; see
        :func:`recon.decompose.decompose`, :func:`recon.brep.build_solid`).

    Returns
    -------
    Conversion
    """
    step = partial(_tell, progress)

    times: dict[str, float] = {}
    t = time.perf_counter()
    step("load", 0.0)
    mesh, spikes = _move_spikes(_as_mesh(mesh))  # a scanner's outliers, before anything measures the mesh
    user, (mesh, holes) = mesh, close_holes(mesh)  # an occluded scan's small holes, covered by the faces around them
    times["load"] = time.perf_counter() - t
    step("load", 1.0)

    if tolerance is not None and not tolerance > 0:
        raise InputError(f"convert: `tolerance` must be > 0, got {tolerance!r}")
    t = time.perf_counter()
    step("decompose", 0.0)
    found, work, dec = _decomposed(mesh, tolerance, scale, jobs)
    times["decompose"] = time.perf_counter() - t
    step("decompose", 1.0)

    run = _Run(mesh, holes, tolerance, deviation, progress, jobs, times)
    if dec is None:  # the exact vertices proved the faces
        result, work = run.finish(found, None), None
    else:
        result = run.finish(None, dec, work)
        # exact faces whose count is open are the answer only where the decomposition's result fails a rule
        if found is not None and not result.verdict.ok:
            log.info("the decomposition's result fails a rule: the exact vertices' faces, their count open, instead")
            result, work = run.finish(found, None), None
    return replace(result, extra=_note_mesh_changes(result.report, user, spikes, holes, work))


def _tell(progress: Progress | None, stage: str, frac: float) -> None:
    """``progress(stage, frac)`` when there is a progress callback."""
    if progress is not None:
        progress(stage, frac)


@dataclass
class _Run:
    """The stages after the decomposition (fit, brep, deviation, report) for one candidate set of faces."""

    mesh: Mesh
    holes: HoleReport
    tolerance: float | None
    deviation: bool
    progress: Progress | None
    jobs: int | None
    times: dict

    def _items(self, name):  # a stage's items, as Count fractions; 0.0 and 1.0 stay the stage's start and end
        progress = self.progress
        if progress is None:
            return None
        return lambda done, total, what: progress(name, Count(done, total, what)) if 0 < done < total else None

    def _step(self, name, frac):
        _tell(self.progress, name, frac)

    def finish(self, found, dec: Decomposition | None, work=None) -> Conversion:
        """The conversion from the exact faces ``found`` or else the decomposition ``dec`` (of the working copy
        ``work`` when there is one)."""
        from .brep import build_solid  # the CAD kernel loads only when a B-rep is wanted
        from .brep._messages import occ_messages  # OpenCascade's own messages: to the log, not to stdout
        from .network import curve_network

        times = dict(self.times)
        full, mesh = self.mesh, (self.mesh if work is None else work.mesh)  # the stages up to the B-rep: the copy
        tolerance = self.tolerance
        if tolerance is None:
            tolerance = tolerance_for(0.0, mesh.diagonal) if dec is None else (
                getattr(dec, "tolerance", None) or tolerance_for(dec.noise, mesh.diagonal))
            log.info("tolerance %.4g", tolerance)

        t = time.perf_counter()
        self._step("fit", 0.0)
        if found is not None:
            labels, fits = found.labels, found.fits
            dec = as_decomposition(mesh, labels)
        else:
            assert dec is not None
            labels, fits = _faces_and_fits(mesh, dec, tolerance, self._items("fit"))
        times["fit"] = time.perf_counter() - t
        self._step("fit", 1.0)

        t = time.perf_counter()
        self._step("brep", 0.0)
        kinds = _face_kinds(dec, labels)
        network = curve_network(mesh.vertices, mesh.faces, labels)
        areas = np.bincount(labels, weights=mesh.face_areas, minlength=labels.max() + 1)
        with occ_messages():
            brep = build_solid(network, fits, tolerance=tolerance, part_kinds=kinds,
                               part_areas={p: float(a) for p, a in enumerate(areas)}, jobs=self.jobs,
                               progress=self._items("brep"), mesh_points=mesh.vertices)
        names = _face_names(brep)  # (an O(faces²) match: once, for the deviation and the report)
        times["brep"] = time.perf_counter() - t
        if work is not None:  # measured and judged against the input's triangles, labelled through the copy
            mesh, labels = full, work.input_labels(labels)
        self._step("brep", 1.0)

        dev, dev_error = None, None
        if self.deviation:
            t = time.perf_counter()
            self._step("deviation", 0.0)
            dev, dev_error = _deviation(mesh, brep, names, self.holes.input_vertices, self._items("deviation"))
            times["deviation"] = time.perf_counter() - t
            self._step("deviation", 1.0)

        exact = None if found is None else {  # the faces were found from exact vertices, not decomposed
            "faces": int(labels.max()) + 1, "notes": list(found.notes), "open_count": list(found.open_count)}
        report = _report(mesh, dec, labels, fits, brep, dev, times, tolerance, names, dev_error, exact)
        return Conversion(report, mesh, dec, labels, fits, brep)


def _deviation(mesh: Mesh, brep, names, input_vertices: int, progress) -> tuple[Any, str | None]:
    """The deviation stage: ``(report, None)``, or ``(None, why)`` when it could not be measured (the B-rep is written
    all the same). Mesh→shape on the user's vertices only (a closed hole's cover is not a measurement)."""
    from .brep._messages import occ_messages
    from .deviation import deviation as measure

    try:
        with occ_messages():
            return measure(mesh.vertices, mesh.faces, brep.occ, names=names, progress=progress,
                           measured=np.arange(len(mesh.vertices)) < input_vertices), None
    except ReconError as err:
        log.warning("deviation not measured: %s", err)
        return None, str(err)


def _note_mesh_changes(report: dict, user: Mesh, spikes: SpikeReport, holes: HoleReport, work) -> dict:
    """The report's entries and warnings for what recon did to the user's mesh before the stages (spikes moved, holes
    closed, a working copy); returns the Conversion's ``extra`` (the copy, the holes' mask)."""
    extra: dict = {}
    if work is not None:  # what the stages up to the B-rep saw
        report["working_copy"] = work.to_json()
        extra["working_copy"] = work
    if len(spikes.vertices):
        report["mesh"]["spikes"] = spikes.to_json(user.diagonal)
        report["warnings"].append(
            f"{len(spikes.vertices)} vertices stood off the surface as spikes (up to "
            f"{report['mesh']['spikes']['max_moved_pct']:.2g} % of the diagonal) and were moved onto their "
            "neighbours' surface; the deviation is measured to where they were moved")
    if holes.closed:  # the mesh returned and judged (also in the written file) is the closed one
        _note_holes(report, user, holes)
        extra["holes"] = holes
    return extra


def _note_holes(report: dict, user: Mesh, holes: HoleReport) -> None:
    """The report's entry and warning for the holes :func:`recon.mesh.close_holes` closed over."""
    report["mesh"]["triangles"] = int(len(user.faces))  # the user's: the added ones are counted under "holes"
    report["mesh"]["holes"] = holes.to_json(user.area)
    report["warnings"].append(
        f"{holes.closed} of {holes.loops} holes in the mesh were closed over by the faces around them "
        f"({report['mesh']['holes']['area_added_pct']:.2g} % of its area); the deviation mesh→shape is measured on "
        "the input's vertices only, shape→mesh to the input's triangles and the cover over the holes")


def _as_mesh(mesh) -> Mesh:
    """A :class:`Mesh` from what :func:`convert` accepts: a Mesh, a mesh file's path, or (vertices, faces)."""
    if isinstance(mesh, (str, os.PathLike)):
        return load_mesh(mesh)
    if isinstance(mesh, Mesh):
        return mesh
    if isinstance(mesh, tuple) and len(mesh) == 2:
        return clean_mesh(*mesh)
    raise InputError(f"convert: `mesh` must be a Mesh, a path or (vertices, faces), got {type(mesh).__name__}")


#: A scanner's noise leaves almost no triangle pairs coplanar to round-off (0.1-0.2 % measured on noisy scans and
#: fixtures); a CAD export's or a remesher's exact vertices give a few percent or more, and no spikes to move (an
#: exported corner's fan of long triangles can stand off its ring's plane like one).
SCAN_COPLANAR_SHARE = 0.01


def _move_spikes(mesh: Mesh) -> tuple[Mesh, SpikeReport]:
    """``mesh`` with its spikes moved (:func:`recon.mesh.move_spikes`) if it is a scan's, as it was otherwise."""
    pairs = coplanar_pairs(mesh, roundoff(mesh.vertices))
    if len(pairs) and pairs.mean() >= SCAN_COPLANAR_SHARE:
        return mesh, SpikeReport(np.zeros(0, dtype=np.int64), np.zeros(0))
    return move_spikes(mesh)


#: The exact-vertex path walks the mesh's plane pieces and seeds in Python (a few ms each): beyond this many triangles
#: its attempt alone would take longer than the decomposition (100k triangles of mostly curved faces: 75k pieces).
EXACT_MAX_TRIANGLES = 50_000


def _exact(mesh: Mesh, tolerance: float | None):
    """The faces of ``mesh`` found from its exact vertices when it is a CAD export's
    (:func:`recon.segment.exact_tessellation`, :func:`~recon.segment.exact_faces`); None for any other
    mesh, or when they do not explain it (it is decomposed)."""

    eps = roundoff(mesh.vertices)
    if len(mesh.faces) > EXACT_MAX_TRIANGLES or not exact_tessellation(mesh, eps):
        return None
    with _one_blas_thread():
        return exact_faces(mesh, tolerance or tolerance_for(0.0, mesh.diagonal), plane_atoms(mesh, eps))


def _decomposed(mesh: Mesh, tolerance: float | None, scale: float | None, jobs: int | None):
    """The decompose stage: ``(found, work, dec)``, the exact-vertex faces (:func:`_exact`) or else the decomposition
    of ``mesh``, or of its working copy ``work`` when a dense noisy scan has one (:func:`recon._working.working_copy`;
    the copy's own noise sets its window and tolerance: its points are what is fitted, bench/scan.md). Exact faces
    whose count is open (``found.open_count``) come with the decomposition too."""
    found = _exact(mesh, tolerance) if scale is None else None
    if found is not None and not found.open_count:
        return found, None, None
    work = working_copy(mesh, tolerance) if scale is None else None
    if work is None:
        return found, None, decompose(mesh, scale=scale, jobs=jobs)
    return found, work, decompose(work.mesh, jobs=jobs)


def _one_blas_thread():
    """A context in which BLAS and LAPACK run on one thread (threadpoolctl).

    The fit stage's least-squares fits take an SVD of a Jacobian of up to 2,000 × 7 every iteration: OpenBLAS
    splits one that size over its threads, and on a shared machine waking and joining them costs more than the
    SVD (2,000 × 7: 0.1 ms on one thread, 1-3 ms on two with the other core busy). The blocks each thread computes
    are the ones one thread computes in turn: the same results, bit for bit.
    """
    return threadpool_limits(limits=1, user_api="blas")


def _faces_and_fits(mesh: Mesh, dec: Decomposition, tolerance: float, progress=None) -> tuple[np.ndarray, dict]:
    """The fit stage: the face label of every triangle and the surface of every face (:func:`recon.segment.segment`)."""
    with _one_blas_thread():
        return segment(mesh, dec, tolerance=tolerance, progress=progress)


def _face_names(brep) -> list[str]:
    """The record name of every face of ``brep.occ``, in the deviation report's face order (``faces_of``); a face
    no record holds (none expected) keeps the deviation's own ``face_i``."""
    from .brep._step_read import faces_of

    named = [(r.face, r.name) for r in brep.faces if r.face is not None]
    names = []
    for i, face in enumerate(faces_of(brep.occ)):
        names.append(next((name for f, name in named if f.IsSame(face)), f"face_{i}"))
    return names


def _face_kinds(dec: Decomposition, labels: np.ndarray) -> dict[int, str]:
    """Kind of each face label: "patch" if it holds a smooth patch, else the kind most of its triangles came from."""
    kinds_of_part = np.array([p.kind for p in dec.parts])
    out = {}
    orig = np.asarray(dec.labels)
    for p in range(labels.max() + 1):
        votes = Counter(kinds_of_part[orig[labels == p]].tolist())
        # A face that holds any patch is a patch that absorbed a sharp edge strip, not a blend.
        out[p] = "patch" if votes["patch"] else votes.most_common(1)[0][0]
    return out


def _report(mesh, dec, labels, fits, brep, dev, times, tolerance, names, dev_error=None, exact=None) -> dict:
    """The conversion's figures as strict JSON data (no NaN or infinity: None where a figure does not exist), with
    the verdict of :func:`recon.verdict.judge` on the result in memory (the command line judges the written file)."""
    from .verdict import judge, strict_json, unmeshed_names

    diag = float(mesh.diagonal)
    val = brep.validity
    faces = []
    for r in brep.faces:
        fit = fits.get(r.part)
        faces.append(
            {
                "name": r.name,
                "part": int(r.part),
                "kind": r.kind,
                "surface": r.surface_type,
                "status": r.status,
                "built": r.face is not None,
                "area": float(r.area),
                # a filled face has no fit of its own: its figures are NaN, which JSON has no word for
                "fit_max": float(fit.deviation["max"]) if fit is not None else None,
                "fit_rms": float(fit.deviation["rms"]) if fit is not None else None,
            }
        )
    report = {
        "mesh": {
            "triangles": int(len(mesh.faces)),
            "input_triangles": int(mesh.n_input_faces),
            "diagonal": diag,
            "open": bool(mesh.report.boundary_edges > 0),  # boundary edges: a shell is the right answer
            "cleaning": mesh.report.summary(),
        },
        "tolerance": float(tolerance),
        "decomposition": dec.counts(),
        "faces_by_type": dict(Counter(r.surface_type for r in brep.faces)),
        "n_faces": int(val.n_faces),
        "validity": {
            "ok": bool(brep.ok),
            "shape_type": val.shape_type,
            "valid": bool(val.valid),
            "closed": bool(val.closed),
            "free_edges": int(val.free_edges),
            "volume": float(val.volume),
            "n_solids": int(val.n_solids),
            "n_shells": int(val.n_shells),
        },
        "warnings": list(brep.warnings),
        "seconds": {k: round(v, 4) for k, v in times.items()},
        "faces": faces,
    }
    if dev is not None:
        report["deviation"] = dev.to_json()
        report["warnings"].extend(dev.notes)
        missing = sum(r.face is None for r in brep.faces)
        if missing:
            report["warnings"].append(
                f"deviation is measured to the {len(brep.faces) - missing} faces that exist; {missing} parts have none"
            )
    if dev_error:
        report["deviation_error"] = dev_error
        report["warnings"].append(f"deviation not measured: {dev_error}")
    report["unmeshed_faces"] = unmeshed_names(brep.occ, names)  # FreeCAD would show holes there
    if exact is not None:
        report["exact_vertices"] = exact
    report = strict_json(report)
    report["verdict"] = judge(report, mesh, labels, source="the result in memory",
                              deviation_error=dev_error).to_json()
    return report
