"""Holes: small missing patches of a scan (occlusion), found from the mesh's boundary loops and closed over.

A boundary loop is a hole to close when its fill is small against the surface (:data:`HOLE_AREA_SHARE` of the
mesh's area) and either the surface goes on around it on all sides (the triangle outside each of its edges reaches
outward in the loop's own plane, :data:`SURROUND_REACH`, as round a cut in a surface) or it is small against the part
(:data:`SMALL_EXTENT`: a hole wrapped round an edge or a shaft). The rim of a scan that never saw a side (a box
without its top) turns away from the plane of its loop and is as large as the part: it stays open (a shell is the
right answer there).

A hole is filled with triangles of the loop's own edge length: a lattice of that spacing inside the loop projected on
its plane (smoothed until it does not cross itself), triangulated with the loop (Delaunay), placed as the membrane
the rim spans and, where the surroundings are a height field over the plane, lifted onto a quadric fitted to the
rings of vertices around the loop, the rim's misfit carried inward harmonically so the patch meets the rim exactly. New vertices and triangles
come after the mesh's own (its arrays are a prefix of the result's), so the input's triangles keep their indices (a
part whose closed surface encloses negative volume, as an open mesh wound inward does, is turned round as a whole).
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.linalg import spsolve

from ._types import Mesh

__all__ = ["HoleReport", "boundary_loops", "close_holes"]

log = logging.getLogger(__name__)

#: Largest fill closed, as a share of the mesh's area: an occluded scan misses patches of 1-3 % of the area (issue 23),
#: a side the scanner never saw (the face a part stood on) is a face of its own, a sixth of a cube's area.
HOLE_AREA_SHARE = 0.05

#: Least median outward reach of the triangles outside a loop's edges, in the loop's plane, per edge length: an
#: equilateral ring in the plane reaches 0.87, one tilted 45° across a crease 0.61; a wall below a missing top turns
#: from the plane by ~90° and reaches ~0 (a quarter: a ring turned by more than ~73° is not around a hole).
SURROUND_REACH = 0.25

#: Largest extent, per the part's diagonal, of a loop closed although its rim turns away from its plane (a hole
#: wrapped round an edge, a rib or a shaft turns away like a side never scanned): an occluded patch of 1-3 % of a
#: cube's area spans 0.1-0.2 of its diagonal, the open top of a box 0.8.
SMALL_EXTENT = 0.25

#: Most area a cover may have per area its rim encloses on its plane: a half turn round a shaft is π/2 times, a
#: crease's two faces √2; a cover beyond three times bulges out of the surface, and the hole is left open.
COVER_BULGE = 3.0

#: Rings of vertices around a loop that the quadric is fitted to: three edge lengths out hold ~3 times the loop's
#: vertices, enough to pin six coefficients against noise, and stay on the faces next to the hole.
FIT_RINGS = 3

#: Smoothing steps (each a quarter of the way to the neighbours' mean) a folded projection of a rim may take to unfold:
#: noise folds it over a few edges, which a few steps undo; a rim still folded after them is wrapped round the part.
PARAMETER_SMOOTHING = 30

#: Share of the triangles around a loop that face the loop's side of its plane for the patch to continue their
#: quadric: noise of the order of the edge length flips a few; a ring wrapped round an edge or shaft flips many.
HEIGHT_FIELD_SHARE = 0.95

#: The share of a plane's misfit (RMS) a quadric must take off to be kept: on a flat face noise alone lets its three
#: more coefficients take ~3/(2n) of it (n ≥ 12 points: an eighth at most), on a curved one the plane's misfit is the sag.
CURVED_GAIN = 0.3

#: Vertices of a smooth region around a hole whose surface is extended across it: twice the six coefficients of its
#: quadric.
REGION_VERTICES = 12

#: Neighbouring normals on one face turn by noise only: this many times their median turn is a crease.
CREASE_NOISE = 3.0

#: The least turn between neighbouring normals taken for a crease (radians, 20°): a blend's normals turn by less
#: over a vertex, however clean the mesh.
CREASE_LEAST = float(np.radians(20.0))

#: A region's surface is not extended along a hole's normal that runs within ~78° of its plane (cos < 0.2): the
#: step onto it grows as 1/cos, and a wall beside a hole is reached through its neighbour's extension.
GRAZING = 0.2

#: A crease vertex no nearer an edge's end than this share of the edge (a thinner sliver's normal turns with noise).
CREASE_END = 0.1

#: Lattice points kept this many edge lengths inside the loop: the Delaunay circle on a rim edge (its diameter) then
#: holds no lattice point, so the triangulation keeps every rim edge.
RIM_CLEARANCE = 0.6


@dataclass(frozen=True)
class HoleReport:
    """What :func:`close_holes` found and closed.

    Attributes
    ----------
    loops : int
        Boundary loops of the mesh.
    closed : int
        Those closed over.
    added : (m',) bool
        Per triangle of the closed mesh: True where it was added (they come after the input's triangles).
    input_vertices : int
        Vertices of the input mesh (the closed mesh's first ones; the rest were added).
    area_added : float
        Area of the added triangles.
    """

    loops: int
    closed: int
    added: np.ndarray
    input_vertices: int
    area_added: float

    def to_json(self, area: float) -> dict:
        """Counts and the added area, also as a percentage of ``area`` (the input's)."""
        return {"loops": int(self.loops), "closed": int(self.closed), "left_open": int(self.loops - self.closed),
                "triangles_added": int(self.added.sum()), "area_added": float(self.area_added),
                "area_added_pct": 100.0 * float(self.area_added) / area if area > 0 else 0.0}


def boundary_loops(mesh: Mesh) -> list[np.ndarray]:
    """The mesh's boundary loops, each as vertex indices in the order of its triangles' edges (a loop through a vertex
    twice is split there into simple ones); in order of their least vertex."""
    F = mesh.faces
    once = mesh.edge_face_count[mesh.face_edges] == 1  # (m, 3): edge i of a triangle is on the boundary
    if not once.any():
        return []
    tail = F[once]
    head = np.roll(F, -1, axis=1)[once]
    out: dict[int, list[int]] = {}
    for a, b in sorted(zip(tail.tolist(), head.tolist())):
        out.setdefault(a, []).append(b)
    loops = []
    for start in sorted(out):
        while out[start]:
            walk = [start]
            while True:
                nxt = out[walk[-1]].pop(0) if out.get(walk[-1]) else None
                if nxt is None or nxt == start:
                    break
                walk.append(nxt)
            if nxt == start:
                loops.extend(_simple(walk))
    return sorted((np.asarray(x, dtype=np.int64) for x in loops if len(x) >= 3), key=lambda x: int(x.min()))


def _simple(walk: list[int]) -> list[list[int]]:
    """A closed walk split at its repeated vertices into simple cycles."""
    out: list[list[int]] = []
    stack: list[int] = []
    where: dict[int, int] = {}
    for v in walk:
        if v in where:  # a cycle closed at v: cut it off the stack
            i = where[v]
            out.append(stack[i:])
            for u in stack[i + 1:]:
                where.pop(u, None)
            stack = stack[: i + 1]
        else:
            where[v] = len(stack)
            stack.append(v)
    out.append(stack)
    return out


def _frame(points: np.ndarray, order_sign: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Centre, axes (e1, e2, n) of a loop's plane, with n along its vector area times ``order_sign``, and that area."""
    c = points.mean(axis=0)
    p = points - c
    vec = 0.5 * np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0)
    area = float(np.linalg.norm(vec))
    n = order_sign * vec / max(area, 1e-300)
    helper = [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0]  # an axis not near n: the cross stays long
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1)
    return c, np.stack([e1, np.cross(n, e1), n]), area


def _surrounded(mesh: Mesh, loop: np.ndarray, n: np.ndarray) -> float:
    """Median reach, per edge length, of the triangle outside each loop edge outward in the plane normal to ``n``."""
    V, F = mesh.vertices, mesh.faces
    a, b = loop, np.roll(loop, -1)
    key = {(int(x), int(y)): i for i, (x, y) in enumerate(zip(a, b))}
    third = np.zeros(len(loop), dtype=np.int64)
    for f in np.unique(np.concatenate([mesh.vertex_faces[int(v)] for v in loop])):
        t = F[f]
        for k in range(3):
            i = key.get((int(t[k]), int(t[(k + 1) % 3])))
            if i is not None:
                third[i] = t[(k + 2) % 3]
    e = V[b] - V[a]
    length = np.linalg.norm(e, axis=1)
    out = np.cross(n, e)  # the fill runs b → a with its interior on its left: the mesh is on the right of a → b
    out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)
    reach = np.einsum("ij,ij->i", V[third] - 0.5 * (V[a] + V[b]), out) / np.maximum(length, 1e-300)
    return float(np.median(reach))


def _adjacency(mesh: Mesh) -> csr_matrix:
    """The vertices' adjacency matrix (1 between the ends of every edge)."""
    E = mesh.edges_unique
    n = len(mesh.vertices)
    return csr_matrix((np.ones(2 * len(E)), (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])), shape=(n, n))


def _rings(adj: csr_matrix, loop: np.ndarray, rings: int) -> np.ndarray:
    """Vertices within ``rings`` edges of the loop (the loop's own included), by the adjacency ``adj``."""
    seen = np.zeros(adj.shape[0], dtype=bool)
    seen[loop] = True
    front = seen.copy()
    for _ in range(rings):
        front = (adj @ front.astype(float) > 0) & ~seen
        seen |= front
    return np.flatnonzero(seen)


def _quadric(xy: np.ndarray, z: np.ndarray):
    """Least-squares z = quadric(x, y), or the plane where the quadric takes less than :data:`CURVED_GAIN` of the
    plane's misfit off (a flat face's noise: its extra coefficients would only bend the extension)."""
    x, y = xy[:, 0], xy[:, 1]
    plane = np.stack([np.ones_like(x), x, y], axis=1)
    coef = np.linalg.lstsq(plane, z, rcond=None)[0]
    if len(x) >= 12:  # twice the quadric's six coefficients
        full = np.c_[plane, x * x, x * y, y * y]
        quad = np.linalg.lstsq(full, z, rcond=None)[0]
        if np.linalg.norm(full @ quad - z) < (1.0 - CURVED_GAIN) * np.linalg.norm(plane @ coef - z):
            coef = quad

    def q(p: np.ndarray) -> np.ndarray:
        u, v = p[:, 0], p[:, 1]
        basis = [np.ones_like(u), u, v] + ([u * u, u * v, v * v] if len(coef) == 6 else [])
        return np.stack(basis, axis=1) @ coef

    return q


def _lattice_disk(loop2: np.ndarray, h: float, taken: set) -> tuple[np.ndarray, np.ndarray] | None:
    """Interior points (a triangular lattice of spacing ``h``) and triangles of the polygon ``loop2`` (counter-
    clockwise); triangles index ``[loop2; points]``, counter-clockwise. None if they do not make a disk on the loop.
    A chord between loop vertices that ``taken`` holds (pairs ``(i, j)``, i < j: an edge the mesh has outside the loop)
    is split at its midpoint: kept, it would be a third triangle's edge."""
    import shapely
    from scipy.spatial import Delaunay

    poly = shapely.Polygon(loop2)
    if not poly.is_valid or poly.area <= 0:
        return None
    lo, hi = loop2.min(axis=0), loop2.max(axis=0)
    ys = np.arange(lo[1], hi[1] + h, h * np.sqrt(3) / 2)  # a triangular lattice: rows h·√3/2 apart, every other shifted
    rows = [np.arange(lo[0] + (0.5 * h if i % 2 else 0.0), hi[0] + h, h) for i in range(len(ys))]
    pts = np.concatenate([np.c_[xs, np.full(len(xs), y)] for xs, y in zip(rows, ys)])
    if len(pts):
        inside = shapely.contains_xy(poly, pts[:, 0], pts[:, 1])
        pts = pts[inside]
        ring = shapely.LinearRing(loop2)
        pts = pts[shapely.distance(ring, shapely.points(pts)) >= RIM_CLEARANCE * h]
    allp = np.vstack([loop2, pts])
    tri = Delaunay(allp).simplices
    cen = allp[tri].mean(axis=1)
    tri = tri[shapely.contains_xy(poly, cen[:, 0], cen[:, 1])]
    d = allp[tri]
    cross = (d[:, 1, 0] - d[:, 0, 0]) * (d[:, 2, 1] - d[:, 0, 1]) - (d[:, 1, 1] - d[:, 0, 1]) * (d[:, 2, 0] - d[:, 0, 0])
    tri = np.where((cross < 0)[:, None], tri[:, [0, 2, 1]], tri)
    if not _is_disk(tri, len(loop2), len(allp)):
        return None
    for _ in range(len(taken)):
        allp, tri, split = _split_chord(allp, tri, len(loop2), taken)
        if not split:
            break
    return allp[len(loop2):], tri


def _split_chord(p: np.ndarray, tri: np.ndarray, n_loop: int, taken: set) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(p, tri)`` with the first chord of ``taken`` the triangles use split at its midpoint (its two triangles made
    four), and whether there was one."""
    for t, k in np.ndindex(len(tri), 3):
        a, b = int(tri[t, k]), int(tri[t, (k + 1) % 3])
        if a < n_loop and b < n_loop and (min(a, b), max(a, b)) in taken:
            other = np.flatnonzero((tri == b).any(axis=1) & (tri == a).any(axis=1) & (np.arange(len(tri)) != t))
            m = len(p)
            p = np.vstack([p, 0.5 * (p[a] + p[b])])
            new = []
            for u in [t, *other.tolist()]:
                row = tri[u].tolist()
                i = next(j for j in range(3) if {row[j], row[(j + 1) % 3]} == {a, b})
                x, y, z = row[i], row[(i + 1) % 3], row[(i + 2) % 3]
                new += [[x, m, z], [m, y, z]]
            keep = np.ones(len(tri), dtype=bool)
            keep[[t, *other.tolist()]] = False
            return p, np.vstack([tri[keep], np.asarray(new)]), True
    return p, tri, False


def _is_disk(tri: np.ndarray, n_loop: int, n_all: int) -> bool:
    """True if the triangles make a disk whose boundary is the loop 0 → 1 → … → n_loop-1 (counter-clockwise)."""
    if len(tri) != n_loop + 2 * (n_all - n_loop) - 2:  # Euler: a disk's triangles from its boundary and inner vertices
        return False
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    key = directed[:, 0] * n_all + directed[:, 1]
    if len(np.unique(key)) != len(key):
        return False
    rev = directed[:, 1] * n_all + directed[:, 0]
    lone = directed[~np.isin(key, rev)]  # edges without their opposite: the disk's boundary
    want = np.c_[np.arange(n_loop), (np.arange(n_loop) + 1) % n_loop]
    return len(lone) == n_loop and set(map(tuple, lone.tolist())) == set(map(tuple, want.tolist()))


def _harmonic(tri: np.ndarray, n_loop: int, n_all: int, rim: np.ndarray) -> np.ndarray:
    """Values on every vertex of the disk: ``rim`` on the loop, the graph-harmonic interpolation inside."""
    if n_all == n_loop:
        return rim
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    A = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_all, n_all)).tocsr()
    A = ((A + A.T) > 0).astype(float)
    deg = np.asarray(A.sum(axis=1)).ravel()
    inner = np.arange(n_loop, n_all)
    L = csr_matrix(-A[inner][:, inner] + csr_matrix((deg[inner], (np.arange(len(inner)), np.arange(len(inner))))))
    rhs = A[inner][:, :n_loop] @ rim
    return np.r_[rim, np.atleast_1d(spsolve(L.tocsc(), rhs))]


def _parameter_polygons(xy: np.ndarray) -> list[np.ndarray]:
    """Simple counter-clockwise polygons to triangulate a loop projected on its plane as ``xy`` in, best first: the
    projection itself, smoothed along the loop until it no longer crosses itself (noise of the order of the edge
    length folds a rim's projection here and there), then a circle of the loop's length (convex: its Delaunay
    triangulation keeps every rim edge, for a loop wrapped round an edge or a shaft or too concave for the lattice)."""
    import shapely

    out = []
    p = xy
    for _ in range(PARAMETER_SMOOTHING):
        if shapely.Polygon(p).is_valid and _signed_area(p) > 0:
            out.append(p)
            break
        p = 0.5 * p + 0.25 * (np.roll(p, 1, axis=0) + np.roll(p, -1, axis=0))
    step = np.linalg.norm(xy - np.roll(xy, 1, axis=0), axis=1)
    t = 2 * np.pi * np.cumsum(step) / step.sum()
    # the circle's area as the loop's own (on its plane): a jagged or wrapped rim is long for what it encloses, and a
    # circle of its length would hold that many times the lattice points the hole needs
    radius = min(step.sum() / (2 * np.pi), np.sqrt(max(abs(_signed_area(xy)), np.median(step) ** 2) / np.pi))
    return out + [radius * np.c_[np.cos(t), np.sin(t)]]


def _signed_area(p: np.ndarray) -> float:
    return 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def _smooth_regions(mesh: Mesh, ring: np.ndarray, adj: csr_matrix) -> list[np.ndarray]:
    """The ring's vertices split at creases into the smooth regions of at least :data:`REGION_VERTICES` (largest
    first, at most three): adjacent vertices join when their normals turn less than :data:`CREASE_NOISE` times the
    ring's median turn between neighbours (what noise turns them on one face), and at least :data:`CREASE_LEAST`."""
    from scipy.sparse.csgraph import connected_components

    F = mesh.faces
    faces = np.unique(np.concatenate([mesh.vertex_faces[int(v)] for v in ring]))
    acc = np.zeros((len(mesh.vertices), 3))
    np.add.at(acc, F[faces].ravel(), np.repeat(mesh.face_cross[faces], 3, axis=0))  # area-weighted
    sub = adj[ring][:, ring]
    nrm = acc[ring] + sub @ acc[ring]  # with their neighbours': one face's noise averaged out
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    i, j = sub.nonzero()
    up = i < j
    i, j = i[up], j[up]
    if not len(i):
        return []
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", nrm[i], nrm[j]), -1.0, 1.0))
    limit = max(CREASE_LEAST, CREASE_NOISE * float(np.median(turn)))
    keep = turn < limit
    n, lab = connected_components(csr_matrix((np.ones(int(keep.sum())), (i[keep], j[keep])), shape=(len(ring),) * 2),
                                  directed=False)
    size = np.bincount(lab, minlength=n)
    big = [r for r in np.argsort(-size, kind="stable") if size[r] >= REGION_VERTICES][:3]
    return [ring[lab == r] for r in big]


class _Patch:
    """A quadric height field over the plane of a smooth region's points, its normal along ``outward``."""

    def __init__(self, points: np.ndarray, outward: np.ndarray):
        self.c = points.mean(axis=0)
        _, _, vt = np.linalg.svd(points - self.c, full_matrices=False)
        n = vt[2] if vt[2] @ outward >= 0 else -vt[2]
        self.axes = np.stack([vt[0], np.cross(n, vt[0]), n])
        local = (points - self.c) @ self.axes.T
        self.q = _quadric(local[:, :2], local[:, 2])

    def offset(self, p: np.ndarray) -> np.ndarray:
        """Signed height of ``p`` over the surface along its normal (> 0 outside)."""
        local = (p - self.c) @ self.axes.T
        return local[:, 2] - self.q(local[:, :2])

    def along(self, p: np.ndarray, n: np.ndarray) -> np.ndarray:
        """The steps t that take each ``p + t n`` onto the surface (inf where n runs along it)."""
        cos = float(n @ self.axes[2])
        if abs(cos) < GRAZING:
            return np.full(len(p), np.inf)
        t = np.zeros(len(p))
        for _ in range(8):  # the quadric's slope is small in its own frame: a few fixed-point steps converge
            t -= self.offset(p + t[:, None] * n) / cos
        return t


class _Envelope:
    """The surface the smooth regions around a hole make when extended across it: their lower envelope along the
    hole's normal ``n`` where every region's points lie below the others' surfaces (a convex crease or corner), the
    upper where above (a concave one)."""

    def __init__(self, patches: list[_Patch], n: np.ndarray, convex: bool):
        self.patches, self.n, self.convex = patches, n, convex

    @classmethod
    def of(cls, mesh: Mesh, regions: list[np.ndarray], n: np.ndarray) -> _Envelope | None:
        """The envelope of ``regions`` (index arrays of vertices), None where the creases are mixed."""
        V = mesh.vertices
        outward = [float(np.sign(n @ np.mean(mesh.face_normals[np.concatenate(
            [mesh.vertex_faces[int(v)] for v in r[:50]])], axis=0))) or 1.0 for r in regions]
        patches = [_Patch(V[r], o * n) for r, o in zip(regions, outward)]
        below = [np.median(patches[b].offset(V[regions[a]])) < 0 for a in range(len(regions))
                 for b in range(len(regions)) if a != b]
        if not (all(below) or not any(below)):
            return None
        return cls(patches, n, all(below))

    def steps(self, p: np.ndarray) -> np.ndarray:
        """(regions, len(p)): the step along n onto each region's surface (±inf where n runs along it)."""
        t = np.stack([q.along(p, self.n) for q in self.patches])
        return t if self.convex else np.where(np.isinf(t), -np.inf, t)

    def pick(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The step onto the envelope (0 where no surface is reached) and the region it lands on, from ``steps``."""
        side = t.argmin(axis=0) if self.convex else t.argmax(axis=0)
        best = t[side, np.arange(t.shape[1])]
        return np.where(np.isfinite(best), best, 0.0), side


def _split_at_creases(env: _Envelope, P: np.ndarray, tri: np.ndarray, n_loop: int, side: np.ndarray):
    """``(P, tri)`` with every edge whose ends lie on different regions' surfaces split where the two surfaces cross
    (the crease), its triangles split with it: no triangle of the cover then spans a crease. The rim's own edges
    (consecutive loop vertices, shared with the mesh) are not split."""
    a, b = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]).T
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    rim = (hi < n_loop) & np.isin(hi - lo, [1, n_loop - 1])
    cut = (side[a] != side[b]) & ~rim
    keys = np.unique(lo[cut] * len(P) + hi[cut])
    if not len(keys):
        return P, tri
    u, v = keys // len(P), keys % len(P)
    tu, tv = env.steps(P[u]), env.steps(P[v])
    k = np.arange(len(u))
    du = tu[side[u], k] - tu[side[v], k]
    dv = tv[side[u], k] - tv[side[v], k]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(np.isfinite(du - dv) & (du != dv), du / (du - dv), 0.5)
    # no nearer an end than a tenth of the edge: a thinner sliver's normal would turn with the noise
    lam = np.clip(np.nan_to_num(lam, nan=0.5), CREASE_END, 1.0 - CREASE_END)
    x = P[u] + lam[:, None] * (P[v] - P[u])
    x += env.pick(env.steps(x))[0][:, None] * env.n
    mid = dict(zip(keys.tolist(), range(len(P), len(P) + len(keys))))
    out = []
    for t in tri.tolist():
        m = [mid.get(min(t[i], t[(i + 1) % 3]) * len(P) + max(t[i], t[(i + 1) % 3])) for i in range(3)]
        out.extend(_split_triangle(t, m))
    return np.vstack([P, x]), np.asarray(out, dtype=np.int64)


def _split_triangle(t: list[int], m: list[int | None]) -> list[list[int]]:
    """Triangle ``t`` (i, j, k) split at the new vertices ``m`` of its edges ij, jk, ki (None: not split), in its
    orientation."""
    count = sum(x is not None for x in m)
    if count == 0:
        return [t]
    if count == 3:
        (i, j, k), (x3, y3, z3) = t, [int(q) for q in m if q is not None]
        return [[i, x3, z3], [x3, j, y3], [z3, y3, k], [x3, y3, z3]]
    r = next(r for r in range(3) if (m[r] is not None) and (count == 1 or m[(r + 2) % 3] is None))
    i, j, k = t[r], t[(r + 1) % 3], t[(r + 2) % 3]
    x, y = m[r], m[(r + 1) % 3]
    assert x is not None
    if count == 1:
        return [[i, x, k], [x, j, k]]
    assert y is not None
    return [[x, j, y], [i, x, y], [i, y, k]]


def _faired(mesh: Mesh, adj: csr_matrix, fill_loop: np.ndarray, tri: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The cover's vertices ``P`` (rim first) with the inner ones placed so that the umbrella Laplacian of the cover
    and its rim is least (thin plate, the rim and the ring of mesh vertices outside it held): the cover leaves the rim
    along the surface's tangents and bends as it does, where neither a height field nor crease planes describe it."""
    n_loop, n_all = len(fill_loop), len(P)
    if n_all == n_loop:
        return P
    sub = adj[fill_loop].tocoo()  # the rim's edges in the mesh: to other rim vertices and to the ring outside
    outer = np.setdiff1d(sub.col, fill_loop)
    where = np.full(len(mesh.vertices), -1, dtype=np.int64)
    where[fill_loop] = np.arange(n_loop)
    where[outer] = n_all + np.arange(len(outer))
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]], np.c_[sub.row, where[sub.col]]])
    n = n_all + len(outer)
    A = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    A = ((A + A.T) > 0).astype(float)
    deg = np.asarray(A.sum(axis=1)).ravel()
    rows = np.arange(n_all)  # the cover's and the rim's vertices: their whole neighbourhood is known
    L = (csr_matrix((np.ones(n_all), (rows, rows)), shape=(n_all, n)) - A[rows].multiply(1.0 / deg[rows, None])).tocsc()
    free = np.arange(n_loop, n_all)
    fixed = np.r_[np.arange(n_loop), np.arange(n_all, n)]
    X = np.vstack([P, mesh.vertices[outer]])
    Lf, Lk = L[:, free], L[:, fixed]
    out = P.copy()
    normal = (Lf.T @ Lf).tocsc()  # the least-squares normal equations: sparse, a few thousand unknowns at most
    out[n_loop:] = np.asarray(spsolve(normal, -(Lf.T @ (Lk @ X[fixed])))).reshape(-1, 3)
    return out


