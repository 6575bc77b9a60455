"""The decomposition of a triangulated surface (Wekel & Hellwich §4, built on §2–3).

Steps, each a vectorised pass over the mesh:

1. Feature measure (:mod:`recon.features`) → smooth triangles, whose components seed the *patches*; their
   extent is decided by fitting (:mod:`._regions`): a patch is what one analytic surface covers within
   tolerance, grown back into the critical region and split where one surface does not fit. Curved regions
   tangent to two or more neighbours are blends and stay in the *critical region* with what no patch covers.
2. The patches' boundary loops are the boundary curves ``C_i`` of §2; the curve potential ``φ`` is the
   arc length along each loop.
3. Every critical vertex gets its nearest patch-boundary vertex (multi-source Dijkstra on the mesh
   edges of the critical region): the discrete "Voronoi diagram" of the boundary points on the surface.
4. Skeleton (§2): the dual of the mesh edges whose two vertices have generating points ``v_r, v_l``
   with ``ω(v_r, v_l) > ω_min`` (condition 3; ``ω = ∞`` between different curves, eq. 1). A skeleton
   vertex is a critical triangle; its degree is the number of such edges it has (0–3).
5. Segment graph (§3): degree-3 triangles (merged with their close neighbours) are junctions, degree-1
   terminals, chains of degree 2 linear parts. Every bridge gets a separator: the geodesic (in the
   critical region) between its two generating boundary points, the surface's Delaunay edge. Cutting
   the critical region along the separators and taking components gives the parts.
"""

from __future__ import annotations

import logging
import os
from typing import TYPE_CHECKING, Callable

import numpy as np
from numpy.typing import ArrayLike
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from ..errors import DecompositionError, InputError
from .._array import row_norms
from ..features import FaceGeometry, FeatureField, _feature_field, mesh_arrays
from ..segment_graph import cut_components
from ._curves import boundary_curves
from ._regions import Regions, fitted_regions
from ..mesh import Mesh
from ..mesh import stable_argsort

if TYPE_CHECKING:
    import trimesh

    from ..fit import SurfaceFit
from ._topology import Topology, topology, unique
from ._types import Decomposition, Part, PartKind, SurfaceSkeleton

__all__ = ["decompose", "DEFAULT_THRESHOLD"]

log = logging.getLogger(__name__)

#: Feature-measure threshold between smooth and critical: a normal variance of 0.02 is a spread of
#: about 8° in the window — a cylinder of radius about 7 windows is still smooth.
DEFAULT_THRESHOLD = 0.02
#: Smallest patch, as a share of the bounding-box diagonal (squared): a property of the part, not the mesh.
MIN_PATCH_DIAGONAL = 0.03
#: Normal tolerance in median normal deviations of the smooth triangles (noise), and its floor in degrees.
ANGLE_NOISE_FACTOR = 3.0
MIN_ANGLE_DEG = 12.0
#: A part is sharp when less than this share of its area has normals in the middle half of its normal
#: range: across a blend the normal turns evenly (share ≈ 0.5), across a sharp edge it jumps (share ≈ 0).
SHARP_MIDDLE_SHARE = 0.2

_INF = np.inf
#: The order critical parts are numbered in, after the patches.
_PART_ORDER = (PartKind.JUNCTION, PartKind.LINEAR, PartKind.TERMINAL, PartKind.PATCH)
#: A component of the critical region holding no skeleton node: it joins a neighbour (:func:`_absorb_orphans`).
_ORPHAN = "orphan"


