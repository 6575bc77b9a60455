"""The penalised least-squares fit of a tensor-product B-spline surface (:mod:`recon.fit._bspline_surface`).

The fit (the approach OCP-NOTES.md measured best; Eilers & Marx' P-splines in two directions):

1. parametrise the patch: orthogonal projection onto its best (PCA) plane when the patch is a height field
   over it (every normal within 80° of the plane normal); otherwise, given the patch's triangles, a
   harmonic (Tutte, uniform-weight) map of the disk-shaped patch onto the unit disk;
2. clamped uniform knots on the parameter box enlarged by 5 % on every side, so the surface extends past
   the patch boundary and can be trimmed there;
3. minimise Σ |S(u_i, v_i) − p_i|² + λ (|Δ²_u P|² + 2 |Δ_u Δ_v P|² + |Δ²_v P|²) over the control grid P
   (second differences of the control points: a discrete thin-plate energy, which also fills the enlarged
   border and any hole in the data);
4. parameter correction: move each (u_i, v_i) to the closest point of the new surface and refit (3 rounds);
5. refine the knots (×1.5 per direction) while the deviation is above tolerance and the data support it.

A patch that wraps around an axis (a lofted tube, a full cylinder band: a topological annulus, possibly with
holes where an open mesh has them) is parametrised cylindrically instead: u the angle about the axis through
the centroids of its two longest boundary loops, v the height along that axis or, when that does not fit,
harmonic between the two loops. The surface is then periodic in u (uniform unclamped knots, control rows
repeating with period n_u, the second differences of the penalty taken cyclically), so it closes on itself
with no seam in the data. A patch that is neither (a torus, a sphere) reports a falsy result: it is the
analytic fitters' job.
"""

from __future__ import annotations

import logging
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from .._array import as_points, x_or_y_helper
from ..errors import FitError
from ._bspline_surface import BSplineSurface, basis_functions, clamped_knots, periodic_knots
from ._noise import estimate_normals
from ._types import SurfaceFit, deviation_stats, within_tolerance

__all__ = ["chord_guides", "fit_bspline_surface", "fit_exact_bspline"]

log = logging.getLogger(__name__)


# ------------------------------------------------------------------------------------- parametrisation


def _plane_frame(points: np.ndarray):
    mean = points.mean(axis=0)
    _, vec = np.linalg.eigh(np.cov((points - mean).T))
    return mean, vec[:, 2], vec[:, 1], vec[:, 0]  # origin, u axis, v axis, normal


