"""Surfaces as OpenCascade geometry beside recon's geometry model, and projection onto them.

A part's surface comes in as either an OpenCascade ``Geom_Surface`` (e.g. the true surface of a CAD
face, ``BRep_Tool.Surface_s``) or a fit from :mod:`recon.fit` (``.type`` and ``.params``, keyed as
:class:`recon.fit.SurfaceFit` documents). An analytic surface is also one of :mod:`recon.fit`'s geometry objects
(``Plane``, ``Cylinder``, ...), made from the OpenCascade surface's own frame, which projects in closed form with
numpy (the curve network projects thousands of points); anything else goes through ``GeomAPI_ProjectPointOnSurf``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

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

from .._array import x_or_y_helper
from ..errors import BrepError, InputError
from ..fit import Cone, Cylinder, Plane, Sphere, SurfaceKind, Torus

__all__ = ["SurfaceModel", "surface_model"]

log = logging.getLogger(__name__)

#: The kind of each ``GeomAbs_SurfaceType`` value (shared by the builder and the deviation analysis).
SURFACE_TYPE_NAMES = {
    GeomAbs_SurfaceType.GeomAbs_Plane: SurfaceKind.PLANE,
    GeomAbs_SurfaceType.GeomAbs_Cylinder: SurfaceKind.CYLINDER,
    GeomAbs_SurfaceType.GeomAbs_Cone: SurfaceKind.CONE,
    GeomAbs_SurfaceType.GeomAbs_Sphere: SurfaceKind.SPHERE,
    GeomAbs_SurfaceType.GeomAbs_Torus: SurfaceKind.TORUS,
    GeomAbs_SurfaceType.GeomAbs_BSplineSurface: SurfaceKind.BSPLINE,
    GeomAbs_SurfaceType.GeomAbs_BezierSurface: SurfaceKind.BEZIER,
    GeomAbs_SurfaceType.GeomAbs_SurfaceOfRevolution: SurfaceKind.REVOLUTION,
    GeomAbs_SurfaceType.GeomAbs_SurfaceOfExtrusion: SurfaceKind.EXTRUSION,
    GeomAbs_SurfaceType.GeomAbs_OffsetSurface: SurfaceKind.OFFSET,
    GeomAbs_SurfaceType.GeomAbs_OtherSurface: SurfaceKind.OTHER,
}


def _vec(p) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()], dtype=np.float64)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _perp(d) -> np.ndarray:
    return _unit(np.cross(d, x_or_y_helper(d)))


def _spread(rel: np.ndarray, m: np.ndarray) -> float:
    """The largest angle between the unit direction ``m`` and the directions of ``rel`` (k, 3)."""
    d = rel / np.maximum(np.linalg.norm(rel, axis=1), 1e-300)[:, None]
    return float(np.arccos(np.clip(d @ m, -1.0, 1.0)).max())


def _step(rim: list | None) -> float:
    """The largest angle between consecutive points of the rim's polylines (directions from the centre): how far the
    true edge may run past a polyline between them. Without a rim, a sixth of a turn: a cap drawn as a hexagon."""
    if not rim:
        return np.pi / 6
    out = 0.0
    for r in rim:
        d = r / np.maximum(np.linalg.norm(r, axis=1), 1e-300)[:, None]
        if len(d) > 1:
            out = max(out, float(np.arccos(np.clip(np.einsum("ij,ij->i", d[1:], d[:-1]), -1.0, 1.0)).max()))
    return out


def _ax3(origin, axis, xdir=None) -> gp_Ax3:
    axis = _unit(axis)
    xdir = _perp(axis) if xdir is None else _unit(np.asarray(xdir) - (np.asarray(xdir) @ axis) * axis)
    return gp_Ax3(gp_Pnt(*map(float, origin)), gp_Dir(*map(float, axis)), gp_Dir(*map(float, xdir)))


@dataclass(frozen=True)
class SurfaceModel:
    """One part's surface: the OCC geometry, and for an analytic kind the same surface in recon's geometry model.

    ``kind`` a :class:`recon.fit.SurfaceKind`; ``surface`` the :class:`recon.fit.Plane`, ``Sphere``, ``Cylinder``,
    ``Cone`` or ``Torus`` read from ``geom``'s own frame (None for the other kinds), which projects in closed form.
    """

    kind: SurfaceKind
    geom: Geom_Surface
    surface: Plane | Sphere | Cylinder | Cone | Torus | None = None
    #: Projections onto a free-form ``geom`` by point (its bytes): the network's alternating projections and
    #: refinement ask for the same point again, and each costs ~2 ms.
    _memo: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def origin(self) -> np.ndarray | None:
        """The plane's point, the apex of a cone, the centre of a sphere or torus, a cylinder's axis point."""
        s = self.surface
        if isinstance(s, Plane):
            return s.origin
        if isinstance(s, Cylinder):
            return s.axis_point
        if isinstance(s, Cone):
            return s.apex
        return None if s is None else s.center

    @property
    def axis(self) -> np.ndarray | None:
        """The plane's normal, the axis of a surface of revolution (a cone's into its opening); None for a sphere."""
        s = self.surface
        return s.normal if isinstance(s, Plane) else getattr(s, "axis_dir", None)

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Closest points and unit normals (sign not meaningful) for ``points (k, 3)``."""
        if self.surface is not None:
            return self.surface.project(points)
        return project_occ(self.geom, np.atleast_2d(np.asarray(points, dtype=np.float64)), memo=self._memo)

    def reframed(self, points, rim: list | None = None) -> "SurfaceModel":
        """The same surface with its seam (and a sphere's poles) turned away from ``points (k, 3)`` (the face's
        samples) and ``rim``: the polylines (j, 3) of its boundary's edges, where known.

        A face across a seam gets its edges split by ShapeFix, and a face over a sphere's pole gets a
        singular parametrisation (degenerate triangles in the STL); rotating the parametrisation about
        the surface's own axis (or choosing the sphere's axis) avoids both without changing the geometry.
        A sphere face reaching 90° from its centre (a hemisphere), or within one step of its rim's polyline of it,
        would have a pole on its rim: it gets the pole at its centre instead, as OpenCascade's own caps.
        """
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        s = self.surface
        if len(pts) == 0 or not isinstance(s, (Cylinder, Cone, Sphere, Torus)):
            return self
        rel = np.concatenate([pts, *rim]) - self.origin if rim else pts - self.origin
        if isinstance(s, Sphere):
            m = rel.mean(axis=0)
            if np.linalg.norm(m) < 1e-12:
                return self
            m = _unit(m)
            if np.pi / 2 - _spread(rel, m) > _step([r - self.origin for r in rim] if rim else None):
                # the poles stay off the face and its rim: its centre on the equator
                geom = Geom_SphericalSurface(_ax3(s.center, _perp(m), -m), s.radius)
            else:  # a pole could reach the face or its rim (a hemisphere's): the pole at its centre, as OCC's caps
                geom = Geom_SphericalSurface(_ax3(s.center, m), s.radius)
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
            if isinstance(s, Cylinder):
                geom = Geom_CylindricalSurface(_ax3(s.axis_point, axis, xdir), s.radius)
            elif isinstance(s, Torus):
                geom = Geom_ToroidalSurface(_ax3(s.center, axis, xdir), s.major_radius, s.minor_radius)
            else:
                if not direct:
                    return self
                cone = GeomAdaptor_Surface(self.geom).Cone()
                loc = _vec(cone.Location())
                # OpenCascade's own axis: with a negative semi-angle it points away from the opening (Cone.axis_dir)
                geom = Geom_ConicalSurface(_ax3(loc, _vec(cone.Axis().Direction()), xdir), cone.SemiAngle(),
                                           cone.RefRadius())
        return _from_geom(geom)

    def signed_normals(self, points) -> np.ndarray:
        """Unit normals ``dS/du × dS/dv`` (the surface's own orientation) at the projections of ``points``."""
        return project_occ(self.geom, points, memo=self._memo)[1]


