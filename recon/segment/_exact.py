"""Faces of a mesh whose vertices are exact (a CAD program's STL export): every vertex lies on its true surface to
round-off, so a face is a set of triangles one surface holds to round-off, however thin the triangles.

- planes are the maximal coplanar, edge-connected triangle sets, decided by the vertices (:func:`plane_atoms`);
- a cylinder, cone, sphere or torus is grown over those sets while a surface fitted to all their vertices holds
  every vertex to round-off and passes within the chord sag of every triangle (:func:`grow_curved`);
- what neither explains (free-form faces) is joined into B-spline faces through the vertices (:func:`free_form`).

:func:`exact_faces` chains them; :func:`exact_tessellation` tells from the mesh whether this path applies.
numpy/scipy only.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cache, partial
from typing import Callable, Union

import numpy as np
import scipy.sparse as sp

from ..errors import FitError
from ..fit import CLOSED_KINDS, SurfaceFit, fit_exact_bspline, fit_cone, fit_cylinder, fit_plane, fit_sphere, fit_torus
from ..mesh import Mesh
from ._context import own_normals
from ._exact_crease import creased_note
from ._exact_enclosed import enclosed_free_form
from ._exact_freeform import impossible_types
from ._exact_gate import coplanar_pairs, exact_tessellation, tri_planes
from ._exact_kinks import kinks as _kinks, tangent_misses
from ._exact_loose import CHAIN_GROWTH, chain, held_slack, long_edge_neighbours
from ._exact_memo import Failures, per_vertex, question
from ._exact_merge import merge_curved
from ._exact_rings import flat_rings, split_undrawn_tori, three_ring_tori
from ._exact_split import split_atoms
from ._exact_strips import strip_faces
from ._exact_turn import drawn_alike, largest_turn
from ._exact_weak import chord_points as _chord_points, edge_midpoints, weak_dropped

__all__ = ["ExactFaces", "as_decomposition", "coplanar_pairs", "exact_faces", "exact_tessellation", "grow_curved", "plane_atoms",
           "roundoff"]

log = logging.getLogger(__name__)

#: Round-off of an exported vertex, in units of the largest coordinate: float32 keeps 2⁻²⁴ ≈ 6e-8 of it, and the
#: vertices on a CAD kernel's edges sit within its edge tolerance (measured up to 6e-7 of it on OCC exports);
#: 2e-6 leaves a margin of 3 over both and stays 20× under the 4e-5 a B-spline face misses any analytic one by.
ROUNDOFF = 2e-6
#: A curved face's triangles are chords of it: none may lie farther from it than a CAD export's chord tolerance,
#: which is at most 1 % of the part's diagonal in any export setting; a surface farther from some triangle is a
#: coincidence of a few vertices (a cube's 8 corners lie on a sphere, 3 parallel edges on a cylinder).
SAG_SHARE = 0.01
#: The curved types by number of parameters (the simplest that fits is preferred); a fit is proven by at least
#: one vertex more than it has parameters.
CURVED = (("sphere", 4), ("cylinder", 5), ("cone", 6), ("torus", 7))
KIND_PARAMS = dict(CURVED)
FITTERS = {"plane": fit_plane, "sphere": fit_sphere, "cylinder": fit_cylinder, "cone": fit_cone,
           "torus": partial(fit_torus, exact=True)}
#: Triangles of one curved face turn by less than this between neighbours: above the coarsest angular deflection
#: a CAD export uses (0.8 rad), below the turn of a crease between faces (a right angle, a hexagon's 60°).
CREASE_RAD = 1.0
COS_CREASE = float(np.cos(CREASE_RAD))


@dataclass
class ExactFaces:
    """The faces of an exact mesh: a label per triangle, a surface per label, the notes for the report, and why the
    face count is open where the vertices hold another count as well (empty when they prove it)."""

    labels: np.ndarray
    fits: dict
    notes: list = field(default_factory=list)
    open_count: list = field(default_factory=list)


def roundoff(vertices: np.ndarray) -> float:
    """The distance within which an exported vertex lies on its surface (:data:`ROUNDOFF` of the largest
    coordinate or the diagonal, whichever is larger)."""
    diag = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    return ROUNDOFF * max(float(np.abs(vertices).max()), diag)


def _plane_of(P: np.ndarray) -> tuple[np.ndarray, float]:
    c = P.mean(axis=0)
    _, _, vt = np.linalg.svd(P - c, full_matrices=False)
    return vt[-1], float(vt[-1] @ c)


def plane_atoms(mesh: Mesh, eps: float) -> np.ndarray:
    """(m,) int: the maximal edge-connected sets of triangles whose vertices lie within ``eps`` of one plane.

    Grown from the largest triangle not yet taken (the best-conditioned plane), a neighbour joining when its
    vertices are within ``eps`` of the set's plane, refitted to all its vertices as it doubles (a sliver's own
    plane tilts; the set's does not)."""
    V, F = mesh.vertices, mesh.faces
    m = len(F)
    nrm, off = tri_planes(V, F)
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    adj = sp.coo_matrix((np.ones(2 * len(pairs)), (np.r_[pairs[:, 0], pairs[:, 1]], np.r_[pairs[:, 1], pairs[:, 0]])),
                        shape=(m, m)).tocsr()
    labels = np.full(m, -1, dtype=np.int64)
    order = np.argsort(-mesh.face_areas, kind="stable")
    k = 0
    for s in order:
        if labels[s] >= 0:
            continue
        n, d = nrm[s], off[s]
        members, front, refit_at = [s], [s], 4
        labels[s] = k
        while front:
            cand = np.unique(np.concatenate([adj.indices[adj.indptr[t]:adj.indptr[t + 1]] for t in front]))
            cand = cand[labels[cand] < 0]
            ok = cand[np.abs(V[F[cand]] @ n - d).max(axis=1) <= eps] if len(cand) else cand
            labels[ok] = k
            members.extend(ok.tolist())
            front = ok.tolist()
            if len(members) >= refit_at:
                n, d = _plane_of(V[np.unique(F[members])])
                refit_at *= 2
        k += 1
    return labels


