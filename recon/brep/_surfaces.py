"""Surfaces as OpenCascade geometry, and fast projection onto them.

A part's surface comes in as either an OpenCascade ``Geom_Surface`` (e.g. the true surface of a CAD
face, ``BRep_Tool.Surface_s``) or a fit from :mod:`recon.fit` (an object with ``.type`` and ``.params``).
Analytic surfaces are projected onto in closed form with numpy (the curve network projects thousands
of points); anything else goes through ``GeomAPI_ProjectPointOnSurf``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from OCP.Geom import (
    Geom_BSplineSurface,
    Geom_ConicalSurface,
    Geom_CylindricalSurface,
    Geom_Plane,
    Geom_SphericalSurface,
    Geom_Surface,
    Geom_ToroidalSurface,
)
from OCP.GeomAbs import GeomAbs_SurfaceType
from OCP.GeomAdaptor import GeomAdaptor_Surface
from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
from OCP.GeomLProp import GeomLProp_SLProps
from OCP.gp import gp_Ax3, gp_Dir, gp_Pnt
from OCP.TColgp import TColgp_Array2OfPnt
from OCP.TColStd import TColStd_Array1OfInteger, TColStd_Array1OfReal

from ..errors import BrepError, InputError

__all__ = ["SurfaceModel", "surface_model"]

log = logging.getLogger(__name__)

#: Report names of ``GeomAbs_SurfaceType`` values (shared by the builder and the deviation analysis).
SURFACE_TYPE_NAMES = {
    GeomAbs_SurfaceType.GeomAbs_Plane: "plane",
    GeomAbs_SurfaceType.GeomAbs_Cylinder: "cylinder",
    GeomAbs_SurfaceType.GeomAbs_Cone: "cone",
    GeomAbs_SurfaceType.GeomAbs_Sphere: "sphere",
    GeomAbs_SurfaceType.GeomAbs_Torus: "torus",
    GeomAbs_SurfaceType.GeomAbs_BSplineSurface: "bspline",
    GeomAbs_SurfaceType.GeomAbs_BezierSurface: "bezier",
    GeomAbs_SurfaceType.GeomAbs_SurfaceOfRevolution: "revolution",
    GeomAbs_SurfaceType.GeomAbs_SurfaceOfExtrusion: "extrusion",
    GeomAbs_SurfaceType.GeomAbs_OffsetSurface: "offset",
    GeomAbs_SurfaceType.GeomAbs_OtherSurface: "other",
}


def _vec(p) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()], dtype=np.float64)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _perp(d) -> np.ndarray:
    a = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
    return _unit(np.cross(d, a))


def _ax3(origin, axis, xdir=None) -> gp_Ax3:
    axis = _unit(axis)
    xdir = _perp(axis) if xdir is None else _unit(np.asarray(xdir) - (np.asarray(xdir) @ axis) * axis)
    return gp_Ax3(gp_Pnt(*map(float, origin)), gp_Dir(*map(float, axis)), gp_Dir(*map(float, xdir)))


@dataclass(frozen=True)
class SurfaceModel:
    """One part's surface: the OCC geometry plus what numpy needs to project onto it.

    ``kind`` is plane/cylinder/cone/sphere/torus/bspline/...; ``origin``/``axis`` are the plane's point
    and normal, the axis of a surface of revolution (cone: ``origin`` is the apex), or the centre;
    ``radius``/``minor``/``angle`` as the kind needs.
    """

    kind: str
    geom: Geom_Surface
    origin: np.ndarray | None = None
    axis: np.ndarray | None = None
    radius: float = 0.0
    minor: float = 0.0
    angle: float = 0.0
    #: Projections onto a free-form ``geom`` by point (its bytes): the network's alternating projections and
    #: refinement ask for the same point again (rocker-arm2500: 28 % of 17,063), and each costs ~2 ms.
    _memo: dict = field(default_factory=dict, compare=False, repr=False)

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Closest points and unit normals (sign not meaningful) for ``points (k, 3)``."""
        x = np.atleast_2d(np.asarray(points, dtype=np.float64))
        k = self.kind
        if k == "plane":
            n = self.axis
            q = x - np.outer((x - self.origin) @ n, n)
            return q, np.broadcast_to(n, x.shape).copy()
        if k in ("cylinder", "torus", "cone"):
            d = self.axis
            rel = x - self.origin
            h = rel @ d
            radial = rel - np.outer(h, d)
            rho = np.linalg.norm(radial, axis=1)
            e = np.where(rho[:, None] > 1e-12, radial / np.maximum(rho, 1e-300)[:, None], self._axis_perp)
            if k == "cylinder":
                return self.origin + np.outer(h, d) + self.radius * e, e
            if k == "torus":
                ring = self.origin + self.radius * e
                w = x - ring
                wn = np.linalg.norm(w, axis=1)
                u = np.where(wn[:, None] > 1e-12, w / np.maximum(wn, 1e-300)[:, None], e)
                return ring + self.minor * u, u
            # cone: in the (rho, h) half-plane about the apex, the generator is g
            g = np.array([abs(np.sin(self.angle)), np.sign(self.angle) * np.cos(self.angle)])
            s = np.maximum(rho * g[0] + h * g[1], 0.0)
            q = self.origin + np.outer(s * g[0], np.ones(3)) * e + np.outer(s * g[1], d)
            nrm = g[1] * e - g[0] * d[None, :]
            return q, nrm / np.linalg.norm(nrm, axis=1)[:, None]
        if k == "sphere":
            w = x - self.origin
            wn = np.linalg.norm(w, axis=1)
            u = np.where(wn[:, None] > 1e-12, w / np.maximum(wn, 1e-300)[:, None], np.array([0, 0, 1.0]))
            return self.origin + self.radius * u, u
        return project_occ(self.geom, x, memo=self._memo)

    @cached_property
    def _axis_perp(self) -> np.ndarray:
        """``_perp(axis)``: the radial direction :meth:`project` gives a point on the axis, made once (the curve
        network projects onto each surface some fifty times)."""
        return _perp(self.axis)

    def reframed(self, points) -> "SurfaceModel":
        """The same surface with its seam (and a sphere's poles) turned away from ``points (k, 3)``.

        A face across a seam gets its edges split by ShapeFix, and a face over a sphere's pole gets a
        singular parametrisation (degenerate triangles in the STL); rotating the parametrisation about
        the surface's own axis (or choosing the sphere's axis) avoids both without changing the geometry.
        """
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        if len(pts) == 0 or self.kind not in ("cylinder", "cone", "sphere", "torus"):
            return self
        rel = pts - self.origin
        if self.kind == "sphere":
            m = rel.mean(axis=0)
            if np.linalg.norm(m) < 1e-12:
                return self
            m = _unit(m)
            axis = _perp(m)
            geom = Geom_SphericalSurface(_ax3(self.origin, axis, -m), self.radius)
        else:
            d = self.axis
            radial = rel - np.outer(rel @ d, d)
            norms = np.linalg.norm(radial, axis=1)
            ok = norms > 1e-12
            if not np.any(ok):
                return self
            m = (radial[ok] / norms[ok, None]).mean(axis=0)
            if np.linalg.norm(m) < 1e-9:  # a full turn: any seam will cut it
                return self
            xdir = -_unit(m)
            ax3 = self.geom.Position() if hasattr(self.geom, "Position") else None
            direct = ax3.Direct() if ax3 is not None else True
            axis = d if direct else -d
            if self.kind == "cylinder":
                geom = Geom_CylindricalSurface(_ax3(self.origin, axis, xdir), self.radius)
            elif self.kind == "torus":
                geom = Geom_ToroidalSurface(_ax3(self.origin, axis, xdir), self.radius, self.minor)
            else:
                cone = GeomAdaptor_Surface(self.geom).Cone()
                loc = _vec(cone.Location())
                geom = Geom_ConicalSurface(_ax3(loc, axis, xdir), cone.SemiAngle(), cone.RefRadius())
                if not direct:
                    return self
        return _from_geom(geom)

    def signed_normals(self, points) -> np.ndarray:
        """Unit normals ``dS/du × dS/dv`` (the surface's own orientation) at the projections of ``points``."""
        return project_occ(self.geom, points, memo=self._memo)[1]


