"""Type selection: the simplest surface that fits within tolerance."""

from __future__ import annotations

from collections.abc import Sequence
import logging

import numpy as np
import numpy.typing as npt

from ..errors import FitError
from ._bspline import fit_bspline_surface
from ._noise import default_tolerance, estimate_normals
from ._primitives import fit_cone, fit_cylinder, fit_plane, fit_sphere, fit_torus
from .._array import as_points
from ._types import MAD_TO_SIGMA, SURFACE_TYPES, SurfaceFit

__all__ = ["fit_surface", "residual_scale", "ANALYTIC_FITTERS", "MISFIT_SCALE", "SIGMAS_PER_TOLERANCE"]

log = logging.getLogger(__name__)

#: The analytic fitters by type, in the order they are tried.
ANALYTIC_FITTERS = {
    "plane": fit_plane,
    "sphere": fit_sphere,
    "cylinder": fit_cylinder,
    "cone": fit_cone,
    "torus": fit_torus,
}
#: Free parameters of each analytic type (the order above is by them).
N_PARAMS = {"plane": 3, "sphere": 4, "cylinder": 5, "cone": 6, "torus": 7}
#: A type within tolerance misfits its points when its residual scale is above √2 × the noise: a systematic
#: deviation as large as the noise itself (σ̂² = σ² + b², b ≥ σ). Below it the residual is the noise plus what
#: a sliver of a neighbouring face adds (the measurements: bench/segment.md).
MISFIT_SCALE = float(np.sqrt(2.0))
#: On a noise-free mesh a later type replaces the first one within tolerance when its chords (the triangles'
#: edges) lie at most this share as far from it (RMS at their midpoints), see :func:`_hugging_chords`.
CHORD_GAIN = 0.5
#: ... and only when the first type's chords are at least this many tolerances off: dense meshes have short
#: chords that every surface through their vertices holds, and nothing is gained there.
CHORD_FLOOR = 0.1
#: A sphere and a cylinder that both hold a part's vertices within this share of the tolerance hold a band on two
#: circles (:func:`_hugging_chords`): exactly, as on a CAD export, not as a compromise.
BAND_EXACT = 0.01