def _harmonic_disk(n_points: int, faces: np.ndarray) -> list[int] | None:
    """The boundary loop (vertex ids in order) of a disk-shaped triangle patch, the rim its Tutte map pins to the unit
    circle; None if the patch is not a disk."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(edges, axis=0, return_counts=True)
    used = np.unique(faces)
    if n_points - len(uniq) + len(faces) != 1 or len(used) != n_points:
        return None  # Euler characteristic of a disk is 1 (and every point must belong to a triangle)
    boundary = uniq[counts == 1]
    if len(boundary) < 3:
        return None
    nxt: dict[int, list[int]] = {}
    for a, b in boundary:
        nxt.setdefault(int(a), []).append(int(b))
        nxt.setdefault(int(b), []).append(int(a))
    if any(len(v) != 2 for v in nxt.values()):
        return None
    loop = [int(boundary[0, 0])]
    prev = -1
    while True:
        a, b = nxt[loop[-1]]
        step = a if a != prev else b
        if step == loop[0]:
            break
        prev = loop[-1]
        loop.append(step)
    if len(loop) != len(boundary):
        return None  # several boundary loops
    return loop


def _harmonic_between(n: int, edges: np.ndarray, zero: np.ndarray, one: np.ndarray) -> np.ndarray:
    """(n,) solution of the uniform-weight (Tutte) Laplace equation on the edge graph, 0 on ``zero``, 1 on ``one``."""
    adj = sp.coo_matrix((np.ones(2 * len(edges)), (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                        shape=(n, n)).tocsr()
    lap = (sp.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj).tocsr()
    val = np.zeros(n)
    val[one] = 1.0
    fixed = np.zeros(n, bool)
    fixed[zero] = fixed[one] = True
    free = ~fixed
    rhs = -lap[free][:, fixed] @ val[fixed]
    val[free] = spsolve(lap[free][:, free].tocsc(), rhs)
    return val


def _boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Vertex loops of the boundary edges of ``faces`` (each (k,) int), longest first; [] if the border branches."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(edges, axis=0, return_counts=True)
    boundary = uniq[counts == 1]
    nxt: dict[int, list[int]] = {}
    for a, b in boundary.tolist():
        nxt.setdefault(a, []).append(b)
        nxt.setdefault(b, []).append(a)
    if any(len(v) != 2 for v in nxt.values()):
        return []
    loops, seen = [], set()
    for start in nxt:
        if start in seen:
            continue
        loop, prev = [start], -1
        seen.add(start)
        while True:
            a, b = nxt[loop[-1]]
            step = a if a != prev else b
            if step == start:
                break
            prev = loop[-1]
            loop.append(step)
            seen.add(step)
        loops.append(np.asarray(loop))
    return sorted(loops, key=len, reverse=True)


#: A band's periodic fit out of tolerance is still reported (to compete with the analytic candidates) when its RMS
#: deviation is within this many tolerances, the bound recon.brep puts on a fit that bounds its own face.
BAND_RMS = 4.0
#: A cylindrical parametrisation is refused when more than this share of the triangles fold over in (u, v).
MAX_FOLDED_SHARE = 0.005
#: Points per control point the control grid may grow to: noise needs about 4 to average out; points that lie
#: exactly on the surface (a CAD tessellation) pin a control point each with fewer, the smoothing holding the
#: grid between them (the measurements: bench/segment.md).
POINTS_PER_CONTROL = 4.0
EXACT_POINTS_PER_CONTROL = 2.0
#: ... for patches of fewer points than this: from there on 4 per control point already allow a grid of 250
#: controls, and a finer one only bends the surface where it leaves the data (bench/segment.md).
EXACT_MAX_POINTS = 1000


def _cylindrical(points: np.ndarray, faces: np.ndarray):
    """Two (n, 2) parametrisations (angle, height) and (angle, harmonic) of a band-shaped patch about the axis
    through its two longest loops, and the mean length of those loops (the band's length along u); (None, None)
    if the patch is not such a band.

    The patch must be an annulus (Euler characteristic 2 − loops; loops beyond two are holes, e.g. an open
    mesh's), and the map must be one-to-one: every triangle turns the same way about the axis (the band is
    star-shaped about it), bar :data:`MAX_FOLDED_SHARE` of them that the parameter correction sorts out.
    """
    loops = _boundary_loops(faces)
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    chi = len(np.unique(faces)) - len(edges) + len(faces)
    if len(loops) < 2 or chi != 2 - len(loops) or len(np.unique(faces)) != len(points):
        return None, None
    c0, c1 = points[loops[0]].mean(axis=0), points[loops[1]].mean(axis=0)
    axis = c1 - c0
    if np.linalg.norm(axis) < 1e-9 * np.ptp(points, axis=0).max():
        return None, None  # two loops around one centre (a washer, a torus cut once): no axis to wrap around
    axis /= np.linalg.norm(axis)
    ex = np.cross(axis, x_or_y_helper(axis))
    ex /= np.linalg.norm(ex)
    ey = np.cross(axis, ex)
    q = points - c0
    u = np.mod(np.arctan2(q @ ey, q @ ex), 2 * np.pi)
    v = q @ axis
    # signed (u, v) area of every triangle, u differences taken the short way round
    du1 = np.angle(np.exp(1j * (u[faces[:, 1]] - u[faces[:, 0]])))
    du2 = np.angle(np.exp(1j * (u[faces[:, 2]] - u[faces[:, 0]])))
    dv1, dv2 = v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]]
    area = du1 * dv2 - du2 * dv1
    major = np.sign(np.sum(np.sign(area)))
    if major == 0 or np.mean(np.sign(area) != major) > MAX_FOLDED_SHARE:
        return None, None
    lengths = [np.linalg.norm(np.diff(points[np.r_[lp, lp[0]]], axis=0), axis=1).sum() for lp in loops[:2]]
    # Two choices of v. The height along the axis is exact for a loft between parallel planes and undisturbed by
    # holes, but crowds the points where the band turns flat (a fillet ring at a pocket's floor); the harmonic
    # map between the loops (0 on one, 1 on the other, a hole's border free; scaled to the band's width) spreads
    # those evenly but bends around a hole
    harmonic = _harmonic_between(len(points), edges, loops[0], loops[1])
    width = float(np.mean(cKDTree(points[loops[0]]).query(points[loops[1]])[0]))
    return [np.column_stack([u, v]), np.column_stack([u, harmonic * width])], float(np.mean(lengths))


def _parametrise(points, normals, faces):
    """Initial (u, v) of every point and a function mapping them; or (None, reason)."""
    origin, eu, ev, en = _plane_frame(points)
    # of the points with a normal: a zero one (see fit_bspline_surface) tells nothing about the patch's steepness
    cosines = np.abs(normals @ en)[np.any(normals != 0, axis=1)]
    if len(cosines) and np.percentile(cosines, 1) > np.cos(np.deg2rad(80)):
        q = points - origin
        return np.column_stack([q @ eu, q @ ev]), "plane", None
    if faces is None:
        return None, "not a height field over its best plane, and no faces were given for a harmonic map", None
    rim = _harmonic_disk(len(points), faces)
    if rim is None:
        uv, circumference = _cylindrical(points, faces)  # a list of two candidate parametrisations
        if uv is None:
            why = "not a height field, not a topological disk and not a band around an axis: fit it analytically"
            return None, why, None
        return uv, "cylindrical", circumference
    loop = np.asarray(rim)
    seg = np.linalg.norm(np.diff(points[np.r_[loop, loop[0]]], axis=0), axis=1)
    angle = 2 * np.pi * np.r_[0.0, np.cumsum(seg)[:-1]] / seg.sum()
    n = len(points)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    adj = sp.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)).tocsr()
    lap = sp.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj
    fixed = np.zeros(n, bool)
    fixed[loop] = True
    uv = np.zeros((n, 2))
    uv[loop] = np.column_stack([np.cos(angle), np.sin(angle)])
    free = ~fixed
    a = lap[free][:, free].tocsc()
    rhs = -lap[free][:, fixed] @ uv[fixed]
    uv[free] = np.column_stack([spsolve(a, rhs[:, 0]), spsolve(a, rhs[:, 1])])
    return uv, "harmonic", None


def chord_guides(points: np.ndarray, normals: np.ndarray, faces: np.ndarray):
    """Guides between the vertices of an exact tessellation, for :func:`fit_bspline_surface`'s ``guide_weights``.

    A CAD exporter leaves a face's inside without vertices wherever its chords stay within the deflection (a loft's
    wall drawn by its two sections alone): the vertices then pin the surface only along its rims. A quadratic surface
    through a triangle's corners lies off it by e(λ) = ½ Σ λ_i λ_j κ_ij ℓ_ij² at barycentric λ, with
    κ_ij ℓ_ij² = (N_j − N_i)·(P_j − P_i) from the corners' unit normals (signed: on the normals' side when > 0). The
    guides are each edge's midpoint and each triangle's centroid lifted by e along their mean normal: the surface's
    points there to second order.

    Returns ``(points, normals, faces, lifts)``: the n points, then a guide per edge and per triangle, the triangles
    split in six over them, and each guide's lift.
    """
    n = len(points)
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    edges, inverse = np.unique(e, axis=0, return_inverse=True)
    mid = inverse.reshape(3, -1).T  # each triangle's edges 01, 12, 20
    pi, pj = points[edges[:, 0]], points[edges[:, 1]]
    turn = np.einsum("ij,ij->i", normals[edges[:, 1]] - normals[edges[:, 0]], pj - pi)  # κ ℓ² per edge
    # e(λ) at an edge's midpoint (λ = ½, ½, 0): κ ℓ² / 8; at the centroid (λ = ⅓ each): Σ κ ℓ² / 18
    lifts = np.r_[turn / 8.0, turn[mid].sum(axis=1) / 18.0]  # analytic factors, not tuned
    bases = np.concatenate([(pi + pj) / 2, points[faces].mean(axis=1)])
    guide_normals = np.concatenate([normals[edges].sum(axis=1), normals[faces].sum(axis=1)])
    guide_normals /= np.maximum(np.linalg.norm(guide_normals, axis=1, keepdims=True), 1e-300)
    a, b, c = faces.T
    ab, bc, ca = (n + mid).T
    g = n + len(edges) + np.arange(len(faces))
    split = np.concatenate([np.c_[a, ab, ca], np.c_[ab, b, bc], np.c_[ca, bc, c],
                            np.c_[ab, bc, g], np.c_[bc, ca, g], np.c_[ca, ab, g]])
    return (np.concatenate([points, bases + lifts[:, None] * guide_normals]),
            np.concatenate([normals, guide_normals]), split, lifts)


#: The vertices alone fix the surface between them when it passes within reach of at least this share of the guides:
#: the median, since a surface the vertices leave free strays from nearly all of them, and one they fix from a few.
GUIDES_AGREE = 0.5


def fit_exact_bspline(points: np.ndarray, normals: np.ndarray, faces: np.ndarray, tolerance: float) -> SurfaceFit:
    """:func:`fit_bspline_surface` through the exact vertices of a CAD tessellation, guided between them where they
    leave it free.

    The fit through the vertices alone stands when it passes within reach of :data:`GUIDES_AGREE` of the
    :func:`chord_guides` (tolerance + the guide's lift: a guide's error grows with its lift, since the long triangles'
    normals are the chords', not the surface's). Else the guides enter the fit, each weighted by the inverse of its
    variance relative to the vertices', min(1, (tolerance / lift)²); that fit is kept when it holds the vertices.
    """
    bare = fit_bspline_surface(points, normals, faces=faces, tolerance=tolerance, exact=True)
    if not bare.ok:
        return bare
    pts, nrm, split, lifts = chord_guides(points, normals, faces)
    reach = tolerance + np.abs(lifts)
    if np.mean(np.abs(bare.distance(pts[len(points):])) <= reach) >= GUIDES_AGREE:
        return bare
    weights = np.minimum(1.0, (tolerance / np.maximum(np.abs(lifts), 1e-300)) ** 2)
    guided = fit_bspline_surface(pts, nrm, faces=split, tolerance=tolerance, exact=True, guide_weights=weights)
    log.debug("bspline: the vertices leave the surface free between them; guided fit %s", guided.deviation)
    return guided if guided.ok else bare


# ------------------------------------------------------------------------------------------------ fit


def _difference(n: int, order: int) -> sp.csr_matrix:
    return sp.csr_matrix(np.diff(np.eye(n), n=order, axis=0))


def _cyclic_difference(n: int, order: int) -> sp.csr_matrix:
    """Differences of a periodic sequence of n values (every row wraps round): (n, n)."""
    d = sp.identity(n, format="csr")
    shift = sp.csr_matrix((np.ones(n), (np.arange(n), (np.arange(n) + 1) % n)), shape=(n, n))
    for _ in range(order):
        d = (shift - sp.identity(n)) @ d
    return d.tocsr()


@lru_cache(maxsize=64)
def _penalty(nu: int, nv: int, periodic_u: bool):
    """(the thin-plate penalty's matrix (nu·nv, nu·nv), the mean of its diagonal, the identity (nu·nv, nu·nv)) of an
    nu × nv control grid (step 3 of the module notes).

    It depends on the grid alone, and a fit solves on one grid four times (the parameter corrections) and most
    fits on the same few grids: building it was most of a B-spline solve. Callers
    must not modify the matrices in place.
    """
    if periodic_u:
        du2, du1 = _cyclic_difference(nu, 2), _cyclic_difference(nu, 1)
    else:
        du2, du1 = _difference(nu, 2), _difference(nu, 1)
    dv2, dv1 = _difference(nv, 2), _difference(nv, 1)
    iu, iv = sp.identity(nu), sp.identity(nv)
    pen = [sp.kron(du2, iv), sp.kron(iu, dv2), np.sqrt(2.0) * sp.kron(du1, dv1)]
    penalty = sum(d.T @ d for d in pen)
    return penalty, float(penalty.diagonal().mean()), sp.identity(nu * nv)


def _design(uv, ku, kv, p, nu, nv, periodic_u=False):
    fu, bu = basis_functions(uv[:, 0], ku, p)
    fv, bv = basis_functions(uv[:, 1], kv, p)
    m = len(uv)
    ar = np.arange(p + 1)
    iu = fu[:, None, None] + ar[None, :, None]
    if periodic_u:
        iu = iu % nu
    cols = iu * nv + (fv[:, None, None] + ar[None, None, :])
    vals = bu[:, :, None] * bv[:, None, :]
    rows = np.repeat(np.arange(m), (p + 1) ** 2)
    return sp.csr_matrix((vals.ravel(), (rows, cols.ravel())), shape=(m, nu * nv))


def _solve(points, uv, box, intervals, degree, smoothing, periodic_u=False, weights=None, held=None):
    (u0, u1), (v0, v1) = box
    kv = clamped_knots(v0, v1, intervals[1], degree)
    nv = intervals[1] + degree
    if periodic_u:
        ku = u0 + periodic_knots(u1 - u0, intervals[0], degree)
        nu = intervals[0]
    else:
        ku = clamped_knots(u0, u1, intervals[0], degree)
        nu = intervals[0] + degree
    a = _design(uv, ku, kv, degree, nu, nv, periodic_u)
    penalty, penalty_mean, ridge = _penalty(nu, nv, periodic_u)
    if weights is None:
        ata, rhs = (a.T @ a).tocsc(), a.T @ points
        lam = smoothing * ata.diagonal().mean() / max(penalty_mean, 1e-300)
    else:
        ata, rhs = (a.T @ sp.diags(weights) @ a).tocsc(), a.T @ (weights[:, None] * points)
        # λ as the held points alone would set it: guides add data, not stiffness
        full = a[:held]
        lam = smoothing * (full.T @ full).diagonal().mean() / max(penalty_mean, 1e-300)
    # a tiny ridge keeps control points with no data and no curvature (corners of the box) determined
    system = (ata + lam * penalty + 1e-10 * ata.diagonal().mean() * ridge).tocsc()
    cp = spsolve(system, rhs)
    return BSplineSurface(degree, degree, ku, kv, np.asarray(cp).reshape(nu, nv, 3), periodic_u)


def fit_bspline_surface(
    points,
    normals=None,
    *,
    faces=None,
    tolerance: float | None = None,
    degree: int = 3,
    intervals: int | None = None,
    smoothing: float = 1e-3,
    corrections: int = 3,
    max_intervals: int = 40,
    exact: bool = False,
    guide_weights=None,
) -> SurfaceFit:
    """Penalised least-squares tensor-product B-spline through a patch (see the module notes for the method).

    Parameters
    ----------
    points : (n, 3) float
        n ≥ 16.
    normals : (n, 3) float, optional
        Any sign; estimated by k-NN PCA when omitted. Used to decide whether the patch is a height field.
    faces : (m, 3) int, optional
        Triangles over ``points`` (indices); needed for patches that are not height fields.
    tolerance : float, optional
        Knots are refined until the deviation meets the acceptance rule (or the data run out).
    degree : int
        Degree in both directions.
    intervals : int, optional
        Knot spans per direction to start with; default about sqrt(n / 40), at least 3.
    smoothing : float
        λ relative to the mean diagonal of AᵀA.
    corrections : int
        Parameter-correction rounds.
    max_intervals : int
        Upper bound on the knot spans per direction.
    exact : bool
        The points lie on the surface without noise (a CAD tessellation): the control grid may grow to one control
        point per :data:`EXACT_POINTS_PER_CONTROL` points instead of :data:`POINTS_PER_CONTROL`, for fewer than
        :data:`EXACT_MAX_POINTS` points; for more, when the grid of :data:`POINTS_PER_CONTROL` misses ``tolerance``.
    guide_weights : (g,) float in (0, 1], optional
        The last g points are guides (:func:`chord_guides`): each enters the least squares with its weight and
        shapes the surface where the other points leave it free (between the vertices of long triangles), but it is
        not held to ``tolerance`` and does not count towards the control grid the data support.

    Returns
    -------
    SurfaceFit
        ``type == "bspline"``; ``params`` as :meth:`BSplineSurface.to_params` (``periodic_u`` for a band around an
        axis). Falsy for a closed or otherwise wrapped patch that is not such a band (a torus).
    """
    pts = as_points(points, min_count=16, error=FitError)
    if normals is None:
        nrm = estimate_normals(pts)
    else:
        nrm = as_points(normals, "normals", error=FitError)
        if len(nrm) != len(pts):
            raise FitError(f"`normals` must have one row per point ({len(pts)}), got {len(nrm)}")
        # a point on zero-area triangles only (or on two that cancel) has a zero normal: it stays zero, no direction
        length = np.linalg.norm(nrm, axis=1, keepdims=True)
        nrm = nrm / np.where(length > 0, length, 1.0)
    if faces is not None:
        faces = np.asarray(faces)
        if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
            raise FitError(f"`faces` must be an (m, 3) int array, got {faces.shape} {faces.dtype}")
        if faces.size and (faces.min() < 0 or faces.max() >= len(pts)):
            raise FitError("`faces` indexes outside `points`")
    if degree < 1:
        raise FitError(f"`degree` must be ≥ 1, got {degree}")
    w = None
    if guide_weights is not None:
        g = np.asarray(guide_weights, dtype=float)
        if g.ndim != 1 or len(g) >= len(pts) - 15 or not np.all((g > 0) & (g <= 1)):
            raise FitError(f"`guide_weights` must be at most {len(pts) - 16} values in (0, 1]")
        w = np.r_[np.ones(len(pts) - len(g)), g]
    held = len(pts) if w is None else len(pts) - len(g)
    uv, how, u_length = _parametrise(pts, nrm, faces)
    if uv is None:
        return SurfaceFit("bspline", {}, deviation_stats(np.empty(0)), len(pts), ok=False, reason=f"bspline: {how}")
    periodic = how == "cylindrical"
    best: SurfaceFit | None = None
    # exact points of many: the coarser grid first (a finer one bends where it leaves the data), the finer one only when
    # the coarser misses the tolerance (a loft's wall of 1,576 exact vertices: 2.2x the tolerance at 4 points per control)
    grids = [EXACT_POINTS_PER_CONTROL] if exact and held < EXACT_MAX_POINTS else (
        [POINTS_PER_CONTROL, EXACT_POINTS_PER_CONTROL] if exact and tolerance is not None else [POINTS_PER_CONTROL])
    for per_control in grids:
        for cand in uv if periodic else [uv]:
            fit = _fit_parametrised(pts, cand, periodic, u_length, tolerance=tolerance, degree=degree,
                                    intervals=intervals, smoothing=smoothing, corrections=corrections,
                                    max_intervals=max_intervals, per_control=per_control, weights=w, held=held)
            if best is None or fit.ok > best.ok or (fit.ok == best.ok and fit.deviation["p99"] < best.deviation["p99"]):
                best = fit
            if fit.ok:
                break  # the first parametrisation that fits is kept: the second costs a whole fit
        if best is not None and best.ok:
            break
    assert best is not None  # one candidate at least: uv is not None here
    log.debug("bspline (%s parametrisation): deviation %s", how, best.deviation)
    if periodic and tolerance is not None and not best.ok and not best.deviation["rms"] <= BAND_RMS * tolerance:
        # not one smooth band (e.g. fillets meeting at sharp corners): a surface this far off would only bound a
        # face far from the mesh
        return SurfaceFit("bspline", {}, deviation_stats(np.empty(0)), len(pts), ok=False,
                          reason=f"bspline: no periodic B-spline fits this band (RMS {best.deviation['rms']:.3g} "
                                 f"> {BAND_RMS:g} × tolerance {tolerance:.3g})")
    return best


def _fit_parametrised(pts, uv, periodic, u_length, *, tolerance, degree, intervals, smoothing, corrections,
                      max_intervals, per_control: float = POINTS_PER_CONTROL, weights=None,
                      held: int | None = None) -> SurfaceFit:
    """Steps 2–5 of the module notes on one initial parametrisation ``uv`` (n, 2); ``weights`` (n,) of the least
    squares; the first ``held`` points (default all) are held to ``tolerance``, the rest are guides."""
    n_held = len(pts) if held is None else held
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    # UV box grown by 5% of its extent so the surface covers its boundary points (scales with the patch)
    margin = 0.05 * (hi - lo)
    box = np.column_stack([lo - margin, hi + margin])
    extent = hi - lo
    if periodic:
        box[0] = (0.0, 2 * np.pi)  # the whole turn, no margin: the surface closes on itself
        # knot spans in proportion to lengths: u's length is the mean circumference about the axis
        extent = np.array([u_length, hi[1] - lo[1]])
    aspect = extent / max(extent.max(), 1e-300)
    # the data must support the control grid: about ≥ `per_control` points per control point
    cap = max(3, int(min(max_intervals, np.sqrt(n_held / per_control) - degree)))
    if periodic:
        # the same ≥ `per_control` points per control point, counted on the actual grid: a band is long in u and short in v,
        # and a square cap would starve u (an elliptic tube of 2,880 points: 23 × 10 controls, RMS 1.8 σ)
        def controls(c):
            return max(degree + 2, round(c * aspect[0])) * (max(2, round(c * aspect[1])) + degree)

        cap = max([c for c in range(3, max_intervals + 1) if controls(c) <= n_held / per_control], default=3)
    # about 40 points per knot span by default: noise averages out (tuned: see POINTS_PER_CONTROL)
    k = intervals or max(3, int(round(np.sqrt(n_held / 40.0))))
    k = min(k, cap)
    while True:
        spans = (max(2, int(round(k * aspect[0]))), max(2, int(round(k * aspect[1]))))
        if periodic:  # a periodic direction needs more control rows than the degree (else rows repeat in a span)
            spans = (max(spans[0], degree + 2), spans[1])
        surf = _solve(pts, uv, box, spans, degree, smoothing, periodic, weights, n_held)
        cur = uv
        for _ in range(corrections):
            cur = surf.closest_parameters(pts, cur, iterations=4)
            surf = _solve(pts, cur, box, spans, degree, smoothing, periodic, weights, n_held)
        d = surf.distance(pts[:n_held], cur[:n_held])
        dev = deviation_stats(d)
        if tolerance is None or within_tolerance(dev, tolerance) or k >= cap:
            break
        k = min(cap, int(np.ceil(k * 1.5)))
    log.debug("bspline: %s control grid, deviation %s", surf.control_points.shape, dev)
    ok, reason = True, ""
    if tolerance is not None and not within_tolerance(dev, tolerance):
        ok = False
        reason = f"bspline: deviation p99 {dev['p99']:.3g} / max {dev['max']:.3g} exceeds tolerance {tolerance:.3g}"
    return SurfaceFit("bspline", surf.to_params(), dev, n_held, ok=ok, reason=reason)
