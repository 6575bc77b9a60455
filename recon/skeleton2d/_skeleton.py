"""Voronoi skeleton with linear-time pruning (Wekel & Hellwich §2) and its dual decomposition (§3).

The Voronoi diagram of the boundary samples is taken as the dual of their Delaunay triangulation
(Qhull through ``scipy.spatial.Delaunay``): a Voronoi vertex is the circumcentre of a triangle, a finite
Voronoi edge is a pair of adjacent triangles and its two sites are their shared Delaunay edge; hull edges
are the infinite Voronoi edges. That makes the separator edges (duals of the bridges) and the junction
triangles of §3 plain array lookups.

Pipeline of :func:`skeletonize`:

1. :func:`resample_curves` samples each curve at ``spacing`` and gives each sample its curve potential φ.
2. Delaunay triangulation, made *conforming*: every sampled boundary edge must be a Delaunay edge (missing
   ones are split in four), so every triangle is wholly inside or outside and the inside triangles tile the
   sampled shape exactly. Then the circumcentres that will be skeleton vertices are kept inside the shape:
   a boundary edge is "encroached" (Ruppert's term) when the angle opposite it in its inside triangle is
   not acute, which puts that triangle's circumcentre on or beyond the edge; encroached edges of triangles
   that carry a kept Voronoi edge, and encroached edges that hide another kept triangle's circumcentre, are
   halved. Up to 12 rounds, each a new triangulation; most shapes need none. Encroachment elsewhere is left
   alone: refining it would cascade at every acute corner for circumcentres that are pruned anyway.
   Limitation: with ω_min of a few spacings or less, branches run into acute corners (< ~60°) where
   12 rounds may not suffice; a warning is logged and such vertices lie less than one spacing outside.
3. Inside/outside of the triangles by the even-odd rule: components of the triangle adjacency cut along the
   boundary edges, with the parity of boundary crossings from the unbounded side.
4. §2 classification of every Voronoi edge at once: finite (condition 1), both triangles inside
   (condition 2), ω(site_r, site_l) > ω_min (condition 3, eq. 1).
5. Co-circular samples (every circular hole) make many circumcentres coincide up to round-off: adjacent
   inside triangles whose circumcentres are closer than ``1e-6 · spacing`` are contracted into one skeleton
   vertex. Contracting edges of the dual graph (rather than merging every close pair found by a k-d tree)
   can never create a spurious cycle. Edges that became self-loops are dropped.
6. §3 segment graph (:mod:`recon.segment_graph`): degrees, bridges, parts as components of the inside
   triangles cut along the separators, part kinds, part polygons.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, QhullError

from .. import segment_graph as sg
from ..errors import DecompositionError, InputError
from ._types import PART_KINDS, Part2D, SegmentGraph, Shape2D, Skeleton2D, SkeletonResult

__all__ = ["skeletonize", "resample_curves", "default_spacing", "default_omega_min"]

log = logging.getLogger(__name__)

#: Default number of boundary samples over the whole shape (see :func:`default_spacing`).
SAMPLES_PER_SHAPE = 2000
#: Fewest samples on any one curve.
MIN_SAMPLES_PER_CURVE = 16
#: Default ω_min as a fraction of the bounding-box diagonal (see :func:`default_omega_min`).
OMEGA_MIN_FRACTION = 0.05
#: Circumcentres of adjacent triangles closer than this times the spacing are one skeleton vertex.
MERGE_TOL = 1e-6
#: Rounds of midpoint insertion to make the triangulation conforming.
MAX_REFINE_ROUNDS = 12
#: Upper bound on the number of samples, to turn an absurd spacing into a clear error.
MAX_SAMPLES = 5_000_000


# ----------------------------------------------------------------------------------------------- sampling


def _clean_curves(curves) -> list[np.ndarray]:
    if isinstance(curves, np.ndarray) or not isinstance(curves, Sequence):
        raise InputError("curves: expected a sequence of (k, 2) arrays (closed curves, first point not repeated)")
    if len(curves) == 0:
        raise InputError("curves: the shape has no boundary curve")
    out = []
    for i, c in enumerate(curves):
        try:
            c = np.asarray(c, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise InputError(f"curves[{i}]: expected a (k, 2) array of numbers") from err
        if c.ndim != 2 or c.shape[1] != 2:
            raise InputError(f"curves[{i}]: expected a (k, 2) array, got shape {c.shape}")
        if not np.isfinite(c).all():
            raise InputError(f"curves[{i}]: contains NaN or infinite coordinates")
        # drop repeated points (including a repeated first point at the end)
        seg = np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1)
        scale = max(float(np.abs(c).max(initial=0.0)), 1.0)
        c = c[seg > 1e-12 * scale]
        if len(c) < 3:
            raise InputError(f"curves[{i}]: needs at least 3 distinct points, got {len(c)}")
        out.append(c)
    return out


def _perimeters(curves: list[np.ndarray]) -> np.ndarray:
    return np.array([np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1).sum() for c in curves])


def default_spacing(shape: Shape2D) -> float:
    """Default boundary sampling spacing: total perimeter / 2000.

    About 2000 samples over the whole shape resolve features down to ~0.05 % of the perimeter, and keep the
    triangulation cheap (a few ms). Each curve still gets at least 16 samples (see :func:`resample_curves`).

    Parameters
    ----------
    shape : Shape2D

    Returns
    -------
    float
        In shape units.
    """
    return float(_perimeters(_clean_curves(shape.curves)).sum()) / SAMPLES_PER_SHAPE


def default_omega_min(shape: Shape2D, *, spacing: float | None = None) -> float:
    """Default pruning threshold ω_min (§2, condition 3): 5 % of the bounding-box diagonal, at least 4 spacings.

    ω is the arc length between the two boundary points that generate a Voronoi edge, so ω_min is the
    shortest stretch of boundary that may grow its own skeleton branch: bumps narrower than 5 % of the part's
    size are treated as noise, and the floor of 4 samples keeps the sampling itself from making branches.

    Parameters
    ----------
    shape : Shape2D
    spacing : float, optional
        The sampling spacing in use (default :func:`default_spacing`).

    Returns
    -------
    float
        In shape units.
    """
    if spacing is None:
        spacing = default_spacing(shape)
    return max(OMEGA_MIN_FRACTION * shape.diagonal, 4.0 * float(spacing))


def resample_curves(curves: Sequence[ArrayLike], spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sample closed curves uniformly by arc length, with their curve potentials φ (§2).

    Each curve gets ``ceil(L / spacing)`` samples, but at least 16 (the spacing on that curve shrinks to
    ``L / 16``). Input vertices with an adjacent input segment at least one spacing long (the corners of a
    coarse polygon, e.g. a square given by its 4 corners, or a slot narrower than the spacing) are kept as
    samples and the stretches between them are sampled uniformly, so a coarse polygon keeps its exact shape.
    Dense input
    (a polyline finer than the spacing) is sampled uniformly and its corners may be cut by up to one spacing.
    φ is the arc length along the input polyline from the curve's first point, which is always a sample.

    Parameters
    ----------
    curves : sequence of (k_i, 2) float
        Closed curves, first point not repeated.
    spacing : float
        Target distance between samples, > 0.

    Returns
    -------
    points : (N, 2) float
        Samples, curve after curve, in the order of each curve.
    curve : (N,) int
        Curve index of each sample.
    potential : (N,) float
        φ of each sample, in ``[0, curve_length)``.
    curve_length : (C,) float
        Length of each input curve.
    """
    curves = _clean_curves(curves)
    spacing = _check_positive(spacing, "spacing")
    lengths = _perimeters(curves)
    estimate = float(np.maximum(np.ceil(lengths / spacing), MIN_SAMPLES_PER_CURVE).sum())
    if estimate > MAX_SAMPLES:
        raise InputError(f"spacing: {spacing:g} would give ~{estimate:.3g} samples (more than {MAX_SAMPLES}); "
                         "use a larger spacing")
    pts, cid, phi = [], [], []
    for i, c in enumerate(curves):
        closed = np.vstack([c, c[:1]])
        seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
        cum = np.r_[0.0, np.cumsum(seg)]
        length = cum[-1]
        s = min(spacing, length / MIN_SAMPLES_PER_CURVE)
        corner = (seg >= s) | (np.roll(seg, 1) >= s)
        corner[0] = True
        brk = np.r_[cum[:-1][corner], length]
        span = np.diff(brk)
        n = np.maximum(np.ceil(span / s - 1e-9).astype(np.int64), 1)
        owner = np.repeat(np.arange(len(span)), n)
        step = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
        p = brk[owner] + span[owner] * step / n[owner]
        xy = np.stack([np.interp(p, cum, closed[:, 0]), np.interp(p, cum, closed[:, 1])], axis=1)
        # corners closer than round-off to a uniform sample would give near-duplicates
        gap = np.linalg.norm(np.roll(xy, -1, axis=0) - xy, axis=1)
        ok = gap > 1e-9 * s
        pts.append(xy[ok])
        phi.append(p[ok])
        cid.append(np.full(int(ok.sum()), i, dtype=np.int64))
    return np.concatenate(pts), np.concatenate(cid), np.concatenate(phi), lengths


