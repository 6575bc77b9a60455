"""Spikes: single vertices a scanner threw far off the surface (outliers), found from their own ring and moved back.

A spike is a vertex whose one-ring of neighbours lies on a plane to within the noise while the vertex itself stands
off that plane by many times the noise and steeply (a tent): no surface through the neighbours passes through it.
A vertex on a sharp edge or corner is not one (its ring is not planar), nor one on a curved face (its ring's
offset grows as h²/2R, the same as its neighbours'). A spike is moved to its ring's centroid: the triangles stay,
so the mesh keeps its topology and closes where it was closed; the report says how many moved and how far.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix

from .._tolerance import MESH_FLOOR
from ._types import Mesh

__all__ = ["SpikeReport", "move_spikes", "find_spikes"]

log = logging.getLogger(__name__)

#: Noise scales between the ring's plane and a spike: a vertex that noise alone put this far off has odds below
#: 1e-15 under Gaussian noise, so on a million-vertex scan no true vertex is taken for one.
SPIKE_SIGMAS = 8.0

#: The least slope of the tent a spike stands on (offset / ring radius): below it the offset is what a curved face
#: gives a clean ring (h/2R), however small its neighbours' noise.
SPIKE_SLOPE = 0.25

#: A tent all round: the triangles of the vertex's fan turn from the triangles beyond them by at least half the
#: least tent's slope angle, in the median (a corner's fan lies flat on its faces' other triangles, but for the
#: link edges on its creases; a spike pushed sideways folds a triangle or two of its fan).
LINK_TURN = 0.5 * float(np.arctan(SPIKE_SLOPE))


@dataclass(frozen=True)
class SpikeReport:
    """The vertices :func:`move_spikes` moved.

    Attributes
    ----------
    vertices : (k,) int
        Their indices.
    offsets : (k,) float
        How far each was moved (mesh units).
    """

    vertices: np.ndarray
    offsets: np.ndarray

    def to_json(self, diagonal: float) -> dict:
        top = float(self.offsets.max()) if len(self.offsets) else 0.0
        return {"count": int(len(self.vertices)), "max_moved": top, "max_moved_pct": 100.0 * top / diagonal}


def _ring_planes(vertices: np.ndarray, edges: np.ndarray, interior: np.ndarray):
    """Per vertex: its neighbours' centroid, the normal and RMS residual of their least-squares plane, and their
    mean distance from the centroid (the ring's radius)."""
    n = len(vertices)
    i = np.concatenate([edges[:, 0], edges[:, 1]])
    j = np.concatenate([edges[:, 1], edges[:, 0]])
    adj = csr_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    deg = np.maximum(np.asarray(adj.sum(axis=1)).ravel(), 1.0)
    centroid = (adj @ vertices) / deg[:, None]
    outer = (adj @ (vertices[:, :, None] * vertices[:, None, :]).reshape(n, 9)).reshape(n, 3, 3) / deg[:, None, None]
    cov = outer - centroid[:, :, None] * centroid[:, None, :]
    values, vectors = np.linalg.eigh(cov[interior])
    normal = np.zeros((n, 3))
    residual = np.zeros(n)
    normal[interior] = vectors[:, :, 0]
    residual[interior] = np.sqrt(np.maximum(values[:, 0], 0.0))
    d = np.linalg.norm(vertices[j] - centroid[i], axis=1)
    radius = np.bincount(i, weights=d, minlength=n) / deg
    return centroid, normal, residual, radius


def _median_link_turn(mesh: Mesh) -> np.ndarray:
    """Per vertex: the median angle between a triangle of its fan and the triangle across that triangle's far edge
    (the edge opposite the vertex, on its link; the lower middle one of an even count); 0 where it has none."""
    pairs = mesh.face_adjacency
    shared = mesh.face_adjacency_edges
    cos = np.einsum("ij,ij->i", mesh.face_normals[pairs[:, 0]], mesh.face_normals[pairs[:, 1]])
    turn = np.arccos(np.clip(cos, -1.0, 1.0))
    # the vertex of each triangle of a pair that is not on their shared edge
    far = np.concatenate([mesh.faces[pairs[:, side]].sum(axis=1) - shared.sum(axis=1) for side in (0, 1)])
    turns = np.concatenate([turn, turn])
    order = np.lexsort((turns, far))
    counts = np.bincount(far, minlength=len(mesh.vertices))
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    median = np.zeros(len(mesh.vertices))
    has = counts > 0
    median[has] = turns[order[starts[has] + (counts[has] - 1) // 2]]
    return median


def find_spikes(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """The spike vertices of ``mesh`` and where each goes (its ring's centroid); interior vertices only."""
    v = mesh.vertices
    edges = mesh.edges_unique
    counts = mesh.edge_face_count
    interior = np.ones(len(v), dtype=bool)
    interior[edges[counts != 2].ravel()] = False  # a boundary or non-manifold vertex has no closed ring
    deg = np.bincount(edges.ravel(), minlength=len(v))
    interior &= deg >= 4  # three points always lie on a plane: no residual to judge by
    centroid, normal, residual, radius = _ring_planes(v, edges, interior)
    offset = np.abs(np.einsum("ij,ij->i", v - centroid, normal))
    # the noise scale: the ring's own residual, at least the offsets' robust spread over the mesh (1.4826 × their
    # median is σ for Gaussian noise); not the neighbours' offsets, which the spike in their rings inflates
    spread = 1.4826 * float(np.median(offset[interior])) if interior.any() else 0.0
    scale = np.maximum(residual, spread)
    # nearer its ring's plane than the least default tolerance, a vertex is within what any result may deviate
    spike = interior & (offset > SPIKE_SIGMAS * scale) & (offset > SPIKE_SLOPE * radius)
    spike &= offset > MESH_FLOOR * mesh.diagonal
    if spike.any():
        spike &= _median_link_turn(mesh) > LINK_TURN
    return np.flatnonzero(spike), centroid[spike]


def move_spikes(mesh: Mesh) -> tuple[Mesh, SpikeReport]:
    """``mesh`` with every spike (:func:`find_spikes`) moved to its ring's centroid, and what moved."""
    index, target = find_spikes(mesh)
    if not len(index):
        return mesh, SpikeReport(index, np.zeros(0))
    offsets = np.linalg.norm(mesh.vertices[index] - target, axis=1)
    vertices = mesh.vertices.copy()
    vertices[index] = target
    log.info("%d spike vertices moved onto their rings (up to %.4g)", len(index), offsets.max())
    return dataclasses.replace(mesh, vertices=vertices), SpikeReport(index, offsets)
