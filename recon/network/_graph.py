"""The curve network of a labelled mesh: the B-rep's vertices, edges and face loops, before any CAD kernel.

A labelled mesh (a part id per triangle) is a map of regions. The edges between differently labelled
triangles chain into the feature curves the paper's §4 turns into CAD edges: the network vertices are
where three or more regions meet (a junction collapses to a vertex, DESIGN.md), each network edge
separates exactly two parts (or one part and the outside, on an open mesh), and each part is bounded
by ordered loops of signed edge references. Building every edge once and letting both neighbouring
faces use it is what makes the B-rep watertight (recon/brep).

Then :func:`network_geometry` moves that network onto the fitted surfaces: vertices to the
least-squares meeting point of their surfaces, edge polylines onto the intersection of their two
surfaces, and fits each edge as a line, circle or B-spline pinned at its end vertices.

numpy/scipy only; the surfaces come in as projection callables.
"""

from __future__ import annotations

import logging
from collections import defaultdict
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._parallel import shared_map
from ..errors import InputError
from ..mesh._topology import stable_argsort, unique_rows

__all__ = [
    "CurveNetwork",
    "EdgeCurve",
    "NetworkGeometry",
    "OUTSIDE",
    "curve_network",
    "network_geometry",
]

log = logging.getLogger(__name__)

#: Part id standing for "no triangle": the far side of an open mesh's boundary.
OUTSIDE = -1

#: How many triangles per part are kept as orientation/shape samples.
_SAMPLES_PER_PART = 48


@dataclass(frozen=True)
class CurveNetwork:
    """Vertices, edges and face loops of a labelled mesh.

    Attributes
    ----------
    vertex_ids : (v,) int
        Mesh vertex index of each network vertex.
    points : (v, 3) float
        Position of each network vertex (the mesh vertex).
    edge_vertices : (e, 2) int
        Start and end network vertex of each edge (equal for a closed loop's anchor).
    edge_parts : (e, 2) int
        ``[left, right]`` part ids: ``left`` sees the edge run along its boundary counter-clockwise (its
        triangles contain the polyline's segments in the same direction); ``right`` is :data:`OUTSIDE`
        for an open mesh's boundary.
    coords : (p, 3) float
        All edge polylines, packed; edge ``i`` is ``coords[offsets[i]:offsets[i + 1]]`` and starts and
        ends at its two network vertices (a closed loop repeats its anchor).
    offsets : (e + 1,) int
        Offsets into ``coords``.
    poly_ids : (p,) int
        Mesh vertex index of each polyline point.
    parts : (f,) int
        Part ids that have a boundary, ascending.
    loops : (l,) int
        Signed edge references ``±(edge + 1)`` of all loops packed: ``+`` uses the edge in its stored
        direction. Loop ``j`` is ``loops[loop_offsets[j]:loop_offsets[j + 1]]``.
    loop_offsets : (l + 1,) int
        Offsets into ``loops``.
    loop_part : (l,) int
        Part id of each loop.
    loop_outer : (l,) bool
        True for the outer loop of its part (one per part), False for inner loops (holes).
    samples : (s, 3) float
        Centroids of up to 48 triangles per part (evenly spread over its triangle list).
    sample_normals : (s, 3) float
        Unit normals of those triangles (the mesh's orientation).
    sample_offsets : (f + 1,) int
        Samples of ``parts[k]`` are ``samples[sample_offsets[k]:sample_offsets[k + 1]]``.
    nonmanifold : (n, 2) int
        Mesh edges shared by more than two triangles; reported and left out of the network.
    """

    vertex_ids: np.ndarray
    points: np.ndarray
    edge_vertices: np.ndarray
    edge_parts: np.ndarray
    coords: np.ndarray
    offsets: np.ndarray
    poly_ids: np.ndarray
    parts: np.ndarray
    loops: np.ndarray
    loop_offsets: np.ndarray
    loop_part: np.ndarray
    loop_outer: np.ndarray
    samples: np.ndarray
    sample_normals: np.ndarray
    sample_offsets: np.ndarray
    nonmanifold: np.ndarray

    @property
    def n_vertices(self) -> int:
        return len(self.points)

    @property
    def n_edges(self) -> int:
        return len(self.edge_vertices)

    def polyline(self, edge: int) -> np.ndarray:
        """``(k, 3) float`` points of one edge, start to end."""
        return self.coords[self.offsets[edge] : self.offsets[edge + 1]]

    def loop(self, index: int) -> np.ndarray:
        """``(k,) int`` signed edge references ``±(edge + 1)`` of one loop."""
        return self.loops[self.loop_offsets[index] : self.loop_offsets[index + 1]]

    def part_loops(self, part: int) -> list[int]:
        """Indices of the loops of ``part``, the outer loop first."""
        idx = np.flatnonzero(self.loop_part == part)
        return sorted(idx.tolist(), key=lambda j: (not self.loop_outer[j], j))

    def part_samples(self, part: int) -> tuple[np.ndarray, np.ndarray]:
        """``(points (k, 3), normals (k, 3))`` of the triangle samples of ``part``."""
        k = int(np.searchsorted(self.parts, part))
        if k >= len(self.parts) or self.parts[k] != part:
            return np.empty((0, 3)), np.empty((0, 3))
        s = slice(self.sample_offsets[k], self.sample_offsets[k + 1])
        return self.samples[s], self.sample_normals[s]


