"""The segment graph of Wekel & Hellwich §3, written for any cell complex.

In 2D the cells are the Delaunay triangles inside the shape and the skeleton vertices are their
(merged) circumcentres; on a surface the cells are mesh triangles and the skeleton is made of
feature-line vertices. Everything here only needs

- a skeleton graph: ``edges (e, 2) int`` over ``n`` skeleton vertices;
- cells (triangles) with their edge adjacency, ``neighbors (m, 3) int`` where ``neighbors[t, k]`` is the
  cell across the edge opposite corner ``k`` of ``cells[t]`` (``-1``: none), the convention of
  ``scipy.spatial.Delaunay.neighbors``;
- which cell adjacencies are cut (the separator edges, duals of the bridges).

All functions are vectorised (numpy / scipy.sparse.csgraph); none loops in Python over cells or edges,
except :func:`part_boundary_loops` at the rare pinch vertices where a part touches itself.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .errors import DecompositionError

__all__ = [
    "JUNCTION",
    "TERMINAL",
    "LINEAR",
    "NO_SKELETON",
    "vertex_degree",
    "bridge_mask",
    "cell_neighbors",
    "cell_adjacency",
    "cut_components",
    "part_kinds",
    "part_boundary_loops",
]

log = logging.getLogger(__name__)

#: Part kind codes returned by :func:`part_kinds`; index into ``recon.skeleton2d.PART_KINDS``.
JUNCTION, TERMINAL, LINEAR = 0, 1, 2
#: Kind code of a part that contains no skeleton vertex (see :func:`part_kinds`).
NO_SKELETON = -1


def vertex_degree(edges: np.ndarray, n_vertices: int) -> np.ndarray:
    """Number of skeleton edges at each vertex, d(v) of §3.

    Parameters
    ----------
    edges : (e, 2) int
        Vertex index pairs (no self-loops expected; a self-loop would count twice).
    n_vertices : int

    Returns
    -------
    (n_vertices,) int
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    return np.bincount(edges.ravel(), minlength=n_vertices).astype(np.int64)


def bridge_mask(edges: np.ndarray, degree: np.ndarray) -> np.ndarray:
    """Which skeleton edges are bridges: at least one endpoint of degree ≠ 2 (§3).

    Parameters
    ----------
    edges : (e, 2) int
    degree : (n,) int
        From :func:`vertex_degree`.

    Returns
    -------
    (e,) bool
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    d = np.asarray(degree)[edges]
    return (d[:, 0] != 2) | (d[:, 1] != 2)


def cell_neighbors(cells: np.ndarray) -> np.ndarray:
    """Edge adjacency of triangles, in the convention of ``scipy.spatial.Delaunay.neighbors``.

    Parameters
    ----------
    cells : (m, 3) int
        Triangles as vertex indices.

    Returns
    -------
    (m, 3) int
        ``neighbors[t, k]``: the triangle sharing the edge opposite corner ``k`` of ``cells[t]``, or ``-1``
        on a border. On a non-manifold edge (more than two triangles) the triangles are paired in sorted
        order and the rest get ``-1``.
    """
    cells = np.asarray(cells, dtype=np.int64)
    m = len(cells)
    # edge opposite corner k joins corners k+1 and k+2
    a = cells[:, [1, 2, 0]].ravel()
    b = cells[:, [2, 0, 1]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * (int(cells.max(initial=0)) + 1) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = ks[1:] == ks[:-1]
    # pair each half-edge with the next one of equal key, but only at even positions within a run
    run_start = np.r_[True, ~same]
    pos = np.arange(len(ks)) - np.maximum.accumulate(np.where(run_start, np.arange(len(ks)), 0))
    first = np.flatnonzero(same & (pos[:-1] % 2 == 0))
    nb = np.full(3 * m, -1, dtype=np.int64)
    i, j = order[first], order[first + 1]
    nb[i] = j // 3
    nb[j] = i // 3
    return nb.reshape(m, 3)


def cell_adjacency(neighbors: np.ndarray, *, active: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each adjacent pair of (active) cells once.

    Parameters
    ----------
    neighbors : (m, 3) int
        See :func:`cell_neighbors`.
    active : (m,) bool, optional
        Only pairs of two active cells are returned (2D: the triangles inside the shape).

    Returns
    -------
    pairs : (p, 2) int
        Cell pairs ``(t, u)`` with ``t < u``.
    corner : (p,) int
        The corner ``k`` of ``t`` opposite the shared edge, so the shared edge is ``cells[t, (k+1)%3]``,
        ``cells[t, (k+2)%3]``.
    """
    neighbors = np.asarray(neighbors, dtype=np.int64)
    t = np.repeat(np.arange(len(neighbors)), 3)
    k = np.tile(np.arange(3), len(neighbors))
    u = neighbors.ravel()
    keep = u > t
    if active is not None:
        active = np.asarray(active, dtype=bool)
        keep &= active[t] & active[np.where(u >= 0, u, 0)]
    return np.stack([t[keep], u[keep]], axis=1), k[keep]


