"""The curve network's graph: vertices, edges and face loops of a labelled mesh, before any CAD kernel.

A labelled mesh (a part id per triangle) is a map of regions. The edges between differently labelled
triangles chain into the feature curves the paper's §4 turns into CAD edges: the network vertices are
where three or more regions meet (a junction collapses to a vertex, DESIGN.md), each network edge
separates exactly two parts (or one part and the outside, on an open mesh), and each part is bounded
by ordered loops of signed edge references. Building every edge once and letting both neighbouring
faces use it is what makes the B-rep watertight (recon/brep).
"""

from __future__ import annotations

import logging
from collections import defaultdict
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..mesh._topology import stable_argsort, unique_rows

__all__ = ["CurveNetwork", "OUTSIDE", "curve_network"]


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
        Part ids, ascending; a part that has no boundary (a closed body one face covers: a whole sphere or torus)
        has no loop.
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


def _check_input(vertices, faces, labels) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


def curve_network(vertices: ArrayLike, faces: ArrayLike, labels: ArrayLike) -> CurveNetwork:
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
    n = len(vertices)
    bu, bv, b_fwd, b_bwd, nonmanifold = _boundary_edges(faces, labels, n)
    node_set = _branch_vertices(faces, labels, n, bu, bv, b_fwd, b_bwd)
    polylines, node_set = _polylines(bu, bv, node_set)
    edge_parts = _orient(polylines, bu, bv, b_fwd, b_bwd)

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


def _boundary_edges(faces, labels, n: int):
    """The mesh edges between differently labelled triangles (or a triangle and the outside).

    Returns their end vertices ``bu < bv``, the part on their forward (``bu``→``bv``) and backward side, each
    ``(b,) int``, and the non-manifold mesh edges ``(k, 2) int`` (more than two triangles: left out).
    """
    m = len(faces)
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
    return bu, bv, b_fwd, b_bwd, nonmanifold


def _branch_vertices(faces, labels, n: int, bu, bv, b_fwd, b_bwd) -> set[int]:
    """Mesh vertices that become network vertices: where three or more parts meet (the outside counts) or where
    the boundary graph does not simply pass through (degree other than 2)."""
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
    return set(np.flatnonzero(is_node).tolist())


def _polylines(bu, bv, node_set: set[int]) -> tuple[list[list[int]], set[int]]:
    """The boundary graph (edges ``bu``–``bv``) walked from node to node into polylines of mesh vertex ids.

    Returns the polylines and the nodes: ``node_set`` plus an anchor (its smallest vertex) on every closed
    boundary that has no node (a hole's circle)."""
    node_set = set(node_set)
    # Walk the boundary graph from node to node (small: O(sqrt(m)) edges, a Python walk is fine).
    adj: dict[int, list[int]] = defaultdict(list)
    for i, (a, b) in enumerate(zip(bu.tolist(), bv.tolist())):
        adj[a].append(i)
        adj[b].append(i)
    used = np.zeros(len(bu), dtype=bool)

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
    return polylines, node_set


def _orient(polylines: list[list[int]], bu, bv, b_fwd, b_bwd) -> np.ndarray:
    """``(e, 2) int`` ``[left, right]`` parts of each polyline, which is reversed in place where needed so that
    the left part is the smaller id (the outside is always right)."""
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
    return edge_parts


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

    # every label is a part; one no edge bounds is a closed body one face covers (a whole sphere or torus): no loop
    parts = np.unique(labels).astype(np.int64)
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