def _check_positive(value, name: str, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as err:
        raise InputError(f"{name}: expected a number, got {value!r}") from err
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise InputError(f"{name}: expected a finite number {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return v


def _successor(curve: np.ndarray) -> np.ndarray:
    """Index of the next sample on the same curve (cyclically); samples are grouped by curve, in order."""
    n = len(curve)
    idx = np.arange(n)
    start = np.r_[True, curve[1:] != curve[:-1]]
    end = np.r_[curve[1:] != curve[:-1], True]
    first = np.maximum.accumulate(np.where(start, idx, 0))
    return np.where(end, first, idx + 1)


def _omega(a: np.ndarray, b: np.ndarray, curve: np.ndarray, potential: np.ndarray,
           curve_length: np.ndarray) -> np.ndarray:
    """ω of §2 eq. 1: the shorter arc between samples ``a`` and ``b`` of one curve, ∞ across curves."""
    d = np.abs(potential[a] - potential[b])
    d = np.minimum(d, curve_length[curve[a]] - d)
    return np.where(curve[a] == curve[b], d, np.inf)


# ----------------------------------------------------------------------------------------- triangulation


class _Triangulation:
    """A conforming Delaunay triangulation of the samples, its inside triangles and §2's Voronoi edges.

    Boundary edges missing from the triangulation are split in four; boundary edges encroached in an inside
    triangle that carries a kept Voronoi edge (its circumcentre, a skeleton vertex, would lie beyond that
    edge, outside the shape) are split in two, and so are the encroached edges that hide another kept
    triangle's circumcentre from it (Ruppert's lemma: a circumcentre outside lies beyond an encroached
    boundary edge). Encroachment elsewhere does not matter: those circumcentres are pruned. Refining every
    encroached edge would cascade at every acute corner. Up to ``MAX_REFINE_ROUNDS`` rounds.
    """

    def __init__(self, points, curve, potential, curve_length, omega_min):
        self.inserted = 0
        for rounds in range(MAX_REFINE_ROUNDS + 1):
            nxt = _successor(curve)
            simp, nb = _delaunay(points)
            a, b = simp[:, [1, 2, 0]], simp[:, [2, 0, 1]]  # edge opposite corner k
            fwd, bwd = nxt[a] == b, nxt[b] == a
            is_bnd = fwd | bwd
            hits = np.bincount(np.where(fwd, a, b)[is_bnd], minlength=len(points))
            split = np.flatnonzero(hits == 0)
            conforming = len(split) == 0
            if conforming:
                inside = _inside(simp, nb, is_bnd)
                pairs, corner = sg.cell_adjacency(nb, active=inside)
                s0 = simp[pairs[:, 0], (corner + 1) % 3]
                s1 = simp[pairs[:, 0], (corner + 2) % 3]
                kept = _omega(s0, s1, curve, potential, curve_length) > omega_min  # §2 conditions 1-3
                carries = np.zeros(len(simp), dtype=bool)
                carries[pairs[kept].ravel()] = True
                split = _encroached(points, simp, a, b, fwd, is_bnd & carries[:, None])
                if len(split) == 0:
                    split = _hiding_edges(points, curve, simp, a, b, fwd, is_bnd & inside[:, None], carries)
                if len(split) == 0 or rounds == MAX_REFINE_ROUNDS:
                    break
            elif rounds == MAX_REFINE_ROUNDS:
                where = points[split[0]]
                raise DecompositionError(
                    f"shape: {len(split)} boundary edges cannot be made Delaunay edges (do curves touch or cross near "
                    f"({where[0]:.6g}, {where[1]:.6g})?)")
            n_before = len(points)
            # missing edges are quartered: the gap to the intruding sample is often far below the spacing
            fractions = (0.5,) if conforming else (0.25, 0.5, 0.75)
            points, curve, potential = _insert_midpoints(points, curve, potential, curve_length, nxt, split, fractions)
            self.inserted += len(points) - n_before
        self.rounds = rounds
        self.points, self.curve, self.potential = points, curve, potential
        self.simplices, self.neighbors, self.inside, self.next = simp, nb, inside, nxt
        self.pairs, self.sites, self.kept = pairs, np.stack([s0, s1], axis=1), kept
        self.encroached = len(split)
        if self.inserted:
            log.info("skeletonize: inserted %d boundary midpoints in %d rounds to make the triangulation conforming",
                     self.inserted, rounds)
        if len(split):
            log.warning("skeletonize: %d boundary edges still encroached after %d refinement rounds; "
                        "some skeleton vertices may lie just outside the shape", len(split), MAX_REFINE_ROUNDS)


def _delaunay(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    try:
        tri = Delaunay(points)
    except QhullError as err:
        raise DecompositionError(f"shape: Qhull could not triangulate the {len(points)} boundary samples "
                                 f"({err.args[0].splitlines()[0]})") from err
    if len(tri.coplanar):
        p = points[tri.coplanar[0, 0]]
        raise DecompositionError(f"shape: boundary samples coincide near ({p[0]:.6g}, {p[1]:.6g}); "
                                 "do curves touch or cross?")
    simp = tri.simplices.astype(np.int64)
    nb = tri.neighbors.astype(np.int64)
    e1, e2 = points[simp[:, 1]] - points[simp[:, 0]], points[simp[:, 2]] - points[simp[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    if cw.any():  # make every triangle counter-clockwise; corner k keeps its opposite neighbour
        simp[cw] = simp[cw][:, [0, 2, 1]]
        nb[cw] = nb[cw][:, [0, 2, 1]]
    return simp, nb


def _inside(simp: np.ndarray, nb: np.ndarray, is_bnd: np.ndarray) -> np.ndarray:
    """Even-odd inside flag of each triangle of a conforming triangulation."""
    m = len(simp)
    t = np.repeat(np.arange(m), 3)
    u = nb.ravel()
    eb = is_bnd.ravel()
    same = (u > t) & ~eb
    g = coo_matrix((np.ones(int(same.sum()), np.int8), (t[same], u[same])), shape=(m, m))
    n_comp, comp = connected_components(g, directed=False)
    # component graph; node n_comp is the unbounded outside
    ext = u < 0
    cu = np.where(ext, n_comp, comp[np.where(ext, 0, u)])
    cross = (ext | (u > t)) & (eb | ext)
    key = np.unique((comp[t[cross]] * (n_comp + 1) + cu[cross]) * 2 + eb[cross])
    adj: dict[int, list[tuple[int, int]]] = {}
    for c01, f in zip((key // 2).tolist(), (key % 2).tolist()):
        c0, c1 = divmod(c01, n_comp + 1)
        adj.setdefault(c0, []).append((c1, f))
        adj.setdefault(c1, []).append((c0, f))
    parity = np.full(n_comp + 1, -1, dtype=np.int64)
    parity[n_comp] = 0
    stack = [n_comp]
    while stack:
        c = stack.pop()
        for d, f in adj.get(c, ()):
            want = parity[c] ^ f
            if parity[d] < 0:
                parity[d] = want
                stack.append(d)
            elif parity[d] != want:
                raise DecompositionError("shape: inside and outside are inconsistent; do boundary curves cross?")
    return parity[comp] == 1


def _encroached(points, simp, a, b, fwd, check, *, edges=False):
    """Boundary edges (by start sample) among ``check (m, 3) bool`` whose opposite angle is not acute.

    With ``edges=True`` also returns each such edge's two end points, ``(e, 2, 2) float``.
    """
    t, k = np.nonzero(check)
    apex = points[simp[t, k]]
    pa, pb = points[a[t, k]] - apex, points[b[t, k]] - apex
    dot = np.einsum("ij,ij->i", pa, pb)
    # a right angle puts the circumcentre on the edge itself: split that too, so skeleton vertices are strictly inside
    bad = dot <= 1e-9 * np.linalg.norm(pa, axis=1) * np.linalg.norm(pb, axis=1)
    start = np.where(fwd[t, k], a[t, k], b[t, k])
    if not edges:
        return np.unique(start[bad])
    return start[bad], np.stack([pa[bad], pb[bad]], axis=1) + apex[bad][:, None, :]


def _hiding_edges(points, curve, simp, a, b, fwd, check, carries) -> np.ndarray:
    """Encroached boundary edges between a kept triangle and its circumcentre, where that centre is outside.

    If no boundary edge is encroached, every circumcentre lies inside (Ruppert's lemma) and nothing is
    tested. Otherwise the circumcentres of the obtuse kept triangles are tested against the sampled shape
    (even-odd over the curves, shapely's prepared point-in-polygon), and the encroached edges closer to an
    outside centre than its radius are returned.
    """
    start, seg = _encroached(points, simp, a, b, fwd, check, edges=True)
    if len(start) == 0:
        return start
    q = points[simp]
    angle_dot = np.einsum("tij,tij->ti", np.roll(q, -1, axis=1) - q, np.roll(q, 1, axis=1) - q)
    cand = np.flatnonzero(carries & (angle_dot.min(axis=1) < 0))  # acute triangles hold their circumcentre
    cc, rr = _circumcentres(points, simp[cand])
    inside = np.zeros(len(cand), dtype=bool)
    for c in range(int(curve.max()) + 1):
        ring = points[curve == c]
        lo, hi = ring.min(axis=0), ring.max(axis=0)
        box = np.flatnonzero(np.all((cc >= lo) & (cc <= hi), axis=1))
        if len(box):
            poly = shapely.Polygon(ring)
            shapely.prepare(poly)
            inside[box] ^= shapely.contains_xy(poly, cc[box, 0], cc[box, 1])
    if inside.all():
        return np.zeros(0, dtype=np.int64)
    cc, rr = cc[~inside], rr[~inside]
    d = seg[None, :, 1, :] - seg[None, :, 0, :]
    w = cc[:, None, :] - seg[None, :, 0, :]
    t = np.clip(np.einsum("cej,cej->ce", w, d) / np.maximum(np.einsum("cej,cej->ce", d, d), 1e-300), 0.0, 1.0)
    dist = np.linalg.norm(w - t[..., None] * d, axis=2)
    return np.unique(start[np.any(dist < rr[:, None], axis=0)])


def _insert_midpoints(points, curve, potential, curve_length, nxt, split, fractions=(0.5,)):
    """Insert points at ``fractions`` of each boundary edge ``split -> nxt[split]``, keeping curve order."""
    f = np.repeat(np.asarray(fractions, dtype=np.float64)[None, :], len(split), axis=0).ravel()
    i = np.repeat(split, len(fractions))
    j = nxt[i]
    new = points[i] + f[:, None] * (points[j] - points[i])
    L = curve_length[curve[i]]
    phi = np.mod(potential[i] + f * np.mod(potential[j] - potential[i], L), L)
    points = np.concatenate([points, new])
    curve = np.concatenate([curve, curve[i]])
    potential = np.concatenate([potential, phi])
    order = np.lexsort((potential, curve))
    return points[order], curve[order], potential[order]


def _circumcentres(points: np.ndarray, simp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = points[simp[:, 0]]
    b = points[simp[:, 1]] - a
    c = points[simp[:, 2]] - a
    d = 2.0 * (b[:, 0] * c[:, 1] - b[:, 1] * c[:, 0])
    bb, cc = (b * b).sum(1), (c * c).sum(1)
    # flat triangles (collinear samples on the convex hull, always outside) get infinite circumcentres
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = (c[:, 1] * bb - b[:, 1] * cc) / d
        uy = (b[:, 0] * cc - c[:, 0] * bb) / d
    return a + np.stack([ux, uy], axis=1), np.hypot(ux, uy)


# ---------------------------------------------------------------------------------------------- skeleton


def skeletonize(shape: Shape2D, *, omega_min: float | None = None, spacing: float | None = None) -> SkeletonResult:
    """Skeleton (§2) and decomposition into junction, terminal and linear parts (§3) of a 2D shape.

    Parameters
    ----------
    shape : Shape2D
        Closed boundary curves; the inside is given by the even-odd rule over all of them.
    omega_min : float, optional
        Pruning threshold of §2 condition 3, in shape units: a Voronoi edge is kept only if the shorter
        boundary arc between its two sites is longer. Default :func:`default_omega_min`.
    spacing : float, optional
        Boundary sampling spacing, in shape units. Default :func:`default_spacing`.

    Returns
    -------
    SkeletonResult
        ``points`` are the Voronoi sites, including any midpoints inserted to make the triangulation
        conforming. ``extra`` holds ``triangles (m, 3) int`` (counter-clockwise), ``triangle_part (m,) int``
        (``-1`` outside), ``refine_rounds`` and ``inserted_points``.

    Notes
    -----
    - A body whose pruned skeleton is empty, or collapses to a single point (a disk: every circumcentre is
      its centre), gets one skeleton vertex of degree 0: the centre of its largest empty circle centred in
      its own (acute) triangle, with that circle's radius. That vertex makes one ``"junction"`` part covering
      the whole body.
    - A skeleton vertex is the mean of the coincident circumcentres it merges; its radius their mean
      circumradius, i.e. the distance to its sites.
    - The segment graph has one edge per bridge, so it can hold parallel edges: a skeleton loop around a
      hole with one junction on it gives two graph edges between that junction and the loop's linear part.
    - Pruned triangles belong to the part they hang from, so the parts tile the shape. A part holding no
      skeleton vertex cannot arise: every piece between separators holds a bridge's endpoint, and a body
      without separators holds its skeleton or the one vertex above.

    Raises
    ------
    InputError
        Malformed curves or options.
    DecompositionError
        Curves that touch or cross, so the triangulation cannot be made conforming.
    """
    if not isinstance(shape, Shape2D):
        raise InputError(f"shape: expected a Shape2D, got {type(shape).__name__}")
    spacing = default_spacing(shape) if spacing is None else _check_positive(spacing, "spacing")
    if omega_min is None:
        omega_min = default_omega_min(shape, spacing=spacing)
    else:
        omega_min = _check_positive(omega_min, "omega_min", allow_zero=True)
    points, curve, potential, curve_length = resample_curves(shape.curves, spacing)
    tri = _Triangulation(points, curve, potential, curve_length, omega_min)
    points, curve, potential = tri.points, tri.curve, tri.potential
    simp, nb, inside = tri.simplices, tri.neighbors, tri.inside
    m = len(simp)

    cc, rr = _circumcentres(points, simp)
    pairs, kept = tri.pairs, tri.kept  # Voronoi edges between inside triangles, and §2's verdict on each
    t, u = pairs[:, 0], pairs[:, 1]
    s0, s1 = tri.sites[:, 0], tri.sites[:, 1]  # the two sites of each Voronoi edge

    cluster = _coincident_clusters(cc, t, u, spacing)
    real, rep, edge_of, used, vid, edges = _skeleton_edges(cluster, kept, t, u)

    # §3: degrees, bridges, parts
    degree = sg.vertex_degree(edges, len(used))
    bridge = sg.bridge_mask(edges, degree)
    cut = np.zeros(len(t), dtype=bool)
    cut[np.flatnonzero(real)] = bridge[edge_of]
    n_parts, label = sg.cut_components(m, pairs, cut, active=inside)

    # a body without any skeleton edge is one part without a vertex: give it one
    tri_vertex = np.where(inside, vid[cluster], -1)  # skeleton vertex of each triangle, -1: none
    part_has = np.bincount(label[tri_vertex >= 0], minlength=n_parts) > 0
    if not part_has.all():
        best = _one_point_skeletons(points, simp, inside, part_has, label, rr, cluster)
        vid[best] = len(used) + np.arange(len(best))
        used = np.r_[used, best]
        degree = np.r_[degree, np.zeros(len(best), dtype=np.int64)]
        tri_vertex = np.where(inside, vid[cluster], -1)
        log.info("skeletonize: %d bodies have a one-point skeleton", len(best))

    has_v = tri_vertex >= 0
    n_v = len(used)
    cnt = np.bincount(tri_vertex[has_v], minlength=n_v)
    vertices = np.stack([np.bincount(tri_vertex[has_v], weights=cc[has_v, i], minlength=n_v) for i in range(2)],
                        axis=1) / cnt[:, None]
    radius = np.bincount(tri_vertex[has_v], weights=rr[has_v], minlength=n_v) / cnt
    vpart = np.full(n_v, -1, dtype=np.int64)
    vpart[tri_vertex[has_v]] = label[has_v]
    kinds = sg.part_kinds(vpart, degree, n_parts)
    if np.any(kinds == sg.NO_SKELETON):  # pragma: no cover - cannot happen, see Notes
        log.warning("skeletonize: %d parts hold no skeleton vertex; labelled terminal",
                    int(np.sum(kinds == sg.NO_SKELETON)))
        kinds[kinds == sg.NO_SKELETON] = sg.TERMINAL

    real_idx = np.flatnonzero(real)[rep]  # representative Voronoi edge (pair index) of each skeleton edge
    b_idx = np.flatnonzero(bridge)
    bp = real_idx[b_idx]
    graph = SegmentGraph(
        edges=np.stack([label[t[bp]], label[u[bp]]], axis=1).reshape(-1, 2),
        bridges=b_idx,
        separators=np.stack([s0[bp], s1[bp]], axis=1).reshape(-1, 2),
    )
    parts = _assemble_parts(points, simp, nb, label, n_parts, kinds, vpart, edges, bridge, tri.next)
    skeleton = Skeleton2D(vertices=vertices.reshape(-1, 2), radius=radius, edges=edges.reshape(-1, 2))
    log.debug("skeletonize: %d samples, %d triangles, %d skeleton vertices, %d edges, %d parts",
              len(points), m, n_v, len(edges), n_parts)
    return SkeletonResult(
        points=points, curve=curve, potential=potential, curve_length=curve_length,
        skeleton=skeleton, parts=parts, segment_graph=graph, omega_min=float(omega_min), spacing=float(spacing),
        extra={"triangles": simp, "triangle_part": label, "refine_rounds": tri.rounds, "inserted_points": tri.inserted,
               "encroached_edges": tri.encroached},
    )


def _coincident_clusters(cc: np.ndarray, t: np.ndarray, u: np.ndarray, spacing: float) -> np.ndarray:
    """(m,) int: each triangle's representative among the triangles whose circumcentres coincide with its own (within
    :data:`MERGE_TOL` spacings, across Voronoi edges ``t``–``u``): co-circular samples make one skeleton vertex."""
    m = len(cc)
    cluster = np.arange(m)
    short = np.flatnonzero(np.linalg.norm(cc[t] - cc[u], axis=1) <= MERGE_TOL * spacing)
    if len(short):
        nodes, inv = np.unique(np.r_[t[short], u[short]], return_inverse=True)
        g = coo_matrix((np.ones(len(short), np.int8), (inv[:len(short)], inv[len(short):])), shape=(len(nodes),) * 2)
        n_cl, lab = connected_components(g, directed=False)
        rep_node = np.full(n_cl, m, dtype=np.int64)
        np.minimum.at(rep_node, lab, nodes)
        cluster[nodes] = rep_node[lab]
    return cluster


def _skeleton_edges(cluster: np.ndarray, kept: np.ndarray, t: np.ndarray, u: np.ndarray):
    """The skeleton's edges: the kept Voronoi edges between different clusters, parallel ones merged.

    Returns ``real`` (which pairs are skeleton edges), ``rep`` and ``edge_of`` (``np.unique``'s index and inverse
    of their keys: a representative pair per edge, the edge of each real pair), the clusters ``used`` as vertices,
    ``vid`` (triangle -> vertex, -1) and ``edges (e, 2)`` in vertex ids."""
    m = len(cluster)
    ct, cu = cluster[t], cluster[u]
    real = kept & (ct != cu)
    ekey, rep, edge_of = np.unique(np.minimum(ct[real], cu[real]) * m + np.maximum(ct[real], cu[real]),
                                   return_index=True, return_inverse=True)
    if len(ekey) < int(real.sum()):
        log.debug("skeletonize: %d parallel skeleton edges merged", int(real.sum()) - len(ekey))
    used = np.unique(np.r_[ekey // m, ekey % m])
    vid = np.full(m, -1, dtype=np.int64)
    vid[used] = np.arange(len(used))
    edges = np.stack([vid[ekey // m], vid[ekey % m]], axis=1).reshape(-1, 2)
    return real, rep, edge_of, used, vid, edges


def _one_point_skeletons(points, simp, inside, part_has, label, rr, cluster) -> np.ndarray:
    """The skeleton vertex (a triangle's cluster) of each body without a skeleton edge (a disk, or ω_min too large):
    the centre of its largest empty circle that lies in its own (acute) triangle, hence inside the body."""
    lonely = np.flatnonzero(inside & ~part_has[np.maximum(label, 0)])
    q = points[simp[lonely]]
    acute = np.all(np.einsum("tij,tij->ti", np.roll(q, -1, axis=1) - q, np.roll(q, 1, axis=1) - q) >= 0, axis=1)
    score = np.where(acute, rr[lonely], -1.0 / (1.0 + rr[lonely]))
    o = lonely[np.lexsort((-score, label[lonely]))]
    return cluster[o[np.r_[True, label[o][1:] != label[o][:-1]]]]


def _assemble_parts(points, simp, nb, label, n_parts, kinds, vpart, edges, bridge, nxt) -> tuple[Part2D, ...]:
    loop_v, offsets, loop_part = sg.part_boundary_loops(simp, nb, label, points=points)
    # signed area of each loop
    nxt_in_loop = np.arange(len(loop_v)) + 1
    nxt_in_loop[offsets[1:] - 1] = offsets[:-1]
    p, q = points[loop_v], points[loop_v[nxt_in_loop]]
    cross = p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]
    loop_len = np.diff(offsets)
    loop_of = np.repeat(np.arange(len(loop_len)), loop_len)
    area = 0.5 * np.bincount(loop_of, weights=cross, minlength=len(loop_len))
    va, vb = loop_v, loop_v[nxt_in_loop]
    on_boundary = (nxt[va] == vb) | (nxt[vb] == va)

    v_order = np.argsort(vpart, kind="stable")
    v_bounds = np.searchsorted(vpart[v_order], np.arange(n_parts + 1))
    epart = np.where(bridge, -1, vpart[edges[:, 0]]) if len(edges) else np.zeros(0, np.int64)
    e_order = np.argsort(epart, kind="stable")
    e_bounds = np.searchsorted(epart[e_order], np.arange(n_parts + 1))
    l_bounds = np.searchsorted(loop_part, np.arange(n_parts + 1))

    parts = []
    for k in range(n_parts):
        outer, holes, segs = None, [], []
        for li in range(l_bounds[k], l_bounds[k + 1]):
            s, e = offsets[li], offsets[li + 1]
            ring = points[loop_v[s:e]]
            if area[li] > 0:
                if outer is not None:  # pragma: no cover - a connected union of cells has one outer loop
                    log.warning("skeletonize: part %d has more than one outer loop; keeping the largest", k)
                    if abs(area[li]) < abs(_signed_area(outer)):
                        holes.append(ring)
                        continue
                    holes.append(outer)
                outer = ring
            else:
                holes.append(ring)
            ob = on_boundary[s:e]
            segs.append(np.stack([va[s:e][ob], vb[s:e][ob]], axis=1))
        parts.append(Part2D(
            kind=PART_KINDS[kinds[k]],
            polygon=outer if outer is not None else np.zeros((0, 2)),
            holes=tuple(holes),
            skeleton_vertices=v_order[v_bounds[k]:v_bounds[k + 1]],
            skeleton_edges=e_order[e_bounds[k]:e_bounds[k + 1]],
            boundary_segments=np.concatenate(segs) if segs else np.zeros((0, 2), np.int64),
        ))
    return tuple(parts)


def _signed_area(ring: np.ndarray) -> float:
    x, y = ring[:, 0], ring[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
