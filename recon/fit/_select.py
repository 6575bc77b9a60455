"""Type selection: the simplest surface that fits within tolerance."""

from __future__ import annotations

import logging

import numpy as np

from ..errors import FitError
from ._bspline import fit_bspline_surface
from ._noise import default_tolerance, estimate_normals
from ._primitives import fit_cone, fit_cylinder, fit_plane, fit_sphere, fit_torus
from ._surfaces import as_points
from ._types import SURFACE_TYPES, SurfaceFit

__all__ = ["fit_surface", "ANALYTIC_FITTERS"]

log = logging.getLogger(__name__)

#: The analytic fitters by type, in the order they are tried.
ANALYTIC_FITTERS = {
    "plane": fit_plane,
    "sphere": fit_sphere,
    "cylinder": fit_cylinder,
    "cone": fit_cone,
    "torus": fit_torus,
}


def fit_surface(
    points,
    normals=None,
    *,
    tolerance: float | None = None,
    types=("plane", "sphere", "cylinder", "cone", "torus"),
    allow_bspline: bool = True,
    faces=None,
) -> SurfaceFit:
    """Fit the simplest surface type that matches the points within ``tolerance``.

    Types are tried in the order plane < sphere < cylinder < cone < torus < B-spline: by number of
    parameters (3, 4, 5, 6, 7, then a whole control grid). A type with fewer parameters that fits within
    tolerance is the less coincidental explanation, and each later analytic type contains earlier ones as
    limits (a cone with half-angle → 0 is a cylinder, a cylinder or sphere with radius → ∞ a plane, a torus
    with major radius → 0 a sphere), so the first accepted type is the most specific one. The fitters
    report such degenerate limits as failures, so e.g. a cylinder is never returned as a near-flat cone.

    Acceptance is :func:`recon.fit.within_tolerance`: 99th percentile of |d| ≤ tolerance and max ≤ 2·tolerance.

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
        The patch's triangles, for the B-spline's parametrisation when the patch is not a height field.

    Returns
    -------
    SurfaceFit
        The accepted fit; or, when nothing fits, the candidate with the smallest p99 deviation, falsy, with
        every candidate's reason joined by "; ".
    """
    pts = as_points(points, min_count=16)
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
            fit = fit_bspline_surface(pts, normals, faces=faces, tolerance=tolerance)
        elif kind in types:
            fit = ANALYTIC_FITTERS[kind](pts, normals, tolerance=tolerance)
        else:
            continue
        if fit:
            log.debug("fit_surface: %s accepted (%s)", kind, fit.deviation)
            return fit
        candidates.append(fit)
    if not candidates:
        raise FitError("`types` is empty and `allow_bspline` is False: nothing to fit")
    scored = [c for c in candidates if np.isfinite(c.deviation["p99"])]
    best = min(scored, key=lambda c: c.deviation["p99"]) if scored else candidates[0]
    reason = "; ".join(c.reason for c in candidates)
    log.info("fit_surface: nothing within tolerance %.3g: %s", tolerance, reason)
    return SurfaceFit(best.type, best.params, best.deviation, best.n_points, ok=False, reason=reason)