def _check_input(vertices, faces, labels):
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces)
    labels = np.asarray(labels)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(f"curve_network: `vertices` must be an (n, 3) array, got shape {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise InputError(f"curve_network: `faces` must be an (m, 3) integer array, got {faces.dtype} {faces.shape}")
    if len(faces) == 0:
        raise InputError("curve_network: `faces` is empty; expected at least one triangle")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError("curve_network: `faces` refers to vertices outside `vertices`")
    if labels.shape != (len(faces),) or not np.issubdtype(labels.dtype, np.integer):
        raise InputError(f"curve_network: `labels` must be an ({len(faces)},) integer array, got {labels.dtype} {labels.shape}")
    if labels.min() < 0:
        raise InputError("curve_network: `labels` must be >= 0 (negative ids are reserved for the outside)")
    if not np.all(np.isfinite(vertices)):
        raise InputError("curve_network: `vertices` contains NaN or inf")
    return vertices, faces.astype(np.int64), labels.astype(np.int64)


def curve_network(vertices, faces, labels) -> CurveNetwork:
    """Chain the boundaries between differently labelled triangles into a network of vertices, edges and loops.

    Parameters
    ----------
    vertices : (n, 3) float
        Mesh vertices.
    faces : (m, 3) int
        Triangles, consistently oriented (counter-clockwise seen from outside).
    labels : (m,) int
        Part id (>= 0) of each triangle.

    Returns
    -------
    CurveNetwork
        Network vertices are mesh vertices where three or more parts meet (the outside of an open mesh
        counts as a part) or where the boundary graph branches; a closed boundary without such a vertex
        (a hole's circle) gets its smallest mesh vertex as anchor. Mesh edges with more than two
        triangles are reported in ``nonmanifold`` and skipped.
    """
    vertices, faces, labels = _check_input(vertices, faces, labels)
    m = len(faces)
    n = len(vertices)

    # Directed half-edges a→b of every triangle, and the undirected edge each belongs to.
    he_a = faces.reshape(-1)
    he_b = faces[:, [1, 2, 0]].reshape(-1)
    he_tri = np.repeat(np.arange(m), 3)
    lo = np.minimum(he_a, he_b)
    hi = np.maximum(he_a, he_b)
    key = lo * n + hi
    order = stable_argsort(key, n * n)
    ukey, start, count = np.unique(key[order], return_index=True, return_counts=True)
    nonmanifold = np.stack([ukey[count > 2] // n, ukey[count > 2] % n], axis=1)
    if len(nonmanifold):
        log.warning("curve_network: %d non-manifold mesh edges skipped", len(nonmanifold))

    # Label on the forward (lo→hi) and backward (hi→lo) side of every manifold undirected edge.
    first = order[start]
    second = np.where(count >= 2, order[np.minimum(start + 1, len(order) - 1)], -1)
    ok = count <= 2
    first, second, ukey = first[ok], second[ok], ukey[ok]
    lab1 = labels[he_tri[first]]
    lab2 = np.where(second >= 0, labels[he_tri[np.maximum(second, 0)]], OUTSIDE)
    fwd1 = he_a[first] < he_b[first]
    fwd_label = np.where(fwd1, lab1, lab2)
    bwd_label = np.where(fwd1, lab2, lab1)
    # An open edge seen backwards: its only triangle runs hi→lo.
    boundary = fwd_label != bwd_label
    bu = ukey[boundary] // n
    bv = ukey[boundary] % n
    b_fwd = fwd_label[boundary]
    b_bwd = bwd_label[boundary]

    # Distinct parts around each vertex (the outside counts) and boundary-graph degree.
    open_edge = (b_fwd == OUTSIDE) | (b_bwd == OUTSIDE)
    open_v = np.concatenate([bu[open_edge], bv[open_edge]])
    vert_lab = np.concatenate([np.stack([faces.reshape(-1), np.repeat(labels, 3)], 1),
                               np.stack([open_v, np.full(len(open_v), OUTSIDE)], 1)])
    # distinct (vertex, part) pairs, packed into one integer each (the outside, -1, shifted to 0)
    first, _ = unique_rows(vert_lab - [0, OUTSIDE], max(n, int(labels.max(initial=0)) + 2))
    n_parts_at = np.bincount(vert_lab[first, 0], minlength=n)
    degree = np.bincount(np.concatenate([bu, bv]), minlength=n)
    is_node = ((n_parts_at >= 3) | ((degree != 2) & (degree > 0))) & (degree > 0)

    # Walk the boundary graph from node to node (small: O(sqrt(m)) edges, a Python walk is fine).
    adj: dict[int, list[int]] = defaultdict(list)
    for i, (a, b) in enumerate(zip(bu.tolist(), bv.tolist())):
        adj[a].append(i)
        adj[b].append(i)
    used = np.zeros(len(bu), dtype=bool)
    node_set = set(np.flatnonzero(is_node).tolist())

    def walk(v0: int, e0: int) -> list[int]:
        path = [v0]
        v, e = v0, e0
        while True:
            used[e] = True
            w = int(bv[e]) if bu[e] == v else int(bu[e])
            path.append(w)
            if w in node_set:
                return path
            nxt = [f for f in adj[w] if not used[f]]
            if not nxt:  # closed back onto a used edge: should not happen on a 2-regular vertex
                return path
            v, e = w, nxt[0]

    polylines: list[list[int]] = []
    for v0 in sorted(node_set):
        for e0 in sorted(adj[v0]):
            if not used[e0]:
                polylines.append(walk(v0, e0))
    # Closed loops with no node: anchor at the smallest vertex (a hole's circle).
    for e0 in range(len(bu)):
        if used[e0]:
            continue
        loop_edges = [e0]
        # find the smallest vertex on this loop first, for a deterministic anchor
        comp_vertices = {int(bu[e0]), int(bv[e0])}
        stack = [int(bu[e0]), int(bv[e0])]
        seen_e = {e0}
        while stack:
            v = stack.pop()
            for f in adj[v]:
                if f not in seen_e and not used[f]:
                    seen_e.add(f)
                    loop_edges.append(f)
                    for w in (int(bu[f]), int(bv[f])):
                        if w not in comp_vertices:
                            comp_vertices.add(w)
                            stack.append(w)
        anchor = min(comp_vertices)
        node_set.add(anchor)
        polylines.append(walk(anchor, min(f for f in adj[anchor] if not used[f])))

    # Edge direction: orient so that the left part is the smaller id (the outside is always right).
    edge_lookup = {(int(a), int(b)): i for i, (a, b) in enumerate(zip(bu.tolist(), bv.tolist()))}
    edge_parts = np.empty((len(polylines), 2), dtype=np.int64)
    for k, path in enumerate(polylines):
        a, b = path[0], path[1]
        i = edge_lookup[(min(a, b), max(a, b))]
        left, right = (b_fwd[i], b_bwd[i]) if a < b else (b_bwd[i], b_fwd[i])
        if left == OUTSIDE or (right != OUTSIDE and right < left):
            path.reverse()
            left, right = right, left
        edge_parts[k] = left, right

    nodes = np.array(sorted(node_set), dtype=np.int64)
    node_index = {int(v): i for i, v in enumerate(nodes)}
    lengths = np.array([len(p) for p in polylines], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    poly_ids = np.concatenate([np.asarray(p, dtype=np.int64) for p in polylines]) if polylines else np.empty(0, np.int64)
    coords = vertices[poly_ids]
    edge_vertices = np.array([[node_index[p[0]], node_index[p[-1]]] for p in polylines], dtype=np.int64).reshape(-1, 2)

    parts, loops, loop_offsets, loop_part, loop_outer = _part_loops(edge_vertices, edge_parts, coords, offsets,
                                                                   vertices, faces, labels)
    samples, sample_normals, sample_offsets = _part_samples(parts, vertices, faces, labels)
    log.debug("curve_network: %d vertices, %d edges, %d loops over %d parts",
              len(nodes), len(polylines), len(loop_part), len(parts))
    return CurveNetwork(
        vertex_ids=nodes,
        points=vertices[nodes],
        edge_vertices=edge_vertices,
        edge_parts=edge_parts,
        coords=coords,
        offsets=offsets,
        poly_ids=poly_ids,
        parts=parts,
        loops=loops,
        loop_offsets=loop_offsets,
        loop_part=loop_part,
        loop_outer=loop_outer,
        samples=samples,
        sample_normals=sample_normals,
        sample_offsets=sample_offsets,
        nonmanifold=nonmanifold,
    )


def _part_loops(edge_vertices, edge_parts, coords, offsets, vertices, faces, labels):
    """Chain each part's signed edges into closed loops; the outer loop has the largest signed area."""
    by_part: dict[int, list[int]] = defaultdict(list)
    for e, (left, right) in enumerate(edge_parts.tolist()):
        by_part[left].append(e + 1)
        if right != OUTSIDE:
            by_part[right].append(-(e + 1))

    # Mean normal per part, to measure each loop's signed area as seen from outside.
    tri = vertices[faces]
    area_vec = 0.5 * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    mean_normal = np.zeros((int(labels.max()) + 1, 3))
    np.add.at(mean_normal, labels, area_vec)

    parts = np.array(sorted(p for p in by_part if p != OUTSIDE), dtype=np.int64)
    loops: list[int] = []
    loop_offsets = [0]
    loop_part: list[int] = []
    loop_outer: list[bool] = []
    for p in parts.tolist():
        refs = sorted(by_part[p], key=lambda r: (abs(r), r))
        out_of: dict[int, list[int]] = defaultdict(list)
        for r in refs:
            e = abs(r) - 1
            a, b = edge_vertices[e] if r > 0 else edge_vertices[e][::-1]
            out_of[int(a)].append(r)
        remaining = set(refs)
        part_loops: list[list[int]] = []
        for r0 in refs:
            if r0 not in remaining:
                continue
            loop = []
            r = r0
            while r in remaining:
                remaining.discard(r)
                loop.append(r)
                e = abs(r) - 1
                end = int(edge_vertices[e][1] if r > 0 else edge_vertices[e][0])
                nxt = [s for s in out_of[end] if s in remaining]
                if not nxt:
                    break
                r = nxt[0]
            part_loops.append(loop)
        # Signed area of each loop about the part's mean normal (outer loop counter-clockwise, largest).
        nrm = mean_normal[p]
        nrm = nrm / (np.linalg.norm(nrm) or 1.0)
        scores = []
        for loop in part_loops:
            pts = np.concatenate([coords[offsets[abs(r) - 1] : offsets[abs(r)]][:: 1 if r > 0 else -1] for r in loop])
            c = pts.mean(axis=0)
            va = 0.5 * np.sum(np.cross(pts[:-1] - c, pts[1:] - c), axis=0)
            length = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
            scores.append((float(va @ nrm), length))
        outer = max(range(len(part_loops)), key=lambda j: scores[j]) if part_loops else -1
        for j, loop in enumerate(part_loops):
            loops.extend(loop)
            loop_offsets.append(len(loops))
            loop_part.append(p)
            loop_outer.append(j == outer)
    return (parts, np.asarray(loops, dtype=np.int64), np.asarray(loop_offsets, dtype=np.int64),
            np.asarray(loop_part, dtype=np.int64), np.asarray(loop_outer, dtype=bool))


def _part_samples(parts, vertices, faces, labels):
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    good = norm > 0
    order = stable_argsort(labels)
    order = order[good[order]]
    sorted_labels = labels[order]
    pts, nrms, offs = [], [], [0]
    for p in parts.tolist():
        lo, hi = np.searchsorted(sorted_labels, [p, p + 1])
        idx = order[lo:hi]
        if len(idx) > _SAMPLES_PER_PART:
            idx = idx[np.linspace(0, len(idx) - 1, _SAMPLES_PER_PART).round().astype(int)]
        pts.append(tri[idx].mean(axis=1))
        nrms.append(cross[idx] / norm[idx, None])
        offs.append(offs[-1] + len(idx))
    cat = lambda xs: np.concatenate(xs) if xs else np.empty((0, 3))  # noqa: E731
    return cat(pts), cat(nrms), np.asarray(offs, dtype=np.int64)


# --------------------------------------------------------------------------------------------------
# Geometry of the network
# --------------------------------------------------------------------------------------------------

#: ``project(part, points (k, 3)) -> (closest points (k, 3), unit normals (k, 3))`` on a part's surface.
Projector = Callable[[int, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class EdgeCurve:
    """A fitted network edge.

    ``kind`` is ``"line"`` (``params``: start, end), ``"circle"`` (center, normal, radius, xdir,
    t0, t1: the arc runs counter-clockwise about ``normal`` from angle ``t0`` to ``t1`` measured from
    ``xdir``) or ``"bspline"`` (knots, control points, degree). ``residual`` is the largest distance
    of the edge's projected points to the curve.
    """

    kind: str
    params: dict
    residual: float


@dataclass(frozen=True)
class NetworkGeometry:
    """A curve network placed on its surfaces.

    Attributes
    ----------
    points : (v, 3) float
        Network vertices at the least-squares meeting point of their incident surfaces.
    vertex_gap : (v,) float
        Largest distance of each vertex to its incident surfaces.
    coords : (p, 3) float
        Edge polylines projected onto the intersection of their two surfaces, packed like
        ``CurveNetwork.coords`` (``offsets``), end points pinned to the vertices.
    offsets : (e + 1,) int
        Offsets into ``coords``.
    edge_gap : (e,) float
        Largest distance of each projected polyline to either of its surfaces.
    curves : tuple of EdgeCurve
        One fitted curve per edge.
    """

    points: np.ndarray
    vertex_gap: np.ndarray
    coords: np.ndarray
    offsets: np.ndarray
    edge_gap: np.ndarray
    curves: tuple

    def polyline(self, edge: int) -> np.ndarray:
        return self.coords[self.offsets[edge] : self.offsets[edge + 1]]


def _vertex_parts(network: CurveNetwork) -> list[list[int]]:
    parts = [set() for _ in range(network.n_vertices)]
    for (a, b), (l, r) in zip(network.edge_vertices.tolist(), network.edge_parts.tolist()):
        for v in (a, b):
            parts[v].add(l)
            if r != OUTSIDE:
                parts[v].add(r)
    return [sorted(s) for s in parts]


#: Surfaces meeting at less than this angle are treated as tangent: their intersection is too poorly
#: conditioned to pin a point down (a noise-level change of a fit moves it by noise / sin(angle)).
TANGENT_ANGLE = np.deg2rad(10.0)


def meeting_point(x0, parts, project: Projector, *, iterations: int = 8, limit: float | None = None):
    """Meeting point of several surfaces near ``x0`` (Gauss–Newton on their tangent planes, truncated SVD).

    Each step solves ``n_i · (x − q_i) = 0`` (``q_i`` the projection of ``x`` onto surface ``i``, ``n_i`` its
    normal) in the least-squares sense, keeping only the directions whose singular value is above
    ``sin(TANGENT_ANGLE)``: the directions the surfaces fix. The others (along the curve two surfaces share,
    or anywhere where fitted surfaces meet tangentially, as a fillet's sphere and cylinders do) keep
    ``x0``'s position, the labelled mesh's own. A point that still moves farther than ``limit`` goes back
    to the mean of its projections.

    Returns
    -------
    x : (3,) float
    gap : float
        Largest distance of ``x`` to the surfaces.
    """
    x0 = np.asarray(x0, dtype=np.float64).copy()
    x = x0.copy()
    smin = np.sin(TANGENT_ANGLE)
    for _ in range(iterations if parts else 0):
        qs, ns = [], []
        for p in parts:
            q, nrm = project(p, x[None])
            qs.append(q[0])
            ns.append(nrm[0])
        q = np.array(qs)
        nrm = np.array(ns)
        rhs = np.einsum("ij,ij->i", nrm, q - x)
        u, sv, vt = np.linalg.svd(nrm, full_matrices=False)
        keep = sv > smin
        step = vt[keep].T @ ((u[:, keep].T @ rhs) / sv[keep])
        x = x + step
        if np.linalg.norm(step) < 1e-12:
            break
    if limit is not None and parts and np.linalg.norm(x - x0) > limit:
        x = np.mean([project(p, x0[None])[0][0] for p in parts], axis=0)
    gap = max(float(np.linalg.norm(project(p, x[None])[0][0] - x)) for p in parts) if parts else 0.0
    return x, gap


def _project_two(pts, pa, pb, project: Projector, iterations: int, limit: float | None = None):
    """Alternate projections onto two surfaces, then a tangent-plane meeting step, for all points at once.

    Where the step would carry a point more than ``limit`` away from where it started (two fitted surfaces
    that meet tangentially, like a fillet and its face, cross at a grazing angle far from the mesh's
    boundary, or not at all) the point goes to the midpoint of its projections instead: between the two
    surfaces, at the labelled boundary.
    """
    x0 = pts.copy()
    x = pts.copy()
    for _ in range(iterations):
        qa, na = project(pa, x)
        qb, nb = project(pb, x)
        # Newton step on the two tangent planes, minimum-norm: moves x onto their intersection line.
        da = np.einsum("ij,ij->i", na, qa - x)
        db = np.einsum("ij,ij->i", nb, qb - x)
        g = np.einsum("ij,ij->i", na, nb)
        det = 1.0 - g * g
        ok = det > np.sin(TANGENT_ANGLE) ** 2
        # x + α na + β nb with na·(…)=da, nb·(…)=db
        alpha = np.where(ok, (da - g * db) / np.where(ok, det, 1.0), 0.5 * (da + db))
        beta = np.where(ok, (db - g * da) / np.where(ok, det, 1.0), 0.0)
        step = alpha[:, None] * na + beta[:, None] * nb
        # Nearly tangent surfaces: no well-defined intersection; take the midpoint of the projections.
        step[~ok] = 0.5 * (qa[~ok] + qb[~ok]) - x[~ok]
        x = x + step
        if limit is not None:
            far = np.linalg.norm(x - x0, axis=1) > limit
            if np.any(far):
                qa0, _ = project(pa, x0[far])
                qb0, _ = project(pb, x0[far])
                x[far] = 0.5 * (qa0 + qb0)
    return x


#: Rounds of chord refinement per edge polyline (each can double its points, see :func:`_refined`).
REFINE_ROUNDS = 6


def _onto_edge(x, left: int, right: int, project: Projector, iterations: int):
    """Points ``x`` near an edge moved onto it: onto ``left``'s surface alone for an open boundary, else onto the
    intersection of the two surfaces (Newton steps on their tangent planes, with no limit on the distance:
    ``x`` may be a chord's midpoint, a sagitta away from both surfaces; the caller checks where it went)."""
    if right == OUTSIDE:
        return project(left, x)[0]
    return _project_two(x, left, right, project, iterations, None)


def _nearest_segment(x, pts) -> np.ndarray:
    """``(m,) int``: for each point of ``x`` (m, 3), the segment of the polyline ``pts`` (k, 3) nearest to it."""
    a, d = pts[:-1], np.diff(pts, axis=0)
    w = x[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("mkj,kj->mk", w, d) / np.maximum(np.einsum("kj,kj->k", d, d), 1e-300), 0.0, 1.0)
    return np.argmin(np.linalg.norm(w - t[:, :, None] * d[None, :, :], axis=2), axis=1)


def _refined(pts, left: int, right: int, project: Projector, *, tolerance: float, iterations: int, max_points: int):
    """The edge polyline with points added where a chord strays more than ``tolerance`` from the edge.

    A mesh made by a CAD tessellator has long triangles: an edge between two spheres on crank is one mesh
    segment 0.55 long on a sphere of radius 0.4, a chord 0.11 inside the surfaces (88 tolerances). Fitted as
    the line through its two points, the edge lies that far off both faces, ShapeFix raises its tolerance to
    match, and the face's wire intersects itself in the surface's parameters. Each round moves the midpoint
    of every chord longer than ``tolerance`` onto the edge (:func:`_onto_edge`) and keeps it where it moved
    by more than ``tolerance``, no more than half the chord, and lies within ``tolerance`` of both surfaces.
    Scan-like meshes, whose segments are short for their curvature, keep their polylines as they are.
    """
    for _ in range(REFINE_ROUNDS):
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        long = np.flatnonzero(seg > tolerance)
        room = max_points - len(pts)
        if not len(long) or room <= 0:
            break
        mids = 0.5 * (pts[long] + pts[long + 1])
        on = _onto_edge(mids, left, right, project, iterations)
        # Only points that reached both surfaces: where the surfaces meet tangentially or not at all near the
        # chord, the edge is no better defined than the chord itself.
        gap = np.zeros(len(on))
        for p in (left, right):
            if p != OUTSIDE:
                gap = np.maximum(gap, np.linalg.norm(project(p, on)[0] - on, axis=1))
        # and a sagitta's distance away, not a far crossing of the two surfaces: a quarter circle's sagitta is
        # 0.21 of its chord, a half circle's 0.5.
        moved = np.linalg.norm(on - mids, axis=1)
        off = (moved > tolerance) & (moved <= 0.5 * seg[long]) & (gap <= tolerance)
        # and onto the part of the edge between the chord's ends, not onto another stretch of the same edge: on
        # crank a plane cuts a sphere in a circle, one edge runs along its arc and back across a chord of it,
        # and the chord's midpoint went to the arc (the nearest point of the circle), so the wire crossed itself.
        # (Nearer a chord's neighbour is allowed: beside a sharp turn an arc can bulge towards the next chord.)
        off &= np.abs(_nearest_segment(on, pts) - long) <= 1
        if not off.any():
            break
        keep = np.flatnonzero(off)
        keep = keep[np.argsort(-seg[long[keep]], kind="stable")[:room]]
        keep.sort()
        pts = np.insert(pts, long[keep] + 1, on[keep], axis=0)
    return pts


def network_geometry(network: CurveNetwork, project: Projector, *, tolerance: float, iterations: int = 6,
                     max_points: int = 64, fit_curve=None, refine=None, jobs: int = 1) -> NetworkGeometry:
    """Place the network on its surfaces and fit each edge.

    Parameters
    ----------
    network : CurveNetwork
    project : callable
        ``project(part, points (k, 3)) -> (closest points (k, 3), unit normals (k, 3))``.
    tolerance : float
        Model tolerance: a line or circle is kept when all projected points are within it.
    iterations : int
        Projection iterations per polyline.
    max_points : int
        Polylines are resampled to at most this many points before projection (cost bound).
    fit_curve : callable, optional
        ``fit_curve(points, *, start, end, tolerance) -> EdgeCurve``; :func:`fit_edge_curve` by default.
    refine : collection of part ids, optional
        Parts whose surfaces are trusted to place an edge between the mesh's points: a polyline gets points
        added where its chords stray from the edge (:func:`_refined`), and a smooth curve that strays from its
        points gives way to them (:func:`_strays`), only when both its parts are in it (an open boundary: its
        one part). Default: every part.
    jobs : int
        Processes to place the edges with: two at most (see :func:`recon._parallel.shared_map`). The result
        does not depend on it.

    Returns
    -------
    NetworkGeometry
    """
    if not tolerance > 0:
        raise InputError(f"network_geometry: `tolerance` must be > 0, got {tolerance!r}")
    fit_curve = fit_curve or fit_edge_curve
    # How far the network may move from the labelled mesh boundary onto an intersection of its surfaces:
    # the mesh boundary is within a few noise levels (and so a few tolerances) of the true edge.
    limit = 3.0 * tolerance
    vparts = _vertex_parts(network)
    points = np.empty_like(network.points)
    vgap = np.zeros(network.n_vertices)
    for v in range(network.n_vertices):
        points[v], vgap[v] = meeting_point(network.points[v], vparts[v], project, limit=limit)

    def edge(e):  # (points, gap to the surfaces, curve, what to log) of edge e
        notes = []
        poly = network.polyline(e)
        a, b = network.edge_vertices[e]
        closed = a == b
        idx = np.unique(np.linspace(0, len(poly) - 1, min(len(poly), max_points)).round().astype(int))
        pts = poly[idx].copy()
        left, right = network.edge_parts[e]
        inner = pts[1:-1]
        if len(inner):
            if right == OUTSIDE:
                inner = project(int(left), inner)[0]
            else:
                inner = _project_two(inner, int(left), int(right), project, iterations, limit)
        pts = np.vstack([points[a][None], inner, points[b][None]])
        trusted = refine is None or (left in refine and (right == OUTSIDE or right in refine))
        if trusted:
            pts = _refined(pts, int(left), int(right), project, tolerance=tolerance, iterations=iterations,
                           max_points=max_points)
        inner = pts[1:-1]
        gap = 0.0
        if len(inner):
            for p in (left, right):
                if p != OUTSIDE:
                    gap = max(gap, float(np.max(np.linalg.norm(project(int(p), inner)[0] - inner, axis=1))))
        try:
            curve = fit_curve(pts, closed=bool(closed), tolerance=tolerance)
        except InputError as err:  # a degenerate edge (all its points coincide): the B-rep reports it
            notes.append(f"network_geometry: edge {e}: {err}")
            return pts, gap, EdgeCurve("line", {"start": pts[0].copy(), "end": pts[-1].copy()}, float("inf")), notes
        if trusted and _strays(curve, pts, int(left), int(right), project, tolerance):
            notes.append(f"network_geometry: edge {e}: its smooth curve strays from its points and their surfaces: "
                         "the polyline is the edge")
            curve = polyline_curve(pts)
        return pts, gap, curve, notes

    # Every edge is placed on its own (the projections depend on the point alone): a second process can place
    # some while this one places the others, with the same result.
    done = shared_map(edge, network.n_edges, grace=SECOND_PROCESS_GRACE) if jobs > 1 and network.n_edges > 1 else {}
    out, offs, egap, curves = [], [0], [], []
    for e in range(network.n_edges):
        pts, gap, curve, notes = done[e] if e in done else edge(e)
        for note in notes:
            log.info("%s", note)
        egap.append(gap)
        out.append(pts)
        offs.append(offs[-1] + len(pts))
        curves.append(curve)
    return NetworkGeometry(points=points, vertex_gap=vgap, coords=np.concatenate(out) if out else np.empty((0, 3)),
                           offsets=np.asarray(offs, dtype=np.int64), edge_gap=np.asarray(egap),
                           curves=tuple(curves))


#: Seconds the first process waits at least for the second's answer once its own share is done (else twice the
#: time its own share took): a second process that hangs (forked from a threaded one: a lock held at the fork)
#: costs this, and its edges are placed by the first.
SECOND_PROCESS_GRACE = 30.0


#: How far (in tolerances) a smooth edge curve may stray from its polyline before it is checked against the
#: surfaces: the sewing tolerance (recon.brep sews at 10×), beyond which sewing cannot mend the gap either.
STRAY_FACTOR = 10.0
#: Samples along a curve (and along its polyline) for that check, at most (each one is two projections).
STRAY_SAMPLES = 128


def polyline_curve(pts) -> EdgeCurve:
    """The polyline ``pts`` (k, 3) as an edge: a degree-1 B-spline through its points (chord-length knots)."""
    pts = np.asarray(pts, dtype=np.float64)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-12])
    pts = pts[keep]
    t = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    t /= t[-1]
    return EdgeCurve("bspline", {"knots": np.concatenate([[0.0, 0.0], t[1:-1], [1.0, 1.0]]),
                                 "control_points": pts.copy(), "degree": 1}, 0.0)


def _strays(curve: EdgeCurve, pts, left: int, right: int, project: Projector, tolerance: float) -> bool:
    """Whether a smooth B-spline edge ``curve`` invents a shape that neither its points nor its surfaces have:
    somewhere it is more than :data:`STRAY_FACTOR` tolerances from its polyline ``pts``, and it does not make up
    for it by lying nearer the surfaces: on average (by arc length) it is farther off them (the larger of its
    distances to the two) than the polyline — or, through 3 points, more than a tolerance off them: the
    quadratic through 3 points has nothing to smooth, its shape between them is the points' spacing alone.
    Then the polyline is the better edge.

    A CAD tessellation's edges can be a few points with chords of very different lengths. On crank the edge
    between a torus and a plane that do not meet there is 3 points, a chord 147 tolerances long and one of 5:
    the quadratic through them bows 35 tolerances sideways, across the plane's hole, 5.7 tolerances off the
    surfaces on average (the chord, 7.4, cannot be refined: no point near its middle lies on both surfaces), and
    the plane's wire crosses itself. Between a cylinder and a sphere that meet at a grazing angle the 64 points
    zigzag and the best spline is 98 tolerances off them and 25 off the surfaces (the points 1.1); beside them
    3 and 4 points whose quadratic and cubic bow 17 and 28 tolerances out, 0.8 and 1.2 tolerances off the
    surfaces where the chords are 0.3 and 0.2 off. A curve nearer the surfaces than its chords is kept: through
    sparse points on an arc the chords are a sagitta inside it; across a zigzag seam cut through one sphere (no
    intersection to follow) the smooth loop is 0.15 tolerances off the sphere, the zigzag 0.63. So are curves of
    more points that are off the surfaces but nearer them than their chords (casting: 4 to 8 points between
    surfaces 1 to 16 tolerances apart): replaced, they moved its deviations both ways. The caller asks only
    where both surfaces are fitted within tolerance (``refine``): box_fillet coarse's B-splines out of
    tolerance lie 8 to 19 tolerances off their edges' points, and its fillings, bounded by the polylines,
    reached twice as far from the mesh (ours to mesh p95 6.3 to 28 % of the diagonal).
    """
    if curve.kind != "bspline" or int(curve.params["degree"]) < 2 or len(pts) < 3:
        return False
    from scipy.interpolate import BSpline
    from scipy.spatial import cKDTree

    n = min(STRAY_SAMPLES, 4 * (len(pts) - 1) + 1)
    spline = BSpline(np.asarray(curve.params["knots"]), np.asarray(curve.params["control_points"]),
                     int(curve.params["degree"]))
    on_curve = spline(np.linspace(0.0, 1.0, n))
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    along = np.linspace(0.0, s[-1], 8 * n)
    on_poly = np.column_stack([np.interp(along, s, pts[:, j]) for j in range(3)])
    if float(np.max(cKDTree(on_poly).query(on_curve)[0])) <= STRAY_FACTOR * tolerance:
        return False
    on_poly = on_poly[:: 8]

    def mean_off(x):
        off = np.zeros(len(x))
        for p in (left, right):
            if p != OUTSIDE:
                off = np.maximum(off, np.linalg.norm(project(p, x)[0] - x, axis=1))
        return float(off.mean())

    curve_off = mean_off(on_curve)
    return curve_off > mean_off(on_poly) or (len(pts) == 3 and curve_off > tolerance)


# --------------------------------------------------------------------------------------------------
# Curve fits with pinned ends
# --------------------------------------------------------------------------------------------------


def _circle_fit(pts):
    """Plane + algebraic (Kåsa) circle fit. Returns center, normal, radius, xdir."""
    c0 = pts.mean(axis=0)
    _, s, vt = np.linalg.svd(pts - c0)
    normal = vt[2]
    u, w = vt[0], vt[1]
    xy = np.stack([(pts - c0) @ u, (pts - c0) @ w], axis=1)
    a = np.column_stack([2 * xy, np.ones(len(xy))])
    sol = np.linalg.lstsq(a, np.sum(xy**2, axis=1), rcond=None)[0]
    cx, cy = sol[:2]
    r2 = sol[2] + cx * cx + cy * cy
    if not r2 > 0:
        return None
    center = c0 + cx * u + cy * w
    return center, normal, float(np.sqrt(r2))


def fit_edge_curve(points, *, closed: bool, tolerance: float) -> EdgeCurve:
    """Fit a line, circle arc or cubic B-spline to an edge polyline whose first and last points are pinned.

    Parameters
    ----------
    points : (k, 3) float
        The polyline, ``points[0]`` and ``points[-1]`` are the network vertices (equal if ``closed``).
    closed : bool
        The edge is a closed loop through one anchor vertex.
    tolerance : float
        A line or circle is accepted when every point lies within ``tolerance`` of it.

    Returns
    -------
    EdgeCurve
        Its ends are exactly ``points[0]`` and ``points[-1]``.
    """
    pts = np.asarray(points, dtype=np.float64)
    p0, p1 = pts[0], pts[-1]
    chord = p1 - p0
    clen = float(np.linalg.norm(chord))
    # Line: the segment between the pinned ends.
    if not closed and clen > 0:
        d = chord / clen
        rel = pts - p0
        dist = np.linalg.norm(rel - np.outer(rel @ d, d), axis=1)
        if float(dist.max()) <= tolerance:
            return EdgeCurve("line", {"start": p0.copy(), "end": p1.copy()}, float(dist.max()))
    # Circle arc through the pinned ends: fit, then test all points.
    if len(pts) >= 4:
        fit = _circle_fit(pts[:-1] if closed else pts)
        if fit is not None:
            center, normal, radius = fit
            # Orient the normal so the polyline runs counter-clockwise about it.
            rel = pts - center
            turn = np.sum(np.cross(rel[:-1], rel[1:]), axis=0)
            if turn @ normal < 0:
                normal = -normal
            xdir = p0 - center
            xdir = xdir - (xdir @ normal) * normal
            if np.linalg.norm(xdir) > 0:
                xdir /= np.linalg.norm(xdir)
                ydir = np.cross(normal, xdir)
                ang = np.unwrap(np.arctan2(rel @ ydir, rel @ xdir))
                ang -= ang[0]
                planar = rel - np.outer(rel @ normal, normal)
                dist = np.hypot(rel @ normal, np.linalg.norm(planar, axis=1) - radius)
                monotone = np.all(np.diff(ang) > -1e-9)
                t1 = 2 * np.pi if closed else float(ang[-1])
                if monotone and float(dist.max()) <= tolerance and 0 < t1 <= 2 * np.pi + 1e-9:
                    return EdgeCurve("circle", {"center": center, "normal": normal, "radius": radius,
                                                "xdir": xdir, "t0": 0.0, "t1": min(t1, 2 * np.pi)},
                                     float(dist.max()))
    return _bspline_pinned(pts, closed=closed, tolerance=tolerance)


#: Data points a knot span must hold at least (on average) for the least-squares spline to stay bounded.
_POINTS_PER_SPAN = 3.0

#: Weight of the second-difference penalty relative to the data term (P-spline; Eilers & Marx 1996).
_SMOOTHING = 1e-6


def _bspline_pinned(pts, *, closed: bool, tolerance: float, degree: int = 3) -> EdgeCurve:
    """Penalised least-squares cubic B-spline (chord-length parameters) with end control points fixed to the ends.

    A plain least-squares spline with as many control points as data points interpolates the projected
    polyline, and where those points zigzag (noise, or neighbours that fell back to different projections)
    it overshoots between them by orders of magnitude: seen on box_fillet noisy20, edges thousands of mm off
    a 70 mm part although they passed through every data point. So the control points are capped at one per
    :data:`_POINTS_PER_SPAN` data points and a small second-difference penalty keeps every span determined
    (Eilers & Marx, P-splines). The residual is measured on the curve densely sampled against the polyline,
    not only at the data points: it is what the B-rep builder and the report can trust.
    """
    from scipy.interpolate import BSpline

    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-12])
    pts = pts[keep]
    if len(pts) < 2:
        raise InputError("fit_edge_curve: an edge polyline has fewer than two distinct points")
    if len(pts) == 2:
        pts = np.vstack([pts[0], 0.5 * (pts[0] + pts[1]), pts[1]])
    t = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    t /= t[-1]
    k = min(degree, len(pts) - 1)
    most = max(k + 1, int(len(pts) / _POINTS_PER_SPAN) + k)
    best = None
    for n_ctrl in sorted({min(most, c) for c in (k + 1, k + 3, k + 6, k + 12, k + 24, most)}):
        # Knots at quantiles of the data parameters, so every span holds data (The NURBS Book, eq. 9.69).
        inner = np.quantile(t, np.linspace(0, 1, n_ctrl - k + 1)[1:-1])
        knots = np.concatenate([np.zeros(k + 1), inner, np.ones(k + 1)])
        basis = BSpline.design_matrix(t, knots, k).toarray()
        # Pin: first and last control points equal the ends (clamped knots interpolate them).
        ctrl = np.zeros((n_ctrl, 3))
        ctrl[0], ctrl[-1] = pts[0], pts[-1]
        if n_ctrl > 2:
            rhs = pts - np.outer(basis[:, 0], ctrl[0]) - np.outer(basis[:, -1], ctrl[-1])
            a = basis[:, 1:-1]
            normal = a.T @ a
            if n_ctrl >= 3:
                diff2 = np.diff(np.eye(n_ctrl), n=2, axis=0)
                pen = diff2.T @ diff2
                lam = _SMOOTHING * float(np.trace(normal)) / max(n_ctrl - 2, 1)
                normal = normal + lam * pen[1:-1, 1:-1]
                rhs_pen = -lam * (pen[1:-1, 0][:, None] * ctrl[0] + pen[1:-1, -1][:, None] * ctrl[-1])
            else:
                rhs_pen = 0.0
            ctrl[1:-1] = np.linalg.solve(normal, a.T @ rhs + rhs_pen)
        curve = BSpline(knots, ctrl, k)
        if _backtracks(curve, pts, t):
            continue
        resid = _curve_polyline_gap(curve, pts, t)
        if best is None or resid < best[3]:
            best = (knots, ctrl, k, resid)
        if resid <= tolerance:
            break
    if best is None:
        # Every smooth fit loops back somewhere (a few points that zigzag along a short edge): the polyline
        # itself, a degree-1 B-spline through the points, is a valid edge that cannot cross itself.
        best = (np.concatenate([[0.0, 0.0], t[1:-1], [1.0, 1.0]]), pts.copy(), 1, 0.0)
    knots, ctrl, k, resid = best
    return EdgeCurve("bspline", {"knots": knots, "control_points": ctrl, "degree": int(k)}, resid)


def _backtracks(curve, pts, t, *, per_span: int = 4) -> bool:
    """True where the curve runs against the polyline's local direction (a loop, or a cusp and a turn back).

    The direction is the chord over three segments about each one, so that one noisy point does not count
    as a reversal. Seen on rocker-arm2500: a cubic through six zigzagging points formed a loop, and the
    face it bounded was a self-intersecting wire.
    """
    n = len(pts)
    w = np.linspace(0.0, 1.0, per_span, endpoint=False)
    fine = (t[:-1, None] * (1 - w) + t[1:, None] * w).ravel()
    seg = np.repeat(np.arange(n - 1), per_span)
    window = pts[np.minimum(seg + 2, n - 1)] - pts[np.maximum(seg - 1, 0)]
    tangent = curve.derivative()(fine)
    return bool(np.any(np.einsum("ij,ij->i", tangent, window) < 0))


def _curve_polyline_gap(curve, pts, t, *, per_span: int = 4) -> float:
    """Largest distance of ``curve`` from the polyline ``pts``: at the data parameters ``t``, and between them
    wherever the curve strays from the polyline by more than a segment's length (an overshoot; a smooth
    curve's sagitta over a chord is far smaller than that)."""
    from scipy.spatial import cKDTree

    at_data = float(np.max(np.linalg.norm(curve(t) - pts, axis=1)))
    w = np.linspace(0.0, 1.0, per_span, endpoint=False)
    fine = (t[:-1, None] * (1 - w) + t[1:, None] * w).ravel()
    dense = (pts[:-1, None, :] * (1 - w)[None, :, None] + pts[1:, None, :] * w[None, :, None]).reshape(-1, 3)
    between = float(np.max(cKDTree(np.vstack([dense, pts[-1:]])).query(curve(fine))[0]))
    seg = float(np.max(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
    return max(at_data, between) if between > seg else at_data
