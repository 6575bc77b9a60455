"""Curve fits: line, circle (full or arc), else a smoothing B-spline (:func:`fit_curve`, free ends), and the
B-rep's edge curves pinned at their two network vertices (:func:`fit_edge_curve`, an :class:`EdgeCurve`).

Input points are ordered along the curve (an edge polyline). Deviations are distances to the fitted
curve: to the infinite line, to the full circle, and to the B-spline over its domain.
"""

from __future__ import annotations

import logging

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from .._array import as_points, perpendicular_frame
from ..errors import FitError, InputError
from ._geometry import BSplineCurve, Circle, EdgeCurve, Line
from ._types import HUGE, MAD_TO_SIGMA, CurveFit, deviation_stats, within_tolerance

__all__ = ["fit_line", "fit_circle", "fit_bspline_curve", "fit_curve", "fit_edge_curve", "polyline_curve",
           "point_curve"]

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
    if not np.isfinite(r2) or r2 <= 0 or np.sqrt(r2) > HUGE * size:
        return _failed_circle(len(pts), "degenerate (collinear points: a line)")
    c0 = sol[0] * e1 + sol[1] * e2

    def fun(x):
        nrm = n0 + x[0] * e1 + x[1] * e2
        nrm = nrm / np.linalg.norm(nrm)
        w = q - (c0 + x[2:5])
        h = w @ nrm
        rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", w, w) - h * h, 0.0))
        return np.hypot(rho - x[5], h)

    from scipy.optimize import least_squares  # imported where used: start-up (bench/speed.md)

    res = least_squares(fun, np.r_[0.0, 0.0, 0.0, 0.0, 0.0, np.sqrt(r2)], x_scale="jac", max_nfev=100)
    normal = n0 + res.x[0] * e1 + res.x[1] * e2
    normal /= np.linalg.norm(normal)
    center = c0 + res.x[2:5] + mean
    radius = abs(float(res.x[5]))
    # 4 sigma of the residuals when no tolerance is given (scales with noise sigma)
    limit = tolerance if tolerance is not None else 4 * MAD_TO_SIGMA * float(np.median(np.abs(res.fun)))
    if radius > HUGE * size or size**2 / (8 * radius) < limit:
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
    from scipy.interpolate import splprep  # imported where used: start-up (bench/speed.md)

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


# --- edge curves pinned at the network vertices (the B-rep's edges) ---

def _distinct(pts: np.ndarray) -> np.ndarray:
    """``pts`` without the points that repeat their predecessor."""
    return pts[np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-12])]


def _chord_params(pts: np.ndarray) -> np.ndarray:
    """Chord-length parameters of the polyline ``pts`` over [0, 1]."""
    t = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    return t / t[-1]


def polyline_curve(pts) -> EdgeCurve:
    """The polyline ``pts`` (k, 3) as an edge: a degree-1 B-spline through its points (chord-length knots)."""
    pts = _distinct(np.asarray(pts, dtype=np.float64))
    t = _chord_params(pts)
    return EdgeCurve.bspline(1, np.concatenate([[0.0, 0.0], t[1:-1], [1.0, 1.0]]), pts.copy(), 0.0)


def point_curve(points) -> EdgeCurve:
    """A degenerate edge (all its points coincide) as the segment between its ends, marked not fitted (residual
    inf): the B-rep reports it."""
    pts = np.asarray(points, dtype=np.float64)
    return EdgeCurve.line(pts[0].copy(), pts[-1].copy(), float("inf"))


def _pinned_circle_fit(pts):
    """Plane + algebraic (Kåsa) circle fit: (center, normal, radius), or None where the points are collinear."""
    c0 = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - c0)
    normal = vt[2]
    u, w = vt[0], vt[1]
    xy = np.stack([(pts - c0) @ u, (pts - c0) @ w], axis=1)
    a = np.column_stack([2 * xy, np.ones(len(xy))])
    sol = np.linalg.lstsq(a, np.sum(xy**2, axis=1), rcond=None)[0]
    cx, cy = sol[:2]
    r2 = sol[2] + cx * cx + cy * cy
    if not r2 > 0:
        return None
    center = c0 + cx * u + cy * w
    return center, normal, float(np.sqrt(r2))