@dataclass
class _Atoms:
    """The plane atoms as sets: triangles and vertices of each, and which atoms share an edge."""

    mesh: Mesh
    labels: np.ndarray
    tris: list
    verts: list
    nbrs: list
    turn: dict
    #: what the path asked already, shared by the atoms a split makes (:mod:`._exact_memo`)
    memo: dict = field(default_factory=dict, repr=False)
    failed: Failures = field(default_factory=Failures, repr=False)

    def smooth(self, a: int, b: int) -> bool:
        """Whether atoms ``a`` and ``b`` meet at no crease (:data:`CREASE_RAD`)."""
        k = len(self.tris)
        return self.turn.get(min(a, b) * k + max(a, b), -1.0) >= COS_CREASE

    @classmethod
    def of(cls, mesh: Mesh, labels: np.ndarray, shared: "_Atoms | None" = None) -> "_Atoms":  # shared: its memo
        k = int(labels.max()) + 1
        order = np.argsort(labels, kind="stable")
        bounds = np.searchsorted(labels[order], np.arange(k + 1))
        tris = [order[bounds[i]:bounds[i + 1]] for i in range(k)]
        verts = [np.unique(mesh.faces[t]) for t in tris]
        pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
        a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
        cross = a != b
        ab = np.unique(np.sort(np.c_[a[cross], b[cross]], axis=1), axis=0)
        nbrs: list = [[] for _ in range(k)]
        for x, y in ab.tolist():
            nbrs[x].append(y)
            nbrs[y].append(x)
        # the sharpest turn of the normals across the edges two atoms share
        fn = mesh.face_normals
        cos = np.einsum("ij,ij->i", fn[pairs[cross, 0]], fn[pairs[cross, 1]])
        key = np.minimum(a[cross], b[cross]) * k + np.maximum(a[cross], b[cross])
        order2 = np.lexsort((cos, key))
        first = np.r_[True, key[order2][1:] != key[order2][:-1]]
        turn = dict(zip(key[order2][first].tolist(), cos[order2][first].tolist()))
        return cls(mesh, labels, tris, verts, nbrs, turn) if shared is None else cls(
            mesh, labels, tris, verts, nbrs, turn, shared.memo, shared.failed)

    def points(self, atoms) -> tuple[np.ndarray, np.ndarray]:
        """(vertex ids, triangles) of a set of atoms."""
        tris = np.concatenate([self.tris[a] for a in atoms])
        return np.unique(np.concatenate([self.verts[a] for a in atoms])), tris


#: Round-off per vertex: one distance for every vertex, or an array over the mesh's vertices (a vertex that a found
#: face's surface holds to round-off may miss a neighbouring face by the STEP edge's tolerance: ``held_slack``).
Tol = Union[float, np.ndarray]


def _floor(eps: Tol) -> float:
    """The round-off of the strict vertices (the smallest of ``eps``)."""
    return float(eps) if np.ndim(eps) == 0 else float(np.min(eps))


def _fits_exactly(fit: SurfaceFit, V: np.ndarray, F: np.ndarray, ids: np.ndarray, tris: np.ndarray, eps: Tol,
                  sag: float, turn: Callable[[], float] | None = None) -> bool:
    """Whether ``fit`` holds the vertices ``ids`` within ``eps`` (each its own) and passes within ``sag`` of the
    triangles, or, given ``turn()`` of a face ``fit`` is proven on, turns across them no more than across it
    (:mod:`._exact_turn`; asked only when the sag test fails)."""
    if not fit.ok or fit.type == "bspline":
        return False
    limit = eps if np.ndim(eps) == 0 else eps[ids]
    if not bool(np.all(np.abs(fit.distance(V[ids])) <= limit)):
        return False
    if float(np.max(np.abs(fit.distance(_chord_points(V, F, tris))))) <= sag:
        return True
    if turn is None:
        return False
    corner_eps = np.full(len(tris), float(eps)) if np.ndim(eps) == 0 else np.asarray(eps)[F[tris]].max(axis=1)
    return drawn_alike(fit, V, F, tris, turn(), corner_eps)


