"""Tensor-product B-spline surfaces: knots, basis functions (The NURBS Book), evaluation and closest points.

The geometry alone; the penalised least-squares fit is :mod:`recon.fit._bspline`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["BSplineSurface", "basis_functions", "clamped_knots", "periodic_knots"]


def clamped_knots(lo: float, hi: float, intervals: int, degree: int) -> np.ndarray:
    """Clamped uniform knot vector on [lo, hi] with ``intervals`` spans: (intervals + 2·degree + 1,) float."""
    inner = np.linspace(lo, hi, intervals + 1)
    return np.r_[np.full(degree, lo), inner, np.full(degree, hi)]


def periodic_knots(period: float, intervals: int, degree: int) -> np.ndarray:
    """Uniform unclamped knots on [0, period] extended by ``degree`` spans on each side: (intervals + 2·degree + 1,).

    With control point ``i mod intervals`` under basis function ``i`` the curve is periodic and C^(degree−1)
    everywhere (The NURBS Book §12.2, "unclamped" B-splines); the domain is [knots[degree], knots[-degree-1]].
    """
    h = period / intervals
    return h * np.arange(-degree, intervals + degree + 1, dtype=float)


def basis_functions(x: np.ndarray, knots: np.ndarray, degree: int, *, derivative: bool = False):
    """The degree + 1 non-zero B-spline basis functions at each ``x`` (The NURBS Book, Algorithm A2.2).

    Parameters
    ----------
    x : (m,) float
        Clamped into the knot range.
    knots : (k,) float
        Clamped knot vector.
    degree : int
    derivative : bool
        Also return the first derivatives (NURBS Book eq. 2.7, from the degree − 1 functions).

    Returns
    -------
    first : (m,) int
        Index of the first non-zero basis function (span − degree).
    values : (m, degree + 1) float
    derivatives : (m, degree + 1) float
        Only when ``derivative`` is True.
    """
    x = np.clip(np.asarray(x, dtype=float), knots[degree], knots[-degree - 1])
    n_basis = len(knots) - degree - 1
    span = np.clip(np.searchsorted(knots, x, side="right") - 1, degree, n_basis - 1)

    def values(p):
        m = len(x)
        n = np.zeros((m, p + 1))
        n[:, 0] = 1.0
        left = np.zeros((m, p + 1))
        right = np.zeros((m, p + 1))
        for j in range(1, p + 1):
            left[:, j] = x - knots[span + 1 - j]
            right[:, j] = knots[span + j] - x
            saved = np.zeros(m)
            for r in range(j):
                den = right[:, r + 1] + left[:, j - r]
                temp = np.divide(n[:, r], den, out=np.zeros(m), where=den != 0)
                n[:, r] = saved + right[:, r + 1] * temp
                saved = left[:, j - r] * temp
            n[:, j] = saved
        return n

    n = values(degree)
    if not derivative:
        return span - degree, n
    lower = values(degree - 1)  # N_{span-degree+1 .. span, degree-1}
    d = np.zeros_like(n)
    first = span - degree
    for j in range(degree + 1):
        i = first + j
        if j >= 1:
            den = knots[i + degree] - knots[i]
            d[:, j] += np.divide(degree * lower[:, j - 1], den, out=np.zeros(len(x)), where=den != 0)
        if j < degree:
            den = knots[i + degree + 1] - knots[i + 1]
            d[:, j] -= np.divide(degree * lower[:, j], den, out=np.zeros(len(x)), where=den != 0)
    return first, n, d


@dataclass(frozen=True)
class BSplineSurface:
    """Non-rational tensor-product B-spline surface with clamped knots (in u optionally periodic).

    Attributes
    ----------
    degree_u, degree_v : int
    knots_u : (nu + degree_u + 1,) float
    knots_v : (nv + degree_v + 1,) float
    control_points : (nu, nv, 3) float
    periodic_u : bool
        ``knots_u`` are :func:`periodic_knots` (nu + 2·degree_u + 1 of them) and basis function i weighs control
        row ``i mod nu``: the surface closes on itself along u with period ``domain[0, 1] − domain[0, 0]``.
    """

    degree_u: int
    degree_v: int
    knots_u: np.ndarray
    knots_v: np.ndarray
    control_points: np.ndarray
    periodic_u: bool = False

    @classmethod
    def from_params(cls, params: dict) -> "BSplineSurface":
        """Rebuild from a :class:`~recon.fit.SurfaceFit`'s plain ``params``."""
        return cls(
            int(params["degree_u"]),
            int(params["degree_v"]),
            np.asarray(params["knots_u"], dtype=float),
            np.asarray(params["knots_v"], dtype=float),
            np.asarray(params["control_points"], dtype=float),
            bool(params.get("periodic_u", False)),
        )

    def to_params(self) -> dict:
        """Plain floats / lists for a :class:`~recon.fit.SurfaceFit`."""
        return {
            "degree_u": self.degree_u,
            "degree_v": self.degree_v,
            "knots_u": self.knots_u.tolist(),
            "knots_v": self.knots_v.tolist(),
            "control_points": self.control_points.tolist(),
            "periodic_u": bool(self.periodic_u),
            "periodic_v": False,
        }

    @property
    def domain(self) -> np.ndarray:
        """(2, 2) float: ``[[u0, u1], [v0, v1]]``."""
        pu, pv = self.degree_u, self.degree_v
        return np.array([[self.knots_u[pu], self.knots_u[-pu - 1]], [self.knots_v[pv], self.knots_v[-pv - 1]]])

    def _wrap_u(self, u):
        if not self.periodic_u:
            return u
        (u0, u1), _ = self.domain
        return u0 + np.mod(u - u0, u1 - u0)

    def _gather(self, fu, fv):
        iu = fu[:, None] + np.arange(self.degree_u + 1)
        if self.periodic_u:
            iu = iu % self.control_points.shape[0]
        iv = fv[:, None] + np.arange(self.degree_v + 1)
        return self.control_points[iu[:, :, None], iv[:, None, :]]  # (m, pu+1, pv+1, 3)

    def evaluate(self, u, v) -> np.ndarray:
        """Points S(u, v), (m, 3) for u, v (m,) (clamped to the domain)."""
        u, v = np.broadcast_arrays(np.atleast_1d(np.asarray(u, float)), np.atleast_1d(np.asarray(v, float)))
        fu, nu = basis_functions(self._wrap_u(u.ravel()), self.knots_u, self.degree_u)
        fv, nv = basis_functions(v.ravel(), self.knots_v, self.degree_v)
        return np.einsum("mi,mj,mijk->mk", nu, nv, self._gather(fu, fv))

    def derivatives(self, u, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """S, ∂S/∂u, ∂S/∂v at (u, v): three (m, 3) arrays."""
        fu, nu, du = basis_functions(self._wrap_u(np.asarray(u, float)), self.knots_u, self.degree_u, derivative=True)
        fv, nv, dv = basis_functions(np.asarray(v, float), self.knots_v, self.degree_v, derivative=True)
        cp = self._gather(fu, fv)
        return (
            np.einsum("mi,mj,mijk->mk", nu, nv, cp),
            np.einsum("mi,mj,mijk->mk", du, nv, cp),
            np.einsum("mi,mj,mijk->mk", nu, dv, cp),
        )

    def closest_parameters(self, points, uv0=None, *, iterations: int = 8, grid: int = 48) -> np.ndarray:
        """Parameters (m, 2) of the closest surface point to each of ``points`` (m, 3).

        Starts from ``uv0`` or from the nearest of ``grid`` × ``grid`` surface samples, then Gauss–Newton
        steps on |S(u, v) − p|², clamped to the domain (u wrapped when periodic). Good for deviations of points
        near the surface (a few grid cells); not a global solver for far-away points.
        """
        pts = np.asarray(points, dtype=float)
        (u0, u1), (v0, v1) = self.domain
        if uv0 is None:
            gu, gv = np.meshgrid(np.linspace(u0, u1, grid), np.linspace(v0, v1, grid), indexing="ij")
            samples = self.evaluate(gu.ravel(), gv.ravel())
            _, idx = cKDTree(samples).query(pts)
            uv = np.column_stack([gu.ravel()[idx], gv.ravel()[idx]])
        else:
            uv = np.array(uv0, dtype=float, copy=True)
        for _ in range(iterations):
            s, su, sv = self.derivatives(uv[:, 0], uv[:, 1])
            r = pts - s
            a11 = np.einsum("ij,ij->i", su, su)
            a12 = np.einsum("ij,ij->i", su, sv)
            a22 = np.einsum("ij,ij->i", sv, sv)
            b1 = np.einsum("ij,ij->i", su, r)
            b2 = np.einsum("ij,ij->i", sv, r)
            det = a11 * a22 - a12 * a12
            det = np.where(np.abs(det) > 1e-300, det, 1e-300)
            uv[:, 0] += (a22 * b1 - a12 * b2) / det
            uv[:, 1] += (a11 * b2 - a12 * b1) / det
            uv[:, 0] = self._wrap_u(uv[:, 0]) if self.periodic_u else np.clip(uv[:, 0], u0, u1)
            uv[:, 1] = np.clip(uv[:, 1], v0, v1)
        return uv

    def distance(self, points, uv0=None) -> np.ndarray:
        """Signed distance (m,) of ``points`` (m, 3), positive on the side of S_u × S_v."""
        pts = np.asarray(points, dtype=float)
        uv = self.closest_parameters(pts, uv0)
        s, su, sv = self.derivatives(uv[:, 0], uv[:, 1])
        r = pts - s
        sign = np.sign(np.einsum("ij,ij->i", r, np.cross(su, sv)))
        return np.where(sign < 0, -1.0, 1.0) * np.linalg.norm(r, axis=1)