def _fill(mesh: Mesh, loop: np.ndarray, adj: csr_matrix) -> tuple[np.ndarray, np.ndarray] | None:
    """New vertices and triangles (indices into ``[mesh vertices; new]``) closing ``loop``; None if it cannot."""
    V = mesh.vertices
    fill_loop = loop[::-1]  # the fill runs against the mesh's own edges
    c, axes, _ = _frame(V[fill_loop], 1.0)
    h = float(np.median(np.linalg.norm(V[fill_loop] - V[np.roll(fill_loop, -1)], axis=1)))
    local = (V - c) @ axes.T
    where = {int(v): i for i, v in enumerate(fill_loop)}
    E = mesh.edges_unique[np.isin(mesh.edges_unique, fill_loop).all(axis=1)]
    pairs = {(min(where[int(a)], where[int(b)]), max(where[int(a)], where[int(b)])) for a, b in E}
    n = len(fill_loop)
    taken = {(i, j) for i, j in pairs if j - i not in (1, n - 1)}  # the loop's own edges are the disk's rim
    disk = next((d for d in (_lattice_disk(p, h, taken) for p in _parameter_polygons(local[fill_loop, :2]))
                 if d is not None), None)
    if disk is None:
        return None
    pts, tri = disk
    n_loop, n_all = len(fill_loop), len(fill_loop) + len(pts)
    rim = local[fill_loop]
    # the membrane the rim spans (each inner vertex the mean of its neighbours): a disk on the rim whatever its shape
    xyz = np.stack([_harmonic(tri, n_loop, n_all, rim[:, k]) for k in range(3)], axis=1)
    ring = _rings(adj, loop, FIT_RINGS)
    regions = _smooth_regions(mesh, ring, adj)
    env = _Envelope.of(mesh, regions, axes[2]) if len(regions) > 1 else None
    faces = np.unique(np.concatenate([mesh.vertex_faces[int(v)] for v in ring]))
    if env is not None:
        # the faces around the hole meet across it: the patch lies on their extensions, to their crease (edges that
        # cross it split there), the rim's misfit carried inward harmonically so that it meets the rim exactly
        P = c + xyz @ axes
        t, side = env.pick(env.steps(P))
        side[:n_loop] = np.argmin(np.abs([q.offset(P[:n_loop]) for q in env.patches]), axis=0)
        P, tri = _split_at_creases(env, P + t[:, None] * axes[2], tri, n_loop, side)
        n_all = len(P)
        P += np.stack([_harmonic(tri, n_loop, n_all, V[fill_loop, k] - P[:n_loop, k]) for k in range(3)], axis=1)
        xyz = (P - c) @ axes.T
    elif np.mean(mesh.face_normals[faces] @ axes[2] > 0) >= HEIGHT_FIELD_SHARE:
        # the surroundings are a height field over the loop's plane: the patch continues their quadric, meeting the
        # rim exactly (its misfit there carried inward harmonically)
        q = _quadric(local[ring, :2], local[ring, 2])
        xyz[:, 2] = q(xyz[:, :2]) + _harmonic(tri, n_loop, n_all, rim[:, 2] - q(rim[:, :2]))
    else:  # wrapped round a shaft or a blend's bend: a thin plate from the rim and the ring outside it
        xyz = (_faired(mesh, adj, fill_loop, tri, c + xyz @ axes) - c) @ axes.T
    new = c + xyz[n_loop:] @ axes
    index = np.r_[fill_loop, len(V) + np.arange(len(new))]
    return new, index[tri]


