"""A free-form face the exact path broke into pieces, taken whole when one B-spline holds it.

A loft's or a sweep's wall is one B-spline face whose quads, few at a time, lie on a cone, a cylinder or a sphere to
round-off (a handful of vertices on two section curves leave a 6-parameter cone room to pass them): the seeds grow
hundreds of small coincidental curved faces there, and the single triangles between them are too many for the path
(a loft's wall: bench/exact.md). The faces that are not proven planes and that border, across smooth
edges, only the free-form pieces (loose single triangles and B-spline faces) and the planes these border are enclosed by the free-form surface:
they are joined with it, and the whole is one face when a B-spline through all its vertices holds them within the
run's tolerance. A true analytic face tangent to some other face beside the free-form one is never enclosed (a
curved piece meeting a plane at a kink is no such face: a blend's coincidental piece beside the plane it is tangent
to), and a plane of more than two triangles is taken only when the free-form pieces surround it across smooth
edges alone (a CAD export draws a free-form face with hardly any flat pair; a plane face of a part meets some other face or a crease).
numpy/scipy only; the B-spline is fitted by the caller's ``fit_piece``.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np
import scipy.sparse as sp

__all__ = ["components", "enclosed_free_form"]


def components(k: int, a: np.ndarray, b: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Connected components (k,) of the faces over the pairs (a, b) whose both ends are in ``keep``."""
    m = keep[a] & keep[b]
    g = sp.coo_matrix((np.ones(int(m.sum())), (a[m], b[m])), shape=(k, k))
    return sp.csgraph.connected_components(g, directed=False)[1]


def enclosed_free_form(labels: np.ndarray, kinds: list, pairs: np.ndarray, smooth: np.ndarray, loose: np.ndarray,
                       fit_piece: Callable[[np.ndarray], Any], kinked: np.ndarray | None = None
                       ) -> list[tuple[np.ndarray, Any]]:
    """The free-form faces found whole: ``(triangles, fit)`` for each group of faces a B-spline holds.

    Parameters
    ----------
    labels : (m,) int
        The face of every triangle.
    kinds : list of str
        The surface type of every face, by label.
    pairs : (e, 2) int
        Triangles sharing an edge.
    smooth : (e,) bool
        Whether each pair turns by less than a crease.
    loose : (k,) bool
        The faces that are single triangles not amid planes (the free-form pieces left over).
    fit_piece : callable
        ``fit_piece(triangles)``: a B-spline fit through their vertices (truthy when it holds them within the
        tolerance) or None.
    kinked : (e,) bool, optional
        The smooth pairs where a curved face meets a plane at a kink, not tangentially: a coincidental piece of a
        blend beside the plane the blend is tangent to, which no true face tangent to that plane would show.
    """
    k = len(kinds)
    count = np.bincount(labels, minlength=k)
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    seed = loose | np.array([t == "bspline" for t in kinds])
    # a plane of more triangles is proven, unless the free-form pieces surround it across smooth edges alone: a flat
    # patch of a few triangles inside a loft's wall, which no face of a part would be
    walled = np.ones(k, bool)
    walled[a[(a != b) & (~smooth | ~seed[b])]] = False  # an edge across a crease, or to a face that is no piece
    walled[b[(a != b) & (~smooth | ~seed[a])]] = False
    proven = np.array([t == "plane" and c > 2 for t, c in zip(kinds, count)]) & ~walled
    # the planes the free-form pieces themselves border: a piece of the free-form face along such a plane's edge
    # borders it too (a loft's wall may meet its end cap at less than the crease angle)
    rim = np.zeros(k, bool)
    rim[b[seed[a] & proven[b]]] = True
    rim[a[seed[b] & proven[a]]] = True
    cut = (a != b) & smooth
    a, b = np.r_[a[cut], b[cut]], np.r_[b[cut], a[cut]]  # smooth face adjacency, both ways
    kink = np.zeros(len(a), bool) if kinked is None else np.r_[kinked[cut], kinked[cut]]
    candidate = ~seed & ~proven
    # a group of candidate faces joins the free-form pieces when every face it borders smoothly is one of them or a
    # plane they border
    comp = components(k, a, b, candidate)
    outside = candidate[a] & ~candidate[b]
    bad = np.zeros(k, bool)
    # (a plane met at a kink does not count: the group is a blend's pieces, not a face tangent to it)
    bad[comp[a[outside & ~seed[b] & ~rim[b] & ~kink]]] = True
    touches = np.zeros(k, bool)
    touches[comp[a[outside & seed[b]]]] = True
    joined = seed | (candidate & touches[comp] & ~bad[comp])
    whole = components(k, a, b, joined)
    out = []
    for g in np.unique(whole[seed]):
        faces = np.flatnonzero(joined & (whole == g))
        if len(faces) < 2:
            continue  # a B-spline face alone is whole already; a single triangle alone has too few vertices
        tris = np.flatnonzero(np.isin(labels, faces))
        fit = fit_piece(tris)
        if fit:
            out.append((tris, fit))
    return out
