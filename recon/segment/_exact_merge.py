"""Curved regions of the exact path joined when one surface holds their union to round-off.

A coarse export draws a torus (a fillet round a pocket's corner) as bands between latitude circles; two circles of a
torus also lie on a cone, a cylinder or a sphere, so each band's seed proves one of those and never grows into its
torus (export seed 35: two tori as about 30 bands each). Three circles tell the torus: two neighbouring bands whose
union the simplest curved surface holds to round-off (and within the sag) are one face. Two different faces that meet
tangentially are never joined: no cylinder, cone, sphere or torus holds a cylinder's and a torus's vertices to
round-off together. numpy only; the surfaces are fitted by the caller's ``fit_union``.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

__all__ = ["merge_curved"]


def _neighbours(at: Any, members: list, owner: np.ndarray, i: int) -> list:
    """The regions sharing an edge with region ``i``, across a crease of the mesh too: a fillet drawn one or two
    triangles across turns by more than a crease between its own pieces, and only one surface holding both to
    round-off joins them (two faces of a part that meet at a crease lie on no common surface)."""
    out = set()
    for a in members[i]:
        for b in at.nbrs[a]:
            o = int(owner[b])
            if o >= 0 and o != i:
                out.add(o)
    return sorted(out)


def merge_curved(at: Any, regions: list, fit_union: Callable[[np.ndarray, np.ndarray], Any],
                 holds: Callable[[Any, np.ndarray, np.ndarray, np.ndarray], bool]) -> list:
    """The curved regions ``(atoms, fit)`` after each, largest first (then by first atom), took in every neighbouring
    region such that a surface holds both: the region's own surface when ``holds(fit, ids, tris, own)`` of the
    neighbour, ``own`` the region's triangles (one surface drawn twice), else ``fit_union(ids, tris)`` of their union (a surface or None). A union that failed is
    not tried again: no surface holds a set that holds a part it failed on."""
    members = [list(r) for r, _ in regions]
    fits = [f for _, f in regions]
    owner = np.full(len(at.tris), -1, dtype=np.int64)
    for i, r in enumerate(members):
        owner[r] = i
    size = [sum(len(at.tris[a]) for a in r) for r in members]
    alive = [True] * len(members)
    failed: set = set()
    for i in sorted(range(len(members)), key=lambda j: (-size[j], min(members[j]))):
        if not alive[i]:
            continue
        grown = True
        while grown:
            grown = False
            for j in sorted(_neighbours(at, members, owner, i), key=lambda j: (-size[j], min(members[j]))):
                if (min(i, j), max(i, j)) in failed:
                    continue
                ids_j, tris_j = at.points(members[j])
                if holds(fits[i], ids_j, tris_j, at.points(members[i])[1]):
                    fit = fits[i]
                else:
                    ids, tris = at.points(members[i] + members[j])
                    fit = fit_union(ids, tris)
                if fit is None:
                    failed.add((min(i, j), max(i, j)))
                    continue
                members[i] += members[j]
                owner[members[j]] = i
                size[i] += size[j]
                fits[i], alive[j], members[j] = fit, False, []
                grown = True
                break  # the neighbours changed: list them again
    return [(members[i], fits[i]) for i in range(len(members)) if alive[i]]
