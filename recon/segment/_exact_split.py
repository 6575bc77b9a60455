"""Plane atoms of the exact path split where a curved face's triangles lie in one plane with a neighbour's.

A plane atom is a maximal set of triangles one plane holds to round-off. Where a face meets a curved face tangentially
(a fillet along a cylinder's rim), a triangle of the fillet can lie in the plane of the cylinder's quad next to it, to
round-off: the atom spans two true faces, no curved surface holds it whole, and the cylinder's strip it belongs to is
cut there (bench/exact.md, "Exit 0 with a wrong face count"). Here each curved region, largest first, takes the single
triangles of such atoms that its surface holds (every vertex to round-off, every chord within the sag), reached across
smooth edges from its own triangles and whose normal agrees with the surface's there (:func:`recon.fit.surface_normals`),
as a chord's does; what is left of the atom stays an atom. The surface test is the caller's ``holds(fit, ids, tris)``.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np
import scipy.sparse as sp

from ..fit import surface_normals

__all__ = ["split_atoms"]

Holds = Callable[[Any, np.ndarray, np.ndarray], bool]


def _chord_normal_ok(fit: Any, V: np.ndarray, tri: np.ndarray, eps: float) -> bool:
    """Whether the triangle's normal lies among the surface's normals at its corners, as a chord's does: its angle to
    the surface's normal at the centroid at most the widest angle between the corners' normals, plus the tilt that
    ``eps`` of round-off at the corners gives over the triangle's shortest height. (A plane's triangle whose corners
    happen to lie on a curved face it cuts at a small angle is off by that angle.)"""
    P = V[tri]
    n = np.cross(P[1] - P[0], P[2] - P[0])
    area2 = float(np.linalg.norm(n))
    longest = float(np.max(np.linalg.norm(P - np.roll(P, 1, axis=0), axis=1)))
    if area2 <= 0.0 or longest <= 0.0:
        return False
    N = surface_normals(fit, np.vstack([P, P.mean(axis=0, keepdims=True)]))
    spread = float(np.arccos(np.clip(np.min(N[:3] @ N[:3].T), -1.0, 1.0)))
    slack = 2 * eps / (area2 / longest)  # round-off tilt over the shortest height
    turn = float(np.arccos(np.clip(abs(float(n @ N[3])) / area2, -1.0, 1.0)))
    return turn <= spread + slack


#: A curved face's share of a mixed atom is what a strip gives an atom: a quad (two triangles) or a fan's triangle. A
#: surface holding more of a plane atom's triangles is tangent to that plane along their corners (a fillet's rim circle
#: on the plane it rounds into: the plane's fan triangles there have every corner on the torus), not through it.
SHARE_TRIANGLES = 2


def _take(at: Any, fit: Any, own: np.ndarray, i: int, size: np.ndarray, tnb: sp.csr_matrix, cos_crease: float,
          eps: float, holds: Holds) -> None:
    """Region ``i`` takes the part of each mixed plane atom its surface holds (at most :data:`SHARE_TRIANGLES`
    triangles, not the whole atom: whole atoms are reclaim's), reached across smooth edges from its triangles and
    belonging to no region as large (``own``: region per triangle, updated in place)."""
    V, F, fn = at.mesh.vertices, at.mesh.faces, at.mesh.face_normals
    decided: set = set()
    front = np.flatnonzero(own == i).tolist()
    while front:
        t = front.pop()
        for u in tnb.indices[tnb.indptr[t]:tnb.indptr[t + 1]].tolist():
            a = int(at.labels[u])
            if a in decided or own[u] == i or float(fn[t] @ fn[u]) < cos_crease:
                continue
            decided.add(a)
            tris = at.tris[a]
            free = [x for x in tris.tolist() if own[x] != i and (own[x] < 0 or size[own[x]] < size[i])]
            held = [x for x in free if holds(fit, F[x], np.array([x])) and _chord_normal_ok(fit, V, F[x], eps)]
            if u not in held or len(held) > SHARE_TRIANGLES or len(held) == len(tris):
                continue
            for x in held:
                if own[x] >= 0:
                    size[own[x]] -= 1
                own[x] = i
            size[i] += len(held)
            front.extend(held)


def _relabel(at: Any, own: np.ndarray) -> tuple[np.ndarray, dict]:
    """New atom labels: each atom split by the region (or none) of its triangles and into edge-connected pieces, the
    first piece keeping the atom's id; and the region of every atom."""
    labels = at.labels.copy()
    k = len(at.tris)
    pairs = np.asarray(at.mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    region_of: dict = {}
    for a, tris in enumerate(at.tris):
        groups = own[tris]
        if (groups == groups[0]).all():
            region_of[a] = int(groups[0])
            continue
        # pieces: triangles of one region joined by the atom's inner edges
        local = {t: j for j, t in enumerate(tris.tolist())}
        inner = [(local[x], local[y]) for x, y in pairs[np.isin(pairs[:, 0], tris) & np.isin(pairs[:, 1], tris)].tolist()
                 if own[x] == own[y]]
        g = sp.coo_matrix((np.ones(len(inner)), ([p for p, _ in inner], [q for _, q in inner])), shape=(len(tris),) * 2)
        _, comp = sp.csgraph.connected_components(g, directed=False)
        for c in range(int(comp.max()) + 1):
            piece = tris[comp == c]
            lab = a if c == 0 else k
            k += c > 0
            labels[piece] = lab
            region_of[lab] = int(own[piece[0]])
    return labels, region_of


def split_atoms(at: Any, regions: list, eps: float, cos_crease: float, holds: Holds,
                rebuild: Callable[[np.ndarray], Any]) -> tuple[Any, list]:
    """``(atoms, regions)`` after each curved region ``(atoms, fit)``, largest first, took the triangles of mixed
    plane atoms its surface holds (see the module's text); ``rebuild(labels)`` makes the atoms of new labels. Unchanged
    when no region takes a triangle."""
    F = at.mesh.faces
    own = np.full(len(F), -1, dtype=np.int64)
    for i, (r, _) in enumerate(regions):
        for a in r:
            own[at.tris[a]] = i
    before = own.copy()
    size = np.bincount(own[own >= 0], minlength=len(regions)).astype(np.int64)
    pairs = np.asarray(at.mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    m = len(F)
    tnb = sp.coo_matrix((np.ones(2 * len(pairs)), (np.r_[pairs[:, 0], pairs[:, 1]], np.r_[pairs[:, 1], pairs[:, 0]])),
                        shape=(m, m)).tocsr()
    for i in sorted(range(len(regions)), key=lambda j: -size[j]):
        _take(at, regions[i][1], own, i, size, tnb, cos_crease, eps, holds)
    if (own == before).all():
        return at, regions
    labels, region_of = _relabel(at, own)
    members: list = [[] for _ in regions]
    for a, i in sorted(region_of.items()):
        if i >= 0:
            members[i].append(a)
    return rebuild(labels), [(members[i], fit) for i, (_, fit) in enumerate(regions) if members[i]]