def _candidates(V: np.ndarray, F: np.ndarray, ids: np.ndarray, tris: np.ndarray, eps: Tol, sag: float, *,
                first: bool = True, above: str | None = None) -> list[SurfaceFit]:
    """The curved surfaces that hold the vertices ``ids`` to round-off and the triangles within the sag, simplest
    first (only the first when ``first``; only types more complex than ``above``); a type needs one vertex more than
    its parameters that it holds to round-off. With round-off per vertex, a type is fitted to the strict vertices
    when they are enough (the loose ones, on a neighbour's surface, are only checked), else to all of them (a strip
    whose every vertex is on its rims) within the loosest round-off."""
    ids_local = np.searchsorted(ids, F[tris])
    nrm = own_normals(V, F[tris], ids_local, len(ids))
    e0 = _floor(eps)
    strict = np.arange(len(ids)) if np.ndim(eps) == 0 else np.flatnonzero(eps[ids] <= e0)
    loose_all = float(np.max(eps[ids])) if np.ndim(eps) else e0
    out: list[SurfaceFit] = []
    kinds = [k for k, _ in CURVED]
    hopeless: dict = {}
    for kind, params in CURVED[kinds.index(above) + 1 if above in kinds else 0:]:
        # the strict vertices when enough, else all (a strip whose every vertex is on its rims)
        use, e = (strict, e0) if len(strict) > params else (np.arange(len(ids)), loose_all)
        if len(use) <= params:
            continue
        pick = use[np.linspace(0, len(use) - 1, FIT_POINTS).astype(int)] if len(use) > FIT_POINTS else use
        # the types whose every surface misses some vertex, proven by one SVD each: no nonlinear fit is tried for them
        key = (len(use), e)
        if key not in hopeless:
            hopeless[key] = impossible_types(V[ids[pick]], e)
        if kind in hopeless[key]:
            continue
        try:
            fit = FITTERS[kind](V[ids[pick]], nrm[pick], tolerance=e)
        except (FitError, np.linalg.LinAlgError, ValueError):
            continue
        # a surface fitted to all is proven by more vertices than its parameters that it holds to round-off
        if _fits_exactly(fit, V, F, ids, tris, eps, sag) and (
                e == e0 or int((np.abs(fit.distance(V[ids])) <= e0).sum()) > params):
            out.append(fit)
            if first:
                break
    return out


def _asked(at: _Atoms, ids: np.ndarray, tris: np.ndarray, eps: Tol, sag: float, *, first: bool = True,
           above: str | None = None) -> list[SurfaceFit]:
    """:func:`_candidates` of the vertices ``ids`` and triangles ``tris``, from ``at.memo`` when asked before."""
    key = question(ids, tris, per_vertex(eps, ids), sag, first, above)
    if key not in at.memo:
        at.memo[key] = _candidates(at.mesh.vertices, at.mesh.faces, ids, tris, eps, sag, first=first, above=above)
    return at.memo[key]


def _union_fit(at: _Atoms, ids: np.ndarray, tris: np.ndarray, eps: Tol, sag: float) -> SurfaceFit | None:
    """The simplest surface holding a union of regions (:func:`_asked`), or None; None at once when the union holds
    one that failed at no looser round-off (``at.failed``)."""
    e = per_vertex(eps, ids)
    if at.failed.implied(ids, e):
        return None
    fit = next(iter(_asked(at, ids, tris, eps, sag)), None)
    if fit is None:
        at.failed.add(ids, e)
    return fit


def _seed(at: _Atoms, s: int, free: np.ndarray, eps: Tol, sag: float, *, rings: bool):
    """A curved surface through atom ``s`` and some of its free small neighbours: ``(atoms, fit)`` or None.

    Tried from the largest set down: the atoms within two steps (inside a curved face they span three rings of
    vertices, which tell a cone or a torus from a sphere at once), within one, then ``s`` with one or two of its
    neighbours (a fillet two strips wide: two quads) — the rings only when ``rings``, the pairs only when not."""
    V, F = at.mesh.vertices, at.mesh.faces

    def small(a, b):
        return free[b] and len(at.tris[b]) <= 2 and at.smooth(a, b)

    nb = [n for n in at.nbrs[s] if small(s, n)]
    ring2 = sorted({s, *nb, *(x for n in nb for x in at.nbrs[n] if small(n, x))})
    if rings:  # the last: the strip's own quads, without the fan triangles of a corner at its end
        combos = [ring2, sorted({s, *nb}), sorted({s, *(n for n in nb if len(at.tris[n]) == len(at.tris[s]))})]
    elif len(at.tris[s]) == 2:  # a fillet two strips wide: a quad and its neighbouring quad
        combos = [[s, n] for n in nb if len(at.tris[n]) == 2]
    else:
        return None
    seen = set()
    for c in combos:
        if len(c) < 2 or tuple(c) in seen:
            continue
        seen.add(tuple(c))
        ids, tris = at.points(c)
        fits = _asked(at, ids, tris, eps, sag)
        if fits:
            return list(c), fits[0]
    return None


def _simpler(kind: str) -> str | None:
    """The curved type before ``kind`` in :data:`CURVED` (None for the first): refits start at ``kind`` itself."""
    kinds = [k for k, _ in CURVED]
    i = kinds.index(kind) if kind in kinds else 0
    return kinds[i - 1] if i > 0 else None


