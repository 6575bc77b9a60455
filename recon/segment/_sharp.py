"""The stage's first labelling: the decomposition's parts with its sharp features dissolved into the faces they
are the edges of (:func:`face_labels`)."""

from __future__ import annotations

import logging

import numpy as np

from ..decompose import Decomposition
from ._context import ANALYTIC, MIN_PART_VERTICES, SegmentContext, fit_parts
from ._labels import absorb, one_label, vertex_counts
from ._split import SPLIT_COVER, SPLIT_MIN_SHARE, grown_inside
from ._tidy import tidy

__all__ = ["face_labels"]

log = logging.getLogger(__name__)

#: A feature part whose area lies this much within tolerance of its neighbouring patches' surfaces is a sharp edge
#: (a strip the noise widened around an edge lies within tolerance of its two faces but for a few stray triangles;
#: a true blend bulges away from both by more than the tolerance over most of its area).
EXPLAINED_SHARE = 0.9


def face_labels(dec: Decomposition, ctx: SegmentContext) -> np.ndarray:
    """The label of the B-rep face every triangle will belong to, before the passes refine them.

    A sharp linear part or junction yields no face: its edge (or vertex) is where its neighbours' surfaces
    meet. A part counts as sharp when the decomposition says so, or when its neighbouring patches' fitted
    surfaces explain it: at least :data:`EXPLAINED_SHARE` of its area lies within tolerance of one of
    them (a strip that noise widened around a sharp edge; a true fillet bulges away from both faces by
    more than that). Each triangle of a sharp part goes to the patch whose surface passes closest to its
    centroid — the face it really lies on (for a junction, the patches next to its neighbours count too).
    On a noise-free mesh every triangle of a sharp edge's strip lies on one of the two faces: a part the
    decomposition calls sharp that its neighbours do not explain, and that analytic surfaces cover
    (:func:`_covered`), is faces of its own; one that nothing covers stays an edge.
    Parts too small to carry a surface of their own (fewer than ``MIN_PART_VERTICES`` vertices) join
    the part they touch most. A label whose triangles fell apart becomes one label per connected piece.
    Labels are renumbered 0..k−1 in order of first appearance, so they are deterministic.
    """
    mesh, tolerance = ctx.mesh, ctx.tolerance
    labels = np.asarray(dec.labels, dtype=np.int64).copy()
    parts = dec.parts
    is_patch = np.array([p.kind == "patch" for p in parts], dtype=bool)
    features = [p.id for p in parts if p.kind != "patch"]
    if not features:
        return tidy(labels, ctx)
    candidates = {}
    for pid in features:
        near = {n for n in parts[pid].neighbours if is_patch[n]}
        if not near or parts[pid].kind == "junction":
            near |= {m for n in parts[pid].neighbours for m in parts[n].neighbours if is_patch[m]}
        candidates[pid] = sorted(near)
    wanted = sorted(set().union(*candidates.values()))
    patch_fits = fit_parts(labels, ctx, only=wanted) if wanted else {}
    centroids, areas = mesh.face_centroids, mesh.face_areas
    dissolved = []
    nverts = vertex_counts(mesh.faces, labels)
    for pid in features:
        cands = [c for c in candidates[pid] if patch_fits[c].params]
        if not cands or (nverts[pid] < MIN_PART_VERTICES and not parts[pid].sharp):
            continue  # a piece too small to judge by its centroids is judged whole, by its vertices (`tidy`)
        tris = np.flatnonzero(labels == pid)
        d = np.stack([np.abs(patch_fits[c].distance(centroids[tris])) for c in cands])
        nearest = d.min(axis=0)
        explained = areas[tris][nearest <= tolerance].sum() / max(areas[tris].sum(), 1e-300)
        if explained >= EXPLAINED_SHARE or parts[pid].sharp and not (ctx.noise_free and _covered(tris, ctx)):
            labels[tris] = np.asarray(cands)[np.argmin(d, axis=0)]
            dissolved.append(pid)
    log.info("%d of %d feature parts are sharp: their triangles went to the patches", len(dissolved), len(features))
    labels = absorb(labels, ctx.pairs, np.isin(labels, dissolved))
    return tidy(labels, ctx)


def _covered(tris: np.ndarray, ctx: SegmentContext) -> bool:
    """Whether one analytic surface fits the triangles ``tris`` within tolerance, or analytic regions grown
    inside them cover them as :func:`recon.segment.split_unfitted` would split them."""
    if fit_parts(one_label(len(ctx.mesh.faces), tris), ctx, only=[0], upto=ANALYTIC[-1])[0].ok:
        return True
    total, found = grown_inside(tris, ctx, min_share=SPLIT_MIN_SHARE)
    return len(found) >= 2 and sum(ctx.mesh.face_areas[r].sum() for r, _ in found) >= SPLIT_COVER * total
