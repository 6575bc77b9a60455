"""Results of the fitters: small frozen dataclasses holding plain numbers (see shared/STYLE.md).

``params`` hold plain floats and lists (JSON-ready, and what ``recon.brep`` turns into ``gp_``/``Geom_``
objects). The geometric object behind them (``.surface`` / ``.curve``) is rebuilt on demand and gives the
vectorised ``distance``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ._geometry import Curve, Surface, curve_from_params, surface_from_params

#: A radius (or apex distance) beyond this many patch diagonals is numerically a plane, line or cylinder
#: (scales with the part's size: its sagitta is below round-off there).
HUGE = 1e3
#: Median |d| of a normal residual is 0.6745σ: the robust scale is 1.4826 × the median.
MAD_TO_SIGMA = 1.4826

__all__ = ["SurfaceFit", "CurveFit", "SURFACE_TYPES", "CURVE_TYPES", "deviation_stats", "within_tolerance"]

#: Surface types in the order :func:`recon.fit.fit_surface` tries them (simplest first, see there).
SURFACE_TYPES = ("plane", "sphere", "cylinder", "cone", "torus", "bspline")
#: Curve types in the order :func:`recon.fit.fit_curve` tries them.
CURVE_TYPES = ("line", "circle", "bspline")

#: Percentile of |d| that must be within tolerance (the max may be up to twice the tolerance).
ACCEPT_PERCENTILE = 99.0
#: Ratio of max |d| to tolerance still accepted.
ACCEPT_MAX_FACTOR = 2.0


def deviation_stats(d: np.ndarray) -> dict[str, float]:
    """Deviation summary of distances ``d`` (n,): ``{"max", "rms", "p99"}`` of |d| as plain floats."""
    a = np.abs(np.asarray(d, dtype=float))
    if a.size == 0:
        return {"max": float("nan"), "rms": float("nan"), "p99": float("nan")}
    top = a.max()
    return {
        "max": float(top),
        "rms": float(np.sqrt(np.mean(a * a))),
        "p99": float(_percentile(a, ACCEPT_PERCENTILE) if np.isfinite(top) else np.percentile(a, ACCEPT_PERCENTILE)),
    }


def _percentile(a: np.ndarray, q: float):
    """``np.percentile(a, q)`` (linear method) of a finite 1-D array, bit for bit, by one partition.

    The region growing of :mod:`recon.decompose` judges tens of thousands of small fits; numpy's general
    percentile costs ~60 µs a call there (axis and method handling), this ~4 µs.
    """
    n = a.size
    v = (n - 1) * np.true_divide(q, 100)  # numpy's virtual index for the linear method
    if v >= n - 1:
        return a.max()
    lo_i = int(np.floor(v))
    part = np.partition(a, (lo_i, lo_i + 1))
    lo, hi = part[lo_i], part[lo_i + 1]
    g = v - lo_i
    diff = hi - lo
    return hi - diff * (1 - g) if g >= 0.5 else lo + diff * g  # numpy's _lerp


def percentile(a: np.ndarray, q: float):
    """``np.percentile(a, q)`` of a 1-D float array of magnitudes (no −0.0), bit for bit: :func:`_percentile`
    when it is finite."""
    a = np.asarray(a)
    if a.size and np.isfinite(a).all():
        return _percentile(a, q)
    return np.percentile(a, q)


def median(a: np.ndarray):
    """``np.median(a)`` of a 1-D float array, bit for bit, without its axis handling (~20 µs a call).

    numpy partitions at the middle one or two positions (and at the last, to see a NaN) and averages them with
    ``np.mean``: ``np.add.reduce`` of the one or two values divided by their count. The same here for a finite
    array; anything else goes to ``np.median``.
    """
    a = np.asarray(a)
    n = a.size
    if a.ndim != 1 or n == 0 or a.dtype != np.float64 or not np.isfinite(a).all():
        return np.median(a)
    h = n // 2
    if n % 2:
        part = np.partition(a, h)
        return np.float64(np.add.reduce(part[h : h + 1]) / 1)
    part = np.partition(a, (h - 1, h))
    return np.float64(np.add.reduce(part[h - 1 : h + 1]) / 2)


def within_tolerance(deviation: dict[str, float], tolerance: float) -> bool:
    """The acceptance rule shared by every fitter.

    A fit is accepted when the 99th percentile of |d| is ≤ ``tolerance`` and the max |d| is ≤ 2·``tolerance``.
    The percentile (not the max) is the criterion because the max of n Gaussian residuals grows like
    σ·sqrt(2 ln n) and a few outliers (a spike left by the mesher, a point from the neighbouring blend) must
    not flip a plane into a B-spline; the cap on the max still rejects a fit that misses a small feature.
    A wrong type leaves a *systematic* deviation over a large fraction of the points and fails the percentile.
    """
    return bool(
        np.isfinite(deviation["p99"])
        and deviation["p99"] <= tolerance
        and deviation["max"] <= ACCEPT_MAX_FACTOR * tolerance
    )


@dataclass(frozen=True)
class _Fit:
    """What every fit carries: its type, parameters, deviation over its points, and whether it succeeded
    (falsy with the reason when not, after scikit-image's ``FailedEstimation``)."""

    type: str
    params: dict[str, Any]
    deviation: dict[str, float]
    n_points: int
    ok: bool = True
    reason: str = ""

    def __bool__(self) -> bool:
        return bool(self.ok)


@dataclass(frozen=True)
class SurfaceFit(_Fit):
    """One fitted surface, or a failed attempt (falsy) with the reason.

    Attributes
    ----------
    type : str
        One of :data:`SURFACE_TYPES`.
    params : dict
        Plain floats / lists. Directions are unit vectors; angles in radians.

        - plane: ``origin`` (a point of the patch: its centroid), ``normal``
        - sphere: ``center``, ``radius``
        - cylinder: ``axis_point`` (foot of the patch centroid on the axis), ``axis_dir``, ``radius``
        - cone: ``apex``, ``axis_dir`` (from the apex into the opening, towards the points), ``half_angle``,
          and ``ref_point``/``ref_radius``: the axis point at the patch's mean height and the cone radius there
          (``gp_Cone`` wants a location with a radius; the apex is a singular point to keep away from)
        - torus: ``center``, ``axis_dir``, ``major_radius``, ``minor_radius``
        - bspline: ``degree_u``, ``degree_v``, ``knots_u``, ``knots_v`` (full clamped knot vectors; when
          ``periodic_u``, ``knots_u`` are uniform and run ``degree_u`` spans past the domain on each side),
          ``control_points`` (nu, nv, 3) nested lists, ``periodic_u`` (a band closed round an axis),
          ``periodic_v`` (always False)
    deviation : dict
        ``{"max", "rms", "p99"}`` of |distance| over the fitted points (NaN when nothing was fitted).
    n_points : int
    ok : bool
        The fit succeeded (and, when a tolerance was given, is within it). ``bool(fit) == fit.ok``.
    reason : str
        Why not, when ``ok`` is False; empty otherwise.
    """

    @cached_property
    def surface(self) -> Surface | None:
        """The geometric surface (``Plane``, ``Sphere``, ...), rebuilt from ``params``; None if there are none."""
        return surface_from_params(self.type, self.params) if self.params else None

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance of ``points`` (n, 3) to the surface, (n,) float.

        Signed where meaningful: positive on the side of a plane's normal, outside a sphere, cylinder,
        cone or torus, and on the side of ``S_u × S_v`` for a B-spline.
        """
        if self.surface is None:
            raise ValueError(f"SurfaceFit of type {self.type!r} has no parameters: {self.reason}")
        return self.surface.distance(points)


@dataclass(frozen=True)
class CurveFit(_Fit):
    """One fitted curve, or a failed attempt (falsy) with the reason.

    Attributes
    ----------
    type : str
        One of :data:`CURVE_TYPES`.
    params : dict
        - line: ``point``, ``direction``, ``start``, ``end`` (the first and last data points projected on the line)
        - circle: ``center``, ``normal``, ``radius``, ``x_dir`` (angle 0), ``start_angle``, ``end_angle``
          (radians, counter-clockwise about ``normal``, start < end, end − start ≤ 2π), ``full`` (bool)
        - bspline: ``degree``, ``knots`` (full knot vector), ``control_points`` (c, 3), ``periodic`` (bool);
          the curve is defined on ``[knots[degree], knots[-degree-1]]``
    deviation : dict
        ``{"max", "rms", "p99"}`` of the distance of the points to the curve.
    n_points : int
    ok : bool
    reason : str
    """

    @cached_property
    def curve(self) -> Curve | None:
        """The geometric curve (``Line``, ``Circle``, ``BSplineCurve``) rebuilt from ``params``."""
        return curve_from_params(self.type, self.params) if self.params else None

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Unsigned distance of ``points`` (n, 3) to the curve, (n,) float."""
        if self.curve is None:
            raise ValueError(f"CurveFit of type {self.type!r} has no parameters: {self.reason}")
        return self.curve.distance(points)
