"""Runs of plane strips turned into the curved face that holds them (the exact path's last look at what it left planes).

A CAD export draws a cylinder or a torus of a revolved part as strips one quad wide: every quad is a coplanar pair of
triangles, a plane atom of its own. The exact path's seeds take a ring of atoms around each quad; where that ring
crosses into the tangent face next to it (a cylinder one strip wide between two fillet tori) no surface holds it, the
seed fails, and a seed of one quad with a quad of the torus passes a sphere that the torus later takes back: the run of
strips is left as planes (export seed 15: 145 planes for 5, two of its cylinders 70 quads each).

Here, once the other curved faces hold their atoms, the small plane atoms nothing took (and strips between two rulings
that rows of vertices cut into more triangles: seed 16's cone) are joined across smooth edges into runs; a run the
simplest curved surface holds whole (every vertex to round-off, every chord within the sag: the caller's
``fit_union``) is that face. A run no one surface holds (two faces meeting tangentially, a narrow flat between
fillets, a variable fillet's strip) stays planes: splitting such runs by seeds grown inside them was tried and found
nothing on the export corpus that the exact path's seeds had missed, at 2-4x its time on free-form parts, while the
pieces it found (3 quads of a variable fillet on a cone, seed 73) tipped the single-triangle give-up (bench/exact.md).
numpy only; the surfaces are fitted by the caller.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

__all__ = ["strip_faces"]

#: An atom of at most this many triangles may be a strip of a curved face (a strip's quad, a fan's triangle); one of
#: more only when it is a quadrilateral with vertices along its sides (:func:`_strip_like`).
STRIP_TRIANGLES = 2
#: A strip between two rulings of a cylinder or cone has four corners (three at a cone's apex), however many rows of
#: vertices the neighbouring faces add along its rulings; a plane polygon of more corners is proven a plane.
STRIP_CORNERS = 4
#: A run of fewer strips is told from a polygon's sides meeting at small angles only by its sag (the exact path's
#: weak-face rule, ``_exact_weak.WEAK_ATOMS``), and the seeds tried each of its atoms with its neighbours already: it stays planes.
STRIP_MIN_ATOMS = 4

FitUnion = Callable[[np.ndarray, np.ndarray], Any]


def _strip_like(at: Any, a: int, eps: float) -> bool:
    """Whether atom ``a`` may be a strip of a curved face: at most :data:`STRIP_TRIANGLES` triangles, or a simple
    polygon of at most :data:`STRIP_CORNERS` corners (a boundary vertex off the line through its two boundary neighbours
    by more than 2 ``eps``: three vertices within ``eps`` of a ruling, the middle one within 2 ``eps`` of the others'
    line)."""
    tris = at.tris[a]
    if len(tris) <= STRIP_TRIANGLES:
        return True
    F, V = at.mesh.faces[tris], at.mesh.vertices
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    rim = uniq[count == 1]
    ends, deg = np.unique(rim, return_counts=True)
    if len(ends) != len(tris) + 2 or (deg != 2).any():  # a simple polygon without inner vertices: n − 2 triangles
        return False
    nb: dict = {}
    for x, y in rim.tolist():
        nb.setdefault(x, []).append(y)
        nb.setdefault(y, []).append(x)
    corners = 0
    for v, (u, w) in nb.items():
        d = V[w] - V[u]
        off = np.cross(V[v] - V[u], d)
        corners += float(np.linalg.norm(off)) > 2 * eps * float(np.linalg.norm(d))
    return corners <= STRIP_CORNERS


def _runs(at: Any, free: np.ndarray) -> list[list[int]]:
    """The sets of free atoms joined across smooth edges (connected components), largest first, then by first atom."""
    seen = np.zeros(len(free), bool)
    runs = []
    for s in np.flatnonzero(free).tolist():
        if seen[s]:
            continue
        seen[s] = True
        run, front = [s], [s]
        while front:
            a = front.pop()
            for b in at.nbrs[a]:
                if free[b] and not seen[b] and at.smooth(a, b):
                    seen[b] = True
                    run.append(b)
                    front.append(b)
        runs.append(sorted(run))
    return sorted(runs, key=lambda r: (-len(r), r[0]))


def strip_faces(at: Any, regions: list, eps: float, fit_union: FitUnion) -> list:
    """The curved regions ``(atoms, fit)`` with a face appended for each run of small plane atoms none of them holds
    (joined across smooth edges, at least :data:`STRIP_MIN_ATOMS`) that ``fit_union(ids, tris)`` gives one surface for
    (see the module's text); a run no one surface holds stays planes."""
    free = np.ones(len(at.tris), bool)
    for r, _ in regions:
        free[r] = False
    free[free] = [_strip_like(at, a, eps) for a in np.flatnonzero(free).tolist()]
    out = list(regions)
    for run in _runs(at, free):
        if len(run) < STRIP_MIN_ATOMS:
            break  # the runs come largest first
        fit = fit_union(*at.points(run))
        if fit is not None:
            out.append((run, fit))
    return out