def fit_surface(
    points: npt.ArrayLike,
    normals: npt.ArrayLike | None = None,
    *,
    tolerance: float | None = None,
    types: Sequence[str] = ("plane", "sphere", "cylinder", "cone", "torus"),
    allow_bspline: bool = True,
    faces: npt.ArrayLike | None = None,
    sigma: float | None = None,
    bspline_normals: npt.ArrayLike | None = None,
) -> SurfaceFit:
    """Fit the simplest surface type that matches the points within ``tolerance``.

    Types are tried in the order plane < sphere < cylinder < cone < torus < B-spline: by number of
    parameters (3, 4, 5, 6, 7, then a whole control grid). A type with fewer parameters that fits within
    tolerance is the less coincidental explanation, and each later analytic type contains earlier ones as
    limits (a cone with half-angle → 0 is a cylinder, a cylinder or sphere with radius → ∞ a plane, a torus
    with major radius → 0 a sphere), so the first accepted type is the most specific one. The fitters
    report such degenerate limits as failures, so e.g. a cylinder is never returned as a near-flat cone.

    Acceptance is :func:`recon.fit.within_tolerance`: 99th percentile of |d| ≤ tolerance and max ≤ 2·tolerance.

    Within tolerance is not yet explained: a simpler type can pass with a *systematic* misfit while a later
    one leaves only the noise (a sphere can hold a steep cone band within tolerance at a residual of twice
    the noise, where the cone leaves the noise alone). So when the
    points' noise ``sigma`` is given and the first accepted type's residual is above it, the later analytic
    types are fitted too and the one of least Bayesian information criterion wins (:func:`_least_complex`);
    at the noise level nothing can do better and the first type stands. Without ``sigma`` (a noise-free mesh,
    whose residuals are its tessellation's, not noise) the first type within tolerance is the answer, unless
    the ``faces`` show its vertices lie on it by coincidence (:func:`_hugging_chords`: a coarse cylinder's
    vertices are its two end circles, which a sphere holds exactly as well); with ``faces`` the B-spline then
    takes the points as exact (``fit_bspline_surface(exact=True)``: a finer control grid for as few points).

    Parameters
    ----------
    points : (n, 3) float
        The patch's points (mesh vertices), n ≥ 16.
    normals : (n, 3) float, optional
        Unit normals, any sign; estimated by k-NN PCA when omitted.
    tolerance : float, optional
        Default :func:`recon.fit.default_tolerance` (max(4σ, 10⁻⁴ · diagonal), σ estimated from the points).
    types : sequence of str
        The analytic types allowed; they are always tried in the order above.
    allow_bspline : bool
        Fall back to :func:`fit_bspline_surface` when no analytic type fits.
    faces : (m, 3) int, optional
        The patch's triangles (indices into ``points``): for the B-spline's parametrisation when the patch is
        not a height field, and, without ``sigma``, to test the chords (see above).
    sigma : float, optional
        The points' noise σ (the tolerance is best its 4σ, as the default is); see above.
    bspline_normals : (n, 3) float, optional
        Normals for the B-spline fallback instead of ``normals`` (the fit stage gives the analytic fitters a
        noise-free part's own normals, the B-spline the mesh's: see :func:`recon.segment._context.own_normals`).

    Returns
    -------
    SurfaceFit
        The accepted fit; or, when nothing fits, the candidate with the smallest p99 deviation, falsy, with
        every candidate's reason joined by "; ".
    """
    pts = as_points(points, min_count=16, error=FitError)
    unknown = set(types) - set(ANALYTIC_FITTERS)
    if unknown:
        raise FitError(f"`types` must be among {tuple(ANALYTIC_FITTERS)}, got {sorted(unknown)}")
    if tolerance is None:
        tolerance = default_tolerance(pts, normals)
    elif not tolerance > 0:
        raise FitError(f"`tolerance` must be > 0, got {tolerance}")
    if normals is None and any(t in types for t in ("cylinder", "cone", "torus")):
        normals = estimate_normals(pts)
    candidates: list[SurfaceFit] = []
    for kind in SURFACE_TYPES:
        if kind == "bspline":
            if not allow_bspline:
                continue
            fit = fit_bspline_surface(pts, normals if bspline_normals is None else bspline_normals, faces=faces,
                                      tolerance=tolerance, exact=sigma is None and faces is not None)
        elif kind in types:
            fit = ANALYTIC_FITTERS[kind](pts, normals, tolerance=tolerance)
        else:
            continue
        if fit:
            log.debug("fit_surface: %s accepted (%s)", kind, fit.deviation)
            if kind == "bspline":
                return fit
            if sigma is None:
                return fit if faces is None else _hugging_chords(fit, pts, normals, faces, tolerance=tolerance,
                                                                 types=types)
            return _least_complex(fit, pts, normals, tolerance=tolerance, sigma=sigma, types=types)
        candidates.append(fit)
    if not candidates:
        raise FitError("`types` is empty and `allow_bspline` is False: nothing to fit")
    scored = [c for c in candidates if np.isfinite(c.deviation["p99"])]
    best = min(scored, key=lambda c: c.deviation["p99"]) if scored else candidates[0]
    reason = "; ".join(c.reason for c in candidates)
    log.info("fit_surface: nothing within tolerance %.3g: %s", tolerance, reason)
    return SurfaceFit(best.type, best.params, best.deviation, best.n_points, ok=False, reason=reason)


def residual_scale(fit: SurfaceFit, pts: np.ndarray) -> float:
    """Robust σ of the residuals: MAD-based, so a sliver of a neighbouring face among the points does not count."""
    return MAD_TO_SIGMA * float(np.median(np.abs(fit.distance(pts))))


def _later_fits(first: SurfaceFit, pts, normals, *, tolerance: float, types, made: dict | None = None):
    """The fits within tolerance of the analytic types after ``first``'s (among ``types``), in order.

    ``made``: every fit made (within tolerance or not) goes in it by type, for a caller that may want one again.
    """
    for kind in tuple(ANALYTIC_FITTERS)[tuple(ANALYTIC_FITTERS).index(first.type) + 1 :]:
        if kind in types:
            fit = ANALYTIC_FITTERS[kind](pts, normals, tolerance=tolerance)
            if made is not None:
                made[kind] = fit
            if fit:
                yield fit