#: Refits of a growing face (the same type on more vertices, or a more complex one), at most: the seed's rings give the type at once nearly always (a
#: sphere band's two circles become a cone or a torus with the next ring); past it only the face's surface is checked.
UPGRADE_TRIES = 32
#: The curved fitters see at most this many of a face's vertices (evenly chosen); every vertex is then checked.
FIT_POINTS = 256


def _grow(at: _Atoms, region: list, fit: SurfaceFit, free: np.ndarray, eps: Tol, sag: float):
    """Grow ``region`` over free neighbouring atoms while a curved surface holds them all (refitted, possibly of a
    more complex type, when a neighbour is off the current one)."""
    V, F = at.mesh.vertices, at.mesh.faces
    inside = set(region)
    rejected: set = set()
    tries, refit_at = 0, len(region)
    front = [n for a in region for n in at.nbrs[a]][::-1]
    while front:
        a = front.pop()
        if a in inside or a in rejected or not free[a] or not all(at.smooth(a, b) for b in at.nbrs[a] if b in inside):
            continue
        ids_a, tris_a = at.verts[a], at.tris[a]
        if not _fits_exactly(fit, V, F, ids_a, tris_a, eps, sag):
            # the same type once the region doubled since the last refit: a seed's few rings pin a torus only to
            # within round-off, twice the vertices pin it tighter (a 14k-triangle torus was 211 pieces without it),
            # and doubling keeps these refits logarithmic in the face's size
            doubled = len(region) >= 2 * refit_at
            if tries >= UPGRADE_TRIES and not doubled:
                rejected.add(a)
                continue
            tries, refit_at = tries + 1, len(region)
            ids, tris = at.points(region + [a])
            # otherwise only a more complex type: an exact surface of the same type would be the same surface
            fits = _asked(at, ids, tris, eps, sag, above=_simpler(fit.type) if doubled else fit.type)
            if not fits:
                rejected.add(a)
                continue
            fit = fits[0]
            rejected.clear()  # a new surface may hold what the last one did not
        region.append(a)
        inside.add(a)
        front.extend(n for n in at.nbrs[a] if n not in inside)
    return region, fit


#: Seeds that may fail before the search for curved faces stops (a free-form face: its small atoms are on no analytic
#: surface; what is left goes to the B-splines): a few per true face a CAD part has (its true planes drawn as one or
#: two triangles fail as seeds), and a share of the atoms.
SEED_BUDGET = 64
SEED_BUDGET_SHARE = 0.1


def _chained(at: _Atoms, s: int, free: np.ndarray, eps: Tol, sag: float, nbr: list) -> tuple[list, SurfaceFit] | None:
    """The face grown from a chain of one-triangle atoms through ``s`` (:func:`chain`) that a curved surface holds,
    when it holds :data:`CHAIN_GROWTH` times the chain's atoms; else None."""
    c = chain(at, s, free, nbr)
    if not c:
        return None
    ids, tris = at.points(c)
    fits = _asked(at, ids, tris, eps, sag)
    if not fits:
        return None
    region, fit = _grow(at, list(c), fits[0], free, eps, sag)
    return (region, fit) if len(region) >= CHAIN_GROWTH * len(c) else None


def grow_curved(at: _Atoms, eps: Tol, sag: float, found: list | None = None,
                tally: list[int] | None = None) -> list[tuple[list, SurfaceFit]]:
    """The curved faces: ``(atoms, fit)`` for every region of plane atoms a cylinder, cone, sphere or torus holds
    to round-off, after the regions ``found`` already (kept as they are, their atoms not free). Seeds are the atoms of
    one or two triangles (a strip's quad, a fan's triangle), first with their rings, then in pairs of quads; each
    stage stops when more seeds fail than :data:`SEED_BUDGET` and :data:`SEED_BUDGET_SHARE` of the atoms allow (what
    is left is free-form)."""
    k = len(at.tris)
    free = np.ones(k, bool)
    regions = list(found or [])
    for r, _ in regions:
        free[r] = False
    # inside a curved face first (every neighbour a small atom across no crease), where the rings tell the type
    inner = [sum(len(at.tris[n]) > 2 or not at.smooth(a, n) for n in at.nbrs[a]) for a in range(k)]
    order = sorted((a for a in range(k) if len(at.tris[a]) <= 2), key=lambda a: (inner[a], a))
    if np.ndim(eps):  # a second pass: only an atom with a loose vertex sees anything the first did not
        order = [a for a in order if free[a] and bool((eps[at.verts[a]] > _floor(eps)).any())]
    nbr = long_edge_neighbours(at.mesh)
    tally = [0, 0] if tally is None else tally
    for stage, rings in enumerate((True, False)):
        failed = tally[stage]
        for s in order if failed <= SEED_BUDGET + k * SEED_BUDGET_SHARE else ():
            if not free[s]:
                continue
            # a zig-zag strip first: a chain along its long edges, kept when its face grows to CHAIN_GROWTH times it
            grown = _chained(at, s, free, eps, sag, nbr) if rings and len(at.tris[s]) == 1 else None
            if grown is None:
                seeded = _seed(at, s, free, eps, sag, rings=rings)
                grown = None if seeded is None else _grow(at, seeded[0], seeded[1], free, eps, sag)
            if grown is None:
                failed += 1
                if failed > SEED_BUDGET + k * SEED_BUDGET_SHARE:
                    log.info("exact: %d seeds failed of %d atoms: the rest is free-form", failed, k)
                    break
                continue
            free[grown[0]] = False
            regions.append(grown)
        tally[stage] = failed
    log.info("exact: %d curved faces of %d atoms", len(regions), k)
    return regions


