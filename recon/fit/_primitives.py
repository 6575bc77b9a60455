"""Analytic surface fits: plane, sphere, cylinder, cone, torus.

Each fit is a closed-form start followed by a robust least-squares refinement of the *geometric* distance
(``scipy.optimize.least_squares`` with the ``soft_l1`` loss), so a few stray points do not drag it:

- plane: PCA (the least-squares plane), then iteratively reweighted PCA with soft-l1 weights;
- sphere: the algebraic (linear) fit ``|p|² = 2 c·p + k``;
- cylinder: axis = the direction most orthogonal to the normals (smallest eigenvector of Σ n nᵀ), then a
  circle fit in the plane orthogonal to it;
- cone: the apex lies on every tangent plane (n·a = n·p, linear in a); seen from the apex the points make a
  constant angle with the axis, so the axis is the normal of the plane fitted to the unit vectors (p − a)/|p − a|;
- torus: the normal lines of a surface of revolution meet its axis. In Plücker coordinates (d, m) the
  condition "meets the normal line (n, p × n)" is linear, d·(p × n) + n·m = 0, so the axis is the smallest
  singular vector of that system (Pottmann & Wallner, *Computational Line Geometry*, §7.2); major and minor
  radius then come from a circle fit in the (ρ, z) half-plane.

None of these uses the sign of the normals, so unoriented PCA normals (``estimate_normals``) suffice.
Directions are refined through a 2-parameter tangent update ``d = normalize(d0 + a e1 + b e2)``, which has no
singularity near the start.
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import FitError
from ._noise import estimate_normals
from ._trf import lm_plain, trf_soft_l1
from .._array import (as_points, col_means, col_sums, columns as _columns, cross3, extent, height_radius,
                      perpendicular_frame, row_norms)
from ._geometry import Cone, Cylinder, Plane, Sphere, Torus, cone_distance
from ._types import HUGE, MAD_TO_SIGMA, SurfaceFit, deviation_stats, median as _median, percentile as _percentile, within_tolerance

__all__ = ["fit_plane", "fit_sphere", "fit_cylinder", "fit_cone", "fit_torus", "MAX_FIT_POINTS"]

log = logging.getLogger(__name__)

#: Larger inputs are fitted on an evenly strided subset of this many points (deviations use all points).
MAX_FIT_POINTS = 2000
#: The first refinement pass runs on about this many points (see ``_refine``).
COARSE_POINTS = 400
#: Evaluation budget per refinement pass: from its closed-form start the right type converged in ≤ 14
#: evaluations on 500 bench patches (σ = 0.02, normals given or estimated); wrong types wander and are cut short.
_MAX_NFEV = 30
#: Run the fits' trust-region loop as recon.fit._trf's port of scipy's rather than through the public ``least_squares``:
#: the same fits bit for bit, and the public one's wrappers cost the fit stage 1.2–1.5× the CPU (bench/segment.md).
DIRECT_LOOP = True
#: Half-angles within this of 0 (or π/2) make a cone a cylinder (or a plane).
_MIN_ANGLE = np.deg2rad(0.5)


# ----------------------------------------------------------------------------------------------- helpers


def _prepare(points, normals, *, min_count: int, need_normals: bool):
    pts = as_points(points, min_count=min_count, error=FitError)
    nrm = None
    if normals is not None:
        nrm = as_points(normals, "normals", error=FitError)
        if len(nrm) != len(pts):
            raise FitError(f"`normals` must have one row per point ({len(pts)}), got {len(nrm)}")
        lengths = row_norms(nrm, keepdims=True)
        if np.any(lengths == 0):
            raise FitError("`normals` contains zero vectors")
        nrm = nrm / lengths
    step = max(1, -(-len(pts) // MAX_FIT_POINTS))
    sub = pts[::step]
    sub_n = None
    if need_normals:
        sub_n = nrm[::step] if nrm is not None else estimate_normals(sub)
    return pts, sub, sub_n


def _extent(points: np.ndarray) -> float:
    return extent(points)


def _refine(fun, x0, q, *, scale, size, tolerance, jac="2-point"):
    """Robust least squares of the geometric residuals ``fun(x, q)``, coarse to fine.

    soft-l1 loss; its ``f_scale`` (where it turns from quadratic to linear) is ``scale`` or the noise
    estimated from the start's residuals. The first pass runs on about :data:`COARSE_POINTS` of ``q``. A
    wrong surface type is rejected there when, with a ``tolerance``, the p99 of |d| over all of ``q`` still
    exceeds 3 × tolerance (a right type's coarse fit is off by ~σ·sqrt(n/COARSE_POINTS)/sqrt(n), far below
    that); otherwise a second pass polishes on all of ``q`` from the coarse solution.
    """
    step = -(-len(q) // COARSE_POINTS)
    coarse = q[::step]
    f0 = fun(x0, coarse)
    f_scale = _scale(f0, scale, size)
    res = _solve(fun, jac, x0, coarse, f_scale, f0)  # the start's residuals, computed once
    if step == 1:
        return res
    f1 = None
    if tolerance is not None:
        f1 = fun(res.x, q)
        if _percentile(np.abs(f1), 99) > 3 * tolerance:
            return res
    return _solve(fun, jac, res.x, q, f_scale, f1)


def _solve(fun, jac, x0, q, f_scale, f0=None):
    """``least_squares(fun, x0, args=(q,), jac=jac, loss="soft_l1", f_scale=f_scale, x_scale="jac",
    max_nfev=_MAX_NFEV)``, bit for bit, with an analytic ``jac``.

    The decomposition's region growing makes thousands of these fits on a hundred or so points each, where
    ``least_squares``'s input checks and function wrappers (``VectorFunction``: a copy and an ``array_equal``
    per evaluation) cost about a third of the call; this runs scipy's own trust-region loop directly on the
    same inputs (scipy 1.17's ``least_squares``, default ``ftol = xtol = gtol = 1e-8``, ``tr_solver="exact"``).
    ``f0``: ``fun(x0, q)`` when the caller has it (the loop scales it in place: it is not the caller's after this).
    """
    if not DIRECT_LOOP or not callable(jac):
        from scipy.optimize import least_squares  # here: scipy.optimize is 0.1 s of start-up the direct loop never uses

        return least_squares(fun, x0, args=(q,), jac=jac, loss="soft_l1", f_scale=f_scale, x_scale="jac",
                             max_nfev=_MAX_NFEV)
    x0 = np.atleast_1d(x0).astype(float)
    f0 = np.atleast_1d(fun(x0, q) if f0 is None else f0)
    if not np.all(np.isfinite(f0)):
        raise ValueError("Residuals are not finite in the initial point.")  # as least_squares
    # the same loop without scipy's Python around it (recon.fit._trf: same operations, same order)
    return trf_soft_l1(
        lambda x: np.atleast_1d(fun(x, q)), lambda x: np.atleast_2d(jac(x, q)), x0, f0, np.atleast_2d(jac(x0, q)),
        f_scale, _MAX_NFEV,
    )


def _scale(residuals: np.ndarray, scale: float | None, size: float) -> float:
    if scale is not None:
        if not scale > 0:
            raise FitError(f"`scale` must be > 0, got {scale}")
        return float(scale)
    mad = MAD_TO_SIGMA * float(_median(np.abs(residuals - _median(residuals))))
    return max(mad, 1e-9 * size)


def _finish(kind, params, surface, points, tolerance, *, reason: str = "") -> SurfaceFit:
    dev = deviation_stats(surface.distance(points)) if surface is not None else deviation_stats(np.empty(0))
    ok = not reason
    if ok and tolerance is not None and not within_tolerance(dev, tolerance):
        ok = False
        reason = f"{kind}: deviation p99 {dev['p99']:.3g} / max {dev['max']:.3g} exceeds tolerance {tolerance:.3g}"
    return SurfaceFit(kind, params, dev, len(points), ok=ok, reason=reason)


def _limit_tolerance(tolerance: float | None, residuals: np.ndarray) -> float:
    """How close to its simpler limit a fit may come before it is called degenerate.

    The user's tolerance when given, else 4 × the robust σ of the residuals (the default-tolerance rule).
    """
    if tolerance is not None:
        return float(tolerance)
    # 4 sigma of the residuals when no tolerance is given (scales with noise sigma)
    return 4.0 * MAD_TO_SIGMA * float(_median(np.abs(residuals - _median(residuals))))


def _failed(kind: str, n: int, reason: str) -> SurfaceFit:
    log.debug("%s fit failed: %s", kind, reason)
    return SurfaceFit(kind, {}, deviation_stats(np.empty(0)), n, ok=False, reason=f"{kind}: {reason}")


def _direction(d0, e1, e2, a, b):
    d = d0 + a * e1 + b * e2
    return d / np.sqrt(d.dot(d))  # np.linalg.norm(d)


def _direction_jac(d0, e1, e2, a, b):
    """d and its derivatives ∂d/∂a, ∂d/∂b for d = normalize(d0 + a e1 + b e2)."""
    v = d0 + a * e1 + b * e2
    nv = np.sqrt(v.dot(v))  # np.linalg.norm(v)
    d = v / nv
    return d, (e1 - d * (d @ e1)) / nv, (e2 - d * (d @ e2)) / nv


def _radial(w: np.ndarray, d: np.ndarray):
    """Height h, distance ρ to the axis and the unit radial direction u of vectors w from an axis point."""
    h = w @ d
    radial = w - h[:, None] * d
    rho = row_norms(radial)
    u = radial / np.maximum(rho, 1e-300)[:, None]
    return h, rho, u


def _circle_2d(xy: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Algebraic (Kåsa) circle fit: x² + y² = 2 c·x + k. Returns (centre, radius) or None if degenerate."""
    mean = col_means(xy)
    q = xy - mean
    a = _columns(2 * q, np.ones(len(q)))
    b = np.einsum("ij,ij->i", q, q)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    c, k = sol[:2], sol[2]
    r2 = k + c @ c
    if not np.isfinite(r2) or r2 <= 0:
        return None
    return c + mean, float(np.sqrt(r2))


def _vec(v) -> list[float]:
    return [float(x) for x in v]


# ----------------------------------------------------------------------------------------------- fitters


def fit_plane(points, normals=None, *, tolerance: float | None = None, scale: float | None = None) -> SurfaceFit:
    """Fit a plane.

    Parameters
    ----------
    points : (n, 3) float
        n ≥ 3.
    normals : (n, 3) float, optional
        Not needed (accepted so every fitter has the same signature).
    tolerance : float, optional
        When given, ``ok`` also requires the acceptance rule of :func:`recon.fit.within_tolerance`.
    scale : float, optional
        Robust loss scale (≈ noise σ); default 1.4826·MAD of the PCA plane's residuals.

    Returns
    -------
    SurfaceFit
        ``params``: ``origin`` (weighted centroid), ``normal``.
    """
    pts, sub, _ = _prepare(points, normals, min_count=3, need_normals=False)
    w = np.ones(len(sub))
    s = None
    for _ in range(4):  # IRLS with soft-l1 weights 1/sqrt(1 + (r/s)²)
        origin = col_sums(w[:, None] * sub) / w.sum()
        q = sub - origin
        _, vec = np.linalg.eigh((w[:, None] * q).T @ q)
        normal = vec[:, 0]
        r = q @ normal
        if s is None:
            s = _scale(r, scale, _extent(sub))
        w = 1.0 / np.sqrt(1.0 + (r / s) ** 2)
    params = {"origin": _vec(origin), "normal": _vec(normal)}
    return _finish("plane", params, Plane(origin, normal), pts, tolerance)


def fit_sphere(points, normals=None, *, tolerance: float | None = None, scale: float | None = None) -> SurfaceFit:
    """Fit a sphere: algebraic start, robust geometric refinement.

    Parameters
    ----------
    points : (n, 3) float
        n ≥ 4.
    normals : (n, 3) float, optional
        Not needed.
    tolerance, scale : float, optional
        See :func:`fit_plane`.

    Returns
    -------
    SurfaceFit
        ``params``: ``center``, ``radius``. Falsy if degenerate: the points are coplanar, or the sagitta
        L²/(8r) over the patch diagonal L is below the tolerance (4σ of the residuals when no tolerance is
        given) — then it is a plane.
    """
    pts, sub, _ = _prepare(points, normals, min_count=4, need_normals=False)
    size = _extent(sub)
    mean = col_means(sub)
    q = sub - mean
    a = _columns(2 * q, np.ones(len(q)))
    sol, *_ = np.linalg.lstsq(a, np.einsum("ij,ij->i", q, q), rcond=None)
    c0, r2 = sol[:3], sol[3] + sol[:3] @ sol[:3]
    if not np.isfinite(r2) or r2 <= 0 or np.sqrt(r2) > HUGE * size:
        return _failed("sphere", len(pts), "degenerate (points are coplanar: a plane)")

    def fun(x, q):
        return row_norms(q - x[:3]) - x[3]

    def jac(x, q):
        diff = q - x[:3]
        dist = row_norms(diff, keepdims=True)
        return _columns(-diff / np.maximum(dist, 1e-300), -np.ones(len(q)))

    x0 = np.r_[c0, np.sqrt(r2)]
    res = _refine(fun, x0, q, scale=scale, size=size, tolerance=tolerance, jac=jac)
    center, radius = res.x[:3] + mean, abs(float(res.x[3]))
    if size**2 / (8 * radius) < _limit_tolerance(tolerance, res.fun):
        return _failed("sphere", len(pts), f"degenerate (radius {radius:.3g}: within tolerance of a plane)")
    params = {"center": _vec(center), "radius": radius}
    return _finish("sphere", params, Sphere(center, radius), pts, tolerance)


def fit_cylinder(points, normals=None, *, tolerance: float | None = None, scale: float | None = None) -> SurfaceFit:
    """Fit a circular cylinder: axis from the normal field, circle in the orthogonal plane, robust refinement.

    Parameters
    ----------
    points : (n, 3) float
        n ≥ 5.
    normals : (n, 3) float, optional
        Surface normals (any sign); estimated by k-NN PCA when omitted.
    tolerance, scale : float, optional
        See :func:`fit_plane`.

    Returns
    -------
    SurfaceFit
        ``params``: ``axis_point`` (foot of the centroid on the axis), ``axis_dir``, ``radius``. Falsy if
        degenerate: sagitta L²/(8r) below the tolerance (4σ of the residuals without one), i.e. a plane.
    """
    pts, sub, nrm = _prepare(points, normals, min_count=5, need_normals=True)
    size = _extent(sub)
    mean = col_means(sub)
    q = sub - mean
    _, vec = np.linalg.eigh(nrm.T @ nrm)
    d0 = vec[:, 0]
    e1, e2 = perpendicular_frame(d0)
    circle = _circle_2d(_columns(q @ e1, q @ e2))
    if circle is None or circle[1] > HUGE * size:
        return _failed("cylinder", len(pts), "degenerate start (no curvature across the axis: a plane)")
    c0 = circle[0][0] * e1 + circle[0][1] * e2

    def fun(x, q):
        d = _direction(d0, e1, e2, x[0], x[1])
        w = q - (c0 + x[2] * e1 + x[3] * e2)
        h = w @ d
        return np.sqrt(np.maximum(np.einsum("ij,ij->i", w, w) - h * h, 0.0)) - x[4]

    def jac(x, q):
        d, da, db = _direction_jac(d0, e1, e2, x[0], x[1])
        w = q - (c0 + x[2] * e1 + x[3] * e2)
        h, rho, u = _radial(w, d)
        k = -h / np.maximum(rho, 1e-300)  # ∂ρ/∂d = -(h/ρ) w
        return _columns(k * (w @ da), k * (w @ db), -(u @ e1), -(u @ e2), -np.ones(len(q)))

    x0 = np.array([0.0, 0.0, 0.0, 0.0, circle[1]])
    res = _refine(fun, x0, q, scale=scale, size=size, tolerance=tolerance, jac=jac)
    d = _direction(d0, e1, e2, res.x[0], res.x[1])
    c = c0 + res.x[2] * e1 + res.x[3] * e2
    c = c - (c @ d) * d + mean  # foot of the centroid on the axis
    radius = abs(float(res.x[4]))
    if size**2 / (8 * radius) < _limit_tolerance(tolerance, res.fun):
        return _failed("cylinder", len(pts), f"degenerate (radius {radius:.3g}: within tolerance of a plane)")
    params = {"axis_point": _vec(c), "axis_dir": _vec(d), "radius": radius}
    return _finish("cylinder", params, Cylinder(c, d, radius), pts, tolerance)


def fit_cone(points, normals=None, *, tolerance: float | None = None, scale: float | None = None) -> SurfaceFit:
    """Fit a circular cone (one nappe): apex from the tangent planes, axis from the apex's view, robust refinement.

    Parameters
    ----------
    points : (n, 3) float
        n ≥ 6.
    normals : (n, 3) float, optional
        Surface normals (any sign); estimated by k-NN PCA when omitted.
    tolerance, scale : float, optional
        See :func:`fit_plane`.

    Returns
    -------
    SurfaceFit
        ``params``: ``apex``, ``axis_dir`` (into the opening), ``half_angle`` (radians), ``ref_point``,
        ``ref_radius``. Falsy when degenerate: the radius changes by less than the tolerance (4σ of the
        residuals without one) across the patch, half-angle < 0.5°, or the cone is not significantly better
        than the best cylinder (χ²₁ test; a cylinder); half-angle > 89.5° (a plane).
    """
    pts, sub, nrm = _prepare(points, normals, min_count=6, need_normals=True)
    size = _extent(sub)
    mean = col_means(sub)
    q = sub - mean
    start = _cone_start(q, nrm, size)
    if start is None:
        return _failed("cone", len(pts), "degenerate start (no axis: a plane)")
    c0, d0, r0, alpha0 = start
    e1, e2 = perpendicular_frame(d0)

    # Parametrised like gp_Cone: an axis point c, the radius there and the half-angle α, which may pass
    # through 0 — a cylinder is an ordinary point of this chart, not an apex at infinity. The signed
    # distance (ρ − r) cos α − h sin α is exact away from the apex, where the data of a cone face are.
    def fun(x, q):
        d = _direction(d0, e1, e2, x[0], x[1])
        h, rho, _ = _radial(q - (c0 + x[2] * e1 + x[3] * e2), d)
        return (rho - x[4]) * np.cos(x[5]) - h * np.sin(x[5])

    def jac(x, q):
        d, da, db = _direction_jac(d0, e1, e2, x[0], x[1])
        w = q - (c0 + x[2] * e1 + x[3] * e2)
        h, rho, u = _radial(w, d)
        sa, ca = np.sin(x[5]), np.cos(x[5])
        k = -(h * ca / np.maximum(rho, 1e-300) + sa)
        d_c = -ca * u + sa * d
        return _columns(k * (w @ da), k * (w @ db), d_c @ e1, d_c @ e2, np.full(len(q), -ca), -(rho - x[4]) * sa - h * ca)

    x0 = np.array([0.0, 0.0, 0.0, 0.0, r0, alpha0])
    res = _refine(fun, x0, q, scale=scale, size=size, tolerance=tolerance, jac=jac)
    d = _direction(d0, e1, e2, res.x[0], res.x[1])
    c = c0 + res.x[2] * e1 + res.x[3] * e2
    radius, alpha = float(res.x[4]), float(res.x[5])
    if alpha < 0:  # opens the other way along the axis
        alpha, d = -alpha, -d
    heights = (q - c) @ d
    spread = (heights.max() - heights.min()) * np.tan(alpha)  # change of radius across the patch
    if alpha < _MIN_ANGLE or spread < _limit_tolerance(tolerance, res.fun):
        return _failed("cone", len(pts), f"degenerate (half-angle {np.rad2deg(alpha):.3g}°: a cylinder)")
    if alpha > np.pi / 2 - _MIN_ANGLE:
        return _failed("cone", len(pts), f"degenerate (half-angle {np.rad2deg(alpha):.3g}°: a plane)")
    apex = c - (radius / np.tan(alpha)) * d
    if np.linalg.norm(apex) > HUGE * size:
        return _failed("cone", len(pts), "degenerate (apex at infinity: a cylinder)")
    if np.median((q - apex) @ d) < 0 or radius < 0:
        return _failed("cone", len(pts), "degenerate (the points straddle the apex)")
    residuals = cone_distance(q, apex, d, alpha)
    if tolerance is not None and not within_tolerance(deviation_stats(residuals), tolerance):
        pass  # fails on its deviation below; the likelihood-ratio test would only cost a cylinder fit
    elif not _better_than_cylinder(q, nrm, residuals):
        return _failed("cone", len(pts), "degenerate (not significantly better than a cylinder)")
    apex = apex + mean
    h = float(np.mean((pts - apex) @ d))
    params = {
        "apex": _vec(apex),
        "axis_dir": _vec(d),
        "half_angle": alpha,
        "ref_point": _vec(apex + h * d),
        "ref_radius": float(h * np.tan(alpha)),
    }
    return _finish("cone", params, Cone(apex, d, alpha), pts, tolerance)


def _cone_start(q: np.ndarray, nrm: np.ndarray, size: float):
    """(axis point at the centroid's height, axis, radius there, half-angle) from normals; None if degenerate.

    The apex lies on every tangent plane (n·a = n·p, linear in a); seen from it the points make a constant
    angle with the axis (the normal of the plane fitted to the unit vectors (p − a)/|p − a|). When the
    normals do not span 3D the apex is at infinity: start from the cylinder (axis ⟂ normals, α = 0).
    """
    m = nrm.T @ nrm
    evals, vec = np.linalg.eigh(m)
    apex = None
    # eigenvalue ratio below 1e-6: the normals are coplanar, a cylinder, no apex (scale-free)
    if evals[0] > 1e-6 * evals[-1]:
        apex = np.linalg.solve(m, np.einsum("ij,ij->i", nrm, q) @ nrm)
        if np.linalg.norm(apex) > HUGE * size:
            apex = None
    if apex is not None:
        u = q - apex
        u /= np.maximum(row_norms(u, keepdims=True), 1e-300)
        _, uvec = np.linalg.eigh(np.cov(u.T))
        d = uvec[:, 0] if np.mean(u @ uvec[:, 0]) > 0 else -uvec[:, 0]
        alpha = float(np.arccos(np.clip(np.mean(u @ d), -1.0, 1.0)))
        h = float(np.mean((q - apex) @ d))
        return apex + h * d, d, h * np.tan(alpha), alpha
    d = vec[:, 0]
    e1, e2 = perpendicular_frame(d)
    circle = _circle_2d(_columns(q @ e1, q @ e2))
    if circle is None:
        return None
    return circle[0][0] * e1 + circle[0][1] * e2, d, circle[1], 0.0


def _better_than_cylinder(q: np.ndarray, nrm: np.ndarray, cone_residuals: np.ndarray) -> bool:
    """Likelihood-ratio test of the cone's one extra parameter against the best cylinder.

    On cylinder data the cone's optimum runs off to an apex at infinity along a flat valley and stops
    anywhere on it. Keep the cone only if it lowers the residual sum of squares by more than 10 σ̂²
    (χ²₁ > 10: p ≈ 0.002).
    """
    cyl = fit_cylinder(q, nrm)
    if not cyl:
        return True
    ss_cone = float(cone_residuals @ cone_residuals)
    d_cyl = cyl.distance(q)
    ss_cyl = float(d_cyl @ d_cyl)
    return ss_cyl - ss_cone > 10.0 * ss_cone / max(len(q) - 6, 1)


def _revolution_axis(q: np.ndarray, nrm: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Least-squares line meeting all normal lines (q_i, n_i), in Plücker coordinates; (point, unit dir)."""
    s = np.sqrt(np.mean(np.einsum("ij,ij->i", q, q)))
    qs = q / s
    a = _columns(np.cross(qs, nrm), nrm)
    _, vec = np.linalg.eigh(a.T @ a)
    d, mom = vec[:3, 0], vec[3:, 0]
    nd = np.linalg.norm(d)
    # a direction shorter than 1e-6 of a unit one is no direction (round-off, scale-free)
    if nd < 1e-6:
        return None
    d, mom = d / nd, mom / nd
    mom -= (mom @ d) * d  # Plücker constraint d·m = 0
    return cross3(d, mom) * s, d


#: Evaluations a torus fit on exact points may continue for when the budget left it a spindle torus: a narrow patch's
#: major radius and axis tilt trade off along a curved valley that the trust region crawls (13 exact vertices of a
#: fillet: ~500 evaluations from the normal-line start, ~0.2 s; bench/exact.md).
_EXACT_NFEV = 1000
#: ... taken in chunks of this many, and given up when a chunk lowers the largest residual by less than
#: :data:`_EXACT_GAIN`: a fit crawling towards the torus gains a factor each chunk (0.5–0.82), one stuck on a torus
#: the points do not lie on a few per cent (0.95–0.99; bench/speed.md, stop 34).
_EXACT_CHUNK = 100
_EXACT_GAIN = 0.9


def _continued(fun, jac, x, q):
    """Plain least squares from ``x`` for at most :data:`_EXACT_NFEV` evaluations, while each chunk still gains."""
    spent, worst = 0, float(np.max(np.abs(fun(x, q))))
    while True:
        if DIRECT_LOOP:  # least_squares(method="lm") without its wrappers, bit for bit (recon.fit._trf)
            res = lm_plain(lambda x: fun(x, q), lambda x: jac(x, q), x, _EXACT_CHUNK)
        else:
            from scipy.optimize import least_squares  # only here: see _solve

            res = least_squares(fun, x, args=(q,), jac=jac, method="lm", x_scale="jac", max_nfev=_EXACT_CHUNK)
        spent += res.nfev
        now = float(np.max(np.abs(res.fun)))
        if res.status != 0 or spent >= _EXACT_NFEV or now > _EXACT_GAIN * worst:
            return res
        x, worst = res.x, now


def fit_torus(points, normals=None, *, tolerance: float | None = None, scale: float | None = None,
              exact: bool = False) -> SurfaceFit:
    """Fit a torus: axis as the line meeting all normal lines, radii from a (ρ, z) circle, robust refinement.

    Parameters
    ----------
    points : (n, 3) float
        n ≥ 7.
    normals : (n, 3) float, optional
        Surface normals (any sign); estimated by k-NN PCA when omitted.
    tolerance, scale : float, optional
        See :func:`fit_plane`.
    exact : bool
        The points lie on the surface to round-off (a CAD export's vertices): a refinement that its evaluation budget
        stopped at a spindle torus, or short of the ``tolerance``, is continued (plain least squares, nothing to
        down-weight) while it still gains, up to :data:`_EXACT_NFEV` evaluations, as it was still descending a valley,
        not at the answer.

    Returns
    -------
    SurfaceFit
        ``params``: ``center``, ``axis_dir``, ``major_radius``, ``minor_radius``. Falsy when degenerate:
        major radius below the tolerance (a sphere), sagitta L²/(8R) below the tolerance (a cylinder; the
        tolerance is 4σ of the residuals without one), or major < minor (a self-intersecting spindle torus,
        which B-rep faces do not want).
    """
    pts, sub, nrm = _prepare(points, normals, min_count=7, need_normals=True)
    size = _extent(sub)
    mean = col_means(sub)
    q = sub - mean
    axis = _revolution_axis(q, nrm)
    if axis is None:
        return _failed("torus", len(pts), "degenerate start (normal lines meet no common line)")
    c0, d0 = axis
    h, rho = height_radius(q, c0, d0)
    circle = _circle_2d(_columns(rho, h))
    if circle is None or circle[1] > HUGE * size:
        return _failed("torus", len(pts), "degenerate start (no curvature in the (ρ, z) half-plane)")
    (r_major0, z0), r_minor0 = circle
    c0 = c0 + z0 * d0
    e1, e2 = perpendicular_frame(d0)

    # _direction, height_radius, _direction_jac and _radial inlined, the Jacobian filled in place: the same operations in the
    # same order (the same floats), called ~100 times per fit on ~10 exact vertices, where each call is its overhead
    def fun(x, q):
        d = d0 + x[0] * e1 + x[1] * e2
        d = d / np.sqrt(d.dot(d))
        w = q - (c0 + x[2:5])
        hh = w @ d
        rr = np.sqrt(np.maximum(np.einsum("ij,ij->i", w, w) - hh * hh, 0.0))
        return np.hypot(rr - x[5], hh) - x[6]

    def jac(x, q):
        v = d0 + x[0] * e1 + x[1] * e2
        nv = np.sqrt(v.dot(v))
        d = v / nv
        w = q - (c0 + x[2:5])
        h = w @ d
        radial = w - h[:, None] * d
        rho = row_norms(radial)
        u = radial / np.maximum(rho, 1e-300)[:, None]
        off = rho - x[5]
        dist = np.maximum(np.hypot(off, h), 1e-300)
        k = h * x[5] / (dist * np.maximum(rho, 1e-300))  # ∂r/∂d = w · hR/(Dρ)
        out = np.empty((len(q), 7))
        out[:, 0] = k * (w @ ((e1 - d * (d @ e1)) / nv))
        out[:, 1] = k * (w @ ((e2 - d * (d @ e2)) / nv))
        out[:, 2:5] = -(off / dist)[:, None] * u - (h / dist)[:, None] * d
        out[:, 5] = -off / dist
        out[:, 6] = -1.0
        return out

    x0 = np.array([0.0, 0.0, 0.0, 0.0, 0.0, r_major0, r_minor0])
    res = _refine(fun, x0, q, scale=scale, size=size, tolerance=tolerance, jac=jac)
    # exact points: a fit the budget stopped short of them (a spindle torus, or a narrow patch still off by more
    # than their round-off) was still descending; continued while it gains
    if exact and res.status == 0 and len(q) >= len(x0) and (
            res.x[5] < res.x[6] or tolerance is None or float(np.max(np.abs(fun(res.x, q)))) > tolerance):
        res = _continued(fun, jac, res.x, q)
    d = _direction(d0, e1, e2, res.x[0], res.x[1])
    center = c0 + res.x[2:5] + mean
    big, small = float(res.x[5]), float(res.x[6])
    limit = _limit_tolerance(tolerance, res.fun)
    # a major radius below a thousandth of the patch is no torus (scales with part size)
    if big < max(1e-3 * size, limit):
        return _failed("torus", len(pts), f"degenerate (major radius {big:.3g} ≈ 0: a sphere)")
    if size**2 / (8 * big) < limit:
        return _failed("torus", len(pts), f"degenerate (major radius {big:.3g} ≫ patch: a cylinder)")
    if small <= 0 or small > HUGE * size:
        return _failed("torus", len(pts), f"degenerate (minor radius {small:.3g})")
    if big < small:
        return _failed("torus", len(pts), f"spindle torus (major {big:.3g} < minor {small:.3g}) is not supported")
    params = {"center": _vec(center), "axis_dir": _vec(d), "major_radius": big, "minor_radius": small}
    return _finish("torus", params, Torus(center, d, big, small), pts, tolerance)
