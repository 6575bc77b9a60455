"""Passes that move boundary triangles to the neighbouring face whose analytic surface they lie on
(:func:`grow_faces`), give away faces their neighbours' surfaces hold (:func:`dissolve_explained`) and faces no
surface fits (:func:`dissolve_misfits`)."""

from __future__ import annotations

import logging
from typing import Callable

import numpy as np

from ..features import EDGE_FACTOR, NOISE_FACTOR
from ..fit import ACCEPT_MAX_FACTOR, MISFIT_SCALE, fit_plane, residual_scale, surface_normals
from ._context import (ANALYTIC, EXACT_MISFIT, EXACT_RESIDUAL, GROW_ANGLE_DEG, MIN_FLAT_VERTICES, MIN_PART_VERTICES,
                       SegmentContext, fit_parts)
from ._labels import drawn_flat, vertex_sets
from ._split import TRIM_COVER, TRIM_SEEDS, grown_inside, planar_pieces, receivers_fits

__all__ = ["dissolve_explained", "dissolve_misfits", "grow_faces"]

log = logging.getLogger(__name__)

#: Triangles of a face :func:`_maybe_held` looks at first, at most (an even subset): enough that a face mostly
#: on its own surface shows a triangle off its neighbours' at once.
HELD_SAMPLE = 64
#: ... and the slack of its test, relative: far above round-off, far below any real margin.
HELD_SLACK = 1e-9

#: ``on(q, tris, slack=0.0)``: each triangle's largest vertex distance to face q's surface; inf where it does not
#: lie on it.
OnSurface = Callable[..., np.ndarray]


def grow_faces(labels: np.ndarray, fits: dict, ctx: SegmentContext) -> np.ndarray:
    """Labels with boundary triangles moved to the neighbouring face whose analytic surface they lie on.

    The decomposition draws its parts' borders before any face is fitted whole, and under noise it draws them
    badly: a part can hold strips of its neighbours (a chamfer with strips of both planes, which a cylinder
    then covers within tolerance), and a face can lie in pieces over many parts.
    With every face fitted, a triangle *lies on* a face's analytic surface when its vertices are within
    tolerance of it and its normal within ``GROW_ANGLE_DEG`` of the surface's. A boundary triangle
    moves to a neighbouring face it lies on

    - when it does not lie on its own face's surface, or its own face has no analytic one (a B-spline is the
      fallback: an analytic surface that holds the triangle is the simpler explanation);
    - when its own face's surface *misfits* — a robust residual above :data:`recon.fit._select.MISFIT_SCALE`
      × the noise, the mark of a compromise such as the chamfer's cylinder — and the neighbour's surface
      passes closer. On a noise-free mesh whose vertices are exact (a CAD export: most analytic faces fit to
      round-off), a surface misfits when its residual is a share of the tolerance (``EXACT_MISFIT``).

    A surface that fits at the noise level keeps what it holds: near a tangent seam a neighbour's extension
    holds a face's rim as closely as the noise allows (a fillet's cylinder can take a corner sphere whole). Moves are made ring by ring over the new borders with the surfaces fixed; a
    triangle only moves to a surface that holds it closer than where it was, so it ends. A face is taken
    whole or left with enough vertices for a surface (``MIN_PART_VERTICES``) — or as a planar face of its own
    that no surface around it holds (:func:`recon.segment._split.planar_pieces`: a corner triangle a compromise
    cylinder over it and a piece of a chamfer leaves when it gives the chamfer back) — and a face that received
    triangles must still fit its own type within tolerance, or it gets none. Returns ``labels`` itself when
    nothing moved.
    """
    return _grow(labels, fits, ctx)


def dissolve_explained(labels: np.ndarray, fits: dict, ctx: SegmentContext) -> np.ndarray:
    """:func:`grow_faces` where only the faces every triangle of which lies on a neighbouring face's surface give
    triangles away, whatever their own surface, and receive none.

    Such a face is pieces of its neighbours that a surface of its own also holds within the noise, which no
    merge can take in (their union with either neighbour fits neither). On a noisy mesh a face narrower than the
    feature window whose vertices all lie within tolerance of its neighbours' surfaces is one too, whatever its
    triangles' normals (:func:`_crease_strips`): a crease the mesh's triangles bevel. Returns ``labels`` itself
    when nothing moved.
    """
    return _grow(labels, fits, ctx, dissolve=True)


