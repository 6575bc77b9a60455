"""Seeded samples of known surfaces and curves, for tests, benchmarks and notebooks.

Every sampler returns the exact points before noise is added by :func:`add_noise`, together with the true
unit normals, so a test can compare a fit with the truth. Patches are sampled uniformly in their parameters
(not in area: good enough for fitting tests).
"""

from __future__ import annotations

import numpy as np

from recon._array import perpendicular_frame

__all__ = [
    "random_rotation",
    "add_noise",
    "sample_plane",
    "sample_sphere",
    "sample_cylinder",
    "sample_cone",
    "sample_torus",
]


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation matrix (3, 3)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q


def add_noise(points: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Isotropic Gaussian noise of standard deviation ``sigma`` per coordinate (so σ along any normal)."""
    return points + rng.normal(scale=sigma, size=points.shape)


def _frame(axis):
    d = np.asarray(axis, dtype=float)
    d = d / np.linalg.norm(d)
    e1, e2 = perpendicular_frame(d)
    return e1, e2, d


def sample_plane(n, rng, *, origin=(0, 0, 0), normal=(0, 0, 1), size=20.0):
    """n points on a ``size`` × ``size`` square of the plane; returns (points, normals)."""
    e1, e2, d = _frame(normal)
    uv = rng.uniform(-size / 2, size / 2, size=(n, 2))
    pts = np.asarray(origin, float) + uv[:, :1] * e1 + uv[:, 1:] * e2
    return pts, np.tile(d, (n, 1))


def sample_sphere(n, rng, *, center=(0, 0, 0), radius=10.0, axis=(0, 0, 1), theta=(0, np.pi / 2), phi=(0.3, 1.2)):
    """n points of a sphere patch: azimuth ``theta`` about ``axis``, polar angle ``phi`` from it."""
    e1, e2, d = _frame(axis)
    t = rng.uniform(*theta, size=(n, 1))
    p = rng.uniform(*phi, size=(n, 1))
    nrm = np.sin(p) * (np.cos(t) * e1 + np.sin(t) * e2) + np.cos(p) * d
    return np.asarray(center, float) + radius * nrm, nrm


def sample_cylinder(n, rng, *, axis_point=(0, 0, 0), axis=(0, 0, 1), radius=10.0, theta=(0, np.pi / 2), height=(0, 20.0)):
    """n points of a cylinder patch: angle ``theta`` about the axis, ``height`` along it."""
    e1, e2, d = _frame(axis)
    t = rng.uniform(*theta, size=(n, 1))
    h = rng.uniform(*height, size=(n, 1))
    nrm = np.cos(t) * e1 + np.sin(t) * e2
    return np.asarray(axis_point, float) + radius * nrm + h * d, nrm


def sample_cone(n, rng, *, apex=(0, 0, 0), axis=(0, 0, 1), half_angle=np.deg2rad(30), theta=(0, np.pi / 2), height=(5.0, 20.0)):
    """n points of a cone patch: angle ``theta`` about the axis, axial distance ``height`` from the apex."""
    e1, e2, d = _frame(axis)
    t = rng.uniform(*theta, size=(n, 1))
    h = rng.uniform(*height, size=(n, 1))
    radial = np.cos(t) * e1 + np.sin(t) * e2
    pts = np.asarray(apex, float) + h * d + h * np.tan(half_angle) * radial
    nrm = np.cos(half_angle) * radial - np.sin(half_angle) * d
    return pts, nrm


def sample_torus(n, rng, *, center=(0, 0, 0), axis=(0, 0, 1), major=10.0, minor=3.0, theta=(0, np.pi / 2), phi=(0, np.pi)):
    """n points of a torus patch: ``theta`` about the axis, ``phi`` about the tube (0 = outer equator)."""
    e1, e2, d = _frame(axis)
    t = rng.uniform(*theta, size=(n, 1))
    p = rng.uniform(*phi, size=(n, 1))
    radial = np.cos(t) * e1 + np.sin(t) * e2
    nrm = np.cos(p) * radial + np.sin(p) * d
    return np.asarray(center, float) + major * radial + minor * nrm, nrm
