"""Surfaces and curves as small frozen dataclasses with a vectorised ``distance`` (and, for the analytic surfaces,
``project``: closest points and normals), and their rebuilding from a fit's plain ``params``
(:func:`surface_from_params`, :func:`curve_from_params`). This is recon's one geometry model: :mod:`recon.brep`
projects onto these objects and turns them into OpenCascade surfaces.

Distances are exact Euclidean distances (signed: positive outside / on the normal's side), so a fit's
residuals are geometric, not algebraic.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from .._array import height_radius, x_or_y_helper, row_norms, unit
from ..errors import FitError
from ._bspline_surface import BSplineSurface

if TYPE_CHECKING:
    from scipy.interpolate import BSpline

__all__ = ["Plane", "Sphere", "Cylinder", "Cone", "Torus", "BSplineSurface", "SurfaceKind", "CLOSED_KINDS", "surface_from_params",
           "Line", "Circle", "BSplineCurve", "curve_from_params", "Surface", "Curve", "CurveKind", "EdgeCurve"]


class SurfaceKind(StrEnum):
    """A surface's type: the fitted types, and the other kinds an OpenCascade surface may be (a value equals its
    report name, ``SurfaceKind.PLANE == "plane"``)."""

    PLANE = "plane"
    SPHERE = "sphere"
    CYLINDER = "cylinder"
    CONE = "cone"
    TORUS = "torus"
    BSPLINE = "bspline"
    BEZIER = "bezier"
    REVOLUTION = "revolution"
    EXTRUSION = "extrusion"
    OFFSET = "offset"
    OTHER = "other"


#: The surfaces closed in both directions: one face of them bounds a closed body alone, with no edge but its seams
#: and poles (as OpenCascade's own sphere and torus).
CLOSED_KINDS = (SurfaceKind.SPHERE, SurfaceKind.TORUS)


def _perp(d: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to ``d``: the radial direction a point on an axis is given."""
    return unit(np.cross(d, x_or_y_helper(d)))


def _axis_frame(x: np.ndarray, origin: np.ndarray, d: np.ndarray, perp: np.ndarray):
    """Height ``h`` (k,) of points ``x`` (k, 3) along the unit axis ``d`` through ``origin``, distance ``rho`` (k,)
    to the axis, and unit radial direction ``e`` (k, 3) (``perp`` for a point on the axis)."""
    rel = x - origin
    h = rel @ d
    radial = rel - np.outer(h, d)
    rho = np.linalg.norm(radial, axis=1)
    e = np.where(rho[:, None] > 1e-12, radial / np.maximum(rho, 1e-300)[:, None], perp)
    return h, rho, e


def _points(points) -> np.ndarray:
    return np.atleast_2d(np.asarray(points, dtype=np.float64))


class _Axial:
    """A surface of revolution about ``axis_dir``: the radial direction a point on its axis is given, made once (the
    curve network projects onto one surface many times)."""

    axis_dir: np.ndarray

    @cached_property
    def _axis_perp(self) -> np.ndarray:
        return _perp(self.axis_dir)