def _least_complex(first: SurfaceFit, pts, normals, *, tolerance: float, sigma: float, types) -> SurfaceFit:
    """The analytic type of least BIC among ``first`` (the simplest within tolerance) and the later ones.

    Only when ``first`` misfits: its robust residual scale σ̂ (:func:`residual_scale`) is above
    :data:`MISFIT_SCALE` × the noise ``sigma``; otherwise it is returned without fitting the others. BIC
    (Schwarz 1978) for Gaussian residuals of scale σ̂ with k parameters: n ln σ̂² + k ln n, σ̂ floored at the
    noise (a smaller residual is no evidence).
    """
    floor = float(sigma)
    n = len(pts)
    scale = residual_scale(first, pts)
    if scale <= MISFIT_SCALE * floor:
        return first

    def bic(fit, s):
        return n * np.log(max(s, floor) ** 2) + N_PARAMS[fit.type] * np.log(n)

    best, best_bic = first, bic(first, scale)
    for fit in _later_fits(first, pts, normals, tolerance=tolerance, types=types):
        b = bic(fit, residual_scale(fit, pts))
        if b < best_bic:
            best, best_bic = fit, b
    if best is not first:
        log.debug("fit_surface: %s (σ̂ %.3g) explains the points better than %s (σ̂ %.3g)", best.type,
                  residual_scale(best, pts), first.type, scale)
    return best


def _chord_midpoints(pts: np.ndarray, faces) -> np.ndarray:
    """The midpoints of the triangles' edges (each edge once, in order of their vertex pairs)."""
    f = np.asarray(faces, dtype=np.int64)
    a = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    b = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    # np.sort(pairs, axis=1) element-wise (a sort along an axis of 2 costs several times as much)
    key = np.unique(np.minimum(a, b) * len(pts) + np.maximum(a, b))
    return 0.5 * (pts[key // len(pts)] + pts[key % len(pts)])


def _chord_rms(fit: SurfaceFit, mid: np.ndarray) -> float:
    """RMS distance of ``fit`` at the chords' midpoints ``mid`` (:func:`_chord_midpoints`)."""
    return float(np.sqrt(np.mean(fit.distance(mid) ** 2)))


def _hugging_chords(first: SurfaceFit, pts, normals, faces, *, tolerance: float, types) -> SurfaceFit:
    """On a noise-free mesh: ``first`` (the simplest type within tolerance at the vertices), or the later
    analytic type whose surface the triangles' edges lie on.

    A CAD tessellation places its vertices on the true surface and its edges along it where they can: a
    cylinder's strips run straight from one end circle to the other, on the surface. A sphere through those
    two circles (there is one whenever they have the same radius) holds every vertex exactly, yet bows away
    from every strip's long edge by about ``h² / 8r``. So the chords decide: a later type within tolerance at
    the vertices replaces ``first`` when the RMS distance at the edge midpoints falls to :data:`CHORD_GAIN` of
    ``first``'s or less, once ``first``'s is at least :data:`CHORD_FLOOR` tolerances (the measurement behind both:
    bench/constants.md). A plane holds its chords exactly: it stands.
    """
    if first.type == "plane":
        return first
    mid = _chord_midpoints(pts, faces)  # the same chords for every surface tried
    best, best_c = first, _chord_rms(first, mid)
    first_c = best_c
    made: dict[str, SurfaceFit] = {}  # the later types' fits, by type: the band test below may want the cylinder's
    if best_c >= CHORD_FLOOR * tolerance:
        for fit in _later_fits(first, pts, normals, tolerance=tolerance, types=types, made=made):
            c = _chord_rms(fit, mid)
            if c <= CHORD_GAIN * best_c:
                best, best_c = fit, c
    if best is first and first.type == "sphere" and "cylinder" in types and first.deviation["max"] <= \
            BAND_EXACT * tolerance:
        # a band whose vertices are two circles of one radius (a hole through a thin plate) lies on a sphere as
        # exactly as on the cylinder, and its chords are too short to tell: the cylinder, when it holds the
        # vertices as exactly and the chords no worse. A sphere a designer drew has its vertices on more
        # circles, where no cylinder fits. (The fitters are deterministic: one made above is the same fit.)
        cyl = made["cylinder"] if "cylinder" in made else ANALYTIC_FITTERS["cylinder"](pts, normals,
                                                                                        tolerance=tolerance)
        if cyl and cyl.deviation["max"] <= BAND_EXACT * tolerance:
            c = _chord_rms(cyl, mid)
            if c <= best_c:
                best, best_c = cyl, c
    if best is not first:
        log.debug("fit_surface: the chords lie on the %s (RMS %.3g), not on the %s (%.3g)", best.type, best_c,
                  first.type, first_c)
    return best
