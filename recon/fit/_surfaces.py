"""Analytic surfaces as small frozen dataclasses with a vectorised signed ``distance``.

Distances are exact Euclidean distances (signed: positive outside / on the normal's side), so a fit's
residuals are geometric, not algebraic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._array import row_norms, unit
from ..errors import FitError

__all__ = ["Plane", "Sphere", "Cylinder", "Cone", "Torus", "surface_from_params"]


def _axial_radial(points: np.ndarray, origin: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height along ``axis`` and distance to the axis line of each point."""
    w = points - origin
    h = w @ axis
    rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", w, w) - h * h, 0.0))
    return h, rho


@dataclass(frozen=True)
class Plane:
    """Plane through ``origin`` (3,) with unit ``normal`` (3,)."""

    origin: np.ndarray
    normal: np.ndarray

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,), positive on the normal's side."""
        return (np.asarray(points, dtype=float) - self.origin) @ self.normal


@dataclass(frozen=True)
class Sphere:
    """Sphere of ``radius`` about ``center`` (3,)."""

    center: np.ndarray
    radius: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,), positive outside."""
        return row_norms(np.asarray(points, dtype=float) - self.center) - self.radius


@dataclass(frozen=True)
class Cylinder:
    """Infinite circular cylinder: axis through ``axis_point`` along unit ``axis_dir``, ``radius``."""

    axis_point: np.ndarray
    axis_dir: np.ndarray
    radius: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,), positive outside."""
        _, rho = _axial_radial(np.asarray(points, dtype=float), self.axis_point, self.axis_dir)
        return rho - self.radius


def cone_distance(points: np.ndarray, apex: np.ndarray, axis: np.ndarray, half_angle: float) -> np.ndarray:
    """Signed distance to the nappe of a cone opening from ``apex`` along ``axis`` (positive outside)."""
    w = points - apex
    h, rho = _axial_radial(points, apex, axis)
    s, c = np.sin(half_angle), np.cos(half_angle)
    across = rho * c - h * s
    along = rho * s + h * c  # position along the generator; < 0 means the apex is the closest point
    return np.where(along >= 0.0, across, np.sign(across) * row_norms(w))


@dataclass(frozen=True)
class Cone:
    """Half cone (one nappe) with ``apex`` (3,), unit ``axis_dir`` into the opening, ``half_angle`` in (0, π/2)."""

    apex: np.ndarray
    axis_dir: np.ndarray
    half_angle: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,), positive outside."""
        return cone_distance(np.asarray(points, dtype=float), self.apex, self.axis_dir, self.half_angle)


@dataclass(frozen=True)
class Torus:
    """Torus about ``center`` (3,) and unit ``axis_dir``; ``major_radius`` R (to the tube's centre circle), ``minor_radius`` r."""

    center: np.ndarray
    axis_dir: np.ndarray
    major_radius: float
    minor_radius: float

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (n,) to the tube, positive outside it."""
        h, rho = _axial_radial(np.asarray(points, dtype=float), self.center, self.axis_dir)
        return np.hypot(rho - self.major_radius, h) - self.minor_radius


def surface_from_params(kind: str, params: dict):
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
        from ._bspline import BSplineSurface

        return BSplineSurface.from_params(params)
    raise FitError(f"unknown surface type {kind!r}")