def fit_edge_curve(points, *, closed: bool, tolerance: float) -> EdgeCurve:
    """Fit a line, circle arc or cubic B-spline to an edge polyline whose first and last points are pinned.

    Parameters
    ----------
    points : (k, 3) float
        The polyline, ``points[0]`` and ``points[-1]`` are the network vertices (equal if ``closed``).
    closed : bool
        The edge is a closed loop through one anchor vertex.
    tolerance : float
        A line or circle is accepted when every point lies within ``tolerance`` of it.

    Returns
    -------
    EdgeCurve
        Its ends are exactly ``points[0]`` and ``points[-1]``.
    """
    pts = np.asarray(points, dtype=np.float64)
    p0, p1 = pts[0], pts[-1]
    chord = p1 - p0
    clen = float(np.linalg.norm(chord))
    # Line: the segment between the pinned ends.
    if not closed and clen > 0:
        d = chord / clen
        rel = pts - p0
        dist = np.linalg.norm(rel - np.outer(rel @ d, d), axis=1)
        if float(dist.max()) <= tolerance:
            return EdgeCurve.line(p0.copy(), p1.copy(), float(dist.max()))
    # Circle arc through the pinned ends: fit, then test all points.
    if len(pts) >= 4:
        fit = _pinned_circle_fit(pts[:-1] if closed else pts)
        if fit is not None:
            center, normal, radius = fit
            # Orient the normal so the polyline runs counter-clockwise about it.
            rel = pts - center
            turn = np.sum(np.cross(rel[:-1], rel[1:]), axis=0)
            if turn @ normal < 0:
                normal = -normal
            xdir = p0 - center
            xdir = xdir - (xdir @ normal) * normal
            if np.linalg.norm(xdir) > 0:
                xdir /= np.linalg.norm(xdir)
                ydir = np.cross(normal, xdir)
                ang = np.unwrap(np.arctan2(rel @ ydir, rel @ xdir))
                ang -= ang[0]
                planar = rel - np.outer(rel @ normal, normal)
                dist = np.hypot(rel @ normal, np.linalg.norm(planar, axis=1) - radius)
                monotone = np.all(np.diff(ang) > -1e-9)
                t1 = 2 * np.pi if closed else float(ang[-1])
                if monotone and float(dist.max()) <= tolerance and 0 < t1 <= 2 * np.pi + 1e-9:
                    return EdgeCurve.arc(Circle(center, normal, radius, xdir), p0, p1, 0.0, min(t1, 2 * np.pi),
                                         float(dist.max()))
    return _bspline_pinned(pts, closed=closed, tolerance=tolerance)


#: Data points a knot span must hold at least (on average) for the least-squares spline to stay bounded.
_POINTS_PER_SPAN = 3.0

#: Weight of the second-difference penalty relative to the data term (P-spline; Eilers & Marx 1996).
_SMOOTHING = 1e-6


