"""Curve fits for the B-rep's edges: line, circle (full or arc), else a smoothing B-spline.

Input points are ordered along the curve (an edge polyline). Deviations are distances to the fitted
curve: to the infinite line, to the full circle, and to the B-spline over its domain.
"""

from __future__ import annotations

import logging

import numpy as np
import numpy.typing as npt
from scipy.interpolate import splprep
from scipy.optimize import least_squares

from .._array import as_points, perpendicular_frame
from ..errors import FitError
from ._geometry import BSplineCurve, Circle, Line
from ._types import CurveFit, deviation_stats, within_tolerance

__all__ = ["fit_line", "fit_circle", "fit_bspline_curve", "fit_curve"]

log = logging.getLogger(__name__)


def _finish(kind, params, curve, pts, tolerance, reason=""):
    dev = deviation_stats(curve.distance(pts)) if curve is not None else deviation_stats(np.empty(0))
    ok = not reason
    if ok and tolerance is not None and not within_tolerance(dev, tolerance):
        ok = False
        reason = f"{kind}: deviation p99 {dev['p99']:.3g} / max {dev['max']:.3g} exceeds tolerance {tolerance:.3g}"
    return CurveFit(kind, params, dev, len(pts), ok=ok, reason=reason)


def _vec(v) -> list[float]:
    return [float(x) for x in v]


def fit_line(points, *, tolerance: float | None = None) -> CurveFit:
    """Least-squares line (PCA) through ordered ``points`` (n, 3), n ≥ 2.

    Returns
    -------
    CurveFit
        ``params``: ``point`` (centroid), ``direction`` (from the first point towards the last),
        ``start``, ``end`` (first and last point projected on the line).
    """
    pts = as_points(points, min_count=2, error=FitError)
    mean = pts.mean(axis=0)
    _, vec = np.linalg.eigh((pts - mean).T @ (pts - mean))
    d = vec[:, 2]
    if (pts[-1] - pts[0]) @ d < 0:
        d = -d
    params = {
        "point": _vec(mean),
        "direction": _vec(d),
        "start": _vec(mean + ((pts[0] - mean) @ d) * d),
        "end": _vec(mean + ((pts[-1] - mean) @ d) * d),
    }
    return _finish("line", params, Line(mean, d), pts, tolerance)


def _failed_circle(n: int, reason: str) -> CurveFit:
    return CurveFit("circle", {}, deviation_stats(np.empty(0)), n, ok=False, reason=f"circle: {reason}")


def fit_circle(points, *, tolerance: float | None = None, closed: bool = False) -> CurveFit:
    """Circle or arc through ordered ``points`` (n, 3), n ≥ 3: plane by PCA, Kåsa circle, 3D refinement.

    Parameters
    ----------
    points : (n, 3) float
        Ordered along the curve.
    tolerance : float, optional
        When given, ``ok`` also requires the acceptance rule.
    closed : bool
        The points go all the way round (a full circle) whatever their angular gaps.

    Returns
    -------
    CurveFit
        ``params``: ``center``, ``normal`` (oriented so the points run counter-clockwise), ``radius``,
        ``x_dir`` (towards the first point), ``start_angle`` = 0, ``end_angle`` (the swept angle, or 2π),
        ``full``. An open curve counts as a full circle when its sweep reaches 2π less 1.5 mean sample steps.
        Falsy when degenerate: collinear points, or a sagitta (diagonal²/8r) below the tolerance (4σ of the
        residuals without one) — a line.
    """
    pts = as_points(points, min_count=3, error=FitError)
    mean = pts.mean(axis=0)
    q = pts - mean
    evals, vec = np.linalg.eigh(q.T @ q)
    if evals[1] <= 1e-12 * evals[2]:
        return _failed_circle(len(pts), "degenerate (collinear points: a line)")
    n0 = vec[:, 0]
    e1, e2 = perpendicular_frame(n0)
    xy = np.column_stack([q @ e1, q @ e2])
    a = np.column_stack([2 * xy, np.ones(len(xy))])
    sol, *_ = np.linalg.lstsq(a, np.einsum("ij,ij->i", xy, xy), rcond=None)
    r2 = sol[2] + sol[:2] @ sol[:2]
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    if not np.isfinite(r2) or r2 <= 0 or np.sqrt(r2) > 1e3 * size:
        return _failed_circle(len(pts), "degenerate (collinear points: a line)")
    c0 = sol[0] * e1 + sol[1] * e2

    def fun(x):
        nrm = n0 + x[0] * e1 + x[1] * e2
        nrm = nrm / np.linalg.norm(nrm)
        w = q - (c0 + x[2:5])
        h = w @ nrm
        rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", w, w) - h * h, 0.0))
        return np.hypot(rho - x[5], h)

    res = least_squares(fun, np.r_[0.0, 0.0, 0.0, 0.0, 0.0, np.sqrt(r2)], x_scale="jac", max_nfev=100)
    normal = n0 + res.x[0] * e1 + res.x[1] * e2
    normal /= np.linalg.norm(normal)
    center = c0 + res.x[2:5] + mean
    radius = abs(float(res.x[5]))
    limit = tolerance if tolerance is not None else 4 * 1.4826 * float(np.median(np.abs(res.fun)))
    if radius > 1e3 * size or size**2 / (8 * radius) < limit:
        return _failed_circle(len(pts), f"degenerate (radius {radius:.3g}: within tolerance of a line)")
    w = pts - center
    w -= np.outer(w @ normal, normal)
    x_dir = w[0] / np.linalg.norm(w[0])
    ang = np.unwrap(np.arctan2(w @ np.cross(normal, x_dir), w @ x_dir))
    if ang[-1] < ang[0]:  # run counter-clockwise about the normal
        normal = -normal
        ang = -ang
    sweep = float(ang[-1] - ang[0])
    step = abs(sweep) / max(len(pts) - 1, 1)
    full = bool(closed or sweep >= 2 * np.pi - 1.5 * step)
    params = {
        "center": _vec(center),
        "normal": _vec(normal),
        "radius": radius,
        "x_dir": _vec(x_dir),
        "start_angle": 0.0,
        "end_angle": float(2 * np.pi if full else sweep),
        "full": full,
    }
    return _finish("circle", params, Circle(center, normal, radius, x_dir), pts, tolerance)


