"""Tori on three vertex rings: a face count the vertices do not prove.

A torus's meridian is a circle (three parameters: its centre's height and distance from the axis, its radius), and any
three points lie on one circle. So the vertices of two bands that share a ring — three rings about one axis — always
lie on some torus, whatever the bands are: a cylinder's wall and the 45° chamfer beside it as well as
a fillet drawn as two bands. The mesh shows one face or two equally; four rings prove the meridian circle. A torus with
two rings is one band, a face either way. A three-ring torus tangent to every neighbour is a fillet drawn as two bands
(a wall and its chamfer meet theirs at creases): that one is the face.

Likewise a flat ring beside a torus's top: two points of the meridian circle at one height are mirrored across its
top (their radii average to the major radius R); a plane atom at one height whose radii do not average to R lies on the
torus only through round-off (a ring narrower than √(2 r eps) tangent to it), one face or two. Measured: bench/exact.md, "s39-wrong".

numpy only.
"""

from __future__ import annotations

import numpy as np

from scipy.spatial import cKDTree

from ..fit import surface_normals
from ._exact_enclosed import components
from ._exact_kinks import shortest_height

__all__ = ["RING_SPREAD", "flat_rings", "three_ring_tori"]

#: Vertices of one ring agree in height and radius about the torus's axis to their round-off, and the fitted axis
#: holding them all within eps moves them by a few more; rings of a drawn face lie a chord apart (≫ eps).
RING_SPREAD = 10.0


def rings(V: np.ndarray, center: np.ndarray, axis: np.ndarray, spread: float) -> int:
    """The number of rings the points ``V`` form about the axis through ``center`` along ``axis``: points whose
    (height, radius) lie within ``spread`` of each other, chained."""
    w = V - center
    h = w @ axis
    rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", w, w) - h * h, 0.0))
    hr = np.c_[h, rho]
    ab = cKDTree(hr).query_pairs(spread, output_type="ndarray")
    return len(np.unique(components(len(hr), ab[:, 0], ab[:, 1], np.ones(len(hr), bool))))


def _tangent_to_neighbours(V: np.ndarray, F: np.ndarray, pairs: np.ndarray, ends: np.ndarray, labels: np.ndarray,
                           fits: dict, p: int, eps: float) -> bool:
    """Whether face ``p`` meets every other face along its edges tangentially: the two fitted surfaces' normals at
    each shared edge's ends agree within their round-off tilts (2 eps over the shortest height of the triangle on
    each side). A fillet drawn as two bands does; a wall and its chamfer on three rings meet their neighbours at
    creases (export seeds 114 against 169, bench/exact.md "s39-wrong")."""
    t, u = pairs[:, 0], pairs[:, 1]
    flip = labels[u] == p
    t, u = np.where(flip, u, t), np.where(flip, t, u)  # t on face p
    on = (labels[t] == p) & (labels[u] != p)
    if not on.any():
        return False
    t, u, e = t[on], u[on], ends[on]
    bound = np.repeat([2 * eps / shortest_height(V[F[x]]) + 2 * eps / shortest_height(V[F[y]]) for x, y in zip(t, u)], 2)
    mine = surface_normals(fits[p], V[e.ravel()])
    theirs = np.empty_like(mine)
    side = np.repeat(labels[u], 2)
    for q in np.unique(side):
        theirs[side == q] = surface_normals(fits[int(q)], V[e.ravel()[side == q]])
    turn = np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", mine, theirs)), 0.0, 1.0))
    return bool(np.all(turn <= bound))


def three_ring_tori(V: np.ndarray, F: np.ndarray, labels: np.ndarray, fits: dict, eps: float, pairs: np.ndarray,
                    ends: np.ndarray) -> str:
    """A note when some torus face's vertices lie on exactly three rings about its axis (two bands: the face count
    is not proven, module doc) and it meets a neighbour at a crease; "" otherwise. ``pairs``, ``ends``: the mesh's
    adjacent triangles and their shared edges' vertices."""
    found = [p for p, f in fits.items() if f.type == "torus" and rings(
        V[np.unique(F[labels == p])], np.asarray(f.params["center"], float), np.asarray(f.params["axis_dir"], float),
        RING_SPREAD * eps) == 3 and not _tangent_to_neighbours(V, F, pairs, ends, labels, fits, p, eps)]
    if not found:
        return ""
    return (f"face count not proven: {len(found)} torus face(s) on three vertex rings meeting a neighbour at a crease "
            f"(two bands: any three circles about one axis lie on a torus, so they are one face or two)")


def flat_rings(V: np.ndarray, F: np.ndarray, labels: np.ndarray, fits: dict, atoms: np.ndarray, eps: float) -> str:
    """A note when a torus face holds a whole plane atom (``atoms``: the plane atom of each triangle) at one height
    about its axis whose radii do not average to the major radius (module doc); "" otherwise."""
    found = 0
    order = np.argsort(atoms, kind="stable")
    bounds = np.searchsorted(atoms[order], np.arange(int(atoms.max()) + 2))
    for p, f in fits.items():
        if f.type != "torus":
            continue
        c, a = np.asarray(f.params["center"], float), np.asarray(f.params["axis_dir"], float)
        for q in np.unique(atoms[labels == p]):
            tris = order[bounds[q]:bounds[q + 1]]
            if not (labels[tris] == p).all():
                continue
            w = V[np.unique(F[tris])] - c
            h = w @ a
            rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", w, w) - h * h, 0.0))
            # one height to the vertices' round-off (each within eps); mirrored radii to theirs too
            found += bool(np.ptp(h) <= 2 * eps and abs(rho.min() + rho.max() - 2 * f.params["major_radius"]) > 2 * eps)
    if not found:
        return ""
    return (f"face count not proven: {found} flat ring(s) a torus holds only to round-off (a plane tangent to it "
            f"at its top: one face or two)")
