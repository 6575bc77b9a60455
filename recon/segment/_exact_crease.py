"""Creases inside a free-form face: where the exact path's B-spline held faces that meet at an angle.

A B-spline fitted to a few dozen exact vertices bends as sharply as it must: one can hold a variable fillet and the
chamfers at its ends within the tolerance, across creases of 24-49°. The dihedral angle alone cannot tell such a
crease: on a coarse export two triangles inside one smooth face turn by up to the tessellator's angular limit, and
further where a long sliver spans a fillet's arc (a fillet's triangle may tilt 40° from its surface at its far
vertex). What does tell it: the piece is cut where its triangles turn most, until it falls into two sides each a
B-spline can be fitted to, and each side's own surface gives its normal at the vertices the sides share. Across a
smooth cut both sides fit one surface and their normals there agree (the triangles' dihedral is their own tilt);
across a crease each side's normal is its own face's and they differ by the crease angle, which the triangles on
each side show too. So the cut is a crease when the sides' normals differ by more than half the triangles' dihedral
across it: the midpoint between the two answers, 0 and the dihedral itself.
numpy/scipy only; the B-splines are fitted by the caller.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..fit import surface_normals
from ._exact_enclosed import components

__all__ = ["MIN_SIDE_VERTICES", "crease_inside", "creased_note"]

#: A side must give a B-spline of its own: the fitter's smallest patch (a 4×4 bicubic control grid).
MIN_SIDE_VERTICES = 16


def _big_sides(F: np.ndarray, tris: np.ndarray, inner: np.ndarray, angle: np.ndarray) -> list[np.ndarray] | None:
    """The sides (triangle sets of at least :data:`MIN_SIDE_VERTICES` vertices) of the piece ``tris`` cut along its
    sharpest inner edges, at the highest dihedral at which it falls into two such sides or more; None if it never
    does. ``inner`` (e, 2) pairs of ``tris``'s triangles sharing an edge, ``angle`` (e,) their dihedrals.

    Union-find over the edges by increasing dihedral: the last state with two big sides or more is the highest cut."""
    local = {int(t): i for i, t in enumerate(tris)}
    parent = list(range(len(tris)))
    verts = [set(F[t].tolist()) for t in tris]

    def root(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    big = 0
    order = np.argsort(angle, kind="stable")
    last = -1  # edges order[:last + 1] joined when two big sides or more last existed
    for k, e in enumerate(order.tolist()):
        if big >= 2 and (k == 0 or angle[e] > angle[order[k - 1]]):
            last = k - 1
        a, b = root(local[int(inner[e, 0])]), root(local[int(inner[e, 1])])
        if a == b:
            continue
        if len(verts[a]) < len(verts[b]):
            a, b = b, a
        big -= (len(verts[a]) >= MIN_SIDE_VERTICES) + (len(verts[b]) >= MIN_SIDE_VERTICES)
        verts[a] |= verts[b]
        verts[b] = set()
        parent[b] = a
        big += len(verts[a]) >= MIN_SIDE_VERTICES
    if big >= 2:
        return None  # the piece is not connected over its inner edges: no cut makes its sides
    if last < 0:
        return None
    joined = order[:last + 1]
    a, b = (np.array([local[int(t)] for t in inner[joined, k]], dtype=np.int64) for k in (0, 1))
    comp = components(len(tris), a, b, np.ones(len(tris), bool))
    sides = [tris[comp == r] for r in np.unique(comp)]
    return [s for s in sides if len(np.unique(F[s])) >= MIN_SIDE_VERTICES]


def crease_inside(V: np.ndarray, F: np.ndarray, normals: np.ndarray, tris: np.ndarray, pairs: np.ndarray,
                  fit_piece: Callable[[np.ndarray], Any]) -> float | None:
    """The crease angle (radians, the median over the cut's shared vertices) where the free-form piece ``tris`` is
    two faces meeting at a crease (see the module's text), or None when no cut of it proves one.

    Parameters
    ----------
    V, F : (n, 3) float, (m, 3) int
        The mesh.
    normals : (m, 3) float
        Unit triangle normals.
    tris : (t,) int
        The piece's triangles.
    pairs : (e, 2) int
        The mesh's triangles sharing an edge.
    fit_piece : callable
        ``fit_piece(triangles)``: a B-spline through their vertices (truthy when it holds them) or None.
    """
    inside = np.isin(pairs, tris).all(axis=1)
    inner = pairs[inside]
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", normals[inner[:, 0]], normals[inner[:, 1]]), -1.0, 1.0))
    sides = _big_sides(F, tris, inner, angle)
    if not sides:
        return None
    fits = [fit_piece(s) for s in sides]
    found = []
    for i in range(len(sides)):
        for j in range(i + 1, len(sides)):
            if not (fits[i] and fits[j]):
                continue
            across = (np.isin(inner[:, 0], sides[i]) & np.isin(inner[:, 1], sides[j])) | \
                     (np.isin(inner[:, 0], sides[j]) & np.isin(inner[:, 1], sides[i]))
            shared = np.intersect1d(F[sides[i]], F[sides[j]])
            if not across.any() or len(shared) == 0:
                continue
            ni, nj = surface_normals(fits[i], V[shared]), surface_normals(fits[j], V[shared])
            jump = float(np.median(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", ni, nj)), 0.0, 1.0))))
            if jump > float(np.median(angle[across])) / 2:
                found.append(jump)
    return max(found) if found else None


def creased_note(V: np.ndarray, F: np.ndarray, normals: np.ndarray, pairs: np.ndarray, labels: np.ndarray,
                 kinds: list, fit_piece: Callable[[np.ndarray], Any]) -> str:
    """The reason the exact path's faces are not proven when one of its B-spline faces (``kinds[p] == "bspline"``)
    holds a crease (:func:`crease_inside`); "" when none does. Splitting it at the crease would not prove the count
    either: faces meeting tangentially (a chamfer's end beside its neighbour) stay one B-spline."""
    found = []
    for p, kind in enumerate(kinds):
        if kind == "bspline":
            angle = crease_inside(V, F, normals, np.flatnonzero(labels == p), pairs, fit_piece)
            if angle is not None:
                found.append(angle)
    if not found:
        return ""
    return (f"face count not proven: {len(found)} B-spline face(s) hold a crease (the fitted sides' normals turn by "
            f"{np.degrees(max(found)):.0f}° across it): faces meeting at an angle taken as one")
