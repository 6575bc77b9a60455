"""Exact distances from points to the faces of a B-rep, vectorised where the surface allows it.

The query is in three steps (the usual scheme of deviation tools):

1. *candidates*: a KD-tree on a dense sample of every face (tessellation nodes plus area-uniform
   points on its triangles) names, for each query point, the faces that can hold its nearest point;
2. *projection*: each point is projected onto the untrimmed surface of each candidate face. Plane,
   cylinder, cone, sphere and torus are done in closed form in numpy (every critical point of the
   distance: for a surface of revolution they all lie in the meridian plane through the point);
   other surfaces (B-spline, Bézier, revolution, extrusion, offset) by
   ``ShapeAnalysis_Surface.NextValueOfUV`` per point, started at the UV of the nearest sample;
3. *trimming*: a foot whose (u, v) falls outside the trimmed face is rejected; then the distance is
   the minimum over the remaining critical points and the face's boundary edges (:mod:`._edge_distance`).
   The UV test is a polygon test on the face's p-curves, and ``BRepClass_FaceClassifier`` decides
   exactly for feet within a thin band of the boundary.

Distances are signed: positive on the side the face's outward normal points to (outside a solid).
Distances to a solid are measured to its faces, never "0 inside" (OCP-NOTES).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.spatial import cKDTree

from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve2d, BRepAdaptor_Surface
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
from OCP.BRepClass import BRepClass_FaceClassifier
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.BRepTools import BRepTools, BRepTools_WireExplorer
from OCP.GeomAbs import GeomAbs_CurveType, GeomAbs_SurfaceType
from OCP.gp import gp_Pnt, gp_Pnt2d, gp_Vec
from OCP.ShapeAnalysis import ShapeAnalysis_Surface
from OCP.TopAbs import TopAbs_EDGE, TopAbs_IN, TopAbs_ON, TopAbs_REVERSED, TopAbs_WIRE
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopLoc import TopLoc_Location
from OCP.TopoDS import TopoDS, TopoDS_Shape
from OCP.TopTools import TopTools_IndexedMapOfShape

from ..errors import BrepError, InputError
from ._edge_distance import edge_samples, edges_distance
from ._edge_distance import xyz as _xyz
from ._rings import ring_contains
from ._step_read import faces_of
from ._surfaces import SURFACE_TYPE_NAMES

__all__ = ["BrepDistance", "SURFACE_TYPES"]

log = logging.getLogger(__name__)

SURFACE_TYPES = SURFACE_TYPE_NAMES  # report names of GeomAbs_SurfaceType values
_ANALYTIC = {"plane", "cylinder", "cone", "sphere", "torus"}

# Width of the band (in UV normalised to the face's UV box) in which the polygon test on the
# sampled p-curves is not trusted and the exact OCCT classifier decides.
_BAND = 2e-3
#: Samples along each p-curve for that polygon test: 2^8 + 1, fine against the band (scale-free, UV normalised).
_PCURVE_SAMPLES = 257
# Points per batch of signed_distance.
_QUERY_CHUNK = 100_000
#: with a progress callback: points a chunk, a few seconds' work at most, so that a display moves (each point is
#: measured on its own: the chunking changes no result)
_PROGRESS_CHUNK = 20_000
# UV grid (per side) sampling a face that BRepMesh could not triangulate.
_GRID = 48


@dataclass
class _Face:
    index: int
    face: object
    kind: str
    adaptor: BRepAdaptor_Surface
    frame: tuple = ()  # analytic: (O, X, Y, Z) as (3,) arrays
    radii: tuple = ()  # analytic constants (R, r, semi-angle ...)
    sense: float = 1.0  # multiplies the geometric normal to give the outward normal
    uv_box: tuple = (0.0, 1.0, 0.0, 1.0)
    u_period: float = 0.0
    v_period: float = 0.0
    rings: list = field(default_factory=list)  # closed (r, 2) polygons in normalised UV
    ring_tree: cKDTree | None = None
    edges: list = field(default_factory=list)  # EdgeSamples of its non-degenerate edges
    sas: ShapeAnalysis_Surface | None = None
    surface: object = None


class BrepDistance:
    """A B-rep prepared for exact point distance queries (tessellated and indexed once).

    Parameters
    ----------
    shape : TopoDS_Shape
        Solid, shell, compound or face. Its faces are measured; a solid's interior is not 0.
    deflection : float, optional
        Tessellation deflection for candidate search and sampling; default 1e-3 × bbox diagonal.
        It does not limit the accuracy of the distances, only the work.
    rng : numpy.random.Generator, optional
        For the area-uniform candidate samples; default ``np.random.default_rng(0)``.

    Attributes
    ----------
    faces : list of TopoDS_Face
        In :func:`recon.brep._step_read.faces_of` order; face indices refer to it. Faces of a copy of ``shape``
        (the same geometry, in the same order).
    types : tuple of str
        Surface type of each face (``"plane"``, ``"cylinder"``, ..., ``"bspline"``).
    """

    def __init__(self, shape: TopoDS_Shape, *, deflection: float | None = None, rng=None):
        if not isinstance(shape, TopoDS_Shape) or shape.IsNull():
            raise InputError("shape: expected a non-null TopoDS_Shape")
        # Measured on a copy without the shape's triangulation: BRepMesh refines an existing one instead of
        # starting afresh, so the result depended on what had meshed the shape before, and on a B-rep with a
        # face it cannot mesh re-meshing took minutes and gigabytes, where a fresh copy takes a fraction of a
        # second.
        shape = BRepBuilderAPI_Copy(shape, True, False).Shape()
        self.faces = faces_of(shape)
        if not self.faces:
            raise InputError("shape: expected a shape with at least one face")
        box = Bnd_Box()
        BRepBndLib.Add_s(shape, box)
        xmin, ymin, zmin, xmax, ymax, zmax = box.Get()
        self.diagonal = float(math.dist((xmin, ymin, zmin), (xmax, ymax, zmax)))
        if deflection is None:
            # default deflection: a thousandth of the part's diagonal (scales with part size)
            deflection = 1e-3 * self.diagonal
        rng = np.random.default_rng(0) if rng is None else rng
        mesher = BRepMesh_IncrementalMesh(shape, deflection, False, 0.25, True)
        if not mesher.IsDone():
            raise BrepError("shape: tessellation failed")
        # An edge bounds two faces: it is sampled once (the 3D curve does not depend on the face or orientation).
        self._edge_map = TopTools_IndexedMapOfShape()
        TopExp.MapShapes_s(shape, TopAbs_EDGE, self._edge_map)
        self._edge_cache = {}
        self._faces = [self._prepare(i, f) for i, f in enumerate(self.faces)]
        del self._edge_cache
        self.types = tuple(f.kind for f in self._faces)
        self._build_samples(rng)

    # ------------------------------------------------------------------ preparation
    def _prepare(self, index, face) -> _Face:
        adaptor = BRepAdaptor_Surface(face)
        kind = SURFACE_TYPES.get(adaptor.GetType(), "other")
        fd = _Face(index=index, face=face, kind=kind, adaptor=adaptor)
        if kind in _ANALYTIC:
            gp_surf = {
                "plane": adaptor.Plane,
                "cylinder": adaptor.Cylinder,
                "cone": adaptor.Cone,
                "sphere": adaptor.Sphere,
                "torus": adaptor.Torus,
            }[kind]()
            ax = gp_surf.Position()
            fd.frame = tuple(
                np.array(_xyz(v)) for v in (ax.Location(), ax.XDirection(), ax.YDirection(), ax.Direction())
            )
            if kind in ("cylinder", "sphere"):
                fd.radii = (gp_surf.Radius(),)
            elif kind == "cone":
                fd.radii = (gp_surf.RefRadius(), gp_surf.SemiAngle())
            elif kind == "torus":
                fd.radii = (gp_surf.MajorRadius(), gp_surf.MinorRadius())
        else:
            fd.surface = BRep_Tool.Surface_s(face)
            fd.sas = ShapeAnalysis_Surface(fd.surface)
        umin, umax, vmin, vmax = BRepTools.UVBounds_s(face)
        fd.uv_box = (umin, max(umax - umin, 1e-300), vmin, max(vmax - vmin, 1e-300))
        fd.u_period = adaptor.UPeriod() if adaptor.IsUPeriodic() else 0.0
        fd.v_period = adaptor.VPeriod() if adaptor.IsVPeriodic() else 0.0
        self._prepare_rings(fd)
        self._prepare_edges(fd)
        self._prepare_mesh(fd)
        return fd

    def _prepare_rings(self, fd: _Face):
        wires = TopExp_Explorer(fd.face, TopAbs_WIRE)
        dense = []
        while wires.More():
            wire = TopoDS.Wire_s(wires.Current())
            wires.Next()
            pts = []
            ex = BRepTools_WireExplorer(wire, fd.face)
            while ex.More():
                edge = ex.Current()
                c2 = BRepAdaptor_Curve2d(edge, fd.face)
                n = 2 if c2.GetType() == GeomAbs_CurveType.GeomAbs_Line else _PCURVE_SAMPLES
                t = np.linspace(c2.FirstParameter(), c2.LastParameter(), n)
                if edge.Orientation() == TopAbs_REVERSED:
                    t = t[::-1]
                pts.extend(_xy(c2.Value(ti)) for ti in t)
                ex.Next()
            if len(pts) < 3:
                continue
            ring = self._normalise_uv(fd, np.asarray(pts, dtype=float), wrap=False)
            fd.rings.append(ring)
            # Resample the closed ring so that the band test sees no gaps wider than the band.
            closed = np.vstack([ring, ring[:1]])
            seg = np.diff(closed, axis=0)
            lengths = np.hypot(seg[:, 0], seg[:, 1])
            k = np.maximum(1, np.ceil(lengths / (0.5 * _BAND))).astype(np.int64)
            s = np.repeat(np.arange(len(seg)), k)
            j = np.arange(len(s)) - np.repeat(np.cumsum(k) - k, k)  # 0 … k-1 along each segment
            dense.append(closed[:-1][s] + seg[s] * (j / k[s])[:, None])
        fd.ring_tree = cKDTree(np.vstack(dense)) if dense else None

    def _prepare_edges(self, fd: _Face):
        emap = TopTools_IndexedMapOfShape()
        TopExp.MapShapes_s(fd.face, TopAbs_EDGE, emap)
        for i in range(1, emap.Extent() + 1):
            edge = TopoDS.Edge_s(emap.FindKey(i))
            if BRep_Tool.Degenerated_s(edge):
                continue
            key = self._edge_map.FindIndex(edge) or ("face", fd.index, i)
            if key not in self._edge_cache:
                self._edge_cache[key] = edge_samples(edge, self.diagonal)
            fd.edges.append(self._edge_cache[key])

    def _prepare_mesh(self, fd: _Face):
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(fd.face, loc)
        if tri is None or tri.NbTriangles() == 0:
            # BRepMesh leaves some faces of a broken B-rep (inverted or self-intersecting wires) without
            # triangles; points on its p-curves and a UV grid inside it still let it be measured.
            fd.tris = np.empty((0, 3), dtype=np.int64)
            fd.uv = self._untriangulated_uv(fd)
            fd.nodes = np.array([_xyz(fd.adaptor.Value(u, v)) for u, v in fd.uv]).reshape(-1, 3)
            if len(fd.uv):
                fd.sense = self._calibrate_sense(fd)
            log.debug("face %d (%s) has no triangulation: %d points from its boundary and a UV grid",
                      fd.index, fd.kind, len(fd.uv))
            return
        trsf = loc.Transformation()
        count = range(1, tri.NbNodes() + 1)
        # (gp_Pnt.Transform leaves a point as it is under the identity: skipping it is the same numbers)
        nodes = ([tri.Node(i).Coord() for i in count] if loc.IsIdentity()
                 else [tri.Node(i).Transformed(trsf).Coord() for i in count])
        fd.nodes = np.asarray(nodes)
        if tri.HasUVNodes():
            fd.uv = np.array([tri.UVNode(i).Coord() for i in count])
        else:
            fd.uv = np.zeros((len(nodes), 2))
        fd.tris = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)], dtype=np.int64) - 1
        fd.sense = self._calibrate_sense(fd)

    def _untriangulated_uv(self, fd: _Face) -> np.ndarray:
        """(k, 2) UV points on a face without triangulation: its p-curve samples plus a grid inside it."""
        u0, du, v0, dv = fd.uv_box
        # a UV box a million diagonals (or turns) wide is an unbounded surface, not a face (scales with part size)
        if not all(map(math.isfinite, fd.uv_box)) or max(du, dv) > 1e6 * max(self.diagonal, 2 * math.pi):
            return np.empty((0, 2))
        uv = [np.column_stack([u0 + r[:, 0] * du, v0 + r[:, 1] * dv]) for r in fd.rings]
        g = (np.arange(_GRID) + 0.5) / _GRID
        grid = np.column_stack([u0 + np.repeat(g, _GRID) * du, v0 + np.tile(g, _GRID) * dv])
        uv.append(grid[self._inside(fd, grid)])
        return np.vstack(uv)

    def _calibrate_sense(self, fd: _Face) -> float:
        """Sign turning this module's geometric normal into the face's outward normal.

        Compared with OCCT's D1U × D1V (reversed for a REVERSED face) at the node where that
        product is largest, so that indirect frames and face orientation are both taken care of.
        """
        best, sense = -1.0, 1.0
        step = max(1, len(fd.uv) // 16)
        for (u, v), q in zip(fd.uv[::step], fd.nodes[::step]):
            p, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
            fd.adaptor.D1(u, v, p, du, dv)
            n_occ = np.array(_xyz(du.Crossed(dv)))
            norm = np.linalg.norm(n_occ)
            if norm <= best:
                continue
            n_geo = self._geometric_normal(fd, q[None, :], uv=np.array([[u, v]]))[0]
            dot = float(np.dot(n_occ, n_geo))
            if abs(dot) < 0.5 * norm:
                continue
            best, sense = norm, math.copysign(1.0, dot)
        if fd.face.Orientation() == TopAbs_REVERSED:
            sense = -sense
        return sense

    def _triangle_areas(self) -> list:
        """Area of every tessellation triangle, one (t,) array per face (empty for a face without triangles)."""
        areas = []
        for fd in self._faces:
            if len(fd.tris):
                a, b, c = (fd.nodes[fd.tris[:, k]] for k in range(3))
                areas.append(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1))
            else:
                areas.append(np.empty(0))
        return areas

    def _build_samples(self, rng):
        """Dense points on every face (nodes + area-uniform) for the candidate KD-tree."""
        pts, fid, uvs = [], [], []
        areas = self._triangle_areas()
        total = float(sum(a.sum() for a in areas))
        # Spacing h ≈ diagonal/150, at most 200k samples: the candidate margin below scales with h.
        count = int(min(200_000, max(5_000, total / (self.diagonal / 150.0) ** 2)))
        self.spacing = math.sqrt(total / count) if total > 0 else self.diagonal
        for fd, area in zip(self._faces, areas):
            pts.append(fd.nodes)
            uvs.append(fd.uv)
            fid.append(np.full(len(fd.nodes), fd.index))
            if len(fd.tris) and total > 0:
                k = int(round(count * area.sum() / total))
                p, uv, _ = self._triangle_samples(fd, area, k, rng)
                pts.append(p)
                uvs.append(uv)
                fid.append(np.full(len(p), fd.index))
        if sum(len(q) for q in pts) == 0:
            raise BrepError(f"shape: none of its {len(self._faces)} faces could be tessellated or sampled")
        self._sample_points = np.vstack(pts)
        self._sample_uv = np.vstack(uvs)
        self._sample_face = np.concatenate(fid).astype(np.int64)
        self._tree = cKDTree(self._sample_points)
        log.debug("candidate tree: %d samples, spacing %.3g", len(self._sample_points), self.spacing)

    @staticmethod
    def _triangle_samples(fd: _Face, area, k, rng):
        if k <= 0 or area.sum() <= 0:
            return np.empty((0, 3)), np.empty((0, 2)), np.empty(0, dtype=np.int64)
        t = rng.choice(len(fd.tris), size=k, p=area / area.sum())
        r1, r2 = rng.random(k), rng.random(k)
        s = np.sqrt(r1)
        w = np.stack([1 - s, s * (1 - r2), s * r2], axis=1)
        tri = fd.tris[t]
        p = np.einsum("ij,ijk->ik", w, fd.nodes[tri])
        uv = np.einsum("ij,ijk->ik", w, fd.uv[tri])
        return p, uv, t

    # ------------------------------------------------------------------ UV helpers
    @staticmethod
    def _normalise_uv(fd: _Face, uv, *, wrap=True):
        """UV scaled to the face's UV box; query points are first wrapped into it (periodic)."""
        u0, du, v0, dv = fd.uv_box
        u, v = uv[:, 0].copy(), uv[:, 1].copy()
        tol = 1e-9
        if wrap and fd.u_period:
            u = (u0 - tol * fd.u_period) + np.mod(u - (u0 - tol * fd.u_period), fd.u_period)
        if wrap and fd.v_period:
            v = (v0 - tol * fd.v_period) + np.mod(v - (v0 - tol * fd.v_period), fd.v_period)
        return np.column_stack([(u - u0) / du, (v - v0) / dv])

    def _inside(self, fd: _Face, uv) -> np.ndarray:
        """(n,) bool: does (u, v) lie in the trimmed face (boundary included)?"""
        if not len(uv):
            return np.zeros(0, dtype=bool)
        nuv = self._normalise_uv(fd, uv)
        u0, du, v0, dv = fd.uv_box
        wrapped = np.column_stack([u0 + nuv[:, 0] * du, v0 + nuv[:, 1] * dv])
        inside = np.zeros(len(uv), dtype=bool)
        for ring in fd.rings:
            inside ^= ring_contains(ring, nuv)
        if fd.ring_tree is not None:
            near = fd.ring_tree.query(nuv, k=1, distance_upper_bound=_BAND)[0] < _BAND
            # UV coincidence at 1e-7 of the diagonal: OCC's Precision::Confusion relative to part size
            tol = 1e-7 * self.diagonal
            for i in np.flatnonzero(near):
                state = BRepClass_FaceClassifier(fd.face, gp_Pnt2d(*wrapped[i]), tol).State()
                inside[i] = state in (TopAbs_IN, TopAbs_ON)
        return inside

    # ------------------------------------------------------------------ projections
    def _critical_points(self, fd: _Face, p):
        """Critical points of the distance from ``p`` to the untrimmed surface, nearest first.

        Returns a list of (uv (n, 2), foot (n, 3), normal (n, 3)) with the geometric normal (not yet
        multiplied by ``fd.sense``).
        """
        if fd.kind not in _ANALYTIC:
            raise AssertionError(fd.kind)
        o, x, y, z = fd.frame
        d = p - o
        lx, ly, lz = d @ x, d @ y, d @ z
        if fd.kind == "plane":
            foot = o + lx[:, None] * x + ly[:, None] * y
            n = np.broadcast_to(z, p.shape)
            return [(np.column_stack([lx, ly]), foot, n)]
        u = np.arctan2(ly, lx)
        rho = np.hypot(lx, ly)
        out = []
        if fd.kind == "sphere":
            (radius,) = fd.radii
            v = np.arctan2(lz, rho)
            er = np.cos(u)[:, None] * x + np.sin(u)[:, None] * y
            nrm = np.cos(v)[:, None] * er + np.sin(v)[:, None] * z
            # The foot and its antipode (u + π, -v): the two critical points on a sphere.
            out = [(np.column_stack([u, v]), o + radius * nrm, nrm),
                   (np.column_stack([u + np.pi, -v]), o - radius * nrm, -nrm)]
        for flip in (1.0, -1.0) if fd.kind != "sphere" else ():
            uu = u if flip > 0 else u + np.pi
            er = np.cos(uu)[:, None] * x + np.sin(uu)[:, None] * y
            r = flip * rho  # radial coordinate of p in the half-plane of angle uu
            if fd.kind == "cylinder":
                (radius,) = fd.radii
                foot = o + radius * er + lz[:, None] * z
                out.append((np.column_stack([uu, lz]), foot, er))
            elif fd.kind == "cone":
                radius, alpha = fd.radii
                sa, ca = math.sin(alpha), math.cos(alpha)
                vv = (r - radius) * sa + lz * ca
                foot = o + (radius + vv * sa)[:, None] * er + (vv * ca)[:, None] * z
                nrm = ca * er - sa * z
                out.append((np.column_stack([uu, vv]), foot, np.broadcast_to(nrm, p.shape) if nrm.ndim == 1 else nrm))
            elif fd.kind == "torus":
                major, minor = fd.radii
                for side in (1.0, -1.0):
                    vv = np.arctan2(side * lz, side * (r - major))
                    nrm = np.cos(vv)[:, None] * er + np.sin(vv)[:, None] * z
                    foot = o + major * er + minor * nrm
                    out.append((np.column_stack([uu, vv]), foot, nrm))
        dist = np.stack([np.linalg.norm(p - f, axis=1) for _, f, _ in out], axis=1)
        order = np.argsort(dist, axis=1, kind="stable")
        # Reorder per point so that entry 0 is the nearest critical point.
        uvs = np.stack([c[0] for c in out], axis=1)
        feet = np.stack([c[1] for c in out], axis=1)
        nrms = np.stack([np.broadcast_to(c[2], p.shape) for c in out], axis=1)
        rows = np.arange(len(p))[:, None]
        uvs, feet, nrms = uvs[rows, order], feet[rows, order], nrms[rows, order]
        return [(uvs[:, j], feet[:, j], nrms[:, j]) for j in range(len(out))]

    def _geometric_normal(self, fd: _Face, q, *, uv=None):
        """Geometric normal at points ``q`` on the surface (uv needed for non-analytic faces)."""
        if fd.kind in _ANALYTIC:
            return self._critical_points(fd, q)[0][2]
        if uv is None:
            uv = np.array([_xy(fd.sas.ValueOfUV(gp_Pnt(*qi), 1e-9 * self.diagonal)) for qi in q])
        out = np.empty_like(q)
        for i, (u, v) in enumerate(uv):
            p, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
            fd.adaptor.D1(u, v, p, du, dv)
            out[i] = _xyz(du.Crossed(dv))
        norm = np.linalg.norm(out, axis=1, keepdims=True)
        return out / np.where(norm > 0, norm, 1.0)

    def _generic_projection(self, fd: _Face, p, uv0):
        preci = 1e-9 * self.diagonal
        uv = np.empty((len(p), 2))
        for i, (pi, (u0, v0)) in enumerate(zip(p, uv0)):
            uv[i] = _xy(fd.sas.NextValueOfUV(gp_Pnt2d(u0, v0), gp_Pnt(*pi), preci))
        foot = np.empty_like(p)
        nrm = np.empty_like(p)
        for i, (u, v) in enumerate(uv):
            q, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
            fd.adaptor.D1(u, v, q, du, dv)
            foot[i] = _xyz(q)
            nrm[i] = _xyz(du.Crossed(dv))
        norm = np.linalg.norm(nrm, axis=1, keepdims=True)
        return [(uv, foot, nrm / np.where(norm > 0, norm, 1.0))]

    def _face_query(self, index: int, p, *, uv0=None):
        """Unsigned distance, nearest point and outward normal there: (n,), (n, 3), (n, 3)."""
        best, foot, nrm, later = self._face_query_deferred(index, p, uv0=uv0)
        if len(later):
            nrm[later] = self._edge_normals(index, foot[later])
        return best, foot, nrm

    def _edge_normals(self, index: int, foot):
        """Outward normal at feet ``foot`` (k, 3) on face ``index``'s boundary."""
        fd = self._faces[index]
        return self._geometric_normal(fd, foot) * fd.sense

    def _face_query_deferred(self, index: int, p, *, uv0=None):
        """:meth:`_face_query`, but the normals at boundary feet of a non-analytic face (one surface projection
        each) are left for the caller: (n,), (n, 3), (n, 3), and the rows ``later`` (k,) whose normal is unset."""
        fd = self._faces[index]
        n = len(p)
        later = np.empty(0, dtype=np.int64)
        if n == 0:
            return np.empty(0), np.empty((0, 3)), np.empty((0, 3)), later
        if fd.kind in _ANALYTIC:
            cands = self._critical_points(fd, p)
        else:
            if uv0 is None:
                if not len(fd.nodes):
                    return np.full(n, np.nan), np.full((n, 3), np.nan), np.zeros((n, 3)), later
                j = cKDTree(fd.nodes).query(p)[1]
                uv0 = fd.uv[j]
            cands = self._generic_projection(fd, p, uv0)
        best = np.full(n, np.inf)
        foot = np.zeros((n, 3))
        nrm = np.zeros((n, 3))
        pending = np.arange(n)
        need_edges = None
        edge_d = np.full(n, np.inf)
        for uv, f, nv in cands:
            if not len(pending):
                break
            if need_edges is not None:
                # A critical point farther than the boundary loses to it whether it lies on the face or not: it
                # is not classified (the exact classifier near the boundary was most of a query's time).
                pending = pending[~(np.linalg.norm(p[pending] - f[pending], axis=1) > edge_d[pending])]
            ok = self._inside(fd, uv[pending])
            sel = pending[ok]
            d = np.linalg.norm(p[sel] - f[sel], axis=1)
            best[sel], foot[sel], nrm[sel] = d, f[sel], nv[sel]
            pending = pending[~ok]
            if need_edges is None:
                # The nearest critical point is off the face: the boundary competes with the others.
                need_edges = pending.copy()
                if len(need_edges) and fd.edges:
                    de, fe = edges_distance(fd.edges, p[need_edges])
                    edge_d[need_edges] = de
        if len(need_edges) and fd.edges:
            better = de < best[need_edges]
            sel = need_edges[better]
            best[sel], foot[sel] = de[better], fe[better]
            if len(sel) and fd.kind in _ANALYTIC:
                nrm[sel] = self._geometric_normal(fd, foot[sel])
            elif len(sel):
                later = sel
        best[~np.isfinite(best)] = np.nan
        return best, foot, nrm * fd.sense, later

    def face_signed_distance(self, index: int, points, *, uv0=None):
        """Exact signed distance from ``points`` to face ``index`` (trimmed).

        Parameters
        ----------
        index : int
            Face index.
        points : (n, 3) float
        uv0 : (n, 2) float, optional
            Start (u, v) for non-analytic surfaces; default: UV of the nearest tessellation node.

        Returns
        -------
        signed : (n,) float
            Distance, positive on the outward side of the face.
        foot : (n, 3) float
            Nearest point of the face.
        """
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        dist, foot, nrm = self._face_query(index, p, uv0=uv0)
        sign = np.sign(np.einsum("ij,ij->i", p - foot, nrm))
        return np.where(sign < 0, -dist, dist), foot

    # ------------------------------------------------------------------ public queries
    def signed_distance(self, points, *, neighbours: int = 16,
                        progress: Callable[[int, int, str], None] | None = None):
        """Exact signed distance from each point to the nearest face of the B-rep.

        Parameters
        ----------
        points : (n, 3) float
        neighbours : int, keyword-only
            Samples looked at per point to find candidate faces.
        progress : callable(done, total, what), optional
            Told the points measured ("mesh points measured"), a chunk at a time; the results do not depend on it.

        Returns
        -------
        signed : (n,) float
            Positive outside (on the side of the outward normal of the nearest face).
        face : (n,) int64
            Index of the nearest face.
        foot : (n, 3) float
            Nearest point on the B-rep.
        """
        p = np.asarray(points, dtype=float)
        if p.ndim != 2 or p.shape[1] != 3:
            raise InputError(f"points: expected an (n, 3) array, got shape {p.shape}")
        chunk = _QUERY_CHUNK if progress is None else _PROGRESS_CHUNK
        if len(p) > chunk:  # bounded memory on million-vertex meshes: (n, k) candidate arrays per chunk
            parts = []
            for s in range(0, len(p), chunk):
                parts.append(self.signed_distance(p[s : s + chunk], neighbours=neighbours))
                if progress is not None:
                    progress(min(s + chunk, len(p)), len(p), "mesh points measured")
            return tuple(np.concatenate(x) for x in zip(*parts))
        n = len(p)
        k = int(min(neighbours, len(self._sample_points)))
        dist, idx = self._tree.query(p, k=k)
        dist, idx = dist.reshape(n, k), idx.reshape(n, k)
        faces = self._sample_face[idx]
        # A face whose nearest sample is farther than the nearest sample overall + 2 h cannot hold
        # the nearest point (h: sample spacing, an upper bound on the gap between samples).
        keep = dist <= dist[:, :1] + 2.0 * self.spacing
        nf = len(self._faces)
        key = (np.repeat(np.arange(n), k) * nf + faces.ravel())[keep.ravel()]
        # For each (point, face) pair: the first (nearest) sample of that face, for its UV.
        first_pos = np.repeat(np.arange(n) * k, k)[keep.ravel()] + np.tile(np.arange(k), n)[keep.ravel()]
        key, pos = np.unique(key, return_index=True)
        sample_of_pair = idx.ravel()[first_pos[pos]]
        pair_point, pair_face = key // nf, key % nf

        best = np.full(n, np.inf)
        nearest = np.full(n, -1, dtype=np.int64)
        foot = np.full((n, 3), np.nan)
        normal = np.zeros((n, 3))
        tol = 1e-9 * self.diagonal
        order = np.argsort(pair_face, kind="stable")
        bounds = np.searchsorted(pair_face[order], np.arange(nf + 1))
        # The distances and feet decide the nearest face; the normals only the sign. They are summed in a second
        # pass, once it is known which faces' normals count, so that a boundary foot's normal (a surface
        # projection each on a B-spline face) is only computed where it does.
        steps = []
        for f in range(nf):
            sel = order[bounds[f] : bounds[f + 1]]
            if not len(sel):
                continue
            pts = pair_point[sel]
            a, ft, nv, later = self._face_query_deferred(f, p[pts], uv0=self._sample_uv[sample_of_pair[sel]])
            # Where faces meet (an edge or vertex is the nearest point) the sign comes from the sum
            # of their normals, the pseudo-normal: one face's normal is wrong at an obtuse edge.
            tie = (np.abs(a - best[pts]) <= tol) & (np.linalg.norm(ft - foot[pts], axis=1) <= tol)
            better = (a < best[pts] - tol) | ~np.isfinite(best[pts])
            i = pts[better]
            best[i], nearest[i], foot[i] = a[better], f, ft[better]
            steps.append((f, pts, ft, nv, later, tie, better))
        last = np.full(n, -1, dtype=np.int64)  # the step of each point's last "better" face
        for s, (f, pts, _, _, _, _, better) in enumerate(steps):
            last[pts[better]] = s
        for s, (f, pts, ft, nv, later, tie, better) in enumerate(steps):
            tie &= s > last[pts]
            better &= s == last[pts]
            if len(later):
                later = later[tie[later] | better[later]]
                if len(later):
                    nv[later] = self._edge_normals(f, ft[later])
            normal[pts[tie]] += nv[tie]
            normal[pts[better]] = nv[better]
        sign = np.sign(np.einsum("ij,ij->i", p - foot, normal))
        return np.where(sign < 0, -best, best), nearest, foot

    def surface_samples(self, count: int, *, rng=None, nodes: bool = True):
        """Points exactly on the faces: every tessellation node (unless ``nodes`` is False) plus ``count``
        area-uniform points. The nodes crowd at edges and on curved faces: without them the points are an
        area-uniform sample (their percentiles are shares of the area).

        Returns
        -------
        points : (s, 3) float
        face : (s,) int64
        """
        rng = np.random.default_rng(1) if rng is None else rng
        areas = self._triangle_areas()
        total = float(sum(a.sum() for a in areas))
        pts, fid = [], []
        for fd, area in zip(self._faces, areas):
            if nodes:
                pts.append(fd.nodes)
                fid.append(np.full(len(fd.nodes), fd.index))
            k = int(round(count * area.sum() / total)) if total > 0 else 0
            p, uv, _ = self._triangle_samples(fd, area, k, rng)
            if len(p):
                # Samples on the triangles lie within the deflection; move them onto the face.
                _, on, _, _ = self._face_query_deferred(fd.index, p, uv0=uv)  # the feet only
                pts.append(on)
                fid.append(np.full(len(on), fd.index))
        if not pts:  # no face could be triangulated: nothing to sample, which the caller must report
            return np.empty((0, 3)), np.empty(0, dtype=np.int64)
        return np.vstack(pts), np.concatenate(fid).astype(np.int64)


def _xy(p2) -> tuple[float, float]:
    """The coordinates of a ``gp_Pnt2d`` (one binding call, not two: the same floats)."""
    return p2.Coord()