def cut_components(n_cells: int, pairs: np.ndarray, cut: np.ndarray, *,
                   active: np.ndarray | None = None) -> tuple[int, np.ndarray]:
    """Parts of §3: connected components of the cells after cutting the adjacency along separators.

    Parameters
    ----------
    n_cells : int
    pairs : (p, 2) int
        Adjacent cell pairs (from :func:`cell_adjacency`).
    cut : (p,) bool
        True where the shared edge is a separator edge (the dual of a bridge).
    active : (n_cells,) bool, optional
        Cells that take part; the others get label ``-1``.

    Returns
    -------
    n_parts : int
    label : (n_cells,) int
        Part of each cell, ``0 .. n_parts-1``, numbered in order of each part's lowest cell index; ``-1`` for
        inactive cells.
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    keep = ~np.asarray(cut, dtype=bool)
    p = pairs[keep]
    graph = coo_matrix((np.ones(len(p), dtype=np.int8), (p[:, 0], p[:, 1])), shape=(n_cells, n_cells)).tocsr()
    _, raw = connected_components(graph, directed=False)
    label = np.full(n_cells, -1, dtype=np.int64)
    idx = np.arange(n_cells) if active is None else np.flatnonzero(active)
    # renumber the components that contain active cells, by first occurrence
    uniq, first, inv = np.unique(raw[idx], return_index=True, return_inverse=True)
    rank = np.empty(len(uniq), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(uniq))
    label[idx] = rank[inv]
    return len(uniq), label


def part_kinds(vertex_part: np.ndarray, degree: np.ndarray, n_parts: int) -> np.ndarray:
    """Kind of each part from the degrees of the skeleton vertices it contains (§3).

    A part holding a vertex of degree ≥ 3 is a junction; a vertex of degree 0 (a skeleton reduced to one
    point, e.g. a disk) also makes a junction, the one part covering that whole body. Otherwise a part
    holding a vertex of degree 1 is a terminal, and a part holding only degree-2 vertices is linear. The
    precedence junction > terminal > linear only matters for parts that hold vertices of several kinds,
    which the cut along bridges prevents within one connected skeleton.

    Parameters
    ----------
    vertex_part : (n,) int
        Part of each skeleton vertex (``-1``: none).
    degree : (n,) int
    n_parts : int

    Returns
    -------
    (n_parts,) int
        :data:`JUNCTION`, :data:`TERMINAL`, :data:`LINEAR`, or :data:`NO_SKELETON` for a part without
        any skeleton vertex (the caller decides what that becomes).
    """
    vertex_part = np.asarray(vertex_part, dtype=np.int64)
    degree = np.asarray(degree, dtype=np.int64)
    ok = vertex_part >= 0
    vp, d = vertex_part[ok], degree[ok]
    has_j = np.bincount(vp, weights=((d >= 3) | (d == 0)), minlength=n_parts) > 0
    has_t = np.bincount(vp, weights=(d == 1), minlength=n_parts) > 0
    has_any = np.bincount(vp, minlength=n_parts) > 0
    kind = np.full(n_parts, NO_SKELETON, dtype=np.int64)
    kind[has_any] = LINEAR
    kind[has_t] = TERMINAL
    kind[has_j] = JUNCTION
    return kind


def part_boundary_loops(cells: np.ndarray, neighbors: np.ndarray, label: np.ndarray, *,
                        points: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Border of each part chained into closed loops of vertex indices.

    A border half-edge is a cell edge whose neighbour lies in another part, or outside (``-1`` or a cell
    with label ``-1``). Cells must be consistently oriented; each loop then runs with its part on the
    left (counter-clockwise outer loop, clockwise holes, for counter-clockwise planar cells). Each loop bounds
    one component of the part's complement, so where an edge-connected part touches itself at a vertex
    (a pinch: a hole touching the outer border), the outer loop and the hole's loop stay separate simple
    loops instead of one figure-eight. At a pinch, planar ``points`` decide by angle; without them the loop
    leaves the fan of cells it arrived in, which is exact when two fans meet at the vertex (the usual pinch).

    Parameters
    ----------
    cells : (m, 3) int
    neighbors : (m, 3) int
    label : (m,) int
        Part of each cell; ``-1`` for cells in no part.
    points : (v, 2) float, optional
        Planar vertex coordinates, used only at pinch vertices.

    Returns
    -------
    loop_vertices : (h,) int
        The loops' start vertices, loop after loop (each loop's first vertex not repeated).
    loop_offsets : (L+1,) int
        Loop ``i`` is ``loop_vertices[loop_offsets[i]:loop_offsets[i+1]]``; its ``j``-th half-edge runs
        from vertex ``j`` to ``j+1`` (cyclically).
    loop_part : (L,) int
        The part each loop bounds; loops are sorted by part.
    """
    start, cell_of, nxt, part = _border_successor(cells, neighbors, label, points)
    n = len(start)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros(0, np.int64)
    graph = coo_matrix((np.ones(n, dtype=np.int8), (np.arange(n), nxt)), shape=(n, n)).tocsr()
    n_loops, loop_id = connected_components(graph, directed=True, connection="weak")
    rank = _list_rank(nxt, loop_id, n_loops)
    # order: by part, then loop, then position along the loop
    lpart = np.zeros(n_loops, dtype=np.int64)
    lpart[loop_id] = part
    order = np.lexsort((rank, loop_id, lpart[loop_id]))
    lid_sorted = loop_id[order]
    new_start = np.r_[True, lid_sorted[1:] != lid_sorted[:-1]]
    offsets = np.r_[np.flatnonzero(new_start), n]
    return start[order], offsets.astype(np.int64), lpart[lid_sorted[new_start]]


