"""Runs of plane strips turned into the curved face that holds them (the exact path's last look at what it left planes).

A CAD export draws a cylinder or a torus of a revolved part as strips one quad wide: every quad is a coplanar pair of
triangles, a plane atom of its own. The exact path's seeds take a ring of atoms around each quad; where that ring
crosses into the tangent face next to it (a cylinder one strip wide between two fillet tori) no surface holds it, the
seed fails, and a seed of one quad with a quad of the torus passes a sphere that the torus later takes back: the run of
strips is left as planes (export seed 15: 145 planes for 5, two of its cylinders 70 quads each).

Here, once the other curved faces hold their atoms, the small plane atoms nothing took are joined across smooth edges
into runs; a run the simplest curved surface holds whole (every vertex to round-off, every chord within the sag: the
caller's ``fit_union``) is that face; a run that no one surface holds (two faces meeting tangentially, a narrow flat
between fillets) is grown from its inner atoms while one surface holds the grown set, like the exact path's seeds but
among the run's atoms only, so the faces already found no longer spoil the seeds. An atom no surface holds together
with its smooth neighbours stays a plane. numpy only; the surfaces are fitted by the caller.
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
#: Refits of a growing run to a surface through its union, at most per face: a face's first rings give its surface
#: nearly always (the exact path's ``UPGRADE_TRIES``); past it only the face's surface is checked.
REFITS = 32
#: Seeds of a run that may fail before it is left as planes: a true curved face's run fails only at its ends and where it
#: touches another face's strips (a few rings per face), a free-form run at every atom (its atoms lie on no analytic
#: surface: the B-spline step takes them); the share keeps a long run of several faces searchable.
SEED_FAILS = 16
SEED_FAILS_SHARE = 0.1

FitUnion = Callable[[np.ndarray, np.ndarray], Any]
Holds = Callable[[Any, np.ndarray, np.ndarray], bool]


def _strip_like(at: Any, a: int, eps: float) -> bool:
    """Whether atom ``a`` may be a strip of a curved face: at most :data:`STRIP_TRIANGLES` triangles, or a simple polygon
    of at most :data:`STRIP_CORNERS` corners (a boundary vertex off the line through its two boundary neighbours by
    more than 2 ``eps``: three vertices within ``eps`` of a ruling, the middle one within 2 ``eps`` of the others' line)."""
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


def _ball(at: Any, s: int, free: np.ndarray, steps: int) -> list[int]:
    """The free atoms within ``steps`` smooth steps of ``s``."""
    ball, front = {s}, [s]
    for _ in range(steps):
        front = [b for a in front for b in at.nbrs[a] if free[b] and b not in ball and at.smooth(a, b)]
        front = list(dict.fromkeys(front))
        ball.update(front)
        if not front:
            break
    return sorted(ball)


#: Balls round a seed reach at most this many smooth steps: 17 rings of vertices, past which a ball no surface holds has
#: crossed into another face (the fitters tell a face's type from 3 rings inside it).
SEED_STEPS = 8


def _seed(at: Any, s: int, free: np.ndarray, fit_union: FitUnion) -> tuple[list, Any] | None:
    """The largest ball of free atoms round ``s`` (1, 2, 4, 8 smooth steps) that one surface holds: ``(atoms, fit)`` or
    None. Every radius is tried, not only the first: a small torus patch of a few rings can defeat the fitters where
    more rings do not (export seed 27: no type fits 13 quads of a fillet whose 887 atoms a torus holds to 1.7e-6), and
    a ball past the face's edge fails the round-off at once."""
    best, steps, size = None, 1, 0
    while steps <= SEED_STEPS:
        ball = _ball(at, s, free, steps)
        if len(ball) == size:  # the run is covered
            return best
        size = len(ball)
        fit = fit_union(*at.points(ball))
        if fit is not None:
            best = (ball, fit)
        steps *= 2
    return best


def _grow(at: Any, region: list, fit: Any, free: np.ndarray, fit_union: FitUnion, holds: Holds) -> tuple[list, Any]:
    """``region`` grown over free atoms smooth with it while its surface holds them (refitted to the union when one is
    off it, up to :data:`REFITS` times)."""
    inside = set(region)
    rejected: set = set()
    refits = 0
    front = [n for a in region for n in at.nbrs[a]][::-1]
    while front:
        a = front.pop()
        if a in inside or a in rejected or not free[a] or not all(at.smooth(a, b) for b in at.nbrs[a] if b in inside):
            continue
        if not holds(fit, at.verts[a], at.tris[a]):
            if refits >= REFITS:
                rejected.add(a)
                continue
            refits += 1
            new = fit_union(*at.points(region + [a]))
            if new is None:
                rejected.add(a)
                continue
            fit = new
            rejected.clear()  # the new surface may hold what the last one did not
        region.append(a)
        inside.add(a)
        front.extend(n for n in at.nbrs[a] if n not in inside)
    return region, fit


def _split(at: Any, run: list, fit_union: FitUnion, holds: Holds) -> list[tuple[list, Any]]:
    """The faces grown inside a run no one surface holds: seeds first where every neighbour is in the run (inside a
    face), each grown among the run's atoms not yet taken; stops after :data:`SEED_FAILS` (+ share) seeds fail."""
    free = np.zeros(len(at.tris), bool)
    free[run] = True
    inner = {a: sum(not (free[n] and at.smooth(a, n)) for n in at.nbrs[a]) for a in run}
    out = []
    fails = 0
    near_failed = np.zeros(len(at.tris), bool)
    for s in sorted(run, key=lambda a: (inner[a], a)):
        if not free[s] or near_failed[s]:
            continue
        seeded = _seed(at, s, free, fit_union)
        if seeded is None:
            # its neighbours' balls are its own shifted by one step: they fail alike (a free-form run)
            near_failed[[s, *at.nbrs[s]]] = True
            fails += 1
            if fails > SEED_FAILS + SEED_FAILS_SHARE * len(run):
                break
            continue
        region, fit = _grow(at, list(seeded[0]), seeded[1], free, fit_union, holds)
        free[region] = False
        out.append((region, fit))
    return out


def strip_faces(at: Any, regions: list, eps: float, fit_union: FitUnion, holds: Holds) -> list:
    """The curved regions ``(atoms, fit)`` with the curved faces found among the small plane atoms none of them holds
    (see the module's text) appended: each run of such atoms joined across smooth edges is one face when
    ``fit_union(ids, tris)`` gives a surface for it, else split by growing from its inner atoms."""
    free = np.ones(len(at.tris), bool)
    for r, _ in regions:
        free[r] = False
    free[free] = [_strip_like(at, a, eps) for a in np.flatnonzero(free).tolist()]
    out = list(regions)
    for run in _runs(at, free):
        if len(run) < 2:
            continue
        fit = fit_union(*at.points(run))
        if fit is not None:
            out.append((run, fit))
            continue
        out.extend(_split(at, run, fit_union, holds))
    return out