def dissolve_misfits(labels: np.ndarray, fits: dict, ctx: SegmentContext) -> np.ndarray:
    """Labels with every face that no surface fits by far given to the surfaces around and inside it.

    A face whose best surface leaves its points farther than :data:`recon.fit._types.ACCEPT_MAX_FACTOR` ×
    the tolerance on average (RMS: farther than any accepted fit's largest deviation) is not a face a designer
    drew but a decomposition failure: on a CAD tessellation of long slivers, a fan of triangles that alternate
    with a neighbour's. No face builds on such a surface (nor a filling in its place), and the shell has a hole
    there. So

    - its triangles move, ring by ring, to the neighbouring faces whose analytic surfaces they lie on
      (:func:`grow_faces` with these faces as the only givers; a receiver must still fit its own type), when
      that leaves of it nothing but debris too small for a surface (under ``MIN_PART_VERTICES`` vertices,
      which :func:`recon.segment.tidy` absorbs). ``grow_faces`` would keep such debris and with it the whole
      face; a larger remnant is kept whole instead: a face on its own poor surface may still build where a piece
      of it fails;
    - when one analytic region grown inside it covers ``TRIM_COVER`` of its area (as
      :func:`recon.segment.trim_to_surface` cuts back a face) and what is left beside it after the moves is too
      small for a face of its own (fewer than ``MIN_PART_VERTICES`` vertices: debris), that region is the face.

    A face that fits no surface because it is coarse (a few large triangles across a curved face: the coarse
    fixtures) has no neighbour that holds its triangles and no debris beside one surface, and stays as it is.

    Returns ``labels`` itself when no face is that far out or nothing changed.
    """
    tolerance = ctx.tolerance
    far = sorted(p for p, f in fits.items()
                 if not f.ok and np.isfinite(f.deviation["rms"]) and f.deviation["rms"] > ACCEPT_MAX_FACTOR * tolerance)
    if not far:
        return labels
    out = labels.copy()
    fits = dict(fits)
    kept = {}
    for p in far:
        tris = np.flatnonzero(labels == p)
        _, found = grown_inside(tris, ctx, min_share=TRIM_COVER, max_seeds=TRIM_SEEDS)
        if found:
            q = int(out.max()) + 1
            out[found[0][0]] = q
            new = fit_parts(out, ctx, only=[q])[q]
            if new.ok and new.type in ANALYTIC:
                fits[q] = new
                kept[q] = p
            else:
                out[out == q] = p
    grown = _grow(out, fits, ctx, givers=far)
    for q, p in list(kept.items()):
        # the surface inside is the face only when what is left beside it is debris too small for a face of its
        # own (a flat bottom and the teeth of the wall beside it); a larger rest would be a face no surface fits
        rest = np.flatnonzero(grown == p)
        if len(rest) and len(ctx.vertices(rest)) >= MIN_PART_VERTICES:
            if grown is out:
                grown = out.copy()
            grown[grown == q] = p
            del kept[q]
    if not kept and (grown == labels).all():
        return labels
    log.info("faces %s fit no surface by far (RMS above %g× the tolerance): %d cut back to the analytic surface "
             "inside them, %d triangles given to the faces around them whose surfaces they lie on", far,
             ACCEPT_MAX_FACTOR, len(kept), int((grown != out).sum()))
    return grown


