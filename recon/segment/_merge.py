"""Passes that merge neighbouring faces one surface holds: pieces of one analytic surface
(:func:`merge_same_surface`) and bands of one round surface (:func:`merge_round_bands`)."""

from __future__ import annotations

import hashlib
import logging

import numpy as np

from .._array import unit
from ..fit import quick_fit, residual_scale
from ._context import ANALYTIC, EXACT_MISFIT, SegmentContext, exact_vertices, fit_members, misfits

__all__ = ["merge_round_bands", "merge_same_surface", "one_centre"]

log = logging.getLogger(__name__)

#: A closed form is a little off a noisy region's best fit: the probe lets it be this many tolerances off.
PROBE_SLACK = 2.0
#: Points of the union the probe looks at, at most (every k-th vertex): a closed form of at most 7 parameters is
#: judged as well on a few thousand points as on all.
PROBE_POINTS = 2000

#: Bands of one round surface (:func:`merge_round_bands`): cylinders (or a cylinder and a sphere) whose radii agree
#: within BAND_RADIUS_SLACK tolerances (two fits of one radius each within tolerance), ...
BAND_RADIUS_SLACK = 2.0
#: ... whose axes pass within this share of the radius of each other (of the sphere's centre): bands of one ball
#: meet near its centre, the axes of a chain of fillets a radius or more apart, ...
BAND_CENTRE_SHARE = 0.35
#: ... and are more than this angle apart (nearer to parallel they are coaxial pieces, merge_same_surface's).
BAND_AXIS_ANGLE = np.deg2rad(10.0)


def merge_same_surface(labels: np.ndarray, fits: dict, ctx: SegmentContext) -> np.ndarray:
    """Merge neighbouring faces that one analytic surface covers within tolerance.

    The decomposition can leave a face in two pieces (a sliver patch beside its face, a face cut by a
    short feature); two analytic neighbours whose union one analytic surface fits are one face. The pieces
    need not have the type of the whole: a small piece of a cone fits a plane or a cylinder within tolerance
    (a noisy cone can lie in cone, cylinder and plane pieces). A union that its surface holds only as a
    compromise — a robust residual above :data:`recon.fit._select.MISFIT_SCALE` × the noise, as
    :func:`recon.segment.grow_faces` judges a face — is two faces, not one: under noise a small piece that
    straddles two faces fits some surface within tolerance, and its union with another such piece does too
    (a chamfer's plane piece and a cylinder across the chamfer and both its planes), and the grown
    faces then keep that compromise. Pairs are tried largest shared boundary first, and after every merge the
    pairs are tried again. Returns ``labels`` itself when nothing merged.
    """
    out = labels.copy()
    fits = dict(fits)
    pairs, V = ctx.pairs, ctx.mesh.vertices
    n_merged = 0
    for _ in range(len(fits)):
        a, b = out[pairs[:, 0]], out[pairs[:, 1]]
        diff = a != b
        if not diff.any():
            break
        key = np.sort(np.column_stack([a[diff], b[diff]]), axis=1)
        uniq, count = np.unique(key, axis=0, return_counts=True)
        merged = False
        for (p, q) in uniq[np.argsort(-count, kind="stable")].tolist():
            fp, fq = fits.get(p), fits.get(q)
            if not (fp and fq and fp.type in ANALYTIC and fq.type in ANALYTIC):
                continue
            members = np.flatnonzero((out == p) | (out == q))
            upto = fp.type if fp.type == fq.type else ANALYTIC[-1]
            if fp.type != fq.type and not probe_fits(members, upto, ctx):
                continue
            fit = fit_members(members, p, upto, ctx)
            if fit and fit.type not in (fp.type, fq.type) and both_exact(out, fits, p, q, ctx):
                continue  # (see below)
            if fit and not misfits(fit, V[ctx.vertices(members)], ctx):
                out[out == q] = p
                fits[p] = fit
                del fits[q]
                n_merged += 1
                merged = True
                break
        if not merged:
            break
    if not n_merged:
        return labels
    log.info("%d faces merged with a neighbour on the same surface", n_merged)
    return out


def both_exact(labels: np.ndarray, fits: dict, p: int, q: int, ctx: SegmentContext) -> bool:
    """Whether faces ``p`` and ``q`` both fit their own surfaces to round-off on a mesh whose vertices are exact
    (a CAD export; :func:`recon.segment.grow_faces`' test). Their union then is two faces even where a third type
    holds it too: on the ABC model a fillet's cylinder strip and the plane strip beside it, long triangles whose
    vertices are on three circles, merged into a sphere of about the fillet's radius."""
    if not ctx.noise_free:
        return False
    V = ctx.mesh.vertices
    own = [residual_scale(fits[r], V[ctx.vertices(labels == r)]) for r in (p, q)]
    return max(own) <= EXACT_MISFIT * ctx.tolerance and exact_vertices(labels, fits, ctx)