def default_jobs() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def decompose(
    mesh: Mesh | trimesh.Trimesh | tuple[ArrayLike, ArrayLike],
    *,
    scale: float | None = None,
    omega_min: float | None = None,
    threshold: float | None = None,
    min_patch_area: float | None = None,
    tolerance: float | None = None,
    features: FeatureField | None = None,
    progress: Callable[[str, float], None] | None = None,
    jobs: int | None = None,
) -> Decomposition:
    """Decompose a triangle mesh into smooth patches and the junction/linear/terminal parts of its features.

    Parameters
    ----------
    mesh : Mesh, trimesh.Trimesh or (vertices, faces)
        Vertices (n, 3) float and faces (m, 3) int; indices are kept as given.
    scale : float, optional
        Feature scale (window standard deviation, mesh units). Default: from the sampling and the noise.
    omega_min : float, optional
        Pruning threshold of §2 condition 3 (arc length along a patch boundary). Default: 4 × the
        90th percentile of the critical vertices' distance to the nearest patch boundary.
    threshold : float, optional
        Feature-measure threshold between smooth and critical (default :data:`DEFAULT_THRESHOLD`).
    min_patch_area : float, optional
        Fitted regions smaller than this join the critical region (default :func:`default_min_area`).
    tolerance : float, optional
        Distance within which a triangle lies on a patch's fitted surface (default ``max(4 σ, 5e-4 · diagonal)``
        with σ the estimated noise, the rule of :func:`recon._tolerance.tolerance_for`).
    features : FeatureField, optional
        A precomputed feature field (then ``scale`` is ignored).
    progress : callable(stage: str, fraction: float), optional
    jobs : int, optional
        Processes to use (default: the cores this process may run on). From 2 on, the patches' regions grow
        two at a time in a second process (:mod:`recon._parallel`); the decomposition is the same for any number.

    Returns
    -------
    Decomposition
    """
    V, F = mesh_arrays(mesh)
    m, n = len(F), len(V)
    step = progress or (lambda stage, frac: None)
    threshold = _checked(threshold, omega_min, jobs)

    step("features", 0.0)
    topo = topology(F, n)
    # the face cross products, areas and normals every step uses, formed once (a Mesh's own, cached for the fit stage)
    geom = FaceGeometry(V, F, cross=mesh.face_cross, centroid=mesh.face_centroids) if isinstance(mesh, Mesh) \
        else FaceGeometry(V, F)
    ff = features if features is not None else _feature_field(V, F, scale=scale, geom=geom, pairs=topo.twin_pairs)

    # -- 1. smooth patches: what one analytic surface covers ----------------------------------------------
    step("patches", 0.2)
    pairs = _face_pairs(topo)
    regions = _fitted_patches(V, F, topo, pairs, geom, ff, threshold, min_patch_area, tolerance, jobs)
    patch = _patch_ids(regions, geom.area)
    n_patch = int(patch.max()) + 1 if (patch >= 0).any() else 0
    critical = patch < 0
    log.info("%d patches, %d of %d triangles critical", n_patch, int(critical.sum()), m)

    if critical.any():
        # -- 2.-5. the critical region's skeleton and its parts -----------------------------------------------
        labels, kinds, sharp, sk, w_min, bc = _critical_parts(V, F, topo, pairs, geom, ff.scale, patch, n_patch,
                                                              omega_min, step)
    else:
        labels, kinds, sharp, bc = patch.copy(), [PartKind.PATCH] * n_patch, [False] * n_patch, None
        sk = SurfaceSkeleton(np.zeros((0, 3)), np.zeros((0, 2), np.int64), np.zeros(0, np.int64))
        w_min = 0.0 if omega_min is None else float(omega_min)
    if (labels < 0).any():  # cannot happen by construction; fail loudly rather than emit -1 labels
        raise DecompositionError(f"{int((labels < 0).sum())} triangles were left without a part")

    # progress share done when the curves start (report only)
    step("curves", 0.9)
    curves, neighbours = bc if bc is not None else boundary_curves(V, topo, labels, len(kinds))
    parts = _parts(labels, kinds, sharp, neighbours, geom.area)
    step("done", 1.0)
    log.info("decomposition: %s", {str(k): sum(p.kind == k for p in parts) for k in PartKind})
    return Decomposition(
        labels=labels,
        parts=parts,
        curves=curves,
        skeleton=sk,
        scale=ff.scale,
        omega_min=w_min,
        threshold=threshold,
        noise=ff.noise,
        critical=critical,
        tolerance=float(regions.tolerance),
        extra={"fits": _part_fits(regions, labels, geom.area, kinds)},
    )


def _checked(threshold, omega_min, jobs) -> float:
    """The feature threshold (default :data:`DEFAULT_THRESHOLD`), after checking the options :func:`decompose` takes."""
    threshold = DEFAULT_THRESHOLD if threshold is None else float(threshold)
    if not 0 < threshold < 1:
        raise InputError(f"`threshold` must lie in (0, 1), got {threshold}")
    if omega_min is not None and not omega_min >= 0:
        raise InputError(f"`omega_min` must be a non-negative length, got {omega_min!r}")
    if jobs is not None and not (isinstance(jobs, (int, np.integer)) and jobs >= 1):
        raise InputError(f"`jobs` must be a whole number of processes, at least 1, got {jobs!r}")
    return threshold


