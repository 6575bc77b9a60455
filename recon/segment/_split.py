"""Passes that split faces into the analytic surfaces grown inside them (:func:`split_unfitted`) and cut faces back
to the surface that covers most of them (:func:`trim_to_surface`)."""

from __future__ import annotations

import hashlib
import logging

import numpy as np
import scipy.sparse as sp

from ..decompose import split_by_fitting
from ..fit import fit_plane, surface_normals
from ._context import (ANALYTIC, CURVED, GROW_ANGLE_DEG, MIN_CORNER_VERTICES, MIN_PART_VERTICES, SegmentContext,
                       exact_vertices, fit_members, fit_parts)
from ._labels import absorb, coplanar_pieces

__all__ = ["grown_inside", "planar_pieces", "receivers_fits", "split_unfitted", "trim_to_surface"]

log = logging.getLogger(__name__)

#: A part no surface fits is split into the analytic surfaces found inside it when they cover this share of
#: its area, each at least :data:`SPLIT_MIN_SHARE` of it (the rest, under a tenth, is the seams between them).
SPLIT_COVER = 0.9
SPLIT_MIN_SHARE = 0.05
#: A B-spline face is cut back to one analytic surface grown inside it that covers this share of its area (the
#: rest, slivers of its neighbours, is a thin strip along its border).
TRIM_COVER = 0.85
#: Seeds tried for it, deepest inside the face first (a region that covers 85 % of a face holds its middle).
TRIM_SEEDS = 3


def grown_inside(tris: np.ndarray, ctx: SegmentContext, *, min_share: float, max_seeds=None, types=ANALYTIC
                 ) -> tuple[float, list]:
    """(area of the face ``tris``, the analytic regions grown inside it that reach ``min_share`` of it).

    No regions for a face under twice :data:`MIN_PART_VERTICES` vertices: too small to hold two surfaces.
    """
    mesh, tolerance, memo = ctx.mesh, ctx.tolerance, ctx.memo
    V, F = mesh.vertices, mesh.faces
    total = float(mesh.face_areas[tris].sum())
    if len(ctx.vertices(tris)) < 2 * MIN_PART_VERTICES:
        return total, []
    # The stage asks again for every face each round (trim, grow, trim ...), and most faces have not changed:
    # the regions depend on nothing but the triangles and these arguments (the cost saved: bench/segment.md).
    key = ("grown inside", float(tolerance), float(min_share), max_seeds, tuple(types),
           hashlib.sha1(np.asarray(tris, dtype=np.int64).tobytes()).digest())
    if key in memo:
        return total, memo[key]
    found = split_by_fitting(V, F, tris, vnormal=ctx.vertex_normals, tolerance=tolerance,
                             min_area=min_share * total, max_seeds=max_seeds, types=types)
    memo[key] = found
    return total, found


def split_unfitted(labels: np.ndarray, fits: dict, ctx: SegmentContext) -> np.ndarray:
    """Labels with every part no surface fits split into the analytic surfaces inside it, where they cover it.

    The decomposition can leave several faces in one part: a ring of fillets meeting at a pocket's sharp
    corners is one linear part (the skeleton has no junction there), and no one surface fits it. Regions
    grown from seeds inside such a part (:func:`recon.decompose.split_by_fitting`) that together
    cover :data:`SPLIT_COVER` of its area become faces of their own; the few triangles between them join
    the region they touch most. The split is kept only if every piece then fits its surface within
    tolerance. Returns ``labels`` itself when nothing was split.

    On a noise-free mesh a B-spline face is split the same way: there a B-spline holds almost any set of
    triangles within tolerance, four faces of a slot included (the ABC model), and analytic surfaces that
    cover it are the faces that were drawn.
    """
    pairs, area = ctx.pairs, ctx.mesh.face_areas
    out = labels
    noise_free = ctx.noise_free
    exact = None  # (whether the vertices are exact: asked once, when a B-spline face has regions in it)
    for p, fit in sorted(fits.items()):
        if fit.ok and not (noise_free and fit.type == "bspline"):
            continue
        tris = np.flatnonzero(labels == p)
        total, found = grown_inside(tris, ctx, min_share=SPLIT_MIN_SHARE)
        if noise_free and fit.type == "bspline" and found and exact is None:
            exact = exact_vertices(labels, fits, ctx)
        if exact and fit.type == "bspline" and found:
            found = found + exact_strips(tris, found, ctx)
        if len(found) < 2 or sum(area[r].sum() for r, _ in found) < SPLIT_COVER * total:
            continue
        trial = out.copy()
        base = int(trial.max()) + 1
        trial[tris] = -1
        for i, (r, _) in enumerate(found):
            trial[r] = base + i
        inside = np.isin(pairs[:, 0], tris) & np.isin(pairs[:, 1], tris)
        trial = absorb(trial, pairs[inside], trial == -1)
        if (trial == -1).any():
            continue
        new = list(range(base, base + len(found)))
        pieces = fit_parts(trial, ctx, only=new)
        # (on a noise-free mesh a piece within tolerance, its edges included, is a face even as a B-spline:
        # a thin part bounded by four arcs fits nothing whole; its evidence is in bench/constants.md)
        if not all(pieces[q].ok and (pieces[q].type in ANALYTIC or noise_free and not fit.ok) for q in new):
            continue
        log.info("part %d fits no surface: split into %d (%s)", p, len(new), ", ".join(pieces[q].type for q in new))
        out = trial
    return out


