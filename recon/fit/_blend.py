"""Blend surfaces for the decomposition's linear parts (fillet strips): rolling ball, else a ruled surface."""

from __future__ import annotations

import logging

import numpy as np

from ..errors import FitError
from ._bspline_surface import BSplineSurface, clamped_knots
from ._primitives import fit_cylinder, fit_plane, fit_torus
from .._array import as_points
from ._types import SurfaceFit, deviation_stats, within_tolerance

__all__ = ["fit_rolling_ball", "ruled_surface"]

log = logging.getLogger(__name__)


def _chord_parameter(poly: np.ndarray) -> np.ndarray:
    chord = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(poly, axis=0), axis=1))]
    return chord / chord[-1]


def ruled_surface(left_polyline, right_polyline, *, degree: int = 3, spans: int | None = None) -> SurfaceFit:
    """B-spline surface ruled between two boundary polylines: degree 1 across, ``degree`` along.

    Each polyline is fitted by least squares (chord-length parameter) on one shared clamped knot vector,
    so the two rows of control points pair up; the rulings join equal chord-length fractions.

    Parameters
    ----------
    left_polyline, right_polyline : (a, 3), (b, 3) float
        Ordered points along the two sides; ``right_polyline`` is reversed if it runs the other way.
    degree : int
        Degree along the polylines.
    spans : int, optional
        Knot spans along; default min(a, b) // 4, between 1 and 20.

    Returns
    -------
    SurfaceFit
        ``type == "bspline"`` with ``degree_v == 1``; u runs along, v ∈ [0, 1] across (v = 0 on the left).
        The deviation is that of the polyline points.
    """
    from scipy.interpolate import make_lsq_spline  # imported where used: start-up (bench/speed.md)

    left = as_points(left_polyline, "left_polyline", min_count=2, error=FitError)
    right = as_points(right_polyline, "right_polyline", min_count=2, error=FitError)
    if np.linalg.norm(left[0] - right[-1]) + np.linalg.norm(left[-1] - right[0]) < np.linalg.norm(
        left[0] - right[0]
    ) + np.linalg.norm(left[-1] - right[-1]):
        right = right[::-1]
    degree = int(min(degree, len(left) - 1, len(right) - 1))
    if spans is None:
        spans = int(np.clip(min(len(left), len(right)) // 4, 1, 20))
    spans = max(1, min(spans, min(len(left), len(right)) - degree))
    knots = clamped_knots(0.0, 1.0, spans, degree)
    rows = []
    for poly in (left, right):
        u = _chord_parameter(poly)
        try:
            rows.append(make_lsq_spline(u, poly, knots, k=degree).c)
        except (ValueError, np.linalg.LinAlgError) as err:
            return SurfaceFit("bspline", {}, deviation_stats(np.empty(0)), len(left) + len(right), ok=False, reason=f"ruled: {err}")
    surf = BSplineSurface(degree, 1, knots, np.array([0.0, 0.0, 1.0, 1.0]), np.stack(rows, axis=1))
    pts = np.vstack([left, right])
    uv0 = np.column_stack([np.r_[_chord_parameter(left), _chord_parameter(right)], np.r_[np.zeros(len(left)), np.ones(len(right))]])
    dev = deviation_stats(surf.distance(pts, uv0))
    return SurfaceFit("bspline", surf.to_params(), dev, len(pts))


def _boundary_polyline(points: np.ndarray, dist: np.ndarray, t: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Per bin of ``t``, the point closest to the neighbour; extended linearly to the bins' full range."""
    bins = len(edges) - 1
    which = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, bins - 1)
    order = np.lexsort((dist, which))
    first = order[np.r_[True, np.diff(which[order]) != 0]]
    poly = points[first]
    if len(poly) < 2:
        return poly
    tp = t[first]
    # the overall chord's slope, not the end segment's: neighbouring bin picks can be close in t and far apart across
    slope = (poly[-1] - poly[0]) / max(tp[-1] - tp[0], 1e-300)
    head = poly[0] - slope * (tp[0] - edges[0])
    tail = poly[-1] + slope * (edges[-1] - tp[-1])
    return np.vstack([head, poly, tail])


def fit_rolling_ball(
    points,
    normals,
    neighbour_a: SurfaceFit,
    neighbour_b: SurfaceFit,
    *,
    tolerance: float,
    boundaries=None,
) -> SurfaceFit:
    """Fit a blend strip between two fitted faces.

    A flat strip (a chamfer) is returned as a plane. A rolling-ball fillet between two planes is a cylinder, between a plane and a cylinder (or two coaxial
    surfaces of revolution) a torus: those are tried first and returned with ``params["ball_radius"]``
    (the cylinder's radius / the torus' minor radius). Otherwise the strip becomes a
    :func:`ruled_surface` between its two boundary polylines.

    Parameters
    ----------
    points : (n, 3) float
        The strip's points.
    normals : (n, 3) float or None
        Their normals (any sign); estimated when None.
    neighbour_a, neighbour_b : SurfaceFit
        The fitted faces on either side; their ``distance`` picks the strip's boundary points when
        ``boundaries`` is not given.
    tolerance : float
    boundaries : tuple of two (k, 3) float, optional
        The ordered boundary polylines towards a and towards b (e.g. from the shared edge curves).

    Returns
    -------
    SurfaceFit
        plane (chamfer), cylinder / torus (with ``ball_radius``) or a ruled B-spline; falsy with the reason if neither meets
        the tolerance (the ruled surface's params are still there to use).
    """
    pts = as_points(points, min_count=8, error=FitError)
    if not tolerance > 0:
        raise FitError(f"`tolerance` must be > 0, got {tolerance}")
    chamfer = fit_plane(pts, tolerance=tolerance)
    if chamfer:
        return chamfer
    for fitter, key in ((fit_cylinder, "radius"), (fit_torus, "minor_radius")):
        fit = fitter(pts, normals, tolerance=tolerance)
        if fit:
            params = dict(fit.params, ball_radius=float(fit.params[key]))
            return SurfaceFit(fit.type, params, fit.deviation, fit.n_points)
    if boundaries is None:
        if not (neighbour_a and neighbour_b):
            raise FitError("`neighbour_a` and `neighbour_b` must be successful fits when `boundaries` is not given")
        da = np.abs(neighbour_a.distance(pts))
        db = np.abs(neighbour_b.distance(pts))
        mean = pts.mean(axis=0)
        _, vec = np.linalg.eigh((pts - mean).T @ (pts - mean))
        t = pts @ vec[:, 2]
        span = t.max() - t.min()
        bins = int(np.clip(len(pts) // 40, 2, 50))
        # bins reach 2% of the span beyond the ends so the end points fall inside (scales with the span)
        edges = np.linspace(t.min() - 0.02 * span, t.max() + 0.02 * span, bins + 1)
        on_a = da < db
        left = _boundary_polyline(pts[on_a], da[on_a], t[on_a], edges)
        right = _boundary_polyline(pts[~on_a], db[~on_a], t[~on_a], edges)
        if len(left) < 2 or len(right) < 2:
            return SurfaceFit("bspline", {}, deviation_stats(np.empty(0)), len(pts), ok=False,
                              reason="ruled: the strip has no points near one of its neighbours")
        boundaries = (left, right)
    ruled = ruled_surface(*boundaries)
    if not ruled:
        return ruled
    dev = deviation_stats(ruled.distance(pts))
    ok = within_tolerance(dev, tolerance)
    reason = "" if ok else f"ruled: deviation p99 {dev['p99']:.3g} / max {dev['max']:.3g} exceeds tolerance {tolerance:.3g}"
    return SurfaceFit("bspline", ruled.params, dev, len(pts), ok=ok, reason=reason)
