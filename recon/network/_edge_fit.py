"""Edge curves with pinned ends: a line, circle arc or B-spline through an edge's points, ending exactly at its
two network vertices.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["EdgeCurve", "fit_edge_curve", "polyline_curve"]


@dataclass(frozen=True)
class EdgeCurve:
    """A fitted network edge.

    ``kind`` is ``"line"`` (``params``: start, end), ``"circle"`` (center, normal, radius, xdir,
    t0, t1: the arc runs counter-clockwise about ``normal`` from angle ``t0`` to ``t1`` measured from
    ``xdir``) or ``"bspline"`` (knots, control points, degree). ``residual`` is the largest distance
    of the edge's projected points to the curve.
    """

    kind: str
    params: dict
    residual: float


def polyline_curve(pts) -> EdgeCurve:
    """The polyline ``pts`` (k, 3) as an edge: a degree-1 B-spline through its points (chord-length knots)."""
    pts = np.asarray(pts, dtype=np.float64)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-12])
    pts = pts[keep]
    t = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    t /= t[-1]
    return EdgeCurve("bspline", {"knots": np.concatenate([[0.0, 0.0], t[1:-1], [1.0, 1.0]]),
                                 "control_points": pts.copy(), "degree": 1}, 0.0)


def _circle_fit(pts):
    """Plane + algebraic (Kåsa) circle fit. Returns center, normal, radius, xdir."""
    c0 = pts.mean(axis=0)
    _, s, vt = np.linalg.svd(pts - c0)
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
            return EdgeCurve("line", {"start": p0.copy(), "end": p1.copy()}, float(dist.max()))
    # Circle arc through the pinned ends: fit, then test all points.
    if len(pts) >= 4:
        fit = _circle_fit(pts[:-1] if closed else pts)
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
                    return EdgeCurve("circle", {"center": center, "normal": normal, "radius": radius,
                                                "xdir": xdir, "t0": 0.0, "t1": min(t1, 2 * np.pi)},
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
    from scipy.interpolate import BSpline

    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-12])
    pts = pts[keep]
    if len(pts) < 2:
        raise InputError("fit_edge_curve: an edge polyline has fewer than two distinct points")
    if len(pts) == 2:
        pts = np.vstack([pts[0], 0.5 * (pts[0] + pts[1]), pts[1]])
    t = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    t /= t[-1]
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
            if n_ctrl >= 3:
                diff2 = np.diff(np.eye(n_ctrl), n=2, axis=0)
                pen = diff2.T @ diff2
                lam = _SMOOTHING * float(np.trace(normal)) / max(n_ctrl - 2, 1)
                normal = normal + lam * pen[1:-1, 1:-1]
                rhs_pen = -lam * (pen[1:-1, 0][:, None] * ctrl[0] + pen[1:-1, -1][:, None] * ctrl[-1])
            else:
                rhs_pen = 0.0
            ctrl[1:-1] = np.linalg.solve(normal, a.T @ rhs + rhs_pen)
        curve = BSpline(knots, ctrl, k)
        if _backtracks(curve, pts, t):
            continue
        resid = _curve_polyline_gap(curve, pts, t)
        if best is None or resid < best[3]:
            best = (knots, ctrl, k, resid)
        if resid <= tolerance:
            break
    if best is None:
        # Every smooth fit loops back somewhere (a few points that zigzag along a short edge): the polyline
        # itself, a degree-1 B-spline through the points, is a valid edge that cannot cross itself.
        best = (np.concatenate([[0.0, 0.0], t[1:-1], [1.0, 1.0]]), pts.copy(), 1, 0.0)
    knots, ctrl, k, resid = best
    return EdgeCurve("bspline", {"knots": knots, "control_points": ctrl, "degree": int(k)}, resid)


def _backtracks(curve, pts, t, *, per_span: int = 4) -> bool:
    """True where the curve runs against the polyline's local direction (a loop, or a cusp and a turn back).

    The direction is the chord over three segments about each one, so that one noisy point does not count
    as a reversal: a cubic through a few zigzagging points can form a loop, and the face it bounds has a
    self-intersecting wire.
    """
    n = len(pts)
    w = np.linspace(0.0, 1.0, per_span, endpoint=False)
    fine = (t[:-1, None] * (1 - w) + t[1:, None] * w).ravel()
    seg = np.repeat(np.arange(n - 1), per_span)
    window = pts[np.minimum(seg + 2, n - 1)] - pts[np.maximum(seg - 1, 0)]
    tangent = curve.derivative()(fine)
    return bool(np.any(np.einsum("ij,ij->i", tangent, window) < 0))


def _curve_polyline_gap(curve, pts, t, *, per_span: int = 4) -> float:
    """Largest distance of ``curve`` from the polyline ``pts``: at the data parameters ``t``, and between them
    wherever the curve strays from the polyline by more than a segment's length (an overshoot; a smooth
    curve's sagitta over a chord is far smaller than that)."""
    from scipy.spatial import cKDTree

    at_data = float(np.max(np.linalg.norm(curve(t) - pts, axis=1)))
    w = np.linspace(0.0, 1.0, per_span, endpoint=False)
    fine = (t[:-1, None] * (1 - w) + t[1:, None] * w).ravel()
    dense = (pts[:-1, None, :] * (1 - w)[None, :, None] + pts[1:, None, :] * w[None, :, None]).reshape(-1, 3)
    between = float(np.max(cKDTree(np.vstack([dense, pts[-1:]])).query(curve(fine))[0]))
    seg = float(np.max(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
    return max(at_data, between) if between > seg else at_data