def exact_strips(tris: np.ndarray, found: list, ctx: SegmentContext) -> list:
    """On a mesh with exact vertices: the faces left in a B-spline face beside the regions ``found`` in it, where these are
    strips too thin for regions to grow in (the ABC model: a plane, then a fillet and a plane each one or two long
    triangles wide, 6 % and 0.7 % of the area). Coplanar pieces of at least :data:`MIN_PART_VERTICES` vertices are
    planes; each connected remainder of as many vertices is one surface if an analytic type fits it within
    tolerance. ``[(faces, fit)]``, or ``[]`` unless every remainder that large fits.
    """
    V, F, pairs, tolerance = ctx.mesh.vertices, ctx.mesh.faces, ctx.pairs, ctx.tolerance
    rest = np.setdiff1d(tris, np.concatenate([r for r, _ in found]))
    if not len(rest):
        return []
    big = lambda g: len(ctx.vertices(g)) >= MIN_PART_VERTICES  # noqa: E731
    # (neighbours within tolerance of each other's plane chain round a finely cut fillet too: a plane must hold it)
    out = [(g, fit_plane(V[ctx.vertices(g)], tolerance=tolerance))
           for g in coplanar_pieces(V, F, rest, pairs, tolerance) if big(g)]
    out = [(g, s) for g, s in out if s.ok]
    flats = [g for g, _ in out]
    others = np.setdiff1d(rest, np.concatenate(flats)) if flats else rest
    if len(others):
        inside = np.isin(pairs[:, 0], others) & np.isin(pairs[:, 1], others)
        local = np.full(len(F), -1, dtype=np.int64)
        local[others] = np.arange(len(others))
        a, b = local[pairs[inside, 0]], local[pairs[inside, 1]]
        _, comp = sp.csgraph.connected_components(
            sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(len(others),) * 2), directed=False)
        for c in np.unique(comp):
            g = others[comp == c]
            if not big(g):
                continue  # (a few triangles: they join the region they touch most)
            surface = fit_members(g, -1, ANALYTIC[-1], ctx)
            if not (surface and surface.ok and surface.type in ANALYTIC):
                return []
            out.append((g, surface))
    return out


