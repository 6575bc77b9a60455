"""Edge topology of a triangle list, vectorised (sort-based, no Python loops over triangles).

Half-edge ``3 f + i`` of triangle ``f`` runs from ``faces[f, i]`` to ``faces[f, (i + 1) % 3]``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["unique_edges", "halfedge_order", "manifold_pairs", "unique_rows"]


def unique_rows(keys: np.ndarray, upper: int) -> tuple[np.ndarray, np.ndarray]:
    """Group equal rows of a small non-negative int array.

    Parameters
    ----------
    keys : (n, d) int
        Values in ``[0, upper)``.
    upper : int

    Returns
    -------
    first : (u,) int
        Index of the first occurrence of each distinct row, in order of the sorted rows.
    inverse : (n,) int
        Distinct-row id of every row.
    """
    keys = np.asarray(keys, dtype=np.int64)
    d = keys.shape[1]
    if upper <= 1 or d * np.log2(upper) < 62:
        # Pack each row into one int64: a 1-D sort is several times faster than np.unique(axis=0).
        packed = np.zeros(len(keys), dtype=np.int64)
        for j in range(d):
            packed = packed * np.int64(max(upper, 1)) + keys[:, j]
        _, first, inverse = np.unique(packed, return_index=True, return_inverse=True)
    else:
        _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    return first.astype(np.int64), inverse.reshape(-1).astype(np.int64)


def unique_edges(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edges of a triangle list.

    Parameters
    ----------
    faces : (m, 3) int
    n_vertices : int

    Returns
    -------
    edges : (k, 2) int
        Each edge once as ``(low, high)``, sorted lexicographically.
    face_edges : (m, 3) int
        Edge index of half-edge ``i`` of each triangle.
    count : (k,) int
        Number of half-edges (triangles) on each edge.
    """
    he = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lo = he.min(axis=1)
    hi = he.max(axis=1)
    first, inverse = unique_rows(np.column_stack([lo, hi]), n_vertices)
    edges = np.column_stack([lo[first], hi[first]])
    count = np.bincount(inverse, minlength=len(first)).astype(np.int64)
    return edges, inverse.reshape(-1, 3), count


def halfedge_order(face_edges: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Half-edges grouped by edge.

    Returns
    -------
    order : (3 m,) int
        Half-edge ids sorted by edge (stable: ascending triangle within an edge).
    start : (k + 1,) int
        Edge ``e`` owns ``order[start[e]:start[e + 1]]``.
    """
    order = np.argsort(face_edges.ravel(), kind="stable")
    start = np.zeros(len(count) + 1, dtype=np.int64)
    np.cumsum(count, out=start[1:])
    return order, start


def manifold_pairs(face_edges: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of triangles sharing an edge that exactly two triangles use.

    Returns
    -------
    pairs : (p, 2) int
        Triangle pairs, the lower index first.
    edge : (p,) int
        The shared edge of each pair.
    """
    order, start = halfedge_order(face_edges, count)
    edge = np.flatnonzero(count == 2)
    a = order[start[edge]] // 3
    b = order[start[edge] + 1] // 3
    return np.column_stack([a, b]), edge