def reclaim(at: _Atoms, regions: list, eps: Tol, sag: float) -> list[tuple[list, SurfaceFit]]:
    """The curved regions after each, largest first, took over the neighbouring atoms its surface holds to round-off
    (and within the sag) from smaller curved regions and from the small plane atoms no region took, across no crease.

    A seed's few atoms can pass a coincidental surface that also holds a strip of the face next to it (a slot's side
    and the end strips of its two half-cylinders lie on one circle: a symmetric trapezoid is cyclic), or grow a piece
    of a face before the face's own seed does (a cylinder along a torus's minor circle): the larger face's surface,
    proven by more vertices, holds those strips and takes them back; a piece of the same surface goes whole. A region
    left with one atom is dropped: one atom's triangles are coplanar, the plane is the simplest surface holding them.
    """
    V, F = at.mesh.vertices, at.mesh.faces
    owner = np.full(len(at.tris), -1, dtype=np.int64)
    members = [list(r) for r, _ in regions]
    for i, r in enumerate(members):
        owner[r] = i
    size = [sum(len(at.tris[a]) for a in r) for r in members]
    for i in sorted(range(len(regions)), key=lambda j: -size[j]):
        if len(members[i]) < 2:
            continue
        fit = regions[i][1]
        # the step its proven triangles are drawn at: a neighbour drawn at it is the same surface (:mod:`._exact_turn`)
        turn = cache(partial(largest_turn, fit, V, F, np.concatenate([at.tris[a] for a in members[i]])))
        front = [n for a in members[i] for n in at.nbrs[a]]
        seen: set = set()
        while front:
            a = front.pop()
            o = int(owner[a])
            if a in seen or o == i:
                continue
            seen.add(a)
            # only from smaller regions, or small plane atoms (a plane of more triangles is proven a plane)
            if (o >= 0 and size[o] >= size[i]) or (o < 0 and len(at.tris[a]) > 2):
                continue
            # joined across one smooth edge at least: a sliver's own normal, from float32 corners, may turn by a
            # crease's angle while its vertices and chords lie on the surface to round-off
            if not any(at.smooth(a, b) for b in at.nbrs[a] if owner[b] == i):
                continue
            if not _fits_exactly(fit, V, F, at.verts[a], at.tris[a], eps, sag, turn):
                continue
            if o >= 0:
                members[o].remove(a)
                size[o] -= len(at.tris[a])
            members[i].append(a)
            size[i] += len(at.tris[a])
            owner[a] = i
            front.extend(at.nbrs[a])
    return [(m, regions[i][1]) for i, m in enumerate(members) if len(m) >= 2]


#: Rounds of joining curved regions and reclaiming: each round's joined faces take back the plane atoms between bands,
#: which makes the next bands neighbours; two rounds cover a plane strip between every other band.
MERGE_ROUNDS = 3


def _on_chords(fit: SurfaceFit, V: np.ndarray, F: np.ndarray, tris: np.ndarray, eps: float) -> tuple[int, int]:
    """How many of the triangles' edge midpoints lie on ``fit`` to round-off: a straight edge on the surface (a
    cone's or a cylinder's ruling) proves a ruled surface that a sphere or torus through the same vertices is not;
    then how many lie on it as closely as its own vertices do (a ruling does; a doubly curved surface holds a short
    edge within round-off only by its sag ℓ²/8R, which its vertices do not show)."""
    d = np.abs(fit.distance(edge_midpoints(V, F, tris)))
    own = float(np.abs(fit.distance(V[np.unique(F[tris])])).max())
    return int((d <= eps).sum()), int((d <= own).sum())


def _best_type(at: _Atoms, region: list, fit: SurfaceFit, eps: Tol, sag: float) -> tuple[SurfaceFit, str]:
    """The surface of a grown region among every curved type that holds it: the one with the most edges on it
    (rulings), then the simplest; and the report's note when several fit ("" when one does)."""
    V, F = at.mesh.vertices, at.mesh.faces
    ids, tris = at.points(region)
    fits = _asked(at, ids, tris, eps, sag, first=False) or [fit]
    if len(fits) == 1:
        return fits[0], ""
    (on, _), best = _by_rulings(fits, V, F, tris, eps)[0]
    return best, (f"{best.type} chosen among {', '.join(f.type for f in fits)} that all hold its {len(ids)} vertices "
                  f"to round-off ({on} edges on it)")


