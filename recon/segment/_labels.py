"""Face labels as arrays: connected pieces, absorption of small pieces, vertex sets per label (numpy/scipy only).

A labelling is an (m,) int64 array over the triangles; ``pairs`` (e, 2) are the triangles sharing an edge.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..mesh import unique

__all__ = ["absorb", "coplanar_pieces", "drawn_flat", "majority_neighbour", "one_label", "split_disconnected",
           "vertex_counts", "vertex_sets", "vertices_of", "DRAWN_AREA_RATIO"]

#: A flat piece a CAD export drew with a few large triangles has a mean triangle area this many times the mesh's
#: median: the debris noise-free meshes leave between curved faces stays under 1.4, drawn faces are 4 and more.
DRAWN_AREA_RATIO = 3.0


def majority_neighbour(labels: np.ndarray, pairs: np.ndarray, movable: np.ndarray) -> np.ndarray:
    """For every triangle in ``movable``, the most frequent label among its non-movable neighbours (−1 if none)."""
    a, b = pairs[:, 0], pairs[:, 1]
    rows = np.concatenate([a, b])
    nbr = np.concatenate([labels[b], labels[a]])
    keep = movable[rows] & ~movable[np.concatenate([b, a])]
    rows, nbr = rows[keep], nbr[keep]
    out = np.full(len(labels), -1, dtype=np.int64)
    if len(rows) == 0:
        return out
    order = np.lexsort((nbr, rows))
    rows, nbr = rows[order], nbr[order]
    key_change = np.r_[True, (rows[1:] != rows[:-1]) | (nbr[1:] != nbr[:-1])]
    starts = np.flatnonzero(key_change)
    counts = np.diff(np.r_[starts, len(rows)])
    r, n = rows[starts], nbr[starts]
    best = np.lexsort((-counts, r))  # per row, highest count first
    r, n = r[best], n[best]
    first = np.r_[True, r[1:] != r[:-1]]
    out[r[first]] = n[first]
    return out


def absorb(labels: np.ndarray, pairs: np.ndarray, movable: np.ndarray) -> np.ndarray:
    """Give every movable triangle the label of the region it touches most, growing inwards layer by layer."""
    labels = labels.copy()
    movable = movable.copy()
    while movable.any():
        nbr = majority_neighbour(labels, pairs, movable)
        take = movable & (nbr >= 0)
        if not take.any():
            break  # an island of movable triangles touching nothing else: leave it as it is
        labels[take] = nbr[take]
        movable[take] = False
    return labels


def one_label(m: int, tris: np.ndarray) -> np.ndarray:
    """Labels of ``m`` triangles: 0 on ``tris``, 1 elsewhere."""
    lab = np.ones(m, dtype=np.int64)
    lab[tris] = 0
    return lab


def vertices_of(F: np.ndarray, tris, n: int) -> np.ndarray:
    """``np.unique(F[tris])``: the sorted ids (of ``n`` vertices) of the triangles ``tris``. By a mask over the
    vertices when the corners are not few beside them (no sort: the fit stage asks this of large faces many times)."""
    idx = F[tris].ravel()
    if len(idx) * 32 < n:
        return np.unique(idx)
    mask = np.zeros(n, bool)
    mask[idx] = True
    return np.flatnonzero(mask)


def vertex_sets(F: np.ndarray, labels: np.ndarray, n: int):
    """``lambda q: vertices_of(F, labels == q, n)`` for every label at once: the distinct (label, vertex) pairs
    from one sort of their packed keys (a pass over the mesh per label costs more for more than a few)."""
    key = unique(np.repeat(labels, 3) * np.int64(n) + F.ravel())
    lab = key // n
    bounds = np.searchsorted(lab, np.arange(int(labels.max()) + 2))
    vert = key - lab * n
    return lambda q: vert[bounds[q] : bounds[q + 1]]


def vertex_counts(faces: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """The number of distinct vertices of every label, (k,) int."""
    k = int(labels.max()) + 1
    n = int(faces.max()) + 1
    # distinct (label, vertex) pairs counted per label, as packed keys label · n + vertex sorted by numpy's
    # vectorised sort (np.unique on rows sorts them lexicographically: 15 s at 1M triangles; a sparse label ×
    # vertex matrix's sum_duplicates 16 ms at 100k, this 3 ms)
    key = np.repeat(labels, 3) * np.int64(n) + faces.ravel()
    key.sort()
    distinct = key[np.r_[True, key[1:] != key[:-1]]]
    return np.bincount(distinct // n, minlength=k)


def split_disconnected(labels: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """One label per connected piece of every label (the pieces' numbers are scipy's component ids)."""
    same = labels[pairs[:, 0]] == labels[pairs[:, 1]]
    a, b = pairs[same].T
    m = len(labels)
    graph = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(m, m))
    _, comp = sp.csgraph.connected_components(graph, directed=False)
    return comp


def coplanar_pieces(V: np.ndarray, F: np.ndarray, tris: np.ndarray, pairs: np.ndarray, tolerance: float) -> list:
    """The triangles ``tris`` as connected pieces whose neighbouring triangles lie in one plane: two triangles
    sharing an edge join when each one's far vertex lies within ``tolerance`` of the other's plane."""
    inside = np.isin(pairs[:, 0], tris) & np.isin(pairs[:, 1], tris)
    a, b = pairs[inside, 0], pairs[inside, 1]
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

    def off(x, y):  # the largest distance of y's corners from x's plane
        return np.abs(np.einsum("ij,ikj->ik", n[x], V[F[y]] - V[F[x, 0]][:, None, :])).max(axis=1)

    flat = (off(a, b) <= tolerance) & (off(b, a) <= tolerance)
    m = len(F)
    graph = sp.coo_matrix((np.ones(int(flat.sum())), (a[flat], b[flat])), shape=(m, m))
    _, comp = sp.csgraph.connected_components(graph, directed=False)
    comp = comp[tris]
    return [tris[comp == c] for c in np.unique(comp)]


def drawn_flat(face_areas: np.ndarray):
    """A test of triangle sets: whether their mean area is :data:`DRAWN_AREA_RATIO` times the mesh's median
    triangle area or more (a flat face a CAD export drew with a few large triangles)."""
    limit = DRAWN_AREA_RATIO * float(np.median(face_areas))
    return lambda tris: len(tris) > 0 and float(face_areas[tris].mean()) >= limit