def _area(V: np.ndarray, tri: np.ndarray) -> float:
    return 0.5 * float(np.linalg.norm(np.cross(V[tri[:, 1]] - V[tri[:, 0]], V[tri[:, 2]] - V[tri[:, 0]]), axis=1).sum())


def _outward(mesh: Mesh) -> Mesh:
    """``mesh`` with every closed component of negative signed volume turned inside out: the cleaning oriented an open
    component as most of its area ran, which once closed may enclose negative volume (as it turns closed ones)."""
    V, F, comp = mesh.vertices, mesh.faces, mesh.component
    P = V[F] - V.mean(axis=0)
    vol = np.bincount(comp, weights=np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])))
    open_comp = np.zeros(len(vol), dtype=bool)
    open_comp[comp[(mesh.edge_face_count[mesh.face_edges] != 2).any(axis=1)]] = True
    inside = (vol < 0)[comp] & ~open_comp[comp]
    if not inside.any():
        return mesh
    F = F.copy()
    F[inside] = F[inside][:, ::-1]
    return dataclasses.replace(mesh, faces=F)


def _zip_cracks(mesh: Mesh, loops: list[np.ndarray]) -> tuple[Mesh, int]:
    """``mesh`` with its cracks zipped, and how many loops that closed.

    A crack is a loop whose rim vertices lie on its other edges: cleaning drops a triangle whose corner sits on its
    opposite edge (zero area: an exporter's cap), leaving its three corners a loop that encloses nothing. Each loop
    edge is split at the loop's vertices within the weld tolerance of it (closer than that they would be one point),
    its triangle fanned from its third corner: the pieces lie on the input's triangle (whose input triangle they
    keep), and pair off with the other side's edges. The first piece takes the split triangle's place."""
    V, F, tol = mesh.vertices, mesh.faces, mesh.report.weld_tolerance
    directed = {(int(a), int(b)): t for t, row in enumerate(F.tolist()) for a, b in zip(row, row[1:] + row[:1])}
    rows, pieces, source, comp, split = F.copy(), [], [], [], set()
    for loop in loops:
        for u, v in zip(loop.tolist(), np.roll(loop, -1).tolist()):
            d = V[v] - V[u]
            t = (V[loop] - V[u]) @ d / max(float(d @ d), 1e-300)
            off = np.linalg.norm(V[loop] - V[u] - t[:, None] * d, axis=1)
            on = (t > 0) & (t < 1) & (off <= tol) & (loop != u) & (loop != v)
            tri = directed.get((u, v))
            if not on.any() or tri is None or tri in split:
                continue
            split.add(tri)
            x = next(int(w) for w in F[tri] if w not in (u, v))
            chain = [u, *loop[on][np.argsort(t[on])].tolist(), v]
            rows[tri] = (chain[0], chain[1], x)
            pieces += [(a, b, x) for a, b in zip(chain[1:-1], chain[2:])]
            source.append(np.full(len(chain) - 2, mesh.source_face[tri]))
            comp.append(np.full(len(chain) - 2, mesh.component[tri]))
    if not pieces:
        return mesh, 0
    out = Mesh(V, np.vstack([rows, np.asarray(pieces, dtype=F.dtype)]), np.concatenate([mesh.source_face, *source]),
               mesh.n_input_faces, np.concatenate([mesh.component, *comp]), mesh.report)
    return out, len(loops) - len(boundary_loops(out))