def _bspline_pinned(pts, *, closed: bool, tolerance: float, degree: int = 3) -> EdgeCurve:
    """Penalised least-squares cubic B-spline (chord-length parameters) with end control points fixed to the ends.

    A plain least-squares spline with as many control points as data points interpolates the projected
    polyline, and where those points zigzag (noise, or neighbours that fell back to different projections)
    it overshoots between them by orders of magnitude (edges many part sizes off, although they pass through
    every data point). So the control points are capped at one per
    :data:`_POINTS_PER_SPAN` data points and a small second-difference penalty keeps every span determined
    (Eilers & Marx, P-splines). The residual is measured on the curve densely sampled against the polyline,
    not only at the data points: it is what the B-rep builder and the report can trust.
    """
    from scipy.interpolate import BSpline  # imported where used: start-up (bench/speed.md)

    pts = _distinct(pts)
    if len(pts) < 2:
        raise InputError("fit_edge_curve: an edge polyline has fewer than two distinct points")
    if len(pts) == 2:
        pts = np.vstack([pts[0], 0.5 * (pts[0] + pts[1]), pts[1]])
    t = _chord_params(pts)
    fine = _between(t)
    k = min(degree, len(pts) - 1)
    most = max(k + 1, int(len(pts) / _POINTS_PER_SPAN) + k)
    best = None
    for n_ctrl in sorted({min(most, c) for c in (k + 1, k + 3, k + 6, k + 12, k + 24, most)}):
        # Knots at quantiles of the data parameters, so every span holds data (The NURBS Book, eq. 9.69).
        inner = np.quantile(t, np.linspace(0, 1, n_ctrl - k + 1)[1:-1])
        knots = np.concatenate([np.zeros(k + 1), inner, np.ones(k + 1)])
        basis = BSpline.design_matrix(t, knots, k).toarray()
        # Pin: first and last control points equal the ends (clamped knots interpolate them).
        ctrl = np.zeros((n_ctrl, 3))
        ctrl[0], ctrl[-1] = pts[0], pts[-1]
        if n_ctrl > 2:
            rhs = pts - np.outer(basis[:, 0], ctrl[0]) - np.outer(basis[:, -1], ctrl[-1])
            a = basis[:, 1:-1]
            normal = a.T @ a
            diff2 = np.diff(np.eye(n_ctrl), n=2, axis=0)
            pen = diff2.T @ diff2
            lam = _SMOOTHING * float(np.trace(normal)) / max(n_ctrl - 2, 1)
            normal = normal + lam * pen[1:-1, 1:-1]
            rhs_pen = -lam * (pen[1:-1, 0][:, None] * ctrl[0] + pen[1:-1, -1][:, None] * ctrl[-1])
            ctrl[1:-1] = np.linalg.solve(normal, a.T @ rhs + rhs_pen)
        curve = BSpline(knots, ctrl, k)
        if _backtracks(curve, pts, fine):
            continue
        resid = _curve_polyline_gap(curve, pts, t, fine)
        if best is None or resid < best[3]:
            best = (knots, ctrl, k, resid)
        if resid <= tolerance:
            break
    if best is None:
        # Every smooth fit loops back somewhere (a few points that zigzag along a short edge): the polyline
        # itself, a degree-1 B-spline through the points, is a valid edge that cannot cross itself.
        return polyline_curve(pts)
    knots, ctrl, k, resid = best
    return EdgeCurve.bspline(int(k), knots, ctrl, resid)


#: Curve samples per polyline segment where the fit is checked against the polyline (scale-free: per segment).
_PER_SPAN = 4


def _between(t: np.ndarray) -> np.ndarray:
    """:data:`_PER_SPAN` parameters per segment of the polyline parametrised by ``t``, the segment's start first."""
    w = np.linspace(0.0, 1.0, _PER_SPAN, endpoint=False)
    return (t[:-1, None] * (1 - w) + t[1:, None] * w).ravel()


def _backtracks(curve, pts, fine) -> bool:
    """True where the curve runs against the polyline's local direction (a loop, or a cusp and a turn back).

    The direction is the chord over three segments about each one, so that one noisy point does not count
    as a reversal: a cubic through a few zigzagging points can form a loop, and the face it bounds has a
    self-intersecting wire.
    """
    n = len(pts)
    seg = np.repeat(np.arange(n - 1), _PER_SPAN)
    window = pts[np.minimum(seg + 2, n - 1)] - pts[np.maximum(seg - 1, 0)]
    tangent = curve.derivative()(fine)
    return bool(np.any(np.einsum("ij,ij->i", tangent, window) < 0))


def _curve_polyline_gap(curve, pts, t, fine) -> float:
    """Largest distance of ``curve`` from the polyline ``pts``: at the data parameters ``t``, and between them
    wherever the curve strays from the polyline by more than a segment's length (an overshoot; a smooth
    curve's sagitta over a chord is far smaller than that)."""
    at_data = float(np.max(np.linalg.norm(curve(t) - pts, axis=1)))
    w = np.linspace(0.0, 1.0, _PER_SPAN, endpoint=False)
    dense = (pts[:-1, None, :] * (1 - w)[None, :, None] + pts[1:, None, :] * w[None, :, None]).reshape(-1, 3)
    between = float(np.max(cKDTree(np.vstack([dense, pts[-1:]])).query(curve(fine))[0]))
    seg = float(np.max(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
    return max(at_data, between) if between > seg else at_data
