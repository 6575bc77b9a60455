"""Whether a mesh is a CAD tessellation with exact vertices: the exact path's gate. numpy only."""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh

__all__ = ["FLAT_SHARE", "INNER_SHARE", "coplanar_pairs", "exact_tessellation", "tri_planes"]

#: On a CAD tessellation every plane and every quad of a cylinder's strip is a coplanar pair of triangles, a share
#: of a few tenths of the pairs; noise leaves coplanar pairs only by chance (a few in a thousand).
FLAT_SHARE = 0.02
#: A CAD tessellation draws a plane by its boundary: at most this share of its planes' vertices are inside them next
#: to another inside vertex (a remesher puts most of a plane's vertices inside; a fan's one centre is not counted).
INNER_SHARE = 0.02


def tri_planes(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (m, 3) and offsets (m,) of the triangles' planes."""
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return n, np.einsum("ij,ij->i", n, V[F[:, 0]])


def coplanar_pairs(mesh: Mesh, eps: float) -> np.ndarray:
    """(e,) bool over ``mesh.face_adjacency``: the two triangles lie in one plane (each one's far vertex within
    ``eps`` of the other's plane)."""
    V, F = mesh.vertices, mesh.faces
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    nrm, off = tri_planes(V, F)
    ok = np.ones(len(pairs), bool)
    for x, y in ((0, 1), (1, 0)):
        far = np.abs(np.einsum("ijk,ik->ij", V[F[pairs[:, y]]], nrm[pairs[:, x]]) - off[pairs[:, x], None])
        ok &= far.max(axis=1) <= eps
    return ok


def exact_tessellation(mesh: Mesh, eps: float) -> bool:
    """Whether the mesh is a CAD tessellation with exact vertices: at least :data:`FLAT_SHARE` of its triangle pairs
    lie in one plane to round-off ``eps``, and its planes are drawn by their boundaries — at most
    :data:`INNER_SHARE` of the vertices of coplanar triangles are inside a plane (every pair around them coplanar)
    next to another such vertex (a fan's centre, alone inside its disc, is allowed). A scan's noise leaves no coplanar
    pairs; a remesher's planes have most of their vertices inside, next to each other."""
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    if len(pairs) == 0:
        return False
    flat = coplanar_pairs(mesh, eps)
    if flat.mean() < FLAT_SHARE:
        return False
    # a vertex is inside a plane when every edge around it joins two coplanar triangles
    edges = np.asarray(mesh.face_adjacency_edges, dtype=np.int64).reshape(-1, 2)
    n = len(mesh.vertices)
    crease = np.zeros(n, bool)
    crease[edges[~flat].ravel()] = True
    on = np.zeros(n, bool)
    on[edges[flat].ravel()] = True
    rim = np.asarray(mesh.edge_face_count) != 2  # an open mesh's rim is no plane's inside
    crease[np.asarray(mesh.edges_unique)[rim].ravel()] = True
    inner = on & ~crease
    # a fan drawn from one centre (a disc's cap) is still drawn by its boundary: its centre has no inner neighbour
    deep = np.zeros(n, bool)
    e = np.asarray(mesh.edges_unique, dtype=np.int64).reshape(-1, 2)
    both = inner[e[:, 0]] & inner[e[:, 1]]
    deep[e[both].ravel()] = True
    return bool(deep.sum() <= INNER_SHARE * on.sum())