def _fitted_patches(V, F, topo: Topology, pairs, geom: FaceGeometry, ff: FeatureField, threshold: float,
                    min_patch_area, tolerance, jobs) -> Regions:
    """Step 1: the smooth triangles (feature measure under ``threshold``) seed regions of fitted surfaces
    (:func:`recon.decompose._regions.fitted_regions`)."""
    m = len(F)
    fmeasure = ff.face_measure(F)
    smooth = fmeasure < threshold
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    min_area = default_min_area(diag, ff.scale) if min_patch_area is None else float(min_patch_area)
    return fitted_regions(
        V, F, adj=np.where(topo.twin >= 0, topo.twin // 3, -1).reshape(m, 3), pairs=pairs, edges=topo.edges,
        smooth=smooth, priority=fmeasure, vnormal=ff.normals, area=geom.area, tolerance=tolerance, noise=ff.noise,
        angle=_normal_angle(V, F, ff, smooth, geom.unit), min_area=min_area, diag=diag, fnormal=geom.unit,
        corners=geom.corners, centroid=geom.centroid, jobs=default_jobs() if jobs is None else int(jobs),
    )


def _critical_parts(V, F, topo: Topology, pairs, geom: FaceGeometry, s: float, patch, n_patch: int, omega_min, step):
    """Steps 2-5 on the critical region (``patch < 0``): boundary potentials, nearest boundary points, the pruned
    skeleton, the segment graph and its parts. Returns ``(labels, kinds, sharp, skeleton, ω_min, boundary curves)``.
    """
    m, n = len(F), len(V)
    critical = patch < 0
    # -- 2. boundary curves and potentials ------------------------------------------------------------
    step("boundary", 0.35)
    site_curve, site_phi, curve_len = _boundary_potentials(V, F, topo, patch)

    # -- 3. nearest boundary point of every critical vertex ------------------------------------------
    step("voronoi", 0.45)
    crit_vert = np.zeros(n, bool)
    crit_vert[F[critical].ravel()] = True
    sources = np.flatnonzero(crit_vert & (site_curve >= 0))
    graph = _edge_graph(V, topo, critical, n)
    if len(sources):
        dist, pred, src = dijkstra(graph, directed=False, indices=sources, min_only=True, return_predecessors=True)
    else:
        dist, pred, src = np.full(n, _INF), np.full(n, -9999), np.full(n, -9999)
    w_min = _default_omega_min(dist[crit_vert & (src >= 0)], s) if omega_min is None else float(omega_min)

    # -- 4. skeleton ------------------------------------------------------------------------------------
    step("skeleton", 0.6)
    sk_pairs, sk_cross = _skeleton_edges(topo, critical, src, site_curve, site_phi, curve_len, w_min)

    # -- 5. segment graph and parts ----------------------------------------------------------------------
    step("segment graph", 0.7)
    cut_keys, junction_faces, terminal_faces, chain_faces = _separators(
        V, F, sk_pairs, sk_cross, topo, src, dist, graph, s, geom.centroid
    )
    part_of_face, part_kind = _cut_parts(m, n, pairs, topo, critical, cut_keys, junction_faces, terminal_faces,
                                         chain_faces)
    part_of_face = _absorb_orphans(part_of_face, part_kind, pairs, topo, V, patch)
    labels, kinds = _numbered_parts(patch, n_patch, part_of_face, part_kind)
    bc = boundary_curves(V, topo, labels, len(kinds))  # the labels are final: the same curves as decompose's
    sharp = _sharp_parts(V, F, labels, geom, kinds, n_patch, bc[1])
    return labels, kinds, sharp, _skeleton_output(V, F, sk_pairs), w_min, bc


def _default_omega_min(dist, s: float) -> float:
    """§2's ω_min by default: 4 × the 90th percentile of the critical vertices' distance to the nearest patch
    boundary (``dist``), and at least 4 feature scales."""
    w_min = 4.0 * float(np.percentile(dist, 90)) if len(dist) else 0.0
    return max(w_min, 4.0 * s)


def _numbered_parts(patch, n_patch: int, part_of_face, part_kind: dict) -> tuple[np.ndarray, list]:
    """Labels and kinds: the critical parts numbered after the patches, junctions first; faces absorbed into a patch
    (``part_of_face == -(patch + 2)``) take that patch's id."""
    critical = patch < 0
    labels = patch.copy()
    kinds: list[PartKind] = [PartKind.PATCH] * n_patch
    crit_ids = unique(part_of_face[critical & (part_of_face >= 0)])
    order = sorted(crit_ids, key=lambda c: (_PART_ORDER.index(part_kind[c]), c))
    remap = {int(c): n_patch + i for i, c in enumerate(order)}
    for c in order:
        kinds.append(part_kind[c])
    absorbed = part_of_face <= -2
    labels[critical & absorbed] = -part_of_face[critical & absorbed] - 2
    sel = critical & (part_of_face >= 0)
    lut = np.full(max(remap, default=-1) + 1, -1, np.int64)
    for k, v in remap.items():
        lut[k] = v
    labels[sel] = lut[part_of_face[sel]]
    return labels, kinds


def _sharp_parts(V, F, labels, geom: FaceGeometry, kinds: list, n_patch: int, neighbours) -> list[bool]:
    """Which parts are sharp: a linear part whose normals jump rather than turn (:data:`SHARP_MIDDLE_SHARE`), and a
    junction (a corner vertex) whose linear parts are all sharp. Patches never are."""
    # (only the linear parts' share decides anything: the patches are the largest parts, not measured)
    mid = _middle_share(V, F, labels, geom.area, len(kinds), geom.unit,
                        only=[i for i in range(n_patch, len(kinds)) if kinds[i] == PartKind.LINEAR])
    sharp = [False] * n_patch + [bool(kinds[i] == PartKind.LINEAR and mid[i] < SHARP_MIDDLE_SHARE)
                                 for i in range(n_patch, len(kinds))]
    for i in range(n_patch, len(kinds)):
        if kinds[i] == PartKind.JUNCTION:
            lin = [j for j in neighbours[i] if kinds[j] == PartKind.LINEAR]
            sharp[i] = bool(lin) and all(sharp[j] for j in lin)
    return sharp


def _parts(labels, kinds: list, sharp: list, neighbours, area) -> tuple[Part, ...]:
    """The :class:`Part` records: kind, sharpness, neighbours, triangle count and area of each label."""
    counts = np.bincount(labels, minlength=len(kinds))
    part_area = np.bincount(labels, weights=area, minlength=len(kinds))
    return tuple(
        Part(
            id=i,
            kind=kinds[i],
            sharp=sharp[i],
            neighbours=tuple(int(x) for x in neighbours[i]),
            n_triangles=int(counts[i]),
            area=float(part_area[i]),
        )
        for i in range(len(kinds))
    )


# -- helpers ------------------------------------------------------------------------------------------------


def default_min_area(diagonal: float, scale: float) -> float:
    """Smallest patch area: ``(0.03 · diagonal)²``, and at least a smoothing window (``scale²``)."""
    return max((MIN_PATCH_DIAGONAL * diagonal) ** 2, scale * scale)


def _normal_angle(V, F, ff: FeatureField, smooth, fn=None) -> float:
    """Normal tolerance (radians): 3 × the median angle between smooth triangles' normals and the smoothed ones.

    ``fn``: the unit face normals (:class:`recon.features.FaceGeometry`), when the caller has them."""
    if fn is None:
        fn = FaceGeometry(V, F).unit
    N = ff.normals  # ff.normals[F].sum(axis=1): numpy adds the three corners in order; by columns at a fifth of the cost
    sn = (N[F[:, 0]] + N[F[:, 1]]) + N[F[:, 2]]
    sn /= np.maximum(row_norms(sn, keepdims=True), 1e-300)
    cos = np.clip(np.abs(np.einsum("ij,ij->i", fn, sn)), 0.0, 1.0)
    med = float(np.median(np.arccos(cos[smooth]))) if smooth.any() else 0.0
    return max(np.deg2rad(MIN_ANGLE_DEG), ANGLE_NOISE_FACTOR * med)


#: Share of a critical part's area one blend region must cover for the part to be given that blend's surface.
BLEND_FIT_SHARE = 0.8


def _part_fits(regions: Regions, labels, area, kinds) -> dict:
    """{part id: SurfaceFit}: the region surface that covers most (≥ 80 %) of each part's area.

    A patch is one non-blend region (plus absorbed orphans); a linear part or junction may lie on one blend.
    Free-form regions carry no surface and give no entry.
    """
    k = len(regions.fits)
    lab = regions.label
    has = lab >= 0
    n_parts = len(kinds)
    key = labels[has] * np.int64(k) + lab[has]
    w = np.bincount(key, weights=area[has], minlength=n_parts * k).reshape(n_parts, k)
    tot = np.bincount(labels, weights=area, minlength=n_parts)
    out: dict[int, SurfaceFit] = {}
    if k == 0:
        return out
    best = w.argmax(axis=1)
    for p in range(n_parts):
        r = int(best[p])
        fit = regions.fits[r]
        if fit.type == "free" or not fit or w[p, r] < BLEND_FIT_SHARE * tot[p]:
            continue
        if (kinds[p] == PartKind.PATCH) == bool(regions.blend[r]):
            continue  # a patch on a blend's surface (or the reverse) is not what was fitted for it
        out[p] = fit
    return out


def _patch_ids(regions: Regions, area) -> np.ndarray:
    """(m,) int: patch id per triangle (−1 critical): the non-blend regions, numbered by decreasing area."""
    lab = regions.label
    keep = np.flatnonzero(~regions.blend)
    ra = np.bincount(lab[lab >= 0], weights=area[lab >= 0], minlength=len(regions.fits))
    keep = keep[np.argsort(-ra[keep], kind="stable")]
    lut = np.full(len(regions.fits) + 1, -1, np.int64)
    lut[keep] = np.arange(len(keep))
    return lut[lab]


def _face_pairs(topo: Topology) -> np.ndarray:
    """(p, 3) int: adjacent triangles (f, g) with f < g across undirected edge e, as rows (f, g, e)."""
    h = np.flatnonzero(topo.twin > np.arange(len(topo.twin)))
    return np.stack([h // 3, topo.twin[h] // 3, topo.half_edge[h]], axis=1)


def _edge_graph(V, topo: Topology, critical, n) -> sp.csr_matrix:
    """Mesh edges of the critical triangles, weighted by length."""
    used = np.zeros(len(topo.edges), bool)  # np.unique of the critical half-edges' edges, by a mask
    used[topo.half_edge[np.repeat(critical, 3)]] = True
    e = np.flatnonzero(used)
    a, b = topo.edges[e, 0], topo.edges[e, 1]
    w = row_norms(V[a] - V[b])
    w = np.maximum(w, 1e-12 * max(float(w.max(initial=0.0)), 1.0))
    return sp.csr_matrix((w, (a, b)), shape=(n, n))


def _boundary_potentials(V, F, topo: Topology, patch):
    """Curve id and potential φ (arc length along the loop) of each patch-boundary vertex (§2).

    Returns
    -------
    site_curve : (n,) int
        Boundary curve of each vertex, −1 if the vertex is on no patch boundary.
    site_phi : (n,) float
    curve_len : (c,) float
    """
    n = len(V)
    hface = np.arange(len(topo.half_start)) // 3
    hp = patch[hface]
    other = np.where(topo.twin >= 0, patch[np.maximum(topo.twin, 0) // 3], -1)
    bnd = np.flatnonzero((hp >= 0) & ((topo.twin < 0) | (other != hp)))
    site_curve = np.full(n, -1, np.int64)
    site_phi = np.zeros(n)
    if len(bnd) == 0:
        return site_curve, site_phi, np.zeros(0)
    start, end, bp = topo.half_start[bnd], topo.half_end[bnd], hp[bnd]
    length = row_norms(V[end] - V[start])
    # successor of a boundary half-edge: a boundary half-edge of the same patch leaving its end vertex
    key_start = bp * np.int64(n) + start
    key_end = bp * np.int64(n) + end
    order = stable_argsort(key_start)
    sorted_keys = key_start[order]
    pos = np.searchsorted(sorted_keys, key_end)
    pos = np.minimum(pos, len(order) - 1)
    nxt = np.where(sorted_keys[pos] == key_end, order[pos], -1)
    # pinch vertices (several outgoing boundary half-edges) make nxt non-injective; walk with a visited mask
    used = np.zeros(len(bnd), bool)
    curve_lengths = []
    c = 0
    slot_next = {}  # for pinches: remaining outgoing half-edges per key
    dup = np.flatnonzero(np.diff(sorted_keys) == 0)
    if len(dup):
        for d in unique(sorted_keys[dup]):
            lo, hi = np.searchsorted(sorted_keys, [d, d + 1])
            slot_next[int(d)] = list(order[lo:hi])
    for h0 in range(len(bnd)):
        if used[h0]:
            continue
        phi = 0.0
        h = h0
        while h >= 0 and not used[h]:
            used[h] = True
            v = start[h]
            if site_curve[v] < 0:
                site_curve[v] = c
                site_phi[v] = phi
            phi += length[h]
            k = int(key_end[h])
            if k in slot_next:
                cand = [x for x in slot_next[k] if not used[x]]
                h = cand[0] if cand else -1
            else:
                h = nxt[h]
        curve_lengths.append(phi)
        c += 1
    return site_curve, site_phi, np.asarray(curve_lengths)


def _skeleton_edges(topo: Topology, critical, src, site_curve, site_phi, curve_len, w_min):
    """Dual edges of the skeleton (§2, condition 3) between critical triangles.

    Returns
    -------
    sk_pairs : (e, 2) int
        Triangle pairs.
    sk_cross : (e,) int
        The undirected mesh edge each skeleton edge crosses.
    """
    h = np.flatnonzero(topo.twin > np.arange(len(topo.twin)))
    f, g = h // 3, topo.twin[h] // 3
    ok = critical[f] & critical[g]
    h, f, g = h[ok], f[ok], g[ok]
    a, b = topo.half_start[h], topo.half_end[h]
    sa, sb = src[a], src[b]
    ok = (sa >= 0) & (sb >= 0) & (sa != sb)
    h, f, g, sa, sb = h[ok], f[ok], g[ok], sa[ok], sb[ok]
    ca, cb = site_curve[sa], site_curve[sb]
    same = ca == cb
    dphi = np.abs(site_phi[sa] - site_phi[sb])
    L = curve_len[np.maximum(ca, 0)] if len(curve_len) else np.zeros(len(ca))
    omega = np.where(same, np.minimum(dphi, L - dphi), _INF)  # eq. (1), shortest arc on a closed curve
    keep = omega > w_min
    return np.stack([f[keep], g[keep]], axis=1), topo.half_edge[h[keep]]


def _separators(V, F, sk_pairs, sk_cross, topo, src, dist, graph, s, centroid=None):
    """Classify skeleton nodes and trace the separator of every bridge (§3).

    Returns
    -------
    cut_keys : (c,) int
        Undirected mesh edges on separators.
    junction_faces : list of (k,) int
        Triangles of each junction cluster.
    terminal_faces : (t,) int
    chain_faces : (q,) int
    """
    m = len(F)
    deg = np.bincount(sk_pairs.ravel(), minlength=m)
    nodes = np.flatnonzero(deg > 0)
    if centroid is None:
        centroid = V[F].mean(axis=1)
    # chains: components of the skeleton among degree-2 nodes
    two = deg == 2
    e2 = sk_pairs[two[sk_pairs[:, 0]] & two[sk_pairs[:, 1]]]
    g2 = sp.coo_matrix((np.ones(len(e2), np.int8), (e2[:, 0], e2[:, 1])), shape=(m, m))
    _, chain = connected_components(g2, directed=False)
    seg_len = row_norms(centroid[e2[:, 0]] - centroid[e2[:, 1]])
    chain_len = np.bincount(chain[e2[:, 0]], weights=seg_len, minlength=m)
    # junction clusters: degree ≥ 3 nodes joined directly or through a chain shorter than 2 scales
    high = deg >= 3
    merge = []
    eh = sk_pairs[high[sk_pairs[:, 0]] & high[sk_pairs[:, 1]]]
    merge.append(eh)
    # chain ↔ high-degree attachments
    att = sk_pairs[(high[sk_pairs[:, 0]] & two[sk_pairs[:, 1]]) | (two[sk_pairs[:, 0]] & high[sk_pairs[:, 1]])]
    hi_node = np.where(high[att[:, 0]], att[:, 0], att[:, 1])
    ch_node = np.where(high[att[:, 0]], att[:, 1], att[:, 0])
    ch_id = chain[ch_node]
    short = chain_len[ch_id] < 2.0 * s
    # a short chain between two high-degree nodes joins them (and its own nodes) into one cluster
    ids, cnt = np.unique(ch_id[short], return_counts=True)
    both = set(ids[cnt >= 2].tolist())
    sel = short & np.isin(ch_id, list(both))
    merge.append(np.stack([hi_node[sel], ch_node[sel]], axis=1))
    merge.append(e2[np.isin(chain[e2[:, 0]], list(both))])
    mp = np.concatenate(merge) if merge else np.zeros((0, 2), np.int64)
    gj = sp.coo_matrix((np.ones(len(mp), np.int8), (mp[:, 0], mp[:, 1])), shape=(m, m))
    _, cl = connected_components(gj, directed=False)
    in_cluster = high.copy()
    in_cluster[mp.ravel()] = True
    # bridges: skeleton edges leaving a cluster, or at a degree-1 node
    ea, eb = sk_pairs[:, 0], sk_pairs[:, 1]
    leave = (in_cluster[ea] != in_cluster[eb]) | (in_cluster[ea] & in_cluster[eb] & (cl[ea] != cl[eb]))
    term = (deg[ea] == 1) | (deg[eb] == 1)
    # clusters with fewer than three bridges are chain material (e.g. a noise bubble inside a fillet)
    cl_of_bridge = np.where(in_cluster[ea] & leave, cl[ea], np.where(in_cluster[eb] & leave, cl[eb], -1))
    ncl = np.bincount(cl_of_bridge[cl_of_bridge >= 0], minlength=m)
    real = in_cluster & (ncl[cl] >= 3)
    bridge = (leave & (real[ea] | real[eb])) | term
    junction_faces = [np.flatnonzero(real & (cl == c)) for c in unique(cl[real])]
    terminal_faces = np.flatnonzero(deg == 1)
    chain_faces = np.flatnonzero((deg >= 2) & ~real)

    # separators: geodesic between the bridge's two generating boundary points
    cut = []
    bridges = np.flatnonzero(bridge)
    if len(bridges):
        ed = topo.edges[sk_cross[bridges]]
        s_a, s_b = src[ed[:, 0]], src[ed[:, 1]]
        tree = cKDTree(V)
        for sa_, sb_ in zip(s_a.tolist(), s_b.tolist()):
            path = _local_geodesic(graph, V, sa_, sb_, s, tree)
            if path is not None and len(path) > 1:
                a, b = np.minimum(path[:-1], path[1:]), np.maximum(path[:-1], path[1:])
                cut.append(a * np.int64(len(V)) + b)
    cut_keys = unique(np.concatenate(cut)) if cut else np.zeros(0, np.int64)
    return cut_keys, junction_faces, terminal_faces, chain_faces


def _local_geodesic(graph: sp.csr_matrix, V, a: int, b: int, s: float, tree: cKDTree | None = None):
    """Shortest path a → b in ``graph`` within a ball around both (vertex index list, or None).

    With a ``tree`` of ``V`` the ball's candidates come from it (a slightly larger ball), then the same exact
    test as without: one bridge costs its ball, not a pass over every vertex.
    """
    if a == b:
        return None
    centre = 0.5 * (V[a] + V[b])
    radius = 0.75 * float(np.linalg.norm(V[a] - V[b])) + 2.0 * s
    if tree is None:
        idx = np.flatnonzero(np.einsum("ij,ij->i", V - centre, V - centre) <= radius * radius)
    else:
        # radius grown by a relative 1e-6 so points at the radius itself are included (round-off, scale-free)
        cand = np.sort(np.asarray(tree.query_ball_point(centre, radius * (1.0 + 1e-6) + 1e-12), dtype=np.int64))
        w = V[cand] - centre
        idx = cand[np.einsum("ij,ij->i", w, w) <= radius * radius]
    sub = graph[idx][:, idx]
    ia = np.searchsorted(idx, a)
    ib = np.searchsorted(idx, b)
    _, pred = dijkstra(sub, directed=False, indices=ia, return_predecessors=True)
    if pred[ib] < 0:
        return None
    path = [ib]
    while path[-1] != ia:
        path.append(pred[path[-1]])
    return idx[np.asarray(path[::-1])]


def _cut_parts(m, n_vertices, pairs, topo, critical, cut_keys, junction_faces, terminal_faces, chain_faces):
    """Components of the critical region cut along separators, with their kinds (§3).

    ``cut_keys`` are edges keyed ``a * n_vertices + b`` as :func:`_separators` makes them.
    """
    n = int(n_vertices)
    e = topo.edges[pairs[:, 2]]
    keys = e[:, 0] * np.int64(n) + e[:, 1]
    # np.isin(keys, cut_keys) of the sorted, unique cut keys, by a binary search
    if len(cut_keys):
        pos = np.minimum(np.searchsorted(cut_keys, keys), len(cut_keys) - 1)
        cut = cut_keys[pos] == keys
    else:
        cut = np.zeros(len(keys), bool)
    cut |= ~(critical[pairs[:, 0]] & critical[pairs[:, 1]])
    _, comp = cut_components(m, pairs[:, :2], cut, active=critical)
    kind: dict[int, str] = {}  # PartKind, or _ORPHAN until it is absorbed
    for faces_ in junction_faces:
        for c in unique(comp[faces_]):
            kind[int(c)] = PartKind.JUNCTION
    for c in unique(comp[chain_faces]):
        kind.setdefault(int(c), PartKind.LINEAR)
    for c in unique(comp[terminal_faces]):
        kind.setdefault(int(c), PartKind.TERMINAL)
    for c in unique(comp[critical]):
        kind.setdefault(int(c), _ORPHAN)
    return comp, kind


def _absorb_orphans(comp, kind, pairs, topo, V, patch):
    """Merge components without a skeleton node into the neighbour sharing the longest border.

    Critical neighbours are preferred; an orphan touching only patches joins the patch, encoded as
    ``-(patch + 2)``. An orphan with no neighbour at all stays, as a patch of its own.
    """
    e = topo.edges[pairs[:, 2]]
    elen = row_norms(V[e[:, 0]] - V[e[:, 1]])
    comp = comp.copy()
    for _ in range(10):
        orphans = {c for c, k in kind.items() if k == _ORPHAN}
        if not orphans:
            break
        f, g = pairs[:, 0], pairs[:, 1]
        lf, lg = comp[f], comp[g]
        pf, pg = patch[f], patch[g]
        changed = False
        best: dict[tuple[int, int], float] = {}
        for a_l, b_l, b_p in ((lf, lg, pg), (lg, lf, pf)):
            sel = np.isin(a_l, list(orphans)) & (a_l != b_l)
            # neighbour code: critical part c ≥ 0 (preferred: weight + 1e9) or patch p → -(p + 2)
            nb = np.where(b_l >= 0, b_l, -(b_p + 2))
            # a weight larger than any edge length sum: critical parts always win over patches (an order, not a tuning)
            wgt = elen + np.where((b_l >= 0) & ~np.isin(b_l, list(orphans)), 1e9, 0.0)
            for o, nbr, w in zip(a_l[sel].tolist(), nb[sel].tolist(), wgt[sel].tolist()):
                if nbr >= 0 and nbr in orphans:
                    continue
                k = (o, nbr)
                best[k] = best.get(k, 0.0) + w
        target: dict[int, tuple[float, int]] = {}
        for (o, nbr), w in best.items():
            if o not in target or w > target[o][0]:
                target[o] = (w, nbr)
        for o, (_, nbr) in target.items():
            comp[comp == o] = nbr
            kind.pop(o, None)
            changed = True
        if not changed:
            break
    for c, k in list(kind.items()):
        if k == _ORPHAN:
            kind[c] = PartKind.PATCH
    return comp


def _middle_share(V, F, labels, area, n_parts, nrm=None, only=None):
    """Per part: share of area whose raw normal lies in the middle half of the part's normal range.

    The normals are projected on their main direction of spread (largest eigenvector of their
    covariance); the range is the 5–95 % area quantiles of that projection. ``nrm``: the unit face normals, when
    the caller has them. ``only``: the parts to measure (the others keep 0.5); default all.
    """
    if nrm is None:
        nrm = FaceGeometry(V, F).unit
    out = np.full(n_parts, 0.5)
    order = stable_argsort(labels, n_parts)
    bounds = np.searchsorted(labels[order], np.arange(n_parts + 1))
    for p in range(n_parts) if only is None else only:
        idx = order[bounds[p] : bounds[p + 1]]
        if len(idx) < 8:
            continue
        w = area[idx] / max(area[idx].sum(), 1e-300)
        nn = nrm[idx] - (w[:, None] * nrm[idx]).sum(axis=0)
        cov = (nn * w[:, None]).T @ nn
        axis = np.linalg.eigh(cov)[1][:, -1]
        t = nrm[idx] @ axis
        o = np.argsort(t)
        cw = np.cumsum(w[o])
        # 5%/95% weighted quantiles: the spread of normals without its outlying tails (scale-free)
        lo, hi = t[o][np.searchsorted(cw, 0.05)], t[o][min(np.searchsorted(cw, 0.95), len(o) - 1)]
        a, b = lo + 0.25 * (hi - lo), hi - 0.25 * (hi - lo)
        out[p] = float(w[(t >= a) & (t <= b)].sum())
    return out


def _skeleton_output(V, F, sk_pairs) -> SurfaceSkeleton:
    nodes, inv = np.unique(sk_pairs.ravel(), return_inverse=True)
    return SurfaceSkeleton(
        vertices=V[F[nodes]].mean(axis=1),
        edges=inv.reshape(-1, 2).astype(np.int64),
        faces=nodes.astype(np.int64),
    )