def trim_to_surface(labels: np.ndarray, fits: dict, ctx: SegmentContext) -> np.ndarray:
    """Labels with every B-spline (or unfitted) face that is mostly one analytic surface cut back to it, and
    every curved face that is mostly a plane cut back to the plane.

    Under noise a face can take in slivers of its neighbours (a chamfer's edge on a large plane): one plane
    no longer fits it, a B-spline does, and the plane becomes a free-form face — or a curved surface bends
    to take the slivers in within tolerance (a chamfer and a box face as cones and cylinders). When one
    analytic region grown inside the face (for a curved face, a plane region;
    :func:`recon.decompose.split_by_fitting`) covers :data:`TRIM_COVER` of its area, the rest goes
    to the neighbouring face whose surface passes nearest; the trim is kept only if the face then fits an
    analytic surface (for a curved face, a plane) and every face that received triangles still fits its own
    type within tolerance. A piece of the rest that is a planar face of its own (:func:`planar_pieces`: a
    chamfered box's corner triangle on the end of a chamfer) becomes a face instead.
    Returns ``labels`` itself when nothing was trimmed.
    """
    mesh, pairs = ctx.mesh, ctx.pairs
    out = labels
    for p, fit in sorted(fits.items()):
        # a free-form face may be cut back to any analytic surface, a curved one to a plane
        simpler = ANALYTIC if not fit.ok or fit.type == "bspline" else ("plane",) if fit.type != "plane" else ()
        if not simpler:
            continue
        tris = np.flatnonzero(out == p)
        _, found = grown_inside(tris, ctx, min_share=TRIM_COVER, max_seeds=TRIM_SEEDS, types=simpler)
        if not found:
            continue
        region = found[0][0]
        rest = np.setdiff1d(tris, region)
        # the rest goes to the neighbouring face whose surface passes nearest to it
        in_rest = np.isin(pairs, rest)
        across = in_rest[:, 0] ^ in_rest[:, 1]
        outer = np.where(in_rest[across, 0], pairs[across, 1], pairs[across, 0])
        cands = [int(q) for q in np.unique(out[outer]) if q != p and fits.get(int(q)) and fits[int(q)].params]
        if not cands:  # no neighbour within tolerance to give it to: it may be a face of its own
            across = rest_across_misfits(out, p, rest, fits, ctx, simpler)
            if across is not None:
                log.info("face %d was a %s: cut back to its analytic surface, the rest a face of its own with "
                         "%d triangles of faces out of tolerance", p, fit.type, int((across != out).sum()) - len(rest))
                out = across
            continue
        trial = out.copy()
        # a planar piece of the rest that no neighbouring surface holds is a face of its own (a chamfered box's
        # corner triangle on the end of a chamfer): given to a neighbour, it would bend that one off its surface
        corners = planar_pieces(rest, [fits[q] for q in cands] + [found[0][1]], ctx)
        for piece in corners:
            trial[piece] = trial.max() + 1
        rest = np.setdiff1d(rest, np.concatenate(corners)) if corners else rest
        if len(rest):
            d = np.stack([np.abs(fits[q].distance(mesh.face_centroids[rest])) for q in cands])
            trial[rest] = np.asarray(cands)[np.argmin(d, axis=0)]
        receivers = sorted(set(trial[rest].tolist()))
        new = fit_parts(trial, ctx, only=[p], upto=ANALYTIC[-1])
        if not new[p].ok or new[p].type not in simpler:
            continue
        new.update(receivers_fits(trial, receivers, fits, ctx))
        if not all(new[q].ok and new[q].type == fits[q].type for q in receivers):
            # the slivers given back must not change what their face is (a changed type can fail to build
            # and cost volume) — but the rest may be
            # a face of its own that a neighbour out of tolerance holds the other half of
            across = rest_across_misfits(out, p, rest, fits, ctx, simpler)
            if across is not None:
                log.info("face %d was a %s: cut back to a %s, the rest a face of its own with %d triangles of "
                         "faces out of tolerance", p, fit.type, new[p].type, int((across != out).sum()) - len(rest))
                out = across
            continue
        log.info("face %d was a %s: cut back to a %s, %d triangles to %d neighbours, %d planar pieces kept as faces",
                 p, fit.type, new[p].type, len(rest), len(receivers), len(corners))
        out = trial
    return out


def receivers_fits(labels: np.ndarray, receivers: list, fits: dict, ctx: SegmentContext) -> dict:
    """The surfaces of the faces ``receivers`` under ``labels``, for the test whether each still fits its type of
    ``fits`` within tolerance: an analytic one by the analytic types alone (:func:`recon.segment.fit_parts` ``upto`` the last).

    The test's answer is the full fit's: the analytic types are tried the same way, and the full fit only goes on
    to a B-spline where none of them fits, which fails the test all the same. A trial the test refuses then costs
    no B-spline, and one it accepts costs no second fit (:func:`recon.segment._context.fit_members` takes the full fit from this one).
    """
    analytic = [q for q in receivers if fits[q].type in ANALYTIC]
    out = fit_parts(labels, ctx, only=analytic, upto=ANALYTIC[-1]) if analytic else {}
    rest = [q for q in receivers if fits[q].type not in ANALYTIC]
    if rest:
        out.update(fit_parts(labels, ctx, only=rest))
    return out