def probe_fits(tris: np.ndarray, upto: str, ctx: SegmentContext) -> bool:
    """Whether some analytic type up to ``upto`` may fit the triangles ``tris``: its closed form (the
    decomposition's, from points and normals) lies within :data:`PROBE_SLACK` tolerances. Fitting every pair of
    faces of different types in full took the 100k box's fit stage from 0.5 to 4.7 s."""
    memo, tolerance = ctx.memo, ctx.tolerance
    # merge_same_surface starts over after every merge and probes the same pairs again
    key = ("probe", float(tolerance), upto, hashlib.sha1(np.asarray(tris, dtype=np.int64).tobytes()).digest())
    if key in memo:
        return memo[key]
    ids = ctx.vertices(tris)
    ids = ids[:: max(1, len(ids) // PROBE_POINTS)]  # a closed form needs no more points to be judged
    pts, nrm = ctx.mesh.vertices[ids], ctx.vertex_normals[ids]
    kinds = ANALYTIC[: ANALYTIC.index(upto) + 1]
    found = any(quick_fit(kind, pts, nrm, PROBE_SLACK * tolerance, refine=False) is not None for kind in kinds)
    memo[key] = found
    return found


def merge_round_bands(labels: np.ndarray, fits: dict, ctx: SegmentContext) -> np.ndarray:
    """Merge neighbouring cylinder (and sphere) faces that are bands of one doubly curved surface into one face.

    A coarse tessellation of a round end in long slivers decomposes into bands that each fit a cylinder within
    tolerance, of one radius, their axes crossing, and a sphere of that radius beside them: no analytic surface
    holds their union within tolerance (:func:`merge_same_surface` tries the pieces' own type only), a B-spline
    does. Kept apart, the edges between them are where two cylinders cross, a wandering curve across bands
    0.02 wide, and the faces' boundaries crossed themselves on their surfaces (ShapeFix split them). Groups of
    three or more such faces are merged, only when the union's own fit (any type) is within tolerance.
    Returns ``labels`` itself when nothing merged.
    """
    pairs = ctx.pairs
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    diff = a != b
    key = np.unique(np.sort(np.column_stack([a[diff], b[diff]]), axis=1), axis=0)
    parent = {}

    def root(x):
        while parent.get(x, x) != x:
            x = parent[x]
        return x

    for p, q in key.tolist():
        if _same_round(fits.get(p), fits.get(q), ctx.tolerance):
            parent[root(q)] = root(p)
    groups: dict[int, list[int]] = {}
    for x in list(parent):
        groups.setdefault(root(x), []).append(x)
    out = labels
    for r, members in groups.items():
        members = sorted(set(members) | {r})
        if len(members) < 3:
            continue  # two bands: a fillet's cylinder and its neighbour cross at an angle too
        if not one_centre([fits[k] for k in members]):
            continue  # bands of several balls, chained (a filleted box's fillets and corners: its whole frame)
        tris = np.flatnonzero(np.isin(labels, members))
        fit = fit_members(tris, members[0], None, ctx)
        if not fit:
            continue
        if out is labels:
            out = labels.copy()
        out[tris] = members[0]
        log.info("faces %s: bands of one round surface, merged (%s)", members, fit.type)
    return out


def _centre(f) -> tuple[np.ndarray, np.ndarray | None]:
    """A cylinder's axis (point, direction) or a sphere's centre (point, None)."""
    if f.type == "cylinder":
        return np.asarray(f.params["axis_point"], float), np.asarray(f.params["axis_dir"], float)
    return np.asarray(f.params["center"], float), None


def _same_round(f, g, tolerance: float) -> bool:
    """Whether the fits ``f`` and ``g`` may be two bands of one ball (:func:`merge_round_bands`)."""
    if not (f and g and f.type in ("cylinder", "sphere") and g.type in ("cylinder", "sphere")):
        return False
    if f.type == "sphere" and g.type == "sphere":
        return False  # (merge_same_surface's case)
    if abs(float(f.params["radius"]) - float(g.params["radius"])) > BAND_RADIUS_SLACK * tolerance:
        return False
    (pf, df), (pg, dg) = _centre(f), _centre(g)
    if df is not None and dg is not None:
        if abs(float(df @ dg)) > np.cos(BAND_AXIS_ANGLE):
            return False  # parallel axes: coaxial pieces are merge_same_surface's
        n = np.cross(df, dg)
        dist = abs(float((pg - pf) @ n)) / np.linalg.norm(n)
    else:
        c, (q, d) = (pf, (pg, dg)) if df is None else (pg, (pf, df))
        r = c - q
        dist = float(np.linalg.norm(r - (r @ d) * d))
    return dist <= BAND_CENTRE_SHARE * float(f.params["radius"])


def one_centre(fits) -> bool:
    """Whether the cylinders' axes and the spheres' centres of ``fits`` all pass within BAND_CENTRE_SHARE of the
    radius of one point (their least-squares meeting point): bands of one ball, not a chain of balls.

    Without it a filleted box's 12 fillets and 8 corners chain into one group by pairs (each corner is the ball
    of the three fillets at it), whose union was fitted for nothing: the 100k box's fit stage 0.8 → 5.6 s.
    """
    A, b = np.zeros((3, 3)), np.zeros(3)
    lines = []
    for f in fits:
        if f.type == "cylinder":
            p, d = np.asarray(f.params["axis_point"], float), unit(f.params["axis_dir"])
        else:
            p, d = np.asarray(f.params["center"], float), None
        proj = np.eye(3) if d is None else np.eye(3) - np.outer(d, d)
        A += proj
        b += proj @ p
        lines.append((p, proj))
    c = np.linalg.lstsq(A, b, rcond=None)[0]
    far = max(float(np.linalg.norm(proj @ (c - p))) for p, proj in lines)
    return far <= BAND_CENTRE_SHARE * float(np.median([float(f.params["radius"]) for f in fits]))
