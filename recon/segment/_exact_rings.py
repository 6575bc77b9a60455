"""Tori on three vertex rings: a face count the vertices do not prove.

A torus's meridian is a circle (three parameters: its centre's height and distance from the axis, its radius), and any
three points lie on one circle. So the vertices of two bands that share a ring — three rings about one axis — always
lie on some torus, whatever the bands are: a cylinder's wall and the 45° chamfer beside it as well as
a fillet drawn as two bands. The mesh shows one face or two equally; four rings prove the meridian circle. A torus with
two rings is one band, a face either way. A three-ring torus tangent to every neighbour is a fillet drawn as two bands
(a wall and its chamfer meet theirs at creases): that one is the face.

The exporter's own subdivision often tells them apart. It divides every circle into as few equal sections as keep
both its chord deflection d and its angle a, and a torus's meridian the same way: a ring of n sections over an arc φ
of radius R has d < R (1 − cos(φ / 2 (n − 1))) or a < φ / (n − 1), or n − 1 sections would have done. A torus whose
meridian band turns by more than φ / (n − 1) and sags by more than that chord's sag breaks whichever bound holds, so the
exporter did not draw it: the two bands are two faces (a wall and its chamfer turn by 45° across one band, a ring's
sections by 6-20°); a fillet drawn as two bands keeps both bounds.

Likewise a flat ring beside a torus's top: two points of the meridian circle at one height are mirrored across its
top (their radii average to the major radius R); a plane atom at one height whose radii do not average to R lies on the
torus only through round-off (a ring narrower than √(2 r eps) tangent to it), one face or two. Measured: bench/exact.md, "s39-wrong".

numpy only.
"""

from __future__ import annotations

import numpy as np

from scipy.spatial import cKDTree

from .._array import height_radius
from ..fit import surface_normals
from ._exact_enclosed import components
from ._exact_kinks import roundoff_tilt

__all__ = ["RING_SPREAD", "flat_rings", "split_undrawn_tori", "three_ring_tori"]

#: Vertices of one ring agree in height and radius about the torus's axis to their round-off, and the fitted axis
#: holding them all within eps moves them by a few more; rings of a drawn face lie a chord apart (≫ eps).
RING_SPREAD = 10.0


def _ring_ids(V: np.ndarray, center: np.ndarray, axis: np.ndarray, spread: float) -> np.ndarray:
    """The ring of each of the points ``V`` about the axis through ``center`` along ``axis`` (0, 1, …): points whose
    (height, radius) lie within ``spread`` of each other, chained."""
    hr = np.c_[height_radius(V, center, axis)]
    ab = cKDTree(hr).query_pairs(spread, output_type="ndarray")
    return np.unique(components(len(hr), ab[:, 0], ab[:, 1], np.ones(len(hr), bool)), return_inverse=True)[1]


def rings(V: np.ndarray, center: np.ndarray, axis: np.ndarray, spread: float) -> int:
    """The number of rings the points ``V`` form about the axis through ``center`` along ``axis`` (:func:`_ring_ids`)."""
    return int(_ring_ids(V, center, axis, spread).max()) + 1 if len(V) else 0


#: A band is out of the exporter's bounds only when it turns and sags by more than twice what one section of a ring
#: may: an exporter meets its criteria with some slack, never by half.
UNDRAWN_MARGIN = 2.0


