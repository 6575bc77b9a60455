"""Closed-form analytic surface fits and surface normals, for the many small fits of region growing.

Deliberately not the fitters of :mod:`._primitives`: their closed-form starts and two Gauss–Newton steps, without
the robust least squares, are what region growing can afford thousands of times (the fitter runs when they come near).

:mod:`recon.fit` refines every fit by robust least squares (``scipy.optimize.least_squares``), which costs
milliseconds per call; region growing makes thousands of fits, most of them on small seed discs or on regions
that changed by a few rings. The closed-form *starts* of those fitters (the same constructions, see
:mod:`recon.fit._primitives`) are already within tolerance on most such point sets, so :func:`quick_fit` tries
them first and runs the least-squares fitter only when the closed form comes close (90th percentile of |d|
within :data:`NEAR` tolerances) without being within tolerance:

- plane: PCA;
- sphere: the algebraic fit ``|p|² = 2 c·p + k`` (Kåsa), then Gauss–Newton steps on the geometric distance;
- cylinder: axis = least-orthogonal direction to the normals, circle fit across it, then Gauss–Newton steps;
- cone: the apex lies on every tangent plane (``n·a = n·p``), the axis is the normal of the plane fitted to the
  unit vectors from the apex;
- torus: the axis is the line meeting all normal lines (Plücker coordinates, linear), then a circle fit in the
  (ρ, z) half-plane.

Degenerate results are refused with the fitters' rules (sagitta below the tolerance: the simpler type fits).
"""

from __future__ import annotations

import numpy as np

from .._array import axis_helper, col_means, columns as _columns, cross3, extent, row_norms, row_sums
from ..errors import FitError
from ._select import ANALYTIC_FITTERS
from ._types import HUGE, SurfaceFit, deviation_stats, percentile as _percentile, within_tolerance

__all__ = ["quick_fit", "surface_normals", "closed_form"]

#: A closed form whose 90th percentile of |d| is within this many tolerances is refined by least squares; the
#: cone's and torus's starts (apex, axis from the normals) are less accurate on small or faceted patches.
NEAR = {"plane": 3.0, "sphere": 3.0, "cylinder": 3.0, "cone": 3.0, "torus": 3.0}
#: Gauss–Newton steps polishing the sphere's and the cylinder's closed form.
GN_STEPS = 2


def _unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(row_norms(v, keepdims=True), 1e-300)