def _by_rulings(fits: list, V: np.ndarray, F: np.ndarray, tris: np.ndarray,
                eps: Tol) -> list[tuple[tuple[int, int], SurfaceFit]]:
    """``((edges on it, edges on it as closely as its vertices), fit)`` for each fit, the most of the triangles' edges
    on it (rulings) first, then the most on it to its vertices' own residual (a narrow chamfer band's rulings hold a
    sphere through its two rings within round-off too), the simplest of equals first (``fits`` come simplest first)."""
    ranked = [(_on_chords(f, V, F, tris, _floor(eps)), f) for f in fits]
    return sorted(ranked, key=lambda x: (-x[0][0], -x[0][1]))


def _band_fits(at: _Atoms, tris: np.ndarray, eps: Tol, sag: float) -> list[SurfaceFit]:
    """The surfaces of one band of a split torus: its plane when flat (an annulus), else the curved types that hold
    its vertices to round-off (two coaxial circles lie on a cone, a sphere and a torus), those its strips' edges lie
    on first."""
    V, F = at.mesh.vertices, at.mesh.faces
    ids = np.unique(F[tris])
    flat = fit_plane(V[ids], tolerance=_floor(eps))
    if flat and np.abs(flat.distance(V[ids])).max() <= _floor(eps):
        return [flat]
    return [f for _, f in _by_rulings(list(_asked(at, ids, tris, eps, sag, first=False)), V, F, tris, eps)]


def _crease_free(mesh: Mesh, cos_crease: float) -> np.ndarray:
    """(e, 2) the triangle pairs whose normals turn by less than the crease angle."""
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    n = mesh.face_normals
    return pairs[np.einsum("ij,ij->i", n[pairs[:, 0]], n[pairs[:, 1]]) >= cos_crease]


def free_form(at: _Atoms, taken: np.ndarray, tolerance: float) -> list[tuple[np.ndarray, SurfaceFit]]:
    """B-spline faces through the vertices of the single triangles no plane or curved surface took, joined over
    edges that are no crease: ``(triangles, fit)`` for each piece a B-spline holds within ``tolerance``. (Two
    coplanar triangles are a plane's: a free-form face hardly ever has a flat pair, a CAD export draws a plane's
    rectangle as two.)"""
    mesh = at.mesh
    V, F = mesh.vertices, mesh.faces
    small = np.array([len(t) == 1 for t in at.tris]) & ~taken
    tri_small = small[at.labels]
    pairs = _crease_free(mesh, float(np.cos(CREASE_RAD)))
    pairs = pairs[tri_small[pairs[:, 0]] & tri_small[pairs[:, 1]]]
    m = len(F)
    g = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    _, comp = sp.csgraph.connected_components(g, directed=False)
    out = []
    for c in np.unique(comp[tri_small]):
        tris = np.flatnonzero((comp == c) & tri_small)
        if len(np.unique(at.labels[tris])) < 3:
            continue
        fit = _bspline_through(V, F, tris, tolerance)
        if fit is not None:
            out.append((tris, fit))
    return out


def _bspline_through(V: np.ndarray, F: np.ndarray, tris: np.ndarray, tolerance: float) -> SurfaceFit | None:
    """A B-spline through the vertices of the triangles ``tris`` that holds them within ``tolerance``, or None."""
    ids = np.unique(F[tris])
    if len(ids) < 16:
        return None
    local = np.searchsorted(ids, F[tris])
    try:
        fit = fit_exact_bspline(V[ids], own_normals(V, F[tris], local, len(ids)), local, tolerance)
    except (FitError, np.linalg.LinAlgError, ValueError) as err:
        log.info("free-form piece of %d triangles: no B-spline (%s)", len(tris), err)
        return None
    if not fit.ok:
        log.info("free-form piece of %d triangles: %s", len(tris), fit.reason)
    return fit if fit.ok else None


#: Rounds of taking a free-form face whole: the first joins its pieces, the second the flat patches the joined face
#: then surrounds (each piece alone did not).
ENCLOSED_ROUNDS = 2
#: A CAD part has few faces of one triangle that are not amid planes (a triangular face between them); beyond this
#: share of the faces they are pieces of a free-form face the exact path did not join.
SINGLE_SHARE = 0.05


def _loose_singles(mesh: Mesh, labels: np.ndarray, fits: dict) -> np.ndarray:
    """The faces (k,) bool that are one triangle not bounded by planes of two triangles or more on every side: the pieces of a
    free-form surface lie beside each other or beside the curved faces that took the rest of it. A triangle amid plane
    faces is a triangular face of the part (each corner of a chamfered polygon prism: export seed 78, 10 of its 32
    true faces; a sliver strip's neighbours may turn by a crease, so smoothness does not tell them: seed 85)."""
    count = np.bincount(labels)
    planar = np.array([count[p] >= 2 and fits[p].type == "plane" for p in range(len(count))])
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    # a one-triangle face is loose when any neighbour across its edges is not a plane of two triangles or more
    loose = np.zeros(len(count), bool)
    loose[a[~planar[b]]] = True
    loose[b[~planar[a]]] = True
    return loose & (count == 1)