def _border_successor(cells, neighbors, label, points):
    """Border half-edges (start vertex, cell, part) and the index of the next half-edge along the loop."""
    cells = np.asarray(cells, dtype=np.int64)
    neighbors = np.asarray(neighbors, dtype=np.int64)
    label = np.asarray(label, dtype=np.int64)
    nb_label = np.where(neighbors >= 0, label[np.where(neighbors >= 0, neighbors, 0)], -1)
    is_border = (label[:, None] >= 0) & (nb_label != label[:, None])
    t, k = np.nonzero(is_border)
    a = cells[t, (k + 1) % 3]  # half-edge a -> b, cell on its left for CCW cells
    b = cells[t, (k + 2) % 3]
    part = label[t]
    nv = int(cells.max(initial=0)) + 1
    key = part * nv + a
    order = np.argsort(key, kind="stable")
    ks = key[order]
    want = part * nv + b
    pos = np.searchsorted(ks, want)
    count = np.searchsorted(ks, want, side="right") - pos
    if np.any(count == 0):
        raise DecompositionError("part_boundary_loops: a part's border is not closed; "
                                 "are the cells consistently oriented?")
    nxt = order[np.minimum(pos, len(ks) - 1)]
    pinch = np.flatnonzero(count > 1)
    if len(pinch):
        log.debug("part_boundary_loops: %d border half-edges end at a pinch vertex", len(pinch))
        hkey = t * 3 + k  # half-edges are listed in (cell, corner) order, so hkey is sorted
        for h in pinch:
            cand = order[pos[h]:pos[h] + count[h]]
            if points is not None:
                # the next edge bounds the same complement component: the first outgoing border edge
                # counter-clockwise from the way back (b -> a), i.e. turning through the outside
                back = points[a[h]] - points[b[h]]
                out = points[b[cand]] - points[b[h]]
                ang = np.mod(np.arctan2(out[:, 1], out[:, 0]) - np.arctan2(back[1], back[0]), 2 * np.pi)
                nxt[h] = cand[np.argmin(np.where(ang > 0, ang, 2 * np.pi))]
                continue
            # without coordinates: leave the wedge of cells the half-edge belongs to (right for two wedges)
            own = _wedge_exit(cells, neighbors, is_border, t[h], b[h], hkey)
            others = cand[cand != own]
            nxt[h] = others[0] if len(others) else own
    return a, t, nxt, part


def _wedge_exit(cells, neighbors, is_border, cell, vb, hkey):
    """The border half-edge leaving vertex ``vb`` that closes the fan of part cells containing ``cell``."""
    for _ in range(len(cells)):
        kb = int(np.flatnonzero(cells[cell] == vb)[0])
        kout = (kb + 2) % 3  # the edge opposite corner kout runs vb -> the next corner
        if is_border[cell, kout]:
            return int(np.searchsorted(hkey, cell * 3 + kout))
        cell = neighbors[cell, kout]
    raise DecompositionError("part_boundary_loops: could not walk around a pinch vertex")  # pragma: no cover


def _list_rank(nxt: np.ndarray, loop_id: np.ndarray, n_loops: int) -> np.ndarray:
    """Position of each element along its cycle, counted from the cycle's lowest index (pointer jumping)."""
    n = len(nxt)
    head = np.full(n_loops, n, dtype=np.int64)
    np.minimum.at(head, loop_id, np.arange(n))
    is_head = np.zeros(n, dtype=bool)
    is_head[head] = True
    # distance to the head along successors: d[i] = 0 at the head, else 1 + d[nxt[i]] ... computed as
    # the distance *from* i *to* the head; rank = length - that distance (mod length)
    dist = np.where(is_head, 0, 1).astype(np.int64)
    ptr = np.where(is_head, np.arange(n), nxt)
    while True:
        done = is_head[ptr]
        if done.all():
            break
        dist = dist + np.where(done, 0, dist[ptr])
        ptr = np.where(done, ptr, ptr[ptr])
    length = np.bincount(loop_id, minlength=n_loops)[loop_id]
    return (length - dist) % length