def fit_bspline_curve(points, *, tolerance: float, closed: bool = False, degree: int = 3) -> CurveFit:
    """Smoothing cubic B-spline (FITPACK ``splprep``) through ordered ``points`` (n, 3).

    The smoothing bound s (Σ residual² ≤ s) starts at 2n·(tolerance/4)² — the residual energy of noise with
    σ = tolerance/4 (the inverse of the default-tolerance rule) in the two directions across the curve — and
    is quartered until the acceptance rule holds (at most 6 times).

    Parameters
    ----------
    points : (n, 3) float
        Ordered; n ≥ degree + 2 (closed curves: do not repeat the first point).
    tolerance : float
    closed : bool
        Fit a periodic spline.
    degree : int
        1 … 5.

    Returns
    -------
    CurveFit
        ``params``: ``degree``, ``knots``, ``control_points``, ``periodic``.
    """
    pts = as_points(points, min_count=degree + 2, error=FitError)
    if not 1 <= degree <= 5:
        raise FitError(f"`degree` must be in 1..5, got {degree}")
    if not tolerance > 0:
        raise FitError(f"`tolerance` must be > 0, got {tolerance}")
    data = np.vstack([pts, pts[:1]]) if closed else pts
    keep = np.r_[True, np.linalg.norm(np.diff(data, axis=0), axis=1) > 0]
    data = data[keep]
    chord = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(data, axis=0), axis=1))]
    u = chord / chord[-1]
    s = 2 * len(data) * (tolerance / 4.0) ** 2
    for _ in range(7):  # (at least once: ``fit`` is always bound)
        try:
            (t, c, k), _ = splprep(data.T, u=u, s=s, k=degree, per=int(closed), quiet=2)
        except (ValueError, TypeError) as err:  # FITPACK refuses too few / degenerate points
            return CurveFit("bspline", {}, deviation_stats(np.empty(0)), len(pts), ok=False, reason=f"bspline: {err}")
        cp = np.column_stack(c)[: len(t) - k - 1]
        params = {"degree": int(k), "knots": _vec(t), "control_points": cp.tolist(), "periodic": bool(closed)}
        fit = _finish("bspline", params, BSplineCurve(int(k), np.asarray(t), cp), pts, tolerance)
        if fit:
            break
        s /= 4.0
    return fit


def fit_curve(points: npt.ArrayLike, *, tolerance: float, closed: bool = False) -> CurveFit:
    """The simplest curve within tolerance: line (open curves only) < circle < B-spline.

    Parameters
    ----------
    points : (n, 3) float
        Ordered along the curve, n ≥ 2; a closed curve without its first point repeated.
    tolerance : float
        Acceptance rule of :func:`recon.fit.within_tolerance` (p99 ≤ tol, max ≤ 2·tol).
    closed : bool

    Returns
    -------
    CurveFit
        The accepted fit; when nothing fits, the candidate with the smallest p99 deviation, falsy, with the
        reasons joined.
    """
    pts = as_points(points, min_count=2, error=FitError)
    if not tolerance > 0:
        raise FitError(f"`tolerance` must be > 0, got {tolerance}")
    candidates = []
    if not closed:
        candidates.append(fit_line(pts, tolerance=tolerance))
        if candidates[-1]:
            return candidates[-1]
    if len(pts) >= 3:
        candidates.append(fit_circle(pts, tolerance=tolerance, closed=closed))
        if candidates[-1]:
            return candidates[-1]
    if len(pts) >= 5:
        candidates.append(fit_bspline_curve(pts, tolerance=tolerance, closed=closed))
        if candidates[-1]:
            return candidates[-1]
    scored = [c for c in candidates if np.isfinite(c.deviation["p99"])]
    if not scored:
        raise FitError(f"`points` ({len(pts)}) are too few to fit a closed curve")
    best = min(scored, key=lambda c: c.deviation["p99"])
    return CurveFit(best.type, best.params, best.deviation, best.n_points, ok=False, reason="; ".join(c.reason for c in candidates))