def _curved_stage(at: _Atoms, eps: Tol, sag: float, found: list, tally: list[int]) -> tuple[_Atoms, list]:
    """``(atoms, curved regions)``: the curved faces grown after ``found`` (seeds failing on from ``tally``), then
    reclaimed, split out of mixed plane atoms, found in runs of strips and merged (see :func:`exact_faces`)."""
    mesh = at.mesh
    V, F = mesh.vertices, mesh.faces
    curved = reclaim(at, grow_curved(at, eps, sag, found, tally), eps, sag)
    # plane atoms that hold a curved face's triangle and a tangent neighbour's in one plane split between them
    at, split = split_atoms(at, curved, _floor(eps), COS_CREASE,
                            lambda fit, ids, tris: _fits_exactly(fit, V, F, ids, tris, eps, sag),
                            lambda labels: _Atoms.of(mesh, labels, at))
    if split is not curved:
        curved = reclaim(at, split, eps, sag)
    # runs of plane strips no seed explained (a cylinder one quad wide between fillets: seed 15), then merged as bands
    curved = strip_faces(at, curved, _floor(eps), lambda ids, tris: next(iter(_asked(at, ids, tris, eps, sag)), None))
    # bands of one torus (two latitude circles lie on a cone, a cylinder or a sphere) joined when one surface holds
    # them; the joined face then reclaims the 2-triangle planes between its bands, which may join more (seed 35)
    for _ in range(MERGE_ROUNDS):
        merged = merge_curved(at, curved, lambda ids, tris: _union_fit(at, ids, tris, eps, sag),
                              lambda fit, ids, tris, own: _fits_exactly(fit, V, F, ids, tris, eps, sag,
                                                                        partial(largest_turn, fit, V, F, own)))
        if len(merged) == len(curved):
            break
        curved = reclaim(at, merged, eps, sag)
    return at, curved


def _tri_sets(at: _Atoms, regions: list) -> set[tuple]:
    """Each region's triangles, sorted, as a set: regions compared across passes that may split atoms differently."""
    return {tuple(np.sort(np.concatenate([at.tris[a] for a in r])).tolist()) for r, _ in regions}


def exact_faces(mesh: Mesh, tolerance: float, atoms: np.ndarray | None = None) -> ExactFaces | None:
    """The faces of a mesh with exact vertices and their surfaces (see the module's text).

    Parameters
    ----------
    mesh : Mesh
    tolerance : float
        The run's tolerance (model units): what a free-form face's B-spline must hold its vertices within.
    atoms : (m,) int, optional
        :func:`plane_atoms` of the mesh, when already made.

    Returns
    -------
    ExactFaces, or None when the mesh's faces are not found this way (free-form faces the seeds and B-splines did
    not explain): the caller decomposes it instead.
    """
    V, F = mesh.vertices, mesh.faces
    eps = roundoff(V)
    sag = SAG_SHARE * float(mesh.diagonal)
    if atoms is None:
        atoms = plane_atoms(mesh, eps)
    at = _Atoms.of(mesh, atoms)
    notes: list = []
    labels = np.full(len(F), -1, dtype=np.int64)
    fits: dict = {}
    # one budget of failed seeds for both passes: where the first found the rest free-form, the second seeds nothing
    tally = [0, 0]
    at, curved = _curved_stage(at, eps, sag, [], tally)
    # a second pass where a vertex a found face holds to round-off may miss the face beside it by up to the run's
    # tolerance: the STEP's tolerant edges put a curved face's rim on its neighbour's surface, not on its own
    slack = held_slack(at, curved, eps, max(tolerance, eps))
    made = np.zeros(len(F), bool)  # triangles of the faces only the second pass found
    loosened = False
    if slack is not None:
        first = _tri_sets(at, curved)
        at, curved = _curved_stage(at, slack, sag, curved, tally)
        second = _tri_sets(at, curved)
        made[list({t for r in second - first for t in r})] = True
        loosened = second != first
    # each region judged by its best surface too, not only its seed's: the simplest type first made three quads of a
    # cylinder's arc a sphere whose chords lie 12x farther than the cylinder's, and dropped them as planes (seed 20)
    taken = np.zeros(len(at.tris), bool)
    # judged at round-off alone: a loose rim lets a sphere hold a cylinder's arc within the tolerance; a face found
    # only with loose rims keeps its own surface
    best = {id(r): _best_type(at, r, f, eps, sag) for r, f in curved}
    for region, fit in weak_dropped(at, [(r, f, best[id(r)][0]) for r, f in curved], notes, _floor(eps)):
        p = len(fits)
        fits[p] = fit
        if best[id(region)][1] and fit is best[id(region)][0]:
            notes.append(f"face {p}: {best[id(region)][1]}")
        labels[np.concatenate([at.tris[a] for a in region])] = p
        taken[region] = True
    for tris, fit in free_form(at, taken, tolerance):
        p = len(fits)
        fits[p] = fit
        labels[tris] = p
    for a, tris in enumerate(at.tris):
        rest = tris[labels[tris] < 0]
        if len(rest) == 0:
            continue
        p = len(fits)
        fits[p] = fit_plane(V[np.unique(F[rest])], tolerance=tolerance)
        labels[rest] = p
    loose = _loose_singles(mesh, labels, fits)
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    # a free-form face in pieces, the coincidental curved faces among them taken back: whole if a B-spline holds it;
    # a second round takes the flat patches the whole face now surrounds (the pieces did not, each alone)
    for _ in range(ENCLOSED_ROUNDS):
        if not (loose.any() or any(f.type == "bspline" for f in fits.values())):
            break
        smooth = np.einsum("ij,ij->i", *mesh.face_normals[pairs.T]) >= COS_CREASE
        # judged at the run's tolerance, the loosest a fit's tilt can be: a true tangent face is never taken for a kink
        whole = enclosed_free_form(labels, [fits[p].type for p in range(len(fits))], pairs, smooth, loose,
                                   lambda tris: _bspline_through(V, F, tris, tolerance),
                                   tangent_misses(mesh, pairs, labels, fits, max(tolerance, eps), smooth,
                                                  frozenset(KIND_PARAMS)))
        if not whole:
            break
        labels, fits = _relabelled(labels, fits, whole)
        loose = _loose_singles(mesh, labels, fits)
        notes.append(f"{len(whole)} free-form face(s) taken whole: one B-spline holds the pieces the path found")
    kinks = _kinks(mesh, pairs, labels, fits, eps, np.bincount(labels, made, len(fits)) > 0, max(tolerance, eps),
                   COS_CREASE, frozenset(KIND_PARAMS))
    # faces the loose rims made are proven only where no kink is left: else a blend cut up (export seeds 25, 30)
    why = _gives_up(pairs, labels, fits, int(loose.sum())) or (" ".join(kinks) if loosened else "") or creased_note(
        V, F, mesh.face_normals, pairs, labels, [fits[p].type for p in range(len(fits))],
        lambda tris: _bspline_through(V, F, tris, tolerance))
    if why:
        log.info("exact: %s", why)
        return None
    # two bands a torus holds whatever they are (one face or two), and a flat ring on a torus to round-off: the
    # surfaces are right either way, only the count is open
    ends = np.asarray(mesh.face_adjacency_edges).reshape(-1, 2)
    labels, fits, split, smooth = split_undrawn_tori(V, F, labels, fits, eps, pairs, ends,
                                                     lambda tris: _band_fits(at, tris, eps, sag))
    if split:
        notes.append(f"{split} torus face(s) on three rings split into their two bands: the export's own sections "
                     "are finer than that torus's meridian would be")
    rings = three_ring_tori(V, F, labels, fits, eps, pairs, ends)
    flat = flat_rings(V, F, labels, fits, atoms, eps)
    return ExactFaces(labels, fits, notes + kinks, [n for n in (smooth, rings, flat) if n])