def close_holes(mesh: Mesh) -> tuple[Mesh, HoleReport]:
    """``mesh`` with its small holes closed over (module doc), and what was closed; a mesh without boundary loops
    comes back as the same object."""
    loops = boundary_loops(mesh)
    if not loops:
        return mesh, HoleReport(0, 0, np.zeros(len(mesh.faces), dtype=bool), len(mesh.vertices), 0.0)
    mesh, zipped = _zip_cracks(mesh, loops)
    if zipped:
        log.info("%d cracks (loops enclosing no area) zipped", zipped)
        loops = boundary_loops(mesh)
    nothing = HoleReport(len(loops) + zipped, zipped, np.zeros(len(mesh.faces), dtype=bool), len(mesh.vertices), 0.0)
    if not loops and not zipped:
        return mesh, nothing
    total = mesh.area
    # a hole is small against its own piece too: a triangle soup's every triangle is a piece whose rim is a loop
    piece_area = np.bincount(mesh.component, weights=mesh.face_areas)
    verts, tris, comps, closed = [mesh.vertices], [mesh.faces], [mesh.component], zipped
    count, adj = len(mesh.vertices), _adjacency(mesh)
    for loop in loops:
        _, axes, area = _frame(mesh.vertices[loop[::-1]], 1.0)
        extent = float(np.linalg.norm(np.ptp(mesh.vertices[loop], axis=0)))
        piece = piece_area[mesh.component[mesh.vertex_faces[int(loop[0])][0]]]
        if not area > 0 or area > HOLE_AREA_SHARE * min(total, piece) or (extent > SMALL_EXTENT * mesh.diagonal
                                              and _surrounded(mesh, loop, axes[2]) < SURROUND_REACH):
            continue
        got = _fill(mesh, loop, adj)
        if got is None:
            log.info("a hole of %d rim vertices could not be triangulated on its plane; left open", len(loop))
            continue
        new, tri = got
        cover = _area(np.vstack([mesh.vertices, new]), tri)
        if cover > COVER_BULGE * area:
            log.info("a hole's cover came out %.3g times the area its rim encloses; left open", cover / area)
            continue
        tri = np.where(tri >= len(mesh.vertices), tri - len(mesh.vertices) + count, tri)
        verts.append(new)
        tris.append(tri)
        comps.append(np.full(len(tri), mesh.component[mesh.vertex_faces[int(loop[0])][0]]))
        count += len(new)
        closed += 1
    if not closed:
        return mesh, nothing
    V, F = np.vstack(verts), np.vstack(tris)
    added = np.r_[np.zeros(len(mesh.faces), dtype=bool), np.ones(len(F) - len(mesh.faces), dtype=bool)]
    out = Mesh(V, F, np.r_[mesh.source_face, np.full(int(added.sum()), -1)], mesh.n_input_faces,
               np.concatenate(comps), mesh.report)
    out = dataclasses.replace(_outward(out), report=dataclasses.replace(
        mesh.report, boundary_edges=int((out.edge_face_count == 1).sum()),
        non_manifold_edges=int((out.edge_face_count > 2).sum())))
    area = float(out.face_areas[added].sum())
    log.info("%d of %d boundary loops closed over (%d triangles, %.3g %% of the area)", closed - zipped, len(loops),
             int(added.sum()), 100.0 * area / total)
    return out, HoleReport(len(loops) + zipped, closed, added, len(mesh.vertices), area)
