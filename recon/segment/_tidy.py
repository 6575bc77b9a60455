"""Tidying a labelling after every pass: one label per connected piece, small pieces absorbed or kept as planar
faces, labels renumbered in order of first appearance; and the cut that gives a closed smooth body an edge."""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp

from ..fit import CLOSED_KINDS, SurfaceFit, fit_plane
from ..mesh import unique_first
from ._context import CURVED, MIN_CORNER_VERTICES, MIN_FLAT_VERTICES, MIN_PART_VERTICES, SegmentContext, fit_parts
from ._labels import absorb, coplanar_pieces, drawn_flat, split_disconnected, vertex_counts

__all__ = ["cut_unbounded", "small_faces", "tidy"]

log = logging.getLogger(__name__)

#: Rounds of splitting, keeping small faces and absorbing small pieces (absorbing can leave a label in pieces).
TIDY_ROUNDS = 4


def tidy(labels: np.ndarray, ctx: SegmentContext) -> np.ndarray:
    """One label per connected piece, pieces too small for a surface absorbed by the part they touch most,
    labels renumbered 0..k−1 in order of first appearance (deterministic). Small pieces that are planar faces of
    their own are kept (:func:`small_faces`)."""
    mesh, pairs = ctx.mesh, ctx.pairs
    kept = np.zeros(len(labels), dtype=bool)  # small faces `small_faces` kept stay kept
    # A label that fell apart into several connected pieces is one face per piece; pieces too small to carry a
    # surface of their own join the part they touch most.
    for _ in range(TIDY_ROUNDS):
        labels = split_disconnected(labels, pairs)
        nverts = vertex_counts(mesh.faces, labels)
        small = (nverts[labels] < MIN_PART_VERTICES) & ~kept
        if small.any() and not small.all():
            new, small = small_faces(labels, small, ctx)
            kept |= new > labels.max()
            labels = new
        if not small.any() or small.all():
            break
        labels = absorb(labels, pairs, small)
    uniq, first = unique_first(labels)  # np.unique(labels, return_index=True)
    order = np.argsort(first)
    remap = np.empty(labels.max() + 1, dtype=np.int64)
    remap[uniq[order]] = np.arange(len(order))
    return remap[labels]


