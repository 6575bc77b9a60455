"""Edge and triangle adjacency of a face array, computed once and shared by the decomposition steps."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh import stable_argsort, unique

__all__ = ["Topology", "topology", "unique"]


@dataclass(frozen=True)
class Topology:
    """Half-edges, undirected edges and manifold triangle adjacency.

    Attributes
    ----------
    half_start, half_end : (3m,) int
        Half-edge ``h = 3 f + k`` runs from ``faces[f, k]`` to ``faces[f, (k+1) % 3]``.
    half_edge : (3m,) int
        Undirected edge index of each half-edge.
    edges : (E, 2) int
        Undirected edges, smaller vertex first.
    twin : (3m,) int
        The opposite half-edge across a manifold edge; −1 on a border or non-manifold edge.
    twin_pairs : ((t,) int, (t,) int)
        The manifold edges' two half-edges, the smaller first, in edge order
        (:func:`recon.features.hinge_pairs`).
    """

    half_start: np.ndarray
    half_end: np.ndarray
    half_edge: np.ndarray
    edges: np.ndarray
    twin: np.ndarray
    twin_pairs: tuple = ()

    @property
    def half_face(self) -> np.ndarray:
        return np.arange(len(self.half_start)) // 3


def topology(faces: np.ndarray, n_vertices: int) -> Topology:
    """Build :class:`Topology` for ``faces`` (m, 3) int."""
    start = faces.ravel()
    end = np.roll(faces, -1, axis=1).ravel()
    lo = np.minimum(start, end)
    hi = np.maximum(start, end)
    key = lo * np.int64(n_vertices) + hi
    # np.unique(key, return_inverse=True, return_counts=True) from one stable argsort, which also orders the
    # half-edges by edge (the stable argsort of the inverse is that of the keys)
    order = stable_argsort(key, n_vertices * n_vertices)
    aux = key[order]
    mask = np.empty(len(aux), bool)
    mask[:1] = True
    np.not_equal(aux[1:], aux[:-1], out=mask[1:])
    uniq = aux[mask]
    inv = np.empty(len(key), np.intp)
    inv[order] = np.cumsum(mask) - 1
    counts = np.diff(np.append(np.flatnonzero(mask), len(mask)))
    edges = np.stack([uniq // n_vertices, uniq % n_vertices], axis=1)
    twin = np.full(len(key), -1, dtype=np.int64)
    two = counts[inv[order]] == 2
    first = order[two][0::2]
    second = order[two][1::2]
    twin[first] = second
    twin[second] = first
    return Topology(half_start=start, half_end=end, half_edge=inv, edges=edges, twin=twin, twin_pairs=(first, second))