def rest_across_misfits(labels: np.ndarray, p: int, rest: np.ndarray, fits: dict, ctx: SegmentContext,
                        simpler=ANALYTIC) -> np.ndarray | None:
    """Labels with the rest of face ``p`` (what :func:`trim_to_surface` cuts off it) made a face of its own
    together with the triangles of neighbouring faces out of tolerance that lie on the same analytic surface,
    or None.

    On a CAD tessellation of long slivers a face can lie in two parts whose slivers alternate with its
    neighbours'; neither neighbour keeps them within tolerance and neither can take the other's, so trimming
    gives up. The rest's own surface (fitted to it alone) is grown over the
    triangles of the faces around it that are out of tolerance, ring by ring, while they lie on it (vertices
    within ``tolerance``, normals within :data:`GROW_ANGLE_DEG`). Kept only when the new face has a surface's
    worth of vertices (:data:`MIN_PART_VERTICES`) and fits an analytic surface within tolerance, face ``p``
    without it fits one of the types ``simpler`` within tolerance, and every face that gave triangles fits
    within tolerance without them: every face involved ends within tolerance where two did not.
    """
    mesh, pairs, tolerance = ctx.mesh, ctx.pairs, ctx.tolerance
    V, F = mesh.vertices, mesh.faces
    own = fit_members(np.sort(rest), p, ANALYTIC[-1], ctx)
    if not own.ok or not own.params:
        return None
    misfit = [int(q) for q, f in fits.items() if q != p and not f.ok]
    if not misfit:
        return None
    cos_min = np.cos(np.deg2rad(GROW_ANGLE_DEG))
    cand = np.flatnonzero(np.isin(labels, misfit))
    d = np.abs(own.distance(V[F[cand]].reshape(-1, 3))).reshape(-1, 3).max(axis=1)
    n = surface_normals(own, mesh.face_centroids[cand])
    lies = np.zeros(len(labels), dtype=bool)
    lies[cand[(d <= tolerance) & (np.abs(np.einsum("ij,ij->i", n, mesh.face_normals[cand])) >= cos_min)]] = True
    face = np.zeros(len(labels), dtype=bool)
    face[rest] = True
    while True:  # ring by ring over the triangles that lie on the rest's surface
        a, b = face[pairs[:, 0]], face[pairs[:, 1]]
        nxt = np.concatenate([pairs[a & ~b & lies[pairs[:, 1]], 1], pairs[b & ~a & lies[pairs[:, 0]], 0]])
        if not len(nxt):
            break
        face[nxt] = True
    taken = np.flatnonzero(face & (labels != p))
    if not len(taken):
        return None
    tris = np.flatnonzero(face)
    if len(np.unique(F[tris])) < MIN_PART_VERTICES:
        return None
    trial = labels.copy()
    new = int(labels.max()) + 1
    trial[tris] = new
    givers = sorted(set(labels[taken].tolist()))
    got = fit_parts(trial, ctx, only=[p, new], upto=ANALYTIC[-1])
    if not (got[p].ok and got[p].type in simpler and got[new].ok):
        return None
    got = fit_parts(trial, ctx, only=givers)
    if not all(got[q].ok for q in givers):
        return None
    return trial


def planar_pieces(tris: np.ndarray, surfaces, ctx: SegmentContext) -> list:
    """The connected pieces of the triangles ``tris`` that are planar faces of their own: a plane holds their
    vertices (at least :data:`MIN_CORNER_VERTICES`, fewer than :data:`MIN_PART_VERTICES`: a piece any larger is a
    face the fit stage judges whole) within ``tolerance``, and each of ``surfaces`` (the fits around them) leaves
    some vertex farther than ``tolerance`` away — the test :func:`recon.segment._tidy.small_faces` keeps a small piece by."""
    V, F, pairs, tolerance = ctx.mesh.vertices, ctx.mesh.faces, ctx.pairs, ctx.tolerance
    if len(ctx.vertices(tris)) < MIN_CORNER_VERTICES or any(s.type in CURVED for s in surfaces):
        return []  # next to a curved face a small flat piece is what is left of a blend (`small_faces`)
    inside = np.isin(pairs[:, 0], tris) & np.isin(pairs[:, 1], tris)
    local = np.full(len(F), -1, dtype=np.int64)
    local[tris] = np.arange(len(tris))
    a, b = local[pairs[inside, 0]], local[pairs[inside, 1]]
    graph = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(len(tris), len(tris)))
    _, comp = sp.csgraph.connected_components(graph, directed=False)
    out = []
    for c in np.unique(comp):
        piece = tris[comp == c]
        ids = ctx.vertices(piece)
        if not MIN_CORNER_VERTICES <= len(ids) < MIN_PART_VERTICES:
            continue
        plane = fit_plane(V[ids])
        if np.abs(plane.distance(V[ids])).max() > tolerance:
            continue
        if any(s.params and np.abs(s.distance(V[ids])).max() <= tolerance for s in surfaces):
            continue
        out.append(piece)
    return out