@dataclass(frozen=True)
class Plane:
    """Plane through ``origin`` (3,) with unit ``normal`` (3,)."""

    origin: np.ndarray
    normal: np.ndarray

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,), positive on the normal's side."""
        return (np.asarray(points, dtype=float) - self.origin) @ self.normal

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Closest points (k, 3) and unit normals (k, 3) for ``points`` (k, 3)."""
        x = _points(points)
        n = self.normal
        q = x - np.outer((x - self.origin) @ n, n)
        return q, np.broadcast_to(n, x.shape).copy()


@dataclass(frozen=True)
class Sphere:
    """Sphere of ``radius`` about ``center`` (3,)."""

    center: np.ndarray
    radius: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,), positive outside."""
        return row_norms(np.asarray(points, dtype=float) - self.center) - self.radius

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Closest points (k, 3) and outward unit normals (k, 3) for ``points`` (k, 3) (+z at the centre)."""
        w = _points(points) - self.center
        wn = np.linalg.norm(w, axis=1)
        u = np.where(wn[:, None] > 1e-12, w / np.maximum(wn, 1e-300)[:, None], np.array([0, 0, 1.0]))
        return self.center + self.radius * u, u


@dataclass(frozen=True)
class Cylinder(_Axial):
    """Infinite circular cylinder: axis through ``axis_point`` along unit ``axis_dir``, ``radius``."""

    axis_point: np.ndarray
    axis_dir: np.ndarray
    radius: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,), positive outside."""
        _, rho = height_radius(np.asarray(points, dtype=float), self.axis_point, self.axis_dir)
        return rho - self.radius


    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Closest points (k, 3) and outward unit normals (k, 3) for ``points`` (k, 3)."""
        d = self.axis_dir
        h, _, e = _axis_frame(_points(points), self.axis_point, d, self._axis_perp)
        return self.axis_point + np.outer(h, d) + self.radius * e, e


def cone_distance(points: np.ndarray, apex: np.ndarray, axis: np.ndarray, half_angle: float) -> np.ndarray:
    """Signed distance to the nappe of a cone opening from ``apex`` along ``axis`` (positive outside)."""
    w = points - apex
    h, rho = height_radius(points, apex, axis)
    s, c = np.sin(half_angle), np.cos(half_angle)
    across = rho * c - h * s
    along = rho * s + h * c  # position along the generator; < 0 means the apex is the closest point
    return np.where(along >= 0.0, across, np.sign(across) * row_norms(w))


@dataclass(frozen=True)
class Cone(_Axial):
    """Half cone (one nappe) with ``apex`` (3,), unit ``axis_dir`` into the opening, ``half_angle`` in (0, π/2)."""

    apex: np.ndarray
    axis_dir: np.ndarray
    half_angle: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,), positive outside."""
        return cone_distance(np.asarray(points, dtype=float), self.apex, self.axis_dir, self.half_angle)


    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Closest points (k, 3) on the nappe (the apex for points behind it) and unit normals (k, 3)."""
        d = self.axis_dir
        h, rho, e = _axis_frame(_points(points), self.apex, d, self._axis_perp)
        # in the (rho, h) half-plane about the apex, the generator is g
        g = np.array([abs(np.sin(self.half_angle)), np.sign(self.half_angle) * np.cos(self.half_angle)])
        s = np.maximum(rho * g[0] + h * g[1], 0.0)
        q = self.apex + np.outer(s * g[0], np.ones(3)) * e + np.outer(s * g[1], d)
        nrm = g[1] * e - g[0] * d[None, :]
        return q, nrm / np.linalg.norm(nrm, axis=1)[:, None]


@dataclass(frozen=True)
class Torus(_Axial):
    """Torus about ``center`` (3,) and unit ``axis_dir``; ``major_radius`` R (to the tube's centre circle), ``minor_radius`` r."""

    center: np.ndarray
    axis_dir: np.ndarray
    major_radius: float
    minor_radius: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,) to the tube, positive outside it."""
        h, rho = height_radius(np.asarray(points, dtype=float), self.center, self.axis_dir)
        return np.hypot(rho - self.major_radius, h) - self.minor_radius


    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Closest points (k, 3) on the tube and outward unit normals (k, 3) for ``points`` (k, 3)."""
        x = _points(points)
        _, _, e = _axis_frame(x, self.center, self.axis_dir, self._axis_perp)
        ring = self.center + self.major_radius * e
        w = x - ring
        wn = np.linalg.norm(w, axis=1)
        u = np.where(wn[:, None] > 1e-12, w / np.maximum(wn, 1e-300)[:, None], e)
        return ring + self.minor_radius * u, u


#: every surface type a fit makes
Surface = Plane | Sphere | Cylinder | Cone | Torus | BSplineSurface


def surface_from_params(kind: str, params: dict) -> Surface:
    """Build the geometric surface of a :class:`~recon.fit.SurfaceFit` from its plain ``params``."""
    p = {k: (np.asarray(v, dtype=float) if isinstance(v, (list, tuple)) else v) for k, v in params.items()}
    if kind == "plane":
        return Plane(p["origin"], unit(p["normal"]))
    if kind == "sphere":
        return Sphere(p["center"], float(p["radius"]))
    if kind == "cylinder":
        return Cylinder(p["axis_point"], unit(p["axis_dir"]), float(p["radius"]))
    if kind == "cone":
        return Cone(p["apex"], unit(p["axis_dir"]), float(p["half_angle"]))
    if kind == "torus":
        return Torus(p["center"], unit(p["axis_dir"]), float(p["major_radius"]), float(p["minor_radius"]))
    if kind == "bspline":
        return BSplineSurface.from_params(params)
    raise FitError(f"unknown surface type {kind!r}")


@dataclass(frozen=True)
class Line:
    """Line through ``point`` along unit ``direction``; ``start``/``end`` are the data's ends on it."""

    point: np.ndarray
    direction: np.ndarray

    def evaluate(self, t) -> np.ndarray:
        """Points (m, 3) at signed arc lengths ``t`` (m,) from ``point``."""
        return self.point + np.atleast_1d(np.asarray(t, float))[:, None] * self.direction

    def distance(self, points) -> np.ndarray:
        """Distance (m,) to the infinite line."""
        w = np.asarray(points, dtype=float) - self.point
        return np.linalg.norm(w - np.outer(w @ self.direction, self.direction), axis=1)


@dataclass(frozen=True)
class Circle:
    """Circle about ``center`` in the plane of unit ``normal``; angle 0 along ``x_dir``."""

    center: np.ndarray
    normal: np.ndarray
    radius: float
    x_dir: np.ndarray

    def evaluate(self, angle) -> np.ndarray:
        """Points (m, 3) at ``angle`` (m,) radians, counter-clockwise about ``normal``."""
        a = np.atleast_1d(np.asarray(angle, float))[:, None]
        y_dir = np.cross(self.normal, self.x_dir)
        return self.center + self.radius * (np.cos(a) * self.x_dir + np.sin(a) * y_dir)

    def distance(self, points) -> np.ndarray:
        """Distance (m,) to the full circle."""
        w = np.asarray(points, dtype=float) - self.center
        h = w @ self.normal
        rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", w, w) - h * h, 0.0))
        return np.hypot(rho - self.radius, h)


