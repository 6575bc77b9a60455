"""Clean a triangle soup once, at the entry of the pipeline: weld, drop bad triangles, orient, split.

Everything is vectorised (sorts, ``scipy.sparse.csgraph``), so a million triangles take seconds.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components
from scipy.spatial import cKDTree

from ..errors import InputError, MeshError
from .._array import col_means, row_norms
from ._topology import halfedge_order, unique_edges, unique_rows
from ._types import CleanReport, Mesh

__all__ = ["clean_mesh", "input_labels", "DEFAULT_WELD_RELATIVE"]

log = logging.getLogger(__name__)

#: Default weld tolerance as a fraction of the bounding-box diagonal. Small enough never to merge
#: distinct vertices of a sane CAD tessellation, large enough to merge the copies an STL export
#: writes for every triangle (bit-identical) and float round-off from other exporters.
DEFAULT_WELD_RELATIVE = 1e-6

#: A triangle is degenerate (zero area) when its height is at most this fraction of its longest edge.
FLAT_RELATIVE = 1e-10


def clean_mesh(vertices, faces, *, weld_tolerance: float | None = None) -> Mesh:
    """Weld, drop degenerate and duplicate triangles, orient consistently and split into components.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
        Triangles as vertex indices; their order is "the input order" that ``Mesh.source_face`` refers to.
    weld_tolerance : float, optional
        Vertices closer than this (mesh units) become one. Default ``1e-6`` × the bounding-box diagonal
        of the referenced vertices. ``0`` merges only bit-identical positions. Welding snaps to a grid of
        this pitch and then joins neighbouring cells within the tolerance, so merged clusters can chain
        and a cluster's extent can exceed the tolerance by a few grid pitches on dense noise.

    Returns
    -------
    Mesh
        Kept triangles in input order; a merged vertex takes the position of its first input copy.

    Raises
    ------
    MeshError
        Wrong shapes, indices out of range, NaN/inf coordinates, or no triangle left after cleaning.
    InputError
        A negative or non-finite ``weld_tolerance``.

    Notes
    -----
    Orientation: triangles are oriented by a breadth-first walk over manifold edges (edges with exactly
    two triangles), so every edge-connected patch is consistent where it is orientable; non-manifold
    edges do not propagate orientation. A closed patch is then turned outward (positive signed volume);
    an open patch keeps the orientation most of its input area had.
    """
    v, f = _validated(vertices, faces)
    n_in, m_in = len(v), len(f)

    used = np.bincount(f.ravel(), minlength=n_in) > 0
    lo, hi = _extremes(v if used.all() else v[used])
    diagonal = float(np.linalg.norm(hi - lo))
    if weld_tolerance is None:
        tol = DEFAULT_WELD_RELATIVE * diagonal
    else:
        tol = float(weld_tolerance)
        if not np.isfinite(tol) or tol < 0:
            raise InputError(f"weld_tolerance must be a finite distance >= 0, got {weld_tolerance!r}")

    vid, positions = _weld(v, tol)
    welded = n_in - len(positions)

    F = vid[f]
    repeated = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    P = positions[F]
    e0, e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 1], P[:, 0] - P[:, 2]  # edge vectors p0->p1, p1->p2, p2->p0
    # np.linalg.norm(np.cross(e0, -e2), axis=1) and np.linalg.norm(e, axis=2).max(axis=1), by columns: the same
    # squares, sums and roots, and the same maximum (reductions along axes of 3 cost several times as much)
    twice_area = row_norms(np.cross(e0, -e2))
    longest = np.maximum(np.maximum(row_norms(e0), row_norms(e1)), row_norms(e2))
    # Zero area up to round-off: the normal is meaningless. Thin but real slivers stay, since dropping
    # one would open a crack in an otherwise closed surface.
    flat = twice_area <= FLAT_RELATIVE * longest**2
    degenerate = repeated | flat
    ok = np.flatnonzero(~degenerate)

    # Topology as read (after welding), to report what cleaning changed.
    edges_in, face_edges_in, count_in = unique_edges(F[ok], len(positions))
    keep, n_dup, n_wall = _deduplicated(F, ok, len(positions))
    if len(keep) == 0:
        raise MeshError(
            f"no triangles left after cleaning ({int(degenerate.sum())} degenerate, {n_dup + n_wall} duplicate "
            f"of {m_in}; weld tolerance {tol:.3g})"
        )

    # Compact vertices and edges to those the kept triangles use. Both renumberings are monotone, so the
    # edges stay sorted and nothing needs sorting again.
    F = F[keep]
    used = np.zeros(len(positions), dtype=bool)
    used[F.ravel()] = True
    vertex_id = np.cumsum(used) - 1
    F = vertex_id[F]
    V = positions[used]
    face_edges = face_edges_in[np.searchsorted(ok, keep)]
    count = np.bincount(face_edges.ravel(), minlength=len(edges_in))
    edge_used = count > 0
    face_edges = (np.cumsum(edge_used) - 1)[face_edges]
    count = count[edge_used]
    edges = vertex_id[edges_in[edge_used]]

    flip, component, n_comp, inconsistent = _orientation_and_components(V, F, edges, face_edges, count)
    F[flip] = F[flip][:, [0, 2, 1]]

    report = CleanReport(
        n_input_vertices=n_in,
        n_input_faces=m_in,
        welded_vertices=int(welded),
        degenerate_faces=int(degenerate.sum()),
        duplicate_faces=int(n_dup),
        double_wall_faces=int(n_wall),
        flipped_faces=int(flip.sum()),
        components=int(n_comp),
        boundary_edges=int((count == 1).sum()),
        non_manifold_edges=int((count > 2).sum()),
        inconsistent_edges=int(inconsistent),
        input_boundary_edges=int((count_in == 1).sum()),
        input_non_manifold_edges=int((count_in > 2).sum()),
        weld_tolerance=tol,
    )
    mesh = Mesh(
        vertices=V,
        faces=F,
        source_face=keep.astype(np.int64),
        n_input_faces=m_in,
        component=component,
        report=report,
    )
    # Flipping (a, b, c) -> (a, c, b) keeps the edge set and reverses the half-edge order: prime the
    # cache instead of sorting the edges again.
    face_edges[flip] = face_edges[flip][:, [2, 1, 0]]
    mesh.__dict__["_edges"] = (edges, face_edges, count)
    log.info(report.summary())
    return mesh


def input_labels(mesh: Mesh, labels) -> np.ndarray:
    """Scatter a per-triangle label of ``mesh`` back to the input's triangle order.

    Parameters
    ----------
    mesh : Mesh
    labels : (m,) int
        One label per triangle of ``mesh``.

    Returns
    -------
    (n_input_faces,) int
        ``labels`` at each kept input triangle, ``-1`` at triangles dropped in cleaning.
    """
    labels = np.asarray(labels)
    if labels.shape != (len(mesh.faces),) or not np.issubdtype(labels.dtype, np.integer):
        raise InputError(
            f"labels must be an ({len(mesh.faces)},) int array (one per mesh triangle), "
            f"got {labels.dtype} array of shape {labels.shape}"
        )
    out = np.full(mesh.n_input_faces, -1, dtype=np.int64)
    kept = mesh.source_face >= 0  # (a triangle added to close a hole has no input triangle: -1)
    out[mesh.source_face[kept]] = labels[kept]
    return out


# -- steps ----------------------------------------------------------------------------------------------------


def _validated(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    try:
        v = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise MeshError(f"vertices must be an (n, 3) float array: {err}") from None
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must be an (n, 3) float array, got shape {v.shape}")
    if f.size == 0:
        raise MeshError("the mesh has no triangles")
    if f.ndim != 2 or f.shape[1] != 3:
        raise MeshError(f"faces must be an (m, 3) int array of triangles, got shape {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        raise MeshError(f"faces must be an (m, 3) int array, got dtype {f.dtype}")
    f = f.astype(np.int64, copy=False)
    if f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"faces index vertices outside 0..{len(v) - 1} (found {f.min()}..{f.max()})")
    bad = np.logical_not(np.isfinite(v).all(axis=1))
    if bad.any():
        n_bad = int(bad[f].any(axis=1).sum())
        if n_bad:
            raise MeshError(f"{int(bad.sum())} vertices have NaN or infinite coordinates ({n_bad} triangles use them)")
    return v, f


def _weld(v: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Cluster vertices closer than ``tol``.

    Returns
    -------
    vid : (n,) int
        Cluster of each vertex, numbered by first occurrence.
    positions : (c, 3) float
        Position of each cluster's first vertex.
    """
    n = len(v)
    fin = np.isfinite(v)
    finite = fin[:, 0] & fin[:, 1] & fin[:, 2]  # unreferenced non-finite vertices are each their own cluster
    vv = v if finite.all() else np.where(finite[:, None], v, 0.0)
    lo, hi = _extremes(vv) if n else (np.zeros(3), np.zeros(3))
    span = float((hi - lo).max())
    if tol > 0 and span / tol < 2.0**60:
        cells = np.floor((vv - lo) / tol).astype(np.int64)
        upper = int(cells.max()) + 1
        first, inverse = unique_rows(cells, upper)
    else:
        # Bit patterns: exact equality (adding 0.0 turns -0.0 into +0.0).
        bits = (vv + 0.0).view(np.int64)
        _, first, inverse = np.unique(bits, axis=0, return_index=True, return_inverse=True)
        inverse = inverse.reshape(-1)
    if not finite.all():
        # Give each non-finite vertex its own cluster so that none merges with a real one.
        extra = np.flatnonzero(~finite)
        inverse = inverse.copy()
        inverse[extra] = len(first) + np.arange(len(extra))
        first = np.concatenate([first, extra])
    label = np.arange(len(first))
    if tol > 0 and len(first) > 1:
        # Points in neighbouring grid cells can still be within tol: join them.
        reps = vv[first]
        pairs = cKDTree(reps).query_pairs(tol, output_type="ndarray")
        pairs = pairs[finite[first[pairs[:, 0]]] & finite[first[pairs[:, 1]]]] if len(pairs) else pairs
        if len(pairs):
            graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(first),) * 2)
            _, label = connected_components(graph, directed=False)
    n_clusters = int(label.max()) + 1
    cluster_first = np.full(n_clusters, n, dtype=np.int64)
    np.minimum.at(cluster_first, label, first)
    order = np.argsort(cluster_first)
    renumber = np.empty(n_clusters, dtype=np.int64)
    renumber[order] = np.arange(n_clusters)
    vid = renumber[label[inverse]]
    return vid, v[cluster_first[order]]