def _frame(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e1 = cross3(d, axis_helper(d))  # np.cross(d, np.eye(3)[argmin |d|]), bit for bit
    e1 /= np.sqrt(e1.dot(e1))
    return e1, cross3(d, e1)


def _circle(xy: np.ndarray):
    """Kåsa circle fit; (centre (2,), radius) or None."""
    m = col_means(xy)
    q = xy - m
    a = _columns(2 * q, np.ones(len(q)))
    sol = np.linalg.lstsq(a, row_sums(q * q), rcond=None)[0]
    r2 = sol[2] + sol[:2] @ sol[:2]
    if not np.isfinite(r2) or r2 <= 0:
        return None
    return sol[:2] + m, float(np.sqrt(r2))


def _sphere_gauss_newton(q, c, r, steps=GN_STEPS):
    """Gauss–Newton steps on the geometric residual |q − c| − r from the algebraic start."""
    for _ in range(steps):
        w = q - c
        dist = np.maximum(row_norms(w), 1e-300)
        jac = _columns(-w / dist[:, None], -np.ones(len(q)))
        step = np.linalg.lstsq(jac, -(dist - r), rcond=None)[0]
        c, r = c + step[:3], r + step[3]
    return c, abs(float(r))


def _cylinder_gauss_newton(q, c, d, r, steps=GN_STEPS):
    """Gauss–Newton steps on the distance to the axis minus the radius (axis tilted in its normal plane).

    The normals give the axis only as well as they are smoothed; the positions pin it down.
    """
    for _ in range(steps):
        e1, e2 = _frame(d)
        w = q - c
        h = w @ d
        radial = w - h[:, None] * d
        rho = np.maximum(row_norms(radial), 1e-300)
        u = radial / rho[:, None]
        k = -h / rho
        jac = _columns(k * (w @ e1), k * (w @ e2), -(u @ e1), -(u @ e2), -np.ones(len(q)))
        step = np.linalg.lstsq(jac, -(rho - r), rcond=None)[0]
        d = d + step[0] * e1 + step[1] * e2
        d /= np.sqrt(d.dot(d))
        c = c + step[2] * e1 + step[3] * e2
        r = r + step[4]
    return c, d, abs(float(r))


def closed_form(kind: str, pts: np.ndarray, nrm: np.ndarray, tol: float) -> dict | None:
    """Parameters (as in :class:`recon.fit.SurfaceFit`) of the closed-form fit of ``kind``, or None if degenerate.

    Parameters
    ----------
    kind : str
        ``"plane"``, ``"sphere"``, ``"cylinder"``, ``"cone"`` or ``"torus"``.
    pts, nrm : (n, 3) float
        Points and unit normals (any sign).
    tol : float
        Distance tolerance (decides degeneracy: a sagitta below it means the simpler type).
    """
    mean = col_means(pts)
    q = pts - mean
    size = extent(pts)
    if kind == "plane":
        normal = np.linalg.eigh(q.T @ q)[1][:, 0]
        return {"origin": mean.tolist(), "normal": normal.tolist()}
    if kind == "sphere":
        a = _columns(2 * q, np.ones(len(q)))
        sol = np.linalg.lstsq(a, row_sums(q * q), rcond=None)[0]
        r2 = sol[3] + sol[:3] @ sol[:3]
        if not np.isfinite(r2) or r2 <= 0:
            return None
        c, r = _sphere_gauss_newton(q, sol[:3], float(np.sqrt(r2)))
        if not np.isfinite(r) or r > HUGE * size or size * size / (8 * r) < tol:
            return None
        return {"center": (c + mean).tolist(), "radius": r}
    if kind == "cylinder":
        d = np.linalg.eigh(nrm.T @ nrm)[1][:, 0]
        e1, e2 = _frame(d)
        c = _circle(_columns(q @ e1, q @ e2))
        if c is None or c[1] > HUGE * size or size * size / (8 * c[1]) < tol:
            return None
        centre, d, r = _cylinder_gauss_newton(q, c[0][0] * e1 + c[0][1] * e2, d, c[1])
        if not np.isfinite(r) or r > HUGE * size or size * size / (8 * r) < tol:
            return None
        return {"axis_point": (centre + mean).tolist(), "axis_dir": d.tolist(), "radius": r}
    if kind == "cone":
        m = nrm.T @ nrm
        ev = np.linalg.eigvalsh(m)
        # eigenvalue ratio below 1e-6: the normals are coplanar, a cylinder, no apex (scale-free)
        if not ev[0] > 1e-6 * ev[-1]:
            return None
        apex = np.linalg.solve(m, np.einsum("ij,ij->i", nrm, q) @ nrm)
        if np.linalg.norm(apex) > HUGE * size:
            return None
        u = _unit_rows(q - apex)
        d = np.linalg.eigh(np.cov(u.T))[1][:, 0]
        if np.mean(u @ d) < 0:
            d = -d
        alpha = float(np.arccos(np.clip(np.mean(u @ d), -1.0, 1.0)))
        h = (q - apex) @ d
        if alpha < np.deg2rad(0.5) or alpha > np.pi / 2 - np.deg2rad(0.5) or np.median(h) <= 0:
            return None
        if (h.max() - h.min()) * np.tan(alpha) < tol:
            return None  # the radius hardly changes: a cylinder
        hm = float(h.mean())
        apex = apex + mean
        return {
            "apex": apex.tolist(), "axis_dir": d.tolist(), "half_angle": alpha,
            "ref_point": (apex + hm * d).tolist(), "ref_radius": float(hm * np.tan(alpha)),
        }
    if kind == "torus":
        s = np.sqrt(np.mean(row_sums(q * q)))
        a = _columns(np.cross(q / s, nrm), nrm)
        vec = np.linalg.eigh(a.T @ a)[1][:, 0]
        d, mom = vec[:3], vec[3:]
        nd = np.linalg.norm(d)
        # a direction shorter than 1e-6 of a unit one is no direction (round-off, scale-free)
        if nd < 1e-6:
            return None
        d, mom = d / nd, mom / nd
        mom = mom - (mom @ d) * d
        c0 = cross3(d, mom) * s
        w = q - c0
        h = w @ d
        rho = np.sqrt(np.maximum(row_sums(w * w) - h * h, 0.0))
        c = _circle(_columns(rho, h))
        if c is None:
            return None
        (big, z0), small = c
        # a major radius below a thousandth of the patch is no torus (scales with part size)
        if big < max(1e-3 * size, tol) or big > HUGE * size or size * size / (8 * big) < tol:
            return None
        if small <= 0 or small > HUGE * size or big < small:
            return None
        return {"center": (c0 + z0 * d + mean).tolist(), "axis_dir": d.tolist(),
                "major_radius": float(big), "minor_radius": float(small)}
    raise FitError(f"unknown surface type {kind!r}")


def quick_fit(
    kind: str, pts: np.ndarray, nrm: np.ndarray, tol: float, *, refine: bool = True, polish: bool = False
) -> SurfaceFit | None:
    """The surface of ``kind`` through ``pts`` within ``tol`` (closed form, else least squares when near), or None.

    Parameters
    ----------
    kind : str
    pts, nrm : (n, 3) float
    tol : float
    refine : bool
        Run the least-squares fitter when the closed form is near but not within tolerance.
    polish : bool
        Run the least-squares fitter also when the closed form is within tolerance (a final fit: the
        closed form of a noisy region is a little off, and growing compares distances to it).
    """
    params = closed_form(kind, pts, nrm, tol)
    if params is not None:
        d = np.abs(SurfaceFit(kind, params, {}, len(pts)).distance(pts))
        dev = deviation_stats(d)
        if within_tolerance(dev, tol):
            if not polish:
                return SurfaceFit(kind, params, dev, len(pts))
        elif not refine or _percentile(d, 90) > NEAR[kind] * tol:
            return None
    elif not refine:
        return None
    try:
        fit = ANALYTIC_FITTERS[kind](pts, nrm, tolerance=tol)
    except (FitError, np.linalg.LinAlgError, ValueError):
        return None
    # the fitter's verdict stands even against a closed form within tolerance: it also refuses degenerate
    # surfaces (a cone no better than a cylinder, a sphere of a plane's sagitta)
    return fit if fit else None


def _normal_constants(fit: SurfaceFit):
    """The arrays :func:`surface_normals` builds from ``fit.params``, built once per fit (kept in its ``__dict__``,
    as its cached ``surface`` is): region growing asks one surface for normals thousands of times."""
    c = fit.__dict__.get("_normal_constants")
    if c is None:
        p = fit.params
        if fit.type == "plane":
            c = (np.asarray(p["normal"], float),)
        elif fit.type == "sphere":
            c = (np.asarray(p["center"]),)
        elif fit.type in ("cylinder", "cone", "torus"):
            d = np.asarray(p["axis_dir"], float)
            d = d / np.linalg.norm(d)
            origin = np.asarray(p["axis_point"] if fit.type == "cylinder" else p["apex"] if fit.type == "cone" else p["center"])
            c = (d, origin)
        else:
            raise FitError(f"no analytic normals for a {fit.type!r} surface")
        fit.__dict__["_normal_constants"] = c
    return c


def surface_normals(fit: SurfaceFit, pts: np.ndarray) -> np.ndarray:
    """(n, 3) unit normals of the fitted surface (analytic or B-spline) at its points nearest ``pts`` (n, 3) (any
    sign)."""
    if fit.type == "bspline":
        surface = fit.surface
        uv = surface.closest_parameters(pts)
        _, su, sv = surface.derivatives(uv[:, 0], uv[:, 1])
        return _unit_rows(np.cross(su, sv))
    c = _normal_constants(fit)
    if fit.type == "plane":
        # np.broadcast_to(normal, pts.shape): the same read-only stride-0 view, without its Python (~15 us)
        out = np.ndarray(pts.shape, float, c[0], 0, (0, c[0].strides[0]))
        out.flags.writeable = False
        return out
    if fit.type == "sphere":
        return _unit_rows(pts - c[0])
    d, origin = c
    w = pts - origin
    h = w @ d
    radial = w - h[:, None] * d
    u = _unit_rows(radial)
    if fit.type == "cylinder":
        return u
    p = fit.params
    if fit.type == "cone":
        a = float(p["half_angle"])
        return np.cos(a) * u - np.sin(a) * d
    tube = origin + float(p["major_radius"]) * u
    return _unit_rows(pts - tube)
