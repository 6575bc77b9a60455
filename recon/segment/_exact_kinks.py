"""Kinks where the exact path's faces meet: a note when the face count they give is not proven.

A blend meets the faces it rounds tangentially. Where a plane of one or two triangles meets a curved face across a
smooth edge at a kink, a variable-radius blend (a B-spline no analytic surface holds) was probably cut into analytic
pieces and planes, so the face count there is not proven (measured: bench/exact.md). What counts as a kink is the
turn a correct partition cannot show: the triangle's own round-off tilt, and for a face the second pass made (rims
that may miss it by the run's tolerance) the tilt of a surface fitted through points that miss by that much.

numpy only; the surfaces' normals come from :mod:`recon.fit`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..fit import surface_normals

__all__ = ["fit_tilt", "kinks", "roundoff_tilt", "shortest_height", "tangent_misses"]


def shortest_height(P: np.ndarray) -> float:
    """A triangle's shortest height: the lever its vertices' round-off tilts its normal by."""
    return float(np.linalg.norm(np.cross(P[1] - P[0], P[2] - P[0])) / np.linalg.norm(P - P[[1, 2, 0]], axis=1).max())


def roundoff_tilt(P: np.ndarray, eps: float) -> float:
    """How far round-off ``eps`` at its corners may tilt a triangle ``P``'s normal: 2 eps over its shortest height."""
    return 2 * eps / shortest_height(P)


def fit_tilt(face: np.ndarray, at: np.ndarray, tol: float) -> float:
    """How far a surface fitted through the points ``face``, each off it by up to ``tol``, may tilt its normal at the
    point ``at``: 2 tol over the face's reach from there."""
    return 2 * tol / np.linalg.norm(face - at, axis=1).max()


def _face_points(V: np.ndarray, F: np.ndarray, labels: np.ndarray, cache: dict, p: int) -> np.ndarray:
    """The vertices of face ``p``, found once per face (``cache``)."""
    if p not in cache:
        cache[p] = V[np.unique(F[labels == p])]
    return cache[p]


def kinks(mesh: Any, pairs: np.ndarray, labels: np.ndarray, fits: dict, eps: float, loose: np.ndarray, tol: float,
          cos_crease: float, curved: frozenset) -> list[str]:
    """A note when a plane of one or two triangles meets a curved face across a smooth edge at a kink (``loose[p]``:
    the second pass made face p, its rims missing it by up to ``tol``).

    The turn is the curved surface's normal at the edge's ends against the triangle's. It is a kink above the
    triangle's round-off tilt (2 eps over its shortest height) and, on a face made with rims missing by up to ``tol``,
    above that fit's own tilt: 2 tol over the face's reach from the edge (a plane tangent to a fillet shows 1e-4 rad
    there, a variable fillet cut into cylinders 0.08-0.2 rad: export seeds 39, 73 against 25, 30)."""
    V, F = mesh.vertices, mesh.faces
    ends = np.asarray(mesh.face_adjacency_edges, dtype=np.int64).reshape(-1, 2)
    count = np.bincount(labels, minlength=len(fits))
    n = mesh.face_normals
    small_plane = np.array([fits[p].type == "plane" and count[p] <= 2 for p in range(len(fits))])
    la, lb = labels[pairs[:, 0]], labels[pairs[:, 1]]
    # only smooth edges between two faces, one of them a plane of one or two triangles: the rest cannot be a kink
    near = (la != lb) & (small_plane[la] | small_plane[lb])
    near &= np.einsum("ij,ij->i", n[pairs[:, 0]], n[pairs[:, 1]]) >= cos_crease
    found = 0
    faces: dict = {}
    for (t, u), e in zip(pairs[near], ends[near]):
        a, b = int(labels[t]), int(labels[u])
        for tri, p, c in ((t, a, b), (u, b, a)):
            if not small_plane[p] or fits[c].type not in curved:
                continue
            turn = np.arccos(np.clip(np.abs(surface_normals(fits[c], V[e]) @ n[tri]), 0.0, 1.0)).max()
            bound = roundoff_tilt(V[F[tri]], eps)
            if loose[c]:
                bound = max(bound, fit_tilt(_face_points(V, F, labels, faces, c), V[e].mean(axis=0), tol))
            found += bool(turn > bound)
    if not found:
        return []
    return [f"face count not proven: {found} edge(s) where a plane of one or two triangles meets a curved face at a "
            f"kink, not tangentially (a variable-radius blend cut into analytic pieces?)"]


def tangent_misses(mesh: Any, pairs: np.ndarray, labels: np.ndarray, fits: dict, tol: float, smooth: np.ndarray,
                   curved: frozenset) -> np.ndarray:
    """(e,) bool: the smooth edges where a curved face meets a plane of more than two triangles at a kink: their
    surfaces' normals at the edge's ends turn by more than two fits through points within ``tol`` can tilt (2 tol
    over each face's reach from the edge). A coincidental analytic piece of a blend misses the plane the blend is
    tangent to by hundreds of times the tilt of round-off; a true face tangent to its plane by a few times at most,
    far under this bound where the tolerance is tens of round-offs (measured: bench/exact.md "s42-ff")."""
    V, F = mesh.vertices, mesh.faces
    count = np.bincount(labels, minlength=len(fits))
    kind = np.array([fits[p].type for p in range(len(fits))])
    is_curved = np.isin(kind, list(curved))
    big_plane = (kind == "plane") & (count > 2)
    la, lb = labels[pairs[:, 0]], labels[pairs[:, 1]]
    ask = smooth & (la != lb) & ((is_curved[la] & big_plane[lb]) | (is_curved[lb] & big_plane[la]))
    out = np.zeros(len(pairs), bool)
    if not ask.any():
        return out
    ends = np.asarray(mesh.face_adjacency_edges, dtype=np.int64).reshape(-1, 2)
    faces: dict = {}
    for i in np.flatnonzero(ask).tolist():
        p, q = (int(la[i]), int(lb[i])) if is_curved[la[i]] else (int(lb[i]), int(la[i]))
        e = V[ends[i]]
        turn = np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", surface_normals(fits[p], e),
                                                  surface_normals(fits[q], e))), 0.0, 1.0)).max()
        mid = e.mean(axis=0)
        bound = sum(fit_tilt(_face_points(V, F, labels, faces, f), mid, tol) for f in (p, q))
        out[i] = bool(turn > bound)
    return out