def _extremes(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(x.min(axis=0), x.max(axis=0))`` of (n, 3) points, a column at a time: the same values (a zero's sign
    aside, which neither the diagonal nor the weld grid sees) at a seventh of the cost of numpy's reduction along
    axis 0, which runs one inner loop per row."""
    cols = [x[:, j] for j in range(x.shape[1])]
    return np.array([c.min() for c in cols]), np.array([c.max() for c in cols])


def _deduplicated(F: np.ndarray, ok: np.ndarray, n_vertices: int) -> tuple[np.ndarray, int, int]:
    """Triangles to keep among ``F[ok]`` when several share a vertex set.

    Copies with the same orientation are duplicates: keep the first. A copy in each orientation is a
    zero-thickness double wall (a fin, a leftover of hole filling or a boolean):
    opposite copies cancel in pairs, as oriented triangles of a 2-chain do, unless cancelling would leave
    an edge with a single triangle (then the pair is more likely a flipped copy: keep the first).

    Returns
    -------
    keep : (k,) int
        Ascending indices into ``F``.
    n_duplicates, n_double_wall : int
        Triangles dropped as same-orientation copies, and as cancelled opposite pairs.
    """
    Fo = F[ok]
    srt = np.sort(Fo, axis=1)
    first, group = unique_rows(srt, n_vertices)
    n_groups = len(first)
    if n_groups == len(ok):
        return ok, 0, 0
    # Orientation relative to the sorted order: the parity of the permutation (odd inversions = reversed).
    a, b, c = Fo[:, 0], Fo[:, 1], Fo[:, 2]
    odd = ((a > b).astype(np.int8) + (a > c) + (b > c)) % 2 == 1
    n_odd = np.bincount(group, weights=odd, minlength=n_groups).astype(np.int64)
    n_all = np.bincount(group, minlength=n_groups)
    net = n_all - 2 * n_odd  # even minus odd copies
    # Keep-first choice: the first copy of the majority orientation (the first copy on a tie).
    idx = np.arange(len(ok))
    want_odd = np.where(net == 0, odd[first], net < 0)
    cand = np.where(odd == want_odd[group], idx, len(ok))
    chosen = np.full(n_groups, len(ok), dtype=np.int64)
    np.minimum.at(chosen, group, cand)
    cancel = (net == 0) & (n_all > 1)
    if cancel.any():
        # Edge counts with every tie cancelled; revert the ties that would open a new boundary edge.
        _, fe_keep, count_keep = unique_edges(Fo[chosen], n_vertices)
        after = count_keep - np.bincount(fe_keep[cancel].ravel(), minlength=len(count_keep))
        opened = (after == 1) & (count_keep != 1)
        cancel &= ~opened[fe_keep].any(axis=1)
    keep = ok[np.sort(chosen[~cancel])]
    n_wall = int(n_all[cancel].sum())
    n_dup = len(ok) - len(keep) - n_wall
    return keep, n_dup, n_wall


def _orientation_and_components(V, F, edges, face_edges, count):
    """Flip bits that orient every patch consistently, and edge-connected components.

    Returns
    -------
    flip : (m,) bool
    component : (m,) int
    n_components : int
    inconsistent : int
        Manifold edges whose two triangles still disagree (non-orientable patches).
    """
    m = len(F)
    order, start = halfedge_order(face_edges, count)
    he_edge = face_edges.ravel()
    # A half-edge runs "forward" if it goes from the edge's low vertex to its high vertex.
    forward = F.ravel() == edges[he_edge, 0]

    # Components: consecutive half-edges of one edge (any number of triangles) connect their triangles.
    same = he_edge[order[1:]] == he_edge[order[:-1]]
    ca, cb = order[:-1][same] // 3, order[1:][same] // 3
    n_comp, comp_raw = connected_components(_graph(ca, cb, m), directed=False)
    component = _renumber_by_first(comp_raw, n_comp)

    # Orientation patches: manifold edges only. Two triangles agree if they run their edge oppositely.
    me = np.flatnonzero(count == 2)
    ha, hb = order[start[me]], order[start[me] + 1]
    fa, fb = ha // 3, hb // 3
    disagree = forward[ha] == forward[hb]
    if (count > 2).any():
        n_patch, patch = connected_components(_graph(fa, fb, m), directed=False)
    else:  # no non-manifold edge: the components' graph is this one (the same pairs in the same order)
        n_patch, patch = n_comp, comp_raw
    # a mesh whose every pair agrees (consistently oriented, as a CAD export is) needs no flip: every parity is 0
    flip = _disagreement_parity(fa, fb, disagree, patch, m) if disagree.any() else np.zeros(m, dtype=bool)

    # Orient each patch as a whole: outward if it is closed, else as most of its input area was.
    # (col_means, row_norms: V.mean(axis=0) and np.linalg.norm(cross, axis=1), bit for bit)
    P = V[F] - col_means(V)
    cross = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    area = 0.5 * row_norms(cross)
    six_vol = np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2]))
    sign = np.where(flip, -1.0, 1.0)
    patch_vol = np.bincount(patch, weights=six_vol * sign, minlength=n_patch)
    flipped_area = np.bincount(patch, weights=area * flip, minlength=n_patch)
    kept_area = np.bincount(patch, weights=area * ~flip, minlength=n_patch)
    # A patch is closed if each of its edges carries exactly two of its own half-edges: it touches no
    # boundary edge, and no non-manifold edge with other than two of its own triangles.
    open_patch = np.zeros(n_patch, dtype=bool)
    he_count = count[he_edge]
    open_patch[patch[np.flatnonzero(he_count == 1) // 3]] = True
    he_nm = np.flatnonzero(he_count > 2)
    if len(he_nm):
        pair_key, per_pair = np.unique(patch[he_nm // 3] * len(edges) + he_edge[he_nm], return_counts=True)
        open_patch[(pair_key // len(edges))[per_pair != 2]] = True
    invert = np.where(open_patch, flipped_area > kept_area, patch_vol < 0)
    flip = flip ^ invert[patch]

    inconsistent = int((disagree ^ (flip[fa] != flip[fb])).sum())
    log.debug("orientation: %d patches (%d closed), %d components", n_patch, int((~open_patch).sum()), n_comp)
    return flip, component, n_comp, inconsistent


def _disagreement_parity(fa, fb, disagree, patch, m: int) -> np.ndarray:
    """(m,) bool: the flips that make every orientation patch consistent, given the manifold pairs ``fa``, ``fb``,
    whether the two triangles of each pair disagree, and the patches."""
    _, seeds = np.unique(patch, return_index=True)

    # One BFS from a virtual root joined to every patch's seed gives a spanning forest; the flip of a
    # triangle is the parity of disagreements on its tree path, found by pointer jumping (log depth).
    root = m
    src = np.concatenate([fa, fb, np.full(len(seeds), root)])
    dst = np.concatenate([fb, fa, seeds])
    rel = np.concatenate([disagree, disagree, np.zeros(len(seeds), dtype=bool)]).astype(np.int8) + 1
    graph = coo_matrix((rel, (src, dst)), shape=(m + 1, m + 1)).tocsr()
    graph.sort_indices()
    _, pred = breadth_first_order(graph, root, directed=True, return_predecessors=True)
    parent = pred.astype(np.int64)
    parent[root] = root
    # The disagreement of each tree edge, read from the CSR entries (row-major sorted keys: no argsort).
    entry_key = np.repeat(np.arange(m + 1, dtype=np.int64), np.diff(graph.indptr)) * (m + 1) + graph.indices
    parity = np.zeros(m + 1, dtype=bool)
    tree = np.flatnonzero(parent[:m] != root)  # patch seeds hang from the root with parity 0
    parity[tree] = graph.data[np.searchsorted(entry_key, tree * (m + 1) + parent[tree])] == 2
    while (parent[:m] != root).any():
        parity = parity ^ parity[parent]
        parent = parent[parent]
    return parity[:m]


def _graph(a, b, n):
    return coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(n, n))


def _renumber_by_first(label: np.ndarray, n: int) -> np.ndarray:
    _, first = np.unique(label, return_index=True)
    renumber = np.empty(n, dtype=np.int64)
    renumber[np.argsort(first)] = np.arange(n)
    return renumber[label]