def _grow(labels: np.ndarray, fits: dict, ctx: SegmentContext, *, dissolve: bool = False, givers=None) -> np.ndarray:
    """:func:`grow_faces`; with ``dissolve`` :func:`dissolve_explained`; with ``givers`` (faces no surface fits,
    from :func:`dissolve_misfits`) only those faces give triangles away, and each goes whole — but for debris
    under ``MIN_PART_VERTICES`` vertices, which :func:`recon.segment.tidy` places — or not at all."""
    analytic = np.array(sorted(q for q, f in fits.items() if f.ok and f.type in ANALYTIC), dtype=np.int64)
    misfit, exact = _misfit_faces(labels, fits, analytic, ctx)
    on = _on_surface(fits, ctx)
    explained = _explained_faces(labels, analytic, ctx.pairs, on) if dissolve else np.zeros(0, dtype=np.int64)
    if dissolve and ctx.noise is not None:
        strips = _crease_strips(labels, np.setdiff1d(analytic, explained), analytic, fits, ctx)
        if len(strips):
            explained = np.union1d(explained, strips)
            on = _by_position(on, fits, ctx, np.isin(labels, strips))
    if dissolve and not len(explained):
        return labels
    receiving = np.setdiff1d(analytic, explained)
    only_from = explained if dissolve else None if givers is None else np.asarray(sorted(givers), dtype=np.int64)
    out = _move_rings(labels, ctx.pairs, receiving, only_from, misfit, on)
    _keep_remnants(labels, out, fits, set() if givers is None else {int(g) for g in givers}, exact, ctx)
    moved = out != labels
    if not moved.any():
        return labels
    receivers = sorted(set(out[moved].tolist()))
    new = receivers_fits(out, receivers, fits, ctx)
    refused = [q for q in receivers if not (new[q].ok and new[q].type == fits[q].type)]
    if refused:
        undo = moved & np.isin(out, refused)
        out[undo] = labels[undo]
        if not (out != labels).any():
            return labels
    log.info("%d triangles moved to the neighbouring face whose surface they lie on (%d faces refused them)%s",
             int((out != labels).sum()), len(refused),
             f"; faces {explained.tolist()} lie on their neighbours' surfaces" if dissolve else "")
    return out


def _misfit_faces(labels: np.ndarray, fits: dict, analytic: np.ndarray, ctx: SegmentContext
                  ) -> tuple[dict[int, bool], bool]:
    """Whether each analytic face's surface misfits it (a compromise over pieces of several faces), and whether
    the mesh's vertices are exact (a noise-free mesh whose analytic faces mostly fit to round-off)."""
    V, F, tolerance = ctx.mesh.vertices, ctx.mesh.faces, ctx.tolerance
    ids = vertex_sets(F, labels, len(V))
    scales = {q: residual_scale(fits[q], V[ids(q)]) for q in analytic.tolist()}
    if ctx.noise is not None:
        return {q: s > MISFIT_SCALE * ctx.noise for q, s in scales.items()}, False
    # a noise-free mesh whose vertices are exact (a CAD export: most analytic faces fit to round-off) — not
    # every mesh without noise has them (a remeshed model's lie a share of the tolerance off) — shows a
    # compromise over pieces of several faces by a residual that is a share of the tolerance
    exact = bool(scales) and float(np.median(list(scales.values()))) <= EXACT_RESIDUAL * tolerance
    log.debug("grow_faces: median residual %.3g tolerances (exact vertices: %s)",
              float(np.median(list(scales.values()))) / tolerance if scales else float("nan"), exact)
    return {q: exact and s > EXACT_MISFIT * tolerance for q, s in scales.items()}, exact


def _on_surface(fits: dict, ctx: SegmentContext) -> OnSurface:
    """The test whether triangles lie on a face's surface (vertices within tolerance, normal within
    ``GROW_ANGLE_DEG``), as ``on(q, tris, slack=0.0)``: each triangle's largest vertex distance to face q's surface,
    inf where it does not lie on it (with ``slack``, by a test that much looser: a relative margin over round-off)."""
    mesh, tolerance = ctx.mesh, ctx.tolerance
    V, F = mesh.vertices, mesh.faces
    cos_min = np.cos(np.deg2rad(GROW_ANGLE_DEG))

    def on(q, tris, slack=0.0):
        d = np.abs(fits[q].distance(V[F[tris]].reshape(-1, 3))).reshape(-1, 3)
        d = np.maximum(np.maximum(d[:, 0], d[:, 1]), d[:, 2])  # d.max(axis=1), without the reduction's setup
        n = surface_normals(fits[q], mesh.face_centroids[tris])
        cos = np.abs(np.einsum("ij,ij->i", n, mesh.face_normals[tris]))
        lies = (d <= tolerance * (1.0 + slack)) & (cos >= cos_min - slack)
        return np.where(lies, d, np.inf)

    return on


