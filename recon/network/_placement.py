"""The curve network placed on its fitted surfaces.

Vertices go to the least-squares meeting point of their surfaces, edge polylines onto the intersection of their
two surfaces (refined where a chord strays from it, or midway between them where they do not meet and the edge
would lie beyond the sewing tolerance), and each edge is fitted (:func:`recon.fit.fit_edge_curve`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._parallel import shared_map
from ..errors import InputError
from ..fit import EdgeCurve, fit_edge_curve, point_curve, polyline_curve
from ._graph import OUTSIDE, CurveNetwork

__all__ = ["NetworkGeometry", "Projector", "meeting_point", "network_geometry"]

log = logging.getLogger(__name__)


#: ``project(part, points (k, 3)) -> (closest points (k, 3), unit normals (k, 3))`` on a part's surface.
Projector = Callable[[int, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class NetworkGeometry:
    """A curve network placed on its surfaces.

    Attributes
    ----------
    points : (v, 3) float
        Network vertices at the least-squares meeting point of their incident surfaces.
    vertex_gap : (v,) float
        Largest distance of each vertex to its incident surfaces.
    coords : (p, 3) float
        Edge polylines projected onto the intersection of their two surfaces, packed like
        ``CurveNetwork.coords`` (``offsets``), end points pinned to the vertices.
    offsets : (e + 1,) int
        Offsets into ``coords``.
    edge_gap : (e,) float
        Largest distance of each projected polyline to either of its surfaces.
    curves : tuple of EdgeCurve
        One fitted curve per edge.
    """

    points: np.ndarray
    vertex_gap: np.ndarray
    coords: np.ndarray
    offsets: np.ndarray
    edge_gap: np.ndarray
    curves: tuple

    def polyline(self, edge: int) -> np.ndarray:
        return self.coords[self.offsets[edge] : self.offsets[edge + 1]]


def _vertex_parts(network: CurveNetwork) -> list[list[int]]:
    parts: list[set[int]] = [set() for _ in range(network.n_vertices)]
    for (a, b), (l, r) in zip(network.edge_vertices.tolist(), network.edge_parts.tolist()):
        for v in (a, b):
            parts[v].add(l)
            if r != OUTSIDE:
                parts[v].add(r)
    return [sorted(s) for s in parts]


#: Surfaces meeting at less than this angle are treated as tangent: their intersection is too poorly
#: conditioned to pin a point down (a noise-level change of a fit moves it by noise / sin(angle)).
TANGENT_ANGLE = np.deg2rad(10.0)


def meeting_point(x0, parts, project: Projector, *, iterations: int = 8, limit: float | None = None):
    """Meeting point of several surfaces near ``x0`` (Gauss–Newton on their tangent planes, truncated SVD).

    Each step solves ``n_i · (x − q_i) = 0`` (``q_i`` the projection of ``x`` onto surface ``i``, ``n_i`` its
    normal) in the least-squares sense, keeping only the directions whose singular value is above
    ``sin(TANGENT_ANGLE)``: the directions the surfaces fix. The others (along the curve two surfaces share,
    or anywhere where fitted surfaces meet tangentially, as a fillet's sphere and cylinders do) keep
    ``x0``'s position, the labelled mesh's own. A point that still moves farther than ``limit`` goes back
    to the mean of its projections.

    Returns
    -------
    x : (3,) float
    gap : float
        Largest distance of ``x`` to the surfaces.
    """
    x0 = np.asarray(x0, dtype=np.float64).copy()
    x = x0.copy()
    smin = np.sin(TANGENT_ANGLE)
    for _ in range(iterations if parts else 0):
        qs, ns = [], []
        for p in parts:
            q, nrm = project(p, x[None])
            qs.append(q[0])
            ns.append(nrm[0])
        q = np.array(qs)
        nrm = np.array(ns)
        rhs = np.einsum("ij,ij->i", nrm, q - x)
        u, sv, vt = np.linalg.svd(nrm, full_matrices=False)
        keep = sv > smin
        step = vt[keep].T @ ((u[:, keep].T @ rhs) / sv[keep])
        x = x + step
        if np.linalg.norm(step) < 1e-12:
            break
    if limit is not None and parts and np.linalg.norm(x - x0) > limit:
        x = np.mean([project(p, x0[None])[0][0] for p in parts], axis=0)
    gap = max(float(np.linalg.norm(project(p, x[None])[0][0] - x)) for p in parts) if parts else 0.0
    return x, gap


def _project_two(pts, pa, pb, project: Projector, iterations: int, limit: float | None = None):
    """Alternate projections onto two surfaces, then a tangent-plane meeting step, for all points at once.

    Where the step would carry a point more than ``limit`` away from where it started (two fitted surfaces
    that meet tangentially, like a fillet and its face, cross at a grazing angle far from the mesh's
    boundary, or not at all) the point goes to the midpoint of its projections instead: between the two
    surfaces, at the labelled boundary.
    """
    x0 = pts.copy()
    x = pts.copy()
    for _ in range(iterations):
        qa, na = project(pa, x)
        qb, nb = project(pb, x)
        # Newton step on the two tangent planes, minimum-norm: moves x onto their intersection line.
        da = np.einsum("ij,ij->i", na, qa - x)
        db = np.einsum("ij,ij->i", nb, qb - x)
        g = np.einsum("ij,ij->i", na, nb)
        det = 1.0 - g * g
        ok = det > np.sin(TANGENT_ANGLE) ** 2
        # x + α na + β nb with na·(…)=da, nb·(…)=db
        alpha = np.where(ok, (da - g * db) / np.where(ok, det, 1.0), 0.5 * (da + db))
        beta = np.where(ok, (db - g * da) / np.where(ok, det, 1.0), 0.0)
        step = alpha[:, None] * na + beta[:, None] * nb
        # Nearly tangent surfaces: no well-defined intersection; take the midpoint of the projections.
        step[~ok] = 0.5 * (qa[~ok] + qb[~ok]) - x[~ok]
        x = x + step
        if limit is not None:
            far = np.linalg.norm(x - x0, axis=1) > limit
            if np.any(far):
                qa0, _ = project(pa, x0[far])
                qb0, _ = project(pb, x0[far])
                x[far] = 0.5 * (qa0 + qb0)
    return x


#: Rounds of chord refinement per edge polyline (each can double its points, see :func:`_refined`).
REFINE_ROUNDS = 6


def _onto_edge(x, left: int, right: int, project: Projector, iterations: int):
    """Points ``x`` near an edge moved onto it: onto ``left``'s surface alone for an open boundary, else onto the
    intersection of the two surfaces (Newton steps on their tangent planes, with no limit on the distance:
    ``x`` may be a chord's midpoint, a sagitta away from both surfaces; the caller checks where it went)."""
    if right == OUTSIDE:
        return project(left, x)[0]
    return _project_two(x, left, right, project, iterations, None)


def _nearest_segment(x, pts) -> np.ndarray:
    """``(m,) int``: for each point of ``x`` (m, 3), the segment of the polyline ``pts`` (k, 3) nearest to it."""
    a, d = pts[:-1], np.diff(pts, axis=0)
    w = x[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("mkj,kj->mk", w, d) / np.maximum(np.einsum("kj,kj->k", d, d), 1e-300), 0.0, 1.0)
    return np.argmin(np.linalg.norm(w - t[:, :, None] * d[None, :, :], axis=2), axis=1)


def _off_surfaces(x, left: int, right: int, project: Projector) -> np.ndarray:
    """``(k,)``: each point's larger distance to the edge's two surfaces (its one surface on an open boundary)."""
    off = np.zeros(len(x))
    for p in (left, right):
        if p != OUTSIDE:
            off = np.maximum(off, np.linalg.norm(project(p, x)[0] - x, axis=1))
    return off


def _split_midway(pts, left: int, right: int, project: Projector, *, tolerance: float, reach: float,
                  max_points: int):
    """The polyline with points added midway between the two surfaces where its chords lie off them.

    Where two fits touch at a grazing angle (a fillet's tangent edge, a thin tongue's tip) a chord's midpoint
    reaches no point on both (:func:`_refined` leaves the chord), and the place along the surfaces where they come
    closest is undetermined: the intersection of two nearly tangent fits wanders sideways. Each round gives every
    chord longer than ``tolerance`` the point midway between its midpoint's projections onto the two surfaces, where
    that point lies within ``reach`` of both, nearer them than the midpoint and more than ``tolerance`` from it: it
    moves along the surfaces' normals only, by half the midpoint's distance to the farther one, never sideways.
    """
    for _ in range(REFINE_ROUNDS):
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        long = np.flatnonzero(seg > tolerance)
        room = max_points - len(pts)
        if not len(long) or room <= 0:
            break
        mids = 0.5 * (pts[long] + pts[long + 1])
        q = 0.5 * (project(left, mids)[0] + project(right, mids)[0])
        gap = _off_surfaces(q, left, right, project)
        take = (gap <= reach) & (gap < _off_surfaces(mids, left, right, project))
        take &= np.linalg.norm(q - mids, axis=1) > tolerance
        if not take.any():
            break
        keep = np.flatnonzero(take)
        keep = keep[np.argsort(-seg[long[keep]], kind="stable")[:room]]
        keep.sort()
        pts = np.insert(pts, long[keep] + 1, q[keep], axis=0)
    return pts


def _refined(pts, left: int, right: int, project: Projector, *, tolerance: float, iterations: int, max_points: int):
    """The edge polyline with points added where a chord strays more than ``tolerance`` from the edge.

    A mesh made by a CAD tessellator has long triangles: an edge between two curved faces can be one mesh
    segment, a chord many tolerances inside the surfaces. Fitted as
    the line through its two points, the edge lies that far off both faces, ShapeFix raises its tolerance to
    match, and the face's wire intersects itself in the surface's parameters. Each round moves the midpoint
    of every chord longer than ``tolerance`` onto the edge (:func:`_onto_edge`) and keeps it where it moved
    by more than ``tolerance``, no more than half the chord, and lies within ``tolerance`` of both surfaces.
    Scan-like meshes, whose segments are short for their curvature, keep their polylines as they are.
    """
    for _ in range(REFINE_ROUNDS):
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        long = np.flatnonzero(seg > tolerance)
        room = max_points - len(pts)
        if not len(long) or room <= 0:
            break
        mids = 0.5 * (pts[long] + pts[long + 1])
        on = _onto_edge(mids, left, right, project, iterations)
        # Only points that reached both surfaces: where the surfaces meet tangentially or not at all near the
        # chord, the edge is no better defined than the chord itself.
        gap = _off_surfaces(on, left, right, project)
        # and a sagitta's distance away, not a far crossing of the two surfaces: a quarter circle's sagitta is
        # 0.21 of its chord, a half circle's 0.5.
        moved = np.linalg.norm(on - mids, axis=1)
        off = (moved > tolerance) & (moved <= 0.5 * seg[long]) & (gap <= tolerance)
        # and onto the part of the edge between the chord's ends, not onto another stretch of the same edge (an
        # edge along an arc and back across its chord would send the chord's midpoint to the arc: a crossed wire).
        # (Nearer a chord's neighbour is allowed: beside a sharp turn an arc can bulge towards the next chord.)
        off &= np.abs(_nearest_segment(on, pts) - long) <= 1
        if not off.any():
            break
        keep = np.flatnonzero(off)
        keep = keep[np.argsort(-seg[long[keep]], kind="stable")[:room]]
        keep.sort()
        pts = np.insert(pts, long[keep] + 1, on[keep], axis=0)
    return pts


def network_geometry(network: CurveNetwork, project: Projector, *, tolerance: float, iterations: int = 6,
                     max_points: int = 64, fit_curve=None, refine=None, jobs: int = 1) -> NetworkGeometry:
    """Place the network on its surfaces and fit each edge.

    Parameters
    ----------
    network : CurveNetwork
    project : callable
        ``project(part, points (k, 3)) -> (closest points (k, 3), unit normals (k, 3))``.
    tolerance : float
        Model tolerance: a line or circle is kept when all projected points are within it.
    iterations : int
        Projection iterations per polyline.
    max_points : int
        Polylines are resampled to at most this many points before projection (cost bound).
    fit_curve : callable, optional
        ``fit_curve(points, *, start, end, tolerance) -> EdgeCurve``; :func:`fit_edge_curve` by default.
    refine : collection of part ids, optional
        Parts whose surfaces are trusted to place an edge between the mesh's points: a polyline gets points
        added where its chords stray from the edge (:func:`_refined`), or midway between its two surfaces where
        its curve lies beyond the sewing tolerance (:func:`_within_sewing`), and a smooth curve that strays from
        its points gives way to them (:func:`_strays`), only when both its parts are in it (an open boundary: its
        one part). Default: every part.
    jobs : int
        Processes to place the edges with: two at most (see :func:`recon._parallel.shared_map`). The result
        does not depend on it.

    Returns
    -------
    NetworkGeometry
    """
    if not tolerance > 0:
        raise InputError(f"network_geometry: `tolerance` must be > 0, got {tolerance!r}")
    fit_curve = fit_curve or fit_edge_curve
    # How far the network may move from the labelled mesh boundary onto an intersection of its surfaces:
    # the mesh boundary is within a few noise levels (and so a few tolerances) of the true edge.
    limit = 3.0 * tolerance
    vparts = _vertex_parts(network)
    points = np.empty_like(network.points)
    vgap = np.zeros(network.n_vertices)
    for v in range(network.n_vertices):
        points[v], vgap[v] = meeting_point(network.points[v], vparts[v], project, limit=limit)

    def edge(e):  # (points, gap to the surfaces, curve, what to log) of edge e
        notes = []
        poly = network.polyline(e)
        a, b = network.edge_vertices[e]
        closed = a == b
        idx = np.unique(np.linspace(0, len(poly) - 1, min(len(poly), max_points)).round().astype(int))
        pts = poly[idx].copy()
        left, right = network.edge_parts[e]
        inner = pts[1:-1]
        if len(inner):
            if right == OUTSIDE:
                inner = project(int(left), inner)[0]
            else:
                inner = _project_two(inner, int(left), int(right), project, iterations, limit)
        pts = np.vstack([points[a][None], inner, points[b][None]])
        trusted = refine is None or (left in refine and (right == OUTSIDE or right in refine))
        if trusted:
            pts = _refined(pts, int(left), int(right), project, tolerance=tolerance, iterations=iterations,
                           max_points=max_points)
        inner = pts[1:-1]
        gap = 0.0
        if len(inner):
            for p in (left, right):
                if p != OUTSIDE:
                    gap = max(gap, float(np.max(np.linalg.norm(project(int(p), inner)[0] - inner, axis=1))))
        try:
            curve = fit_curve(pts, closed=bool(closed), tolerance=tolerance)
        except InputError as err:  # a degenerate edge (all its points coincide): the B-rep reports it
            notes.append(f"network_geometry: edge {e}: {err}")
            return pts, gap, point_curve(pts), notes
        if trusted and not closed and right != OUTSIDE:  # (midway between two surfaces: an open boundary has one)
            placed = len(pts)
            pts, curve = _within_sewing(pts, curve, int(left), int(right), project, tolerance=tolerance,
                                        max_points=max_points, fit_curve=fit_curve)
            if len(pts) > placed:
                gap = max(gap, float(np.max(_off_surfaces(pts[1:-1], int(left), int(right), project))))
                notes.append(f"network_geometry: edge {e}: placed midway between its surfaces where they do not "
                             f"meet, within {gap / tolerance:.3g} tolerances of both")
        if trusted and _strays(curve, pts, int(left), int(right), project, tolerance):
            notes.append(f"network_geometry: edge {e}: its smooth curve strays from its points and their surfaces: "
                         "the polyline is the edge")
            curve = polyline_curve(pts)
        return pts, gap, curve, notes

    # Every edge is placed on its own (the projections depend on the point alone): a second process can place
    # some while this one places the others, with the same result.
    done = shared_map(edge, network.n_edges, grace=SECOND_PROCESS_GRACE) if jobs > 1 and network.n_edges > 1 else {}
    out, offs, egap, curves = [], [0], [], []
    for e in range(network.n_edges):
        pts, gap, curve, notes = done[e] if e in done else edge(e)
        for note in notes:
            log.info("%s", note)
        egap.append(gap)
        out.append(pts)
        offs.append(offs[-1] + len(pts))
        curves.append(curve)
    return NetworkGeometry(points=points, vertex_gap=vgap, coords=np.concatenate(out) if out else np.empty((0, 3)),
                           offsets=np.asarray(offs, dtype=np.int64), edge_gap=np.asarray(egap),
                           curves=tuple(curves))


def _curve_points(curve: EdgeCurve, n: int) -> np.ndarray:
    """``(n, 3)`` points along ``curve`` (its start alone for a point curve)."""
    if curve.kind == "circle" and curve.circle is not None:
        return curve.circle.evaluate(np.linspace(curve.t0, curve.t1, n))
    if curve.spline is not None:
        return curve.spline.evaluate(np.linspace(*curve.spline.domain, n))
    return curve.start + np.linspace(0.0, 1.0, n)[:, None] * (curve.end - curve.start)


def _from_points(x, pts) -> float:
    """The largest distance of the points ``x`` to the polyline ``pts`` (sampled at 8 points per curve sample)."""
    from scipy.spatial import cKDTree

    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    along = np.linspace(0.0, s[-1], 8 * len(x))
    on_poly = np.column_stack([np.interp(along, s, pts[:, j]) for j in range(3)])
    return float(np.max(cKDTree(on_poly).query(x)[0]))


def _within_sewing(pts, curve: EdgeCurve, left: int, right: int, project: Projector, *, tolerance: float,
                   max_points: int, fit_curve):
    """``(pts, curve)``, refined where the curve lies more than the sewing tolerance off a surface or its points.

    A chord of a CAD tessellation where two fits touch at a grazing angle (a fillet's tangent edge, a thin tongue's
    tip) has no point on both surfaces to refine it onto: its midpoint stays a sagitta inside the curved one, and the
    chord, or the curve through it, lies farther off that surface than sewing bridges, past what the face's ShapeFix
    may grow the edge's tolerance to; a cubic through a long last chord can bow sideways across its neighbour's
    edge (a thin tongue's tip: bench/brep.md, 2026-12-04). Such an edge gets points midway between its surfaces
    (:func:`_split_midway`), each within the sewing tolerance of both; through them the fitted curve, or the
    polyline where that strays from them by more than the sewing tolerance; kept when it is nearer its surfaces and
    points (the larger distance) than the old one. An edge of one mesh segment (a line) is left as it is.
    """
    sewing = STRAY_FACTOR * tolerance

    def worst(c, p):  # the curve's larger distance to the surfaces and to its points
        x = _curve_points(c, min(STRAY_SAMPLES, 4 * (len(p) - 1) + 1))
        return max(float(np.max(_off_surfaces(x, left, right, project))), _from_points(x, p))

    before = worst(curve, pts)
    # (One mesh segment stays as it is: a line has nothing to bow through, and midway points on fillet-tangent chords
    # 12 T inside their tori left the plane faces valid but not once read back from STEP: bench/brep.md.)
    if before <= sewing or len(pts) == 2:
        return pts, curve
    more = _split_midway(pts, left, right, project, tolerance=tolerance, reach=sewing, max_points=max_points)
    if len(more) == len(pts):
        return pts, curve
    try:
        again = fit_curve(more, closed=False, tolerance=tolerance)
    except InputError:
        return pts, curve
    x = _curve_points(again, min(STRAY_SAMPLES, 4 * (len(more) - 1) + 1))
    if _from_points(x, more) > sewing:
        again = polyline_curve(more)
    return (more, again) if worst(again, more) < before else (pts, curve)


#: Seconds the first process waits at least for the second's answer once its own share is done (else twice the
#: time its own share took): a second process that hangs (forked from a threaded one: a lock held at the fork)
#: costs this, and its edges are placed by the first.
SECOND_PROCESS_GRACE = 30.0


#: How far (in tolerances) a smooth edge curve may stray from its polyline before it is checked against the
#: surfaces: the sewing tolerance (recon.brep sews at 10×), beyond which sewing cannot mend the gap either.
STRAY_FACTOR = 10.0
#: Samples along a curve (and along its polyline) for that check, at most (each one is two projections).
STRAY_SAMPLES = 128


def _strays(curve: EdgeCurve, pts, left: int, right: int, project: Projector, tolerance: float) -> bool:
    """Whether a smooth B-spline edge ``curve`` invents a shape that neither its points nor its surfaces have:
    somewhere it is more than :data:`STRAY_FACTOR` tolerances from its polyline ``pts``, and it does not make up
    for it by lying nearer the surfaces: on average (by arc length) it is farther off them (the larger of its
    distances to the two) than the polyline — or, through 3 points, more than a tolerance off them: the
    quadratic through 3 points has nothing to smooth, its shape between them is the points' spacing alone.
    Then the polyline is the better edge.

    A CAD tessellation's edges can be a few points with chords of very different lengths: the quadratic through
    3 such points can bow many tolerances sideways, across a face's hole, and the face's wire crosses itself;
    where two surfaces meet at a grazing angle the points zigzag and the best spline is farther off the surfaces
    than the points. A curve nearer the surfaces than its chords is kept: through sparse points on an arc the
    chords are a sagitta inside it; across a zigzag seam cut through one surface (no intersection to follow)
    the smooth loop is nearer it than the zigzag. So are curves of more points that are off the surfaces but
    nearer them than their chords. The caller asks only where both surfaces are fitted within tolerance
    (``refine``): a B-spline out of tolerance lies far off its edges' points, and fillings bounded by such
    polylines reach farther from the mesh. The measurements behind each case are in bench/evidence.md.
    """
    if curve.spline is None or curve.spline.degree < 2 or len(pts) < 3:
        return False
    from scipy.interpolate import BSpline
    from scipy.spatial import cKDTree

    n = min(STRAY_SAMPLES, 4 * (len(pts) - 1) + 1)
    spline = BSpline(curve.spline.knots, curve.spline.control_points, curve.spline.degree)
    on_curve = spline(np.linspace(0.0, 1.0, n))
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    along = np.linspace(0.0, s[-1], 8 * n)
    on_poly = np.column_stack([np.interp(along, s, pts[:, j]) for j in range(3)])
    if float(np.max(cKDTree(on_poly).query(on_curve)[0])) <= STRAY_FACTOR * tolerance:
        return False
    on_poly = on_poly[:: 8]

    def mean_off(x):
        off = np.zeros(len(x))
        for p in (left, right):
            if p != OUTSIDE:
                off = np.maximum(off, np.linalg.norm(project(p, x)[0] - x, axis=1))
        return float(off.mean())

    curve_off = mean_off(on_curve)
    return curve_off > mean_off(on_poly) or (len(pts) == 3 and curve_off > tolerance)