@dataclass(frozen=True)
class BSplineCurve:
    """Non-rational B-spline curve: ``degree``, full ``knots`` (k,), ``control_points`` (c, 3)."""

    degree: int
    knots: np.ndarray
    control_points: np.ndarray

    @property
    def domain(self) -> tuple[float, float]:
        return float(self.knots[self.degree]), float(self.knots[-self.degree - 1])

    @property
    def _spline(self) -> BSpline:
        from scipy.interpolate import BSpline  # here: 0.1 s of start-up that lines and arcs never use

        return BSpline(self.knots, self.control_points, self.degree, extrapolate=False)

    def evaluate(self, t) -> np.ndarray:
        """Points (m, 3) at parameters ``t`` (m,), clamped to the domain."""
        t0, t1 = self.domain
        return self._spline(np.clip(np.atleast_1d(np.asarray(t, float)), t0, t1))

    def closest_parameters(self, points, *, samples: int = 2000, iterations: int = 6) -> np.ndarray:
        """Parameter (m,) of the closest curve point: nearest of dense samples, then Newton steps."""
        pts = np.asarray(points, dtype=float)
        t0, t1 = self.domain
        grid = np.linspace(t0, t1, samples)
        spline = self._spline
        _, idx = cKDTree(spline(grid)).query(pts)
        t = grid[idx]
        d1, d2 = spline.derivative(1), spline.derivative(2)
        for _ in range(iterations):
            r = spline(t) - pts
            c1, c2 = d1(t), d2(t)
            g = np.einsum("ij,ij->i", r, c1)
            h = np.einsum("ij,ij->i", c1, c1) + np.einsum("ij,ij->i", r, c2)
            t = np.clip(t - g / np.where(h > 1e-300, h, 1e-300), t0, t1)
        return t

    def distance(self, points) -> np.ndarray:
        """Distance (m,) to the curve over its domain."""
        pts = np.asarray(points, dtype=float)
        return np.linalg.norm(self._spline(self.closest_parameters(pts)) - pts, axis=1)


#: every curve type a fit makes
Curve = Line | Circle | BSplineCurve


def curve_from_params(kind: str, params: dict) -> Curve:
    """Build the geometric curve of a :class:`~recon.fit.CurveFit` from its plain ``params``."""
    a = {k: (np.asarray(v, float) if isinstance(v, (list, tuple)) else v) for k, v in params.items()}
    if kind == "line":
        return Line(a["point"], a["direction"] / np.linalg.norm(a["direction"]))
    if kind == "circle":
        return Circle(a["center"], a["normal"], float(a["radius"]), a["x_dir"])
    if kind == "bspline":
        return BSplineCurve(int(a["degree"]), a["knots"], a["control_points"])
    raise FitError(f"unknown curve type {kind!r}")


class CurveKind(StrEnum):
    """A curve's type (a value equals its report name, ``CurveKind.LINE == "line"``)."""

    LINE = "line"
    CIRCLE = "circle"
    BSPLINE = "bspline"


@dataclass(frozen=True, eq=False)
class EdgeCurve:
    """A B-rep edge's curve from ``start`` to ``end`` (its two network vertices, or one twice on a closed edge).

    A :attr:`~CurveKind.LINE` is the segment between the ends; a :attr:`~CurveKind.CIRCLE` the arc of ``circle``
    counter-clockwise about its normal from angle ``t0`` to ``t1`` (from its ``x_dir``); a
    :attr:`~CurveKind.BSPLINE` the clamped ``spline`` over [0, 1], whose end control points are the ends.
    ``residual`` is the largest distance of the edge's points to the curve (inf: not fitted).
    """

    kind: CurveKind
    start: np.ndarray
    end: np.ndarray
    residual: float
    circle: Circle | None = None
    t0: float = 0.0
    t1: float = 0.0
    spline: BSplineCurve | None = None

    @classmethod
    def line(cls, start: np.ndarray, end: np.ndarray, residual: float) -> EdgeCurve:
        return cls(CurveKind.LINE, np.array(start, float), np.array(end, float), float(residual))

    @classmethod
    def arc(cls, circle: Circle, start: np.ndarray, end: np.ndarray, t0: float, t1: float,
            residual: float) -> EdgeCurve:
        return cls(CurveKind.CIRCLE, np.array(start, float), np.array(end, float), float(residual), circle=circle,
                   t0=float(t0), t1=float(t1))

    @classmethod
    def bspline(cls, degree: int, knots: np.ndarray, control_points: np.ndarray, residual: float) -> EdgeCurve:
        ctrl = np.asarray(control_points, float)
        return cls(CurveKind.BSPLINE, ctrl[0].copy(), ctrl[-1].copy(), float(residual),
                   spline=BSplineCurve(int(degree), np.asarray(knots, float), ctrl))