def _move_rings(labels: np.ndarray, pairs: np.ndarray, receiving: np.ndarray, only_from, misfit: dict,
                on: OnSurface) -> np.ndarray:
    """The labels after moving triangles, ring by ring over the new borders, to the receiving face whose surface
    holds them closer than their own (:func:`grow_faces`' rule; ``only_from``: only these faces give)."""
    out = labels.copy()
    # A candidate move depends on nothing but the labels of its two triangles, with the surfaces fixed: after
    # the first ring, only pairs with a triangle that just moved can offer one.
    live = np.ones(len(pairs), dtype=bool)
    for _ in range(len(labels)):
        a, b = out[pairs[:, 0]], out[pairs[:, 1]]
        cross = (a != b) & live
        tri = np.concatenate([pairs[cross, 0], pairs[cross, 1]])
        face = np.concatenate([b[cross], a[cross]])
        keep = np.isin(face, receiving)
        cand = np.unique(np.column_stack([tri[keep], face[keep]]), axis=0)
        if not len(cand):
            break
        tri, face = cand[:, 0], cand[:, 1]
        there = np.full(len(tri), np.inf)
        for q in np.unique(face):
            there[face == q] = on(q, tri[face == q])
        here = np.full(len(tri), np.inf)  # what a move must beat
        own = out[tri]
        for p in np.intersect1d(own, receiving):
            d = on(p, tri[own == p])
            here[own == p] = d if misfit[p] else np.where(np.isfinite(d), -1.0, np.inf)
        if only_from is not None:
            here[~np.isin(own, only_from)] = -np.inf  # only the explained faces (the givers) give triangles away
        better = there < here
        if not better.any():
            break
        tri, face, d = tri[better], face[better], there[better]
        order = np.lexsort((d, tri))  # per triangle, the nearest surface first
        tri, face = tri[order], face[order]
        first = np.r_[True, tri[1:] != tri[:-1]]
        out[tri[first]] = face[first]
        just = np.zeros(len(labels), dtype=bool)
        just[tri[first]] = True
        live = just[pairs[:, 0]] | just[pairs[:, 1]]
    return out


def _keep_remnants(labels: np.ndarray, out: np.ndarray, fits: dict, misfit_givers: set, exact: bool,
                   ctx: SegmentContext) -> None:
    """Undo, in ``out``, the moves out of a face that would leave a remnant no face can be made of.

    A remnant too small for a surface would go to the face it touches most (:func:`recon.segment.tidy`), which
    need not hold it — unless the remnant is a planar face of its own that no neighbour holds (a chamfered box's
    corner left when a compromise surface over it and a piece of a chamfer gives the chamfer back): ``tidy``
    keeps it. A face no surface fits (``misfit_givers``) goes whole, but for debris too small for a surface, or
    stays whole: a larger remnant may still get a face on its own poor surface, and a piece of it may not.
    """
    V, pairs, tolerance = ctx.mesh.vertices, ctx.pairs, ctx.tolerance
    moved = out != labels
    for p in np.unique(labels[moved]):
        rest = np.flatnonzero(out == p)
        if int(p) in misfit_givers:
            if len(ctx.vertices(rest)) >= MIN_PART_VERTICES:
                out[moved & (labels == p)] = p
            continue
        if len(rest) and len(ctx.vertices(rest)) < MIN_PART_VERTICES:
            in_rest = np.isin(pairs, rest)
            across = in_rest[:, 0] ^ in_rest[:, 1]
            around = np.unique(out[np.where(in_rest[across, 0], pairs[across, 1], pairs[across, 0])])
            pieces = planar_pieces(rest, [fits[q] for q in around.tolist() if q in fits], ctx)
            ids = ctx.vertices(rest)
            if exact and not pieces and drawn_flat(ctx.mesh.face_areas)(rest) and len(ids) >= MIN_FLAT_VERTICES \
                    and np.abs(fit_plane(V[ids]).distance(V[ids])).max() <= tolerance:
                pieces = [rest]  # a face a CAD export drew flat with a few large triangles (`small_faces` keeps it)
            if sum(len(c) for c in pieces) < len(rest):
                out[moved & (labels == p)] = p