def _relabelled(labels: np.ndarray, fits: dict, whole: list) -> tuple[np.ndarray, dict]:
    """The labels and fits with each ``(triangles, fit)`` of ``whole`` one face, numbered from 0 without gaps."""
    labels = labels.copy()
    fits = dict(fits)
    for tris, fit in whole:
        p = len(fits)
        fits[p] = fit
        labels[tris] = p
    used, labels = np.unique(labels, return_inverse=True)
    return labels.astype(np.int64), {i: fits[int(p)] for i, p in enumerate(used)}


def _gives_up(pairs: np.ndarray, labels: np.ndarray, fits: dict, loose: int) -> str:
    """Why the faces found do not explain the mesh ("" when they do); ``pairs`` its triangles sharing an edge."""
    bounded = np.zeros(len(fits), bool)
    cut = labels[pairs[:, 0]] != labels[pairs[:, 1]]
    bounded[labels[pairs[cut].ravel()]] = True
    # a closed body one face covers is built on that face's own seams when it is a sphere or torus; any other such face
    # has nothing to bound it: the decomposition cuts it
    if any(not bounded[p] and fits[p].type not in CLOSED_KINDS for p in range(len(fits))):
        return "a face with no boundary on a surface that does not close on itself"
    if loose > SINGLE_SHARE * len(fits) + 2:
        return f"{loose} of {len(fits)} faces are single triangles not amid planes: a free-form surface no B-spline took"
    return ""


def as_decomposition(mesh: Mesh, labels: np.ndarray):
    """A :class:`recon.decompose.Decomposition` whose parts are the exact faces, each a patch (the report and the
    B-rep's face names read the decomposition; an exact mesh needs no skeleton: its faces are found directly)."""
    from ..decompose._types import BoundaryCurves, Decomposition, Part, SurfaceSkeleton

    k = int(labels.max()) + 1
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    nb: list = [set() for _ in range(k)]
    for x, y in zip(a[a != b].tolist(), b[a != b].tolist()):
        nb[x].add(y)
        nb[y].add(x)
    areas = np.bincount(labels, weights=mesh.face_areas, minlength=k)
    counts = np.bincount(labels, minlength=k)
    parts = tuple(Part(p, "patch", False, tuple(sorted(nb[p])), int(counts[p]), float(areas[p])) for p in range(k))
    none3, none = np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    curves = BoundaryCurves(none3, none, np.zeros(1, dtype=np.int64), np.zeros((0, 2), dtype=np.int64),
                            np.zeros(0, bool))
    skeleton = SurfaceSkeleton(none3, np.zeros((0, 2), dtype=np.int64), none)
    return Decomposition(labels, parts, curves, skeleton, scale=float("nan"), omega_min=float("nan"),
                         threshold=float("nan"), noise=0.0, critical=np.zeros(len(labels), bool))