def project_occ(geom: Geom_Surface, points, *, memo: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Closest points and oriented unit normals by ``GeomAPI_ProjectPointOnSurf`` (0.1–2 ms a point).

    ``memo`` (point bytes → (closest point, normal)) holds earlier answers on this ``geom``: a projection is
    initialised afresh for every point, so an answer depends on the point alone. (Initialising once per surface
    and calling ``Perform`` per point is 2× faster but lands on a farther local minimum for some points:
    23 of 17,063 on rocker-arm2500, by up to 2e-4.)
    """
    x = np.atleast_2d(np.asarray(points, dtype=np.float64))
    q = np.empty_like(x)
    nrm = np.zeros_like(x)
    proj = GeomAPI_ProjectPointOnSurf()
    for i, p in enumerate(x):
        key = p.tobytes() if memo is not None else None
        if key is not None and key in memo:
            q[i], nrm[i] = memo[key]
            continue
        proj.Init(gp_Pnt(*p), geom)
        if not proj.IsDone() or proj.NbPoints() == 0:
            q[i] = p
        else:
            u, v = proj.LowerDistanceParameters()
            props = GeomLProp_SLProps(geom, u, v, 1, 1e-9)
            q[i] = _vec(props.Value())
            if props.IsNormalDefined():
                nrm[i] = _vec(props.Normal())
        if key is not None:
            memo[key] = (q[i].copy(), nrm[i].copy())
    return q, nrm


def _from_geom(geom: Geom_Surface) -> SurfaceModel:
    ad = GeomAdaptor_Surface(geom)
    kind = SURFACE_TYPE_NAMES.get(ad.GetType(), "other")
    if kind == "plane":
        pln = ad.Plane()
        pos = pln.Position()
        n = np.cross(_vec(pos.XDirection()), _vec(pos.YDirection()))
        return SurfaceModel("plane", geom, _vec(pln.Location()), _unit(n))
    if kind == "cylinder":
        c = ad.Cylinder()
        return SurfaceModel("cylinder", geom, _vec(c.Location()), _vec(c.Axis().Direction()), c.Radius())
    if kind == "cone":
        c = ad.Cone()
        return SurfaceModel("cone", geom, _vec(c.Apex()), _vec(c.Axis().Direction()), c.RefRadius(),
                            angle=c.SemiAngle())
    if kind == "sphere":
        s = ad.Sphere()
        return SurfaceModel("sphere", geom, _vec(s.Location()), None, s.Radius())
    if kind == "torus":
        t = ad.Torus()
        return SurfaceModel("torus", geom, _vec(t.Location()), _vec(t.Axis().Direction()), t.MajorRadius(),
                            minor=t.MinorRadius())
    return SurfaceModel(kind, geom)


def _param(params: dict, *names, default=None):
    for n in names:
        if n in params and params[n] is not None:
            return params[n]
    if default is not None:
        return default
    raise InputError(f"surface fit params: expected one of {names}, got keys {sorted(params)}")


def _from_fit(fit) -> SurfaceModel:
    """A :mod:`recon.fit` result (``.type`` + ``.params``) as OCC geometry."""
    kind = str(fit.type).lower()
    p = dict(fit.params)
    if kind == "plane":
        origin = np.asarray(_param(p, "origin", "point", "center", "centroid"), float)
        normal = np.asarray(_param(p, "normal", "axis"), float)
        return _from_geom(Geom_Plane(_ax3(origin, normal)))
    if kind == "cylinder":
        origin = np.asarray(_param(p, "origin", "point", "center", "axis_point"), float)
        axis = np.asarray(_param(p, "axis_dir", "axis", "direction"), float)
        r = float(_param(p, "radius"))
        return _from_geom(Geom_CylindricalSurface(_ax3(origin, axis), r))
    if kind == "sphere":
        c = np.asarray(_param(p, "center", "origin"), float)
        return _from_geom(Geom_SphericalSurface(_ax3(c, [0, 0, 1.0]), float(_param(p, "radius"))))
    if kind == "torus":
        c = np.asarray(_param(p, "center", "origin"), float)
        axis = np.asarray(_param(p, "axis_dir", "axis", "normal"), float)
        return _from_geom(Geom_ToroidalSurface(_ax3(c, axis), float(_param(p, "major_radius", "R", "radius")),
                                               float(_param(p, "minor_radius", "r", "minor"))))
    if kind == "cone":
        apex = np.asarray(_param(p, "apex", "origin"), float)
        axis = _unit(np.asarray(_param(p, "axis_dir", "axis", "direction"), float))
        half = float(_param(p, "half_angle", "semi_angle", "angle"))
        # OCC wants a reference circle with positive radius, away from the singular apex.
        if p.get("ref_point") is not None and p.get("ref_radius") is not None:
            loc, ref_r = np.asarray(p["ref_point"], float), float(p["ref_radius"])
        else:
            loc, ref_r = apex + np.cos(half) * axis, np.sin(half)
        return _from_geom(Geom_ConicalSurface(_ax3(loc, axis), half, ref_r))
    if kind == "bspline":
        return _from_geom(_bspline_surface(p))
    raise InputError(f"surface fit: unsupported type {fit.type!r}; expected plane/cylinder/cone/sphere/torus/bspline")


def _bspline_surface(p: dict) -> Geom_BSplineSurface:
    ctrl = np.asarray(_param(p, "control_points", "poles", "ctrl"), float)
    if ctrl.ndim != 3 or ctrl.shape[2] != 3:
        raise InputError(f"bspline surface fit: control_points must be (nu, nv, 3), got {ctrl.shape}")
    du = int(_param(p, "degree_u", "du", "degree"))
    dv = int(_param(p, "degree_v", "dv", "degree"))
    ku = np.asarray(_param(p, "knots_u", "tu"), float)
    kv = np.asarray(_param(p, "knots_v", "tv"), float)

    def knots(flat):
        vals, mults = np.unique(np.round(flat, 12), return_counts=True)
        a = TColStd_Array1OfReal(1, len(vals))
        m = TColStd_Array1OfInteger(1, len(vals))
        for i, (v, c) in enumerate(zip(vals, mults), start=1):
            a.SetValue(i, float(v))
            m.SetValue(i, int(c))
        return a, m

    periodic_u = bool(p.get("periodic_u", False))
    if periodic_u:
        # recon's periodic knots run `degree` spans past the domain on each side; OpenCascade takes the domain's
        # knots only (all of multiplicity 1) and repeats the n poles itself, pole i under the same basis function
        ku = ku[du : len(ku) - du]
    poles = TColgp_Array2OfPnt(1, ctrl.shape[0], 1, ctrl.shape[1])
    for i in range(ctrl.shape[0]):
        for j in range(ctrl.shape[1]):
            poles.SetValue(i + 1, j + 1, gp_Pnt(*map(float, ctrl[i, j])))
    uk, um = knots(ku)
    vk, vm = knots(kv)
    try:
        return Geom_BSplineSurface(poles, uk, vk, um, vm, du, dv, periodic_u, False)
    except Exception as err:  # OCC raises Standard_ConstructionError on inconsistent knots/poles
        raise BrepError(f"bspline surface fit: OpenCascade rejected knots/poles ({err})") from err


def surface_model(surface) -> SurfaceModel:
    """Turn a ``Geom_Surface``, a :class:`SurfaceModel` or a ``recon.fit`` result into a :class:`SurfaceModel`."""
    if isinstance(surface, SurfaceModel):
        return surface
    if isinstance(surface, Geom_Surface):
        return _from_geom(surface)
    if hasattr(surface, "type") and hasattr(surface, "params"):
        return _from_fit(surface)
    raise InputError(f"surface: expected a Geom_Surface or a fit with .type/.params, got {type(surface).__name__}")