def _explained_faces(labels: np.ndarray, analytic: np.ndarray, pairs: np.ndarray, on: OnSurface) -> np.ndarray:
    """The faces among ``analytic`` every triangle of which lies (``on``) on a neighbouring analytic face's surface."""
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    cross = (a != b) & np.isin(a, analytic) & np.isin(b, analytic)
    nbr = np.unique(np.column_stack([np.r_[a[cross], b[cross]], np.r_[b[cross], a[cross]]]), axis=0)
    out = []
    for p in analytic.tolist():
        tris = np.flatnonzero(labels == p)
        around = nbr[nbr[:, 0] == p, 1].tolist()
        if not _maybe_held(tris, around, on):
            continue
        held = np.zeros(len(tris), dtype=bool)
        for q in around:
            held[~held] = np.isfinite(on(q, tris[~held]))
            if held.all():
                out.append(p)
                break
    return np.asarray(out, dtype=np.int64)


def _maybe_held(tris: np.ndarray, around: list, on: OnSurface) -> bool:
    """False when some triangle of an even sample of ``tris`` surely lies on none of the faces ``around`` (``on``
    with :data:`HELD_SLACK`): the face is then not explained, whatever its other triangles do. A large face is
    mostly its own surface; this spares testing all its triangles against every neighbour."""
    if len(tris) <= HELD_SAMPLE:
        return True
    sample = tris[:: -(-len(tris) // HELD_SAMPLE)]
    held = np.zeros(len(sample), dtype=bool)
    for q in around:
        held[~held] = np.isfinite(on(q, sample[~held], HELD_SLACK))
        if held.all():
            return True
    return False


def _crease_strips(labels: np.ndarray, candidates: np.ndarray, analytic: np.ndarray, fits: dict,
                   ctx: SegmentContext) -> np.ndarray:
    """The faces among ``candidates`` of a noisy mesh that are a crease its triangles bevel, not a face: narrower
    (area / length) than the feature window ``max(EDGE_FACTOR · h, NOISE_FACTOR · σ)``, and with every vertex within
    the tolerance of a neighbouring analytic face's (``analytic``) surface.

    Nothing narrower than the window is told apart from the noise (:mod:`recon.features`), and a strip whose
    points the neighbours' surfaces hold within the tolerance is explained by their intersection; its triangles
    straddle the crease, so their normals turn from both surfaces (``GROW_ANGLE_DEG``) and :func:`_explained_faces`
    does not see it. A fillet wider than the window, or bulging farther than the tolerance from its neighbours'
    intersection, stays.
    """
    mesh = ctx.mesh
    V, F, areas = mesh.vertices, mesh.faces, mesh.face_areas
    window = max(EDGE_FACTOR * mesh.mean_edge_length, NOISE_FACTOR * float(ctx.noise))
    a, b = labels[ctx.pairs[:, 0]], labels[ctx.pairs[:, 1]]
    cross = a != b
    out = []
    for p in candidates.tolist():
        tris = np.flatnonzero(labels == p)
        ids = ctx.vertices(tris)
        pts = V[ids] - V[ids].mean(axis=0)
        length = float(np.ptp(pts @ np.linalg.svd(pts, full_matrices=False)[2][0]))
        if not length > 0 or areas[tris].sum() / length > window:
            continue
        around = np.intersect1d(np.r_[b[cross & (a == p)], a[cross & (b == p)]], analytic).tolist()
        if len(around) < 2:
            continue
        d = np.min([np.abs(fits[q].distance(V[ids])) for q in around], axis=0)
        if d.max() <= ctx.tolerance:
            out.append(p)
    return np.asarray(out, dtype=np.int64)


def _by_position(on: OnSurface, fits: dict, ctx: SegmentContext, strip: np.ndarray) -> OnSurface:
    """``on``, but for the triangles where ``strip`` is set a triangle lies on a surface when its vertices are
    within the tolerance of it, whatever its normal (a bevelled crease's triangles turn from both surfaces)."""
    V, F, tolerance = ctx.mesh.vertices, ctx.mesh.faces, ctx.tolerance

    def on_strip(q, tris, slack=0.0):
        out = on(q, tris, slack)
        loose = strip[tris]
        if loose.any():
            d = np.abs(fits[q].distance(V[F[tris[loose]]].reshape(-1, 3))).reshape(-1, 3).max(axis=1)
            out[loose] = np.where(d <= tolerance * (1.0 + slack), d, np.inf)
        return out

    return on_strip