def _meridian(fit, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """(centre, axis, R, r) of a surface of revolution about ``axis`` whose meridian is a circle of radius r centred
    R from the axis (a torus; a sphere: R = 0); None for a ruled one (a cone's or cylinder's meridian is straight)."""
    if fit.type == "torus":
        return (np.asarray(fit.params["center"], float), np.asarray(fit.params["axis_dir"], float),
                float(fit.params["major_radius"]), float(fit.params["minor_radius"]))
    if fit.type == "sphere":
        return np.asarray(fit.params["center"], float), axis, 0.0, float(fit.params["radius"])
    return None


def _frame(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e1 = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def _section_step(w: np.ndarray, e1: np.ndarray, e2: np.ndarray) -> float:
    """The angle one section of a ring would span with one section fewer: the ring's points ``w`` (relative to a point
    of its axis, ``e1``, ``e2`` across it); a full circle's sections are its points, an arc's one fewer, over the arc
    (its largest gap left out)."""
    around = np.sort(np.arctan2(w @ e2, w @ e1))
    gaps = np.diff(np.r_[around, around[0] + 2 * np.pi])
    whole = gaps.max() < 1.5 * np.median(gaps)
    return float(2 * np.pi / (len(w) - 1) if whole else (2 * np.pi - gaps.max()) / max(len(w) - 2, 1))


def _undrawn(P: np.ndarray, ring: np.ndarray, meridian) -> tuple[bool, np.ndarray]:
    """Whether the exporter cannot have drawn the surface of revolution ``meridian`` (:func:`_meridian`) with the
    points ``P`` on the rings ``ring`` (0 … k − 1) as its sections (module doc); and the rings in their order along the
    meridian arc the points span."""
    c, a, R, r = meridian
    w = P - c
    h, rho = height_radius(P, c, a)
    e1, e2 = _frame(a)
    k = int(ring.max()) + 1
    psi, bounds = np.empty(k), []
    for q in range(k):
        on = ring == q
        if on.sum() < 3:
            return False, np.arange(k)
        psi[q] = np.arctan2(h[on].mean(), rho[on].mean() - R)  # where the ring sits on the meridian circle
        step = _section_step(w[on], e1, e2)
        bounds.append((step, rho[on].mean() * (1 - np.cos(step / 2))))
    order = np.argsort(psi)
    gaps = np.diff(np.r_[psi[order], psi[order[0]] + 2 * np.pi])
    skip = int(np.argmax(gaps))  # the meridian arc the rings span leaves out the largest gap
    along = order[(skip + 1 + np.arange(k)) % k]
    turns = np.delete(np.roll(gaps, -(skip + 1)), k - 1)
    undrawn = any(t > UNDRAWN_MARGIN * step and r * (1 - np.cos(t / 2)) > UNDRAWN_MARGIN * chord
                  for t in turns for step, chord in bounds)
    return undrawn, along


def _tilts(V: np.ndarray, F: np.ndarray, t: np.ndarray, u: np.ndarray, eps: float) -> np.ndarray:
    """How far round-off may tilt two fitted surfaces' normals apart across each edge between triangles ``t`` and
    ``u``: the round-off tilt of the triangle on each side."""
    return np.array([roundoff_tilt(V[F[x]], eps) + roundoff_tilt(V[F[y]], eps) for x, y in zip(t, u)])


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
    bound = np.repeat(_tilts(V, F, t, u, eps), 2)
    mine = surface_normals(fits[p], V[e.ravel()])
    theirs = np.empty_like(mine)
    side = np.repeat(labels[u], 2)
    for q in np.unique(side):
        theirs[side == q] = surface_normals(fits[int(q)], V[e.ravel()[side == q]])
    turn = np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", mine, theirs)), 0.0, 1.0))
    return bool(np.all(turn <= bound))


def _three_rings(P: np.ndarray, fit, eps: float):
    """``(meridian, ring, undrawn, along)`` of a torus through the points ``P`` (:func:`_ring_ids`, :func:`_undrawn`);
    ``undrawn`` only where they lie on three rings."""
    torus = _meridian(fit, np.zeros(3))
    ring = _ring_ids(P, torus[0], torus[1], RING_SPREAD * eps)
    if ring.max() != 2:
        return torus, ring, False, None
    return (torus, ring, *_undrawn(P, ring, torus))


def undrawn_torus(P: np.ndarray, fit, eps: float) -> bool:
    """Whether ``fit`` is a torus on three rings of the points ``P`` that its exporter cannot have drawn (its two bands
    are two faces, :func:`split_undrawn_tori`): the wrong surface, whose chords sag as no drawn face's do."""
    return fit.type == "torus" and bool(_three_rings(P, fit, eps)[2])


def split_undrawn_tori(V: np.ndarray, F: np.ndarray, labels: np.ndarray, fits: dict, eps: float, pairs: np.ndarray,
                       ends: np.ndarray, band_fits) -> tuple[np.ndarray, dict, int, str]:
    """``(labels, fits, n, note)``: every torus face on three vertex rings that its exporter cannot have drawn so
    (:func:`_undrawn`) split into its two bands, each with the first of ``band_fits(triangles)`` (the surfaces that
    hold them, best first) the exporter can have drawn (None left: the torus stays), or given the one band surface
    that holds all three rings; a band joins a neighbour (``pairs``: the mesh's adjacent triangles) whose surface
    holds it and whose vertices its own surface holds (the rest of one cone). ``n`` the tori split; ``note`` when a band
    meets a neighbour as smoothly as one face's sections may turn (:func:`_smooth_join`): the count is then open."""
    labels, fits, n, smooth = labels.copy(), dict(fits), 0, 0
    for p in [p for p, f in fits.items() if f.type == "torus"]:
        tris = np.flatnonzero(labels == p)
        ids, local = np.unique(F[tris], return_inverse=True)
        torus, ring, undrawn, along = _three_rings(V[ids], fits[p], eps)
        if not undrawn:
            continue
        corner = ring[local.reshape(-1, 3)]
        first, last = (corner == along[0]).any(axis=1), (corner == along[2]).any(axis=1)
        if np.any(first & last):
            continue  # a triangle spanning both bands: not two bands
        new = []
        for side in (tris[~last], tris[last]):
            band_ids = np.unique(F[side])
            band_ring = np.unique(ring[np.searchsorted(ids, band_ids)], return_inverse=True)[1]
            new.append(next((f for f in band_fits(side) if (m := _meridian(f, torus[1])) is None
                             or not _undrawn(V[band_ids], band_ring, m)[0]), None))
        if any(f is None for f in new):
            continue
        whole = [f for f in new if np.abs(f.distance(V[ids])).max() <= RING_SPREAD * eps]
        if whole:  # one ruled surface holds all three rings (a cone drawn with a ring inside it): one face
            fits[p] = whole[0]
            continue
        fits[p], fits[len(fits)] = new
        labels[tris[last]] = len(fits) - 1
        n += 1
        for q in (p, len(fits) - 1):
            _join_alike(V, F, labels, fits, q, pairs, RING_SPREAD * eps)
            smooth += _smooth_join(V, F, labels, fits, q, pairs, ends, torus[0], torus[1], eps)
    used, labels = np.unique(labels, return_inverse=True)
    note = (f"face count not proven: {smooth} band(s) of a split torus meet a neighbour no more sharply than one "
            "face's sections may turn (a surface of revolution drawn in rings, or two faces)") if smooth else ""
    return labels.astype(np.int64), {i: fits[int(q)] for i, q in enumerate(used)}, n, note


def _neighbours(labels: np.ndarray, pairs: np.ndarray, q: int) -> list[int]:
    """The faces sharing an edge with face ``q`` (``pairs``: the mesh's adjacent triangles)."""
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    return [int(r) for r in np.unique(np.r_[b[a == q], a[b == q]]) if r != q]


def _smooth_join(V: np.ndarray, F: np.ndarray, labels: np.ndarray, fits: dict, q: int, pairs: np.ndarray,
                 ends: np.ndarray, center: np.ndarray, axis: np.ndarray, eps: float) -> bool:
    """Whether face ``q`` meets a neighbour along a ring about ``axis`` with the two surfaces' normals turning by no
    more than :data:`UNDRAWN_MARGIN` sections of that ring: one face's meridian drawn in rings turns so much between
    them (a cone stack for a curved profile), so the two may be one face. A join that turns by no more than the fits'
    round-off tilts (2 eps over each side's shortest triangle height) is a blend's tangent edge, not such a ring."""
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    e1, e2 = _frame(axis)
    for r in _neighbours(labels, pairs, q):
        on = ((a == q) & (b == r)) | ((a == r) & (b == q))
        shared = np.unique(ends[on])
        if len(shared) < 3:
            continue
        turn = np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", surface_normals(fits[q], V[shared]),
                                                  surface_normals(fits[r], V[shared]))), 0.0, 1.0))
        if np.all(turn <= _tilts(V, F, pairs[on, 0], pairs[on, 1], eps).min()):
            continue
        if np.median(turn) <= UNDRAWN_MARGIN * _section_step(V[shared] - center, e1, e2):
            return True
    return False


def _join_alike(V: np.ndarray, F: np.ndarray, labels: np.ndarray, fits: dict, q: int, pairs: np.ndarray,
                spread: float) -> None:
    """Face ``q`` relabelled (in place) as the first neighbour of its type whose surface holds its vertices within
    ``spread`` and whose vertices its own surface holds: two pieces of one surface."""
    mine = np.unique(F[labels == q])
    for r in _neighbours(labels, pairs, q):
        if fits[r].type != fits[q].type:
            continue
        theirs = np.unique(F[labels == r])
        if np.abs(fits[r].distance(V[mine])).max() <= spread and np.abs(fits[q].distance(V[theirs])).max() <= spread:
            labels[labels == q] = r
            return


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
            h, rho = height_radius(V[np.unique(F[tris])], c, a)
            # one height to the vertices' round-off (each within eps); mirrored radii to theirs too
            found += bool(np.ptp(h) <= 2 * eps and abs(rho.min() + rho.max() - 2 * f.params["major_radius"]) > 2 * eps)
    if not found:
        return ""
    return (f"face count not proven: {found} flat ring(s) a torus holds only to round-off (a plane tangent to it "
            f"at its top: one face or two)")