def project_occ(geom: Geom_Surface, points, *, memo: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Closest points and oriented unit normals by ``GeomAPI_ProjectPointOnSurf`` (0.1–2 ms a point).

    ``memo`` (point bytes → (closest point, normal)) holds earlier answers on this ``geom``: a projection is
    initialised afresh for every point, so an answer depends on the point alone. (Initialising once per surface
    and calling ``Perform`` per point is 2× faster but lands on a farther local minimum for some points.)
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
    kind = SURFACE_TYPE_NAMES.get(ad.GetType(), SurfaceKind.OTHER)
    if kind == SurfaceKind.PLANE:
        pln = ad.Plane()
        pos = pln.Position()
        n = np.cross(_vec(pos.XDirection()), _vec(pos.YDirection()))
        return SurfaceModel(kind, geom, Plane(_vec(pln.Location()), _unit(n)))
    if kind == SurfaceKind.CYLINDER:
        c = ad.Cylinder()
        return SurfaceModel(kind, geom, Cylinder(_vec(c.Location()), _vec(c.Axis().Direction()), c.Radius()))
    if kind == SurfaceKind.CONE:
        c = ad.Cone()
        a = c.SemiAngle()  # OpenCascade's is signed: negative when the cone opens against its axis
        d = _vec(c.Axis().Direction())
        return SurfaceModel(kind, geom, Cone(_vec(c.Apex()), d if a > 0 else -d, abs(a)))
    if kind == SurfaceKind.SPHERE:
        sph = ad.Sphere()
        return SurfaceModel(kind, geom, Sphere(_vec(sph.Location()), sph.Radius()))
    if kind == SurfaceKind.TORUS:
        t = ad.Torus()
        return SurfaceModel(kind, geom, Torus(_vec(t.Location()), _vec(t.Axis().Direction()), t.MajorRadius(),
                                              t.MinorRadius()))
    return SurfaceModel(kind, geom)


def _params(fit, *names: str) -> list:
    """The values of ``names`` in ``fit.params`` (the keys :class:`recon.fit.SurfaceFit` documents for its type)."""
    p = fit.params
    missing = [n for n in names if p.get(n) is None]
    if missing:
        raise InputError(f"{fit.type} surface fit: params need {missing}, got keys {sorted(p)}")
    return [p[n] for n in names]


def _from_fit(fit) -> SurfaceModel:
    """A :mod:`recon.fit` result (``.type`` + ``.params``) as OCC geometry."""
    kind = str(fit.type).lower()
    if kind == "plane":
        origin, normal = (np.asarray(v, float) for v in _params(fit, "origin", "normal"))
        return _from_geom(Geom_Plane(_ax3(origin, normal)))
    if kind == "cylinder":
        origin, axis, r = _params(fit, "axis_point", "axis_dir", "radius")
        return _from_geom(Geom_CylindricalSurface(_ax3(np.asarray(origin, float), np.asarray(axis, float)), float(r)))
    if kind == "sphere":
        c, r = _params(fit, "center", "radius")
        return _from_geom(Geom_SphericalSurface(_ax3(np.asarray(c, float), [0, 0, 1.0]), float(r)))
    if kind == "torus":
        c, axis, big, small = _params(fit, "center", "axis_dir", "major_radius", "minor_radius")
        return _from_geom(Geom_ToroidalSurface(_ax3(np.asarray(c, float), np.asarray(axis, float)), float(big),
                                               float(small)))
    if kind == "cone":
        apex, axis, half = _params(fit, "apex", "axis_dir", "half_angle")
        apex, axis, half = np.asarray(apex, float), _unit(np.asarray(axis, float)), float(half)
        p = fit.params
        # OCC wants a reference circle with positive radius, away from the singular apex.
        if p.get("ref_point") is not None and p.get("ref_radius") is not None:
            loc, ref_r = np.asarray(p["ref_point"], float), float(p["ref_radius"])
        else:
            loc, ref_r = apex + np.cos(half) * axis, np.sin(half)
        return _from_geom(Geom_ConicalSurface(_ax3(loc, axis), half, ref_r))
    if kind == "bspline":
        return _from_geom(_bspline_surface(fit))
    raise InputError(f"surface fit: unsupported type {fit.type!r}; expected plane/cylinder/cone/sphere/torus/bspline")


def _bspline_surface(fit) -> Geom_BSplineSurface:
    ctrl, du, dv, ku, kv = _params(fit, "control_points", "degree_u", "degree_v", "knots_u", "knots_v")
    p = fit.params
    ctrl = np.asarray(ctrl, float)
    if ctrl.ndim != 3 or ctrl.shape[2] != 3:
        raise InputError(f"bspline surface fit: control_points must be (nu, nv, 3), got {ctrl.shape}")
    du, dv = int(du), int(dv)
    ku, kv = np.asarray(ku, float), np.asarray(kv, float)

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