def small_faces(labels: np.ndarray, small: np.ndarray, ctx: SegmentContext) -> tuple[np.ndarray, np.ndarray]:
    """Keep the clusters of small pieces that are planar faces no neighbour's surface explains.

    A chamfered box's corner is a small triangle between three chamfers, often split by the decomposition
    into a junction and terminals of a triangle or two each. Joined to a chamfer it bends that chamfer off
    its plane, and the chamfer becomes a B-spline. So a connected cluster of small pieces becomes one face
    of its own when a plane holds its vertices within tolerance (at least :data:`MIN_CORNER_VERTICES`
    of them) while the surface fitted to each neighbouring part leaves some vertex farther than
    tolerance away — absorbing it anywhere would bend that face — and no neighbour is a curved analytic
    surface (next to one, such a piece is the remnant of a blend, and a face made of it can make the solid
    invalid). A planar cluster that does lie on a neighbour's surface joins that neighbour (not the one it
    touches most). Returns the labels and the still-small mask (clusters placed here are no longer small).
    """
    mesh, pairs, tolerance = ctx.mesh, ctx.pairs, ctx.tolerance
    V, F = mesh.vertices, mesh.faces
    a, b = pairs[:, 0], pairs[:, 1]
    both = small[a] & small[b]
    m = len(labels)
    graph = sp.coo_matrix((np.ones(int(both.sum())), (a[both], b[both])), shape=(m, m))
    _, comp = sp.csgraph.connected_components(graph, directed=False)
    comp = np.where(small, comp, -1)
    neighbour_fits: dict[int, SurfaceFit] = {}
    labels, small = labels.copy(), small.copy()
    # On a noise-free mesh a CAD export draws a flat face with as few triangles as it can, each far larger than
    # the mesh's typical one (`drawn_flat`): such a piece is a face from 4 vertices on, next to curved faces
    # too, and a cluster of them that is not flat is judged by its flat pieces (a slot's ring of four walls).
    big = drawn_flat(mesh.face_areas) if ctx.noise_free else (lambda tris: False)
    clusters = []
    for c in np.unique(comp[comp >= 0]):
        tris = np.flatnonzero(comp == c)
        ids = ctx.vertices(tris)
        if big(tris) and np.abs(fit_plane(V[ids]).distance(V[ids])).max() > tolerance:
            clusters += [g for g in coplanar_pieces(V, F, tris, pairs, tolerance) if big(g)]
        else:
            clusters.append(tris)
    for tris in clusters:
        ids = ctx.vertices(tris)
        drawn = big(tris)
        if len(ids) < (MIN_FLAT_VERTICES if drawn else MIN_CORNER_VERTICES):
            continue
        plane = fit_plane(V[ids])
        if np.abs(plane.distance(V[ids])).max() > tolerance:
            continue
        touch = np.isin(a, tris) ^ np.isin(b, tris)
        others = np.unique(labels[np.where(np.isin(a[touch], tris), b[touch], a[touch])])
        others = [int(o) for o in others if not small[np.flatnonzero(labels == o)[0]]]
        if not others:
            continue
        for o in others:
            if o not in neighbour_fits:
                neighbour_fits[o] = fit_parts(labels, ctx, only=[o])[o]
        off = [np.abs(neighbour_fits[o].distance(V[ids])).max() if neighbour_fits[o].params else np.inf
               for o in others]
        if min(off) <= tolerance:  # it lies on a neighbour's surface: it joins that one, not the one it touches most
            labels[tris] = others[int(np.argmin(off))]
            small[tris] = False
            continue
        if not drawn and any(neighbour_fits[o].type in CURVED for o in others):
            continue  # next to a curved face a small flat piece is what is left of a blend, not a face
        labels[tris] = labels.max() + 1
        small[tris] = False
        log.info("a planar piece of %d triangles between %d faces kept as a face of its own", len(tris), len(others))
    return labels, small


def cut_unbounded(labels: np.ndarray, fits: dict, ctx: SegmentContext) -> np.ndarray:
    """Labels with every closed body that one label covers cut in two (``labels`` itself if there is none).

    A face needs a boundary, and a closed body covered by one smooth part (an ellipsoid, a coarse free-form part)
    has none: no edge bounds it, and the B-rep has nothing to build on; only a sphere or torus fitted within
    tolerance bounds itself (its seams and poles, :data:`recon.fit.CLOSED_KINDS`) and stays one face. Cutting the
    body by the plane through its centroid across its longest principal axis gives two parts sharing one loop, the
    least a closed surface needs (OpenCascade's own sphere has a seam); each half is fitted like any part.
    """
    mesh, pairs = ctx.mesh, ctx.pairs
    body = split_disconnected(np.zeros(len(labels), dtype=np.int64), pairs)
    out = labels
    if np.any(mesh.edge_face_count == 1):  # an open mesh: its boundary bounds its faces
        return labels
    for b in np.unique(body):
        tris = np.flatnonzero(body == b)
        if len(np.unique(labels[tris])) > 1:
            continue
        fit = fits.get(int(labels[tris[0]]))
        if fit is not None and fit.ok and fit.type in CLOSED_KINDS:
            continue  # a whole sphere or torus is one face, bounded by its own seams (recon.brep)
        c = mesh.face_centroids[tris]
        w = mesh.face_areas[tris]
        centre = np.average(c, axis=0, weights=w)
        _, _, vt = np.linalg.svd((c - centre) * np.sqrt(w)[:, None], full_matrices=False)
        side = (c - centre) @ vt[0] > 0
        if side.all() or not side.any():
            continue
        if out is labels:
            out = labels.copy()
        out[tris[side]] = out.max() + 1
        log.info("a closed body is one smooth part: cut in two across its longest axis to give its faces an edge")
    return out
