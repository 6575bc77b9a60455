"""The main job: mesh → decomposition → fitted surfaces → curve network → B-rep solid → report.

Every stage is its own module; this one only chains them, times them and gathers the figures a user
judges a reconstruction by (faces by type, deviation from the mesh, validity, time per stage).
"""

from __future__ import annotations

import hashlib
import logging
import os
import time
from collections import Counter
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp

from threadpoolctl import threadpool_limits

from .decompose import Decomposition, decompose
from .decompose._regions import _unique_inverse, split_by_fitting
from .decompose._topology import unique
from .errors import BrepError, InputError, ReconError
from .fit import SurfaceFit, default_tolerance, fit_plane, fit_surface
from .fit._select import SIGMAS_PER_TOLERANCE
from .fit._surfaces import row_norms
from .mesh import Mesh, clean_mesh, load_mesh
from .mesh._topology import stable_argsort, unique_first

__all__ = ["Conversion", "convert", "face_labels", "STAGES"]

log = logging.getLogger(__name__)

#: The stages in the order they run; progress callbacks receive these names.
STAGES = ("load", "decompose", "fit", "brep", "deviation")

#: Surface types a merge may keep (a B-spline fits anything: merging on it would erase edges).
_ANALYTIC = ("plane", "sphere", "cylinder", "cone", "torus")
_CURVED = _ANALYTIC[1:]

#: A feature part whose area lies this much within tolerance of its neighbouring patches' surfaces is a sharp edge.
EXPLAINED_SHARE = 0.9

#: A part needs this many distinct vertices to carry a surface of its own (``fit_surface`` needs 16).
MIN_PART_VERTICES = 16

#: A part no surface fits is split into the analytic surfaces found inside it when they cover this share of
#: its area, each at least :data:`SPLIT_MIN_SHARE` of it.
SPLIT_COVER = 0.9
SPLIT_MIN_SHARE = 0.05

#: A B-spline face is cut back to one analytic surface grown inside it that covers this share of its area.
TRIM_COVER = 0.85
#: Seeds tried for it, deepest inside the face first (a region that covers 85 % of a face holds its middle).
TRIM_SEEDS = 3

#: A triangle lies on a face's surface when its vertices are within tolerance of it and its normal within this
#: angle of the surface's (the angle :func:`recon.decompose._regions.split_by_fitting` grows regions with; the
#: triangle normals of the σ = 0.2 % fixtures are off their true planes' by 7° median, 20° at the 99th percentile,
#: while a chamfer turns by 45°).
GROW_ANGLE_DEG = 30.0
#: Rounds of growing the faces over their boundaries, refitting them in between (Lloyd's alternation).
GROW_ROUNDS = 3

#: A smaller piece may still be a planar face of its own (a chamfer's corner triangle): it needs this many
#: vertices, the fewest a triangle subdivided once has (3 corners, 3 mid-edge points) — three points are
#: any plane, the other three are the evidence.
MIN_CORNER_VERTICES = 6
#: On a noise-free mesh the vertices are exact and a CAD export draws a rectangular face with 2 triangles: 4
#: vertices, 3 for the plane and 1 as evidence (a single triangle is any plane) ...
MIN_FLAT_VERTICES = 4
#: ... when its triangles are this many times the mesh's median triangle area on average. Measured: the small
#: flat pieces of dense noise-free meshes 0.2–1.4 (joint, casting: debris between curved faces, which kept as
#: faces took joint from 17 to 52 faces); a CAD export's two-triangle faces 4.4–22 (a plate's walls), 187 (the
#: ABC model's tab).
DRAWN_AREA_RATIO = 3.0
#: On a noise-free mesh an analytic surface misfits its face when its robust residual is above this share of the
#: tolerance (:func:`grow_faces`); a surface of the face's own type fits it to round-off.
EXACT_MISFIT = 0.05
#: ... when its vertices are exact: the median robust residual of its analytic faces is under this share of the tolerance.
EXACT_RESIDUAL = 0.001

Progress = Callable[[str, float], None]

#: Fits by (tolerance, triangle set) for the conversion running in this context. The fit stage fits the same
#: part several times over (to dissolve sharp features, after merging, for a small piece's neighbours), and
#: a fit depends on nothing but its triangles: each is made once.
_FIT_MEMO: ContextVar[dict | None] = ContextVar("recon_fit_memo", default=None)


@dataclass(frozen=True)
class Conversion:
    """Result of :func:`convert`.

    Attributes
    ----------
    shape : build123d Solid, Shell or Compound
        The B-rep: keep modelling on it in build123d, or ``cadquery.Shape.cast(shape.wrapped)``. Made on
        first use (``brep.shape``): the command line writes the STEP without importing build123d.
    report : dict
        Strict-JSON figures: faces by type, deviation, validity, time per stage, per-face records, and the
        ``verdict`` of the acceptance rules (:mod:`recon.verdict`).
    mesh : Mesh
    decomposition : Decomposition
    labels : (m,) int
        The face label of every cleaned triangle (the decomposition with sharp features dissolved).
    fits : dict of int → SurfaceFit
    brep : recon.brep.BrepResult
    """

    report: dict
    mesh: Mesh
    decomposition: Decomposition
    labels: np.ndarray
    fits: dict
    brep: Any
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def shape(self):
        return self.brep.shape

    @property
    def verdict(self):
        """The acceptance rules on this result (:class:`recon.verdict.Verdict`, from ``report["verdict"]``): judged
        on the shape in memory, and on the written file once :func:`recon.verdict.write_checked` wrote it."""
        from .verdict import Verdict

        return Verdict.from_json(self.report["verdict"])


def _faces_adjacency(mesh: Mesh) -> np.ndarray:
    return np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)


def _majority_neighbour(labels: np.ndarray, pairs: np.ndarray, movable: np.ndarray) -> np.ndarray:
    """For every triangle in ``movable``, the most frequent label among its non-movable neighbours (−1 if none)."""
    a, b = pairs[:, 0], pairs[:, 1]
    rows = np.concatenate([a, b])
    nbr = np.concatenate([labels[b], labels[a]])
    keep = movable[rows] & ~movable[np.concatenate([b, a])]
    rows, nbr = rows[keep], nbr[keep]
    out = np.full(len(labels), -1, dtype=np.int64)
    if len(rows) == 0:
        return out
    order = np.lexsort((nbr, rows))
    rows, nbr = rows[order], nbr[order]
    key_change = np.r_[True, (rows[1:] != rows[:-1]) | (nbr[1:] != nbr[:-1])]
    starts = np.flatnonzero(key_change)
    counts = np.diff(np.r_[starts, len(rows)])
    r, n = rows[starts], nbr[starts]
    best = np.lexsort((-counts, r))  # per row, highest count first
    r, n = r[best], n[best]
    first = np.r_[True, r[1:] != r[:-1]]
    out[r[first]] = n[first]
    return out


def _absorb(labels: np.ndarray, pairs: np.ndarray, movable: np.ndarray) -> np.ndarray:
    """Give every movable triangle the label of the region it touches most, growing inwards layer by layer."""
    labels = labels.copy()
    movable = movable.copy()
    while movable.any():
        nbr = _majority_neighbour(labels, pairs, movable)
        take = movable & (nbr >= 0)
        if not take.any():
            break  # an island of movable triangles touching nothing else: leave it as it is
        labels[take] = nbr[take]
        movable[take] = False
    return labels


def face_labels(mesh: Mesh, dec: Decomposition, *, tolerance: float) -> np.ndarray:
    """The label of the B-rep face every triangle will belong to.

    A sharp linear part or junction yields no face: its edge (or vertex) is where its neighbours' surfaces
    meet. A part counts as sharp when the decomposition says so, or when its neighbouring patches' fitted
    surfaces explain it: at least :data:`EXPLAINED_SHARE` of its area lies within ``tolerance`` of one of
    them (a strip that noise widened around a sharp edge; a true fillet bulges away from both faces by
    more than that). Each triangle of a sharp part goes to the patch whose surface passes closest to its
    centroid — the face it really lies on (for a junction, the patches next to its neighbours count too).
    Parts too small to carry a surface of their own (fewer than :data:`MIN_PART_VERTICES` vertices) join
    the part they touch most. A label whose triangles fell apart becomes one label per connected piece.
    Labels are renumbered 0..k−1 in order of first appearance, so they are deterministic.
    """
    labels = np.asarray(dec.labels, dtype=np.int64).copy()
    pairs = _faces_adjacency(mesh)
    parts = dec.parts
    is_patch = np.array([p.kind == "patch" for p in parts], dtype=bool)
    features = [p.id for p in parts if p.kind != "patch"]
    if features:
        candidates = {}
        for pid in features:
            near = {n for n in parts[pid].neighbours if is_patch[n]}
            if not near or parts[pid].kind == "junction":
                near |= {m for n in parts[pid].neighbours for m in parts[n].neighbours if is_patch[m]}
            candidates[pid] = sorted(near)
        wanted = sorted(set().union(*candidates.values()))
        patch_fits = _fit_parts(mesh, labels, tolerance=tolerance, only=wanted) if wanted else {}
        centroids = mesh.face_centroids
        areas = mesh.face_areas
        dissolved = []
        nverts = _vertex_counts(mesh.faces, labels)
        # On a noise-free mesh every triangle of a sharp edge's strip lies on one of the two faces: a part the
        # decomposition calls sharp that its neighbours do not explain, and that analytic surfaces cover, is
        # faces of its own (the ABC model's slots, four faces across a thin plate, went into the plate's faces
        # and no plane held them). One that nothing covers stays an edge: casting's kept 98 faces, out of
        # tolerance, and its B-rep came out open.
        noise_free = _noise_free()
        for pid in features:
            cands = [c for c in candidates[pid] if patch_fits[c].params]
            if not cands or (nverts[pid] < MIN_PART_VERTICES and not parts[pid].sharp):
                continue  # a piece too small to judge by its centroids is judged whole, by its vertices (`_tidy`)
            tris = np.flatnonzero(labels == pid)
            d = np.stack([np.abs(patch_fits[c].distance(centroids[tris])) for c in cands])
            nearest = d.min(axis=0)
            explained = areas[tris][nearest <= tolerance].sum() / max(areas[tris].sum(), 1e-300)
            if explained >= EXPLAINED_SHARE or parts[pid].sharp and not (noise_free and _covered(mesh, tris, tolerance)):
                labels[tris] = np.asarray(cands)[np.argmin(d, axis=0)]
                dissolved.append(pid)
        log.info("%d of %d feature parts are sharp: their triangles went to the patches", len(dissolved), len(features))
        labels = _absorb(labels, pairs, np.isin(labels, dissolved))
    return _tidy(mesh, labels, tolerance=tolerance)


def _covered(mesh: Mesh, tris: np.ndarray, tolerance: float) -> bool:
    """Whether one analytic surface fits the triangles ``tris`` within tolerance, or analytic regions grown
    inside them cover them as :func:`split_unfitted` would split them."""
    if _fit_parts(mesh, _one_label(len(mesh.faces), tris), tolerance=tolerance, only=[0], upto=_ANALYTIC[-1])[0].ok:
        return True
    total, found = _grown_inside(mesh, tris, tolerance=tolerance, min_share=SPLIT_MIN_SHARE)
    return len(found) >= 2 and sum(mesh.face_areas[r].sum() for r, _ in found) >= SPLIT_COVER * total


def _one_label(m: int, tris: np.ndarray) -> np.ndarray:
    """Labels of ``m`` triangles: 0 on ``tris``, 1 elsewhere."""
    lab = np.ones(m, dtype=np.int64)
    lab[tris] = 0
    return lab


def _tidy(mesh: Mesh, labels: np.ndarray, *, tolerance: float | None = None) -> np.ndarray:
    """One label per connected piece, pieces too small for a surface absorbed by the part they touch most,
    labels renumbered 0..k−1 in order of first appearance (deterministic).

    With ``tolerance``, small pieces that are planar faces of their own are kept (:func:`_small_faces`).
    """
    pairs = _faces_adjacency(mesh)
    kept = np.zeros(len(labels), dtype=bool)  # small faces `_small_faces` kept stay kept
    # A label that fell apart into several connected pieces is one face per piece; pieces too small to carry a
    # surface of their own join the part they touch most.
    for _ in range(4):
        labels = _split_disconnected(labels, pairs)
        nverts = _vertex_counts(mesh.faces, labels)
        small = (nverts[labels] < MIN_PART_VERTICES) & ~kept
        if tolerance is not None and small.any() and not small.all():
            new, small = _small_faces(mesh, labels, small, pairs, tolerance)
            kept |= new > labels.max()
            labels = new
        if not small.any() or small.all():
            break
        labels = _absorb(labels, pairs, small)
    uniq, first = unique_first(labels)  # np.unique(labels, return_index=True)
    order = np.argsort(first)
    remap = np.empty(labels.max() + 1, dtype=np.int64)
    remap[uniq[order]] = np.arange(len(order))
    return remap[labels]


def _vertices_of(F: np.ndarray, tris, n: int) -> np.ndarray:
    """``np.unique(F[tris])``: the sorted ids (of ``n`` vertices) of the triangles ``tris``. By a mask over the
    vertices when the corners are not few beside them (no sort: the fit stage asks this of large faces many times)."""
    idx = F[tris].ravel()
    if len(idx) * 32 < n:
        return np.unique(idx)
    mask = np.zeros(n, bool)
    mask[idx] = True
    return np.flatnonzero(mask)


def _vertex_sets(F: np.ndarray, labels: np.ndarray, n: int):
    """``lambda q: _vertices_of(F, labels == q, n)`` for every label at once: the distinct (label, vertex) pairs
    from one sort of their packed keys (a pass over the mesh per label costs more for more than a few)."""
    key = unique(np.repeat(labels, 3) * np.int64(n) + F.ravel())
    lab = key // n
    bounds = np.searchsorted(lab, np.arange(int(labels.max()) + 2))
    vert = key - lab * n
    return lambda q: vert[bounds[q] : bounds[q + 1]]


def merge_same_surface(mesh: Mesh, labels: np.ndarray, fits: dict, *, tolerance: float):
    """Merge neighbouring faces that one analytic surface covers within tolerance.

    The decomposition can leave a face in two pieces (a sliver patch beside its face, a face cut by a
    short feature); two analytic neighbours whose union one analytic surface fits are one face. The pieces
    need not have the type of the whole: a small piece of a cone fits a plane or a cylinder within tolerance
    (revolved noisy20's cone lay in cone, cylinder and plane pieces). A union that its surface holds only as a
    compromise — a robust residual above :data:`recon.fit._select.MISFIT_SCALE` × the noise, as
    :func:`grow_faces` judges a face — is two faces, not one: under noise a small piece that straddles two
    faces fits some surface within tolerance, and its union with another such piece does too (box_chamfer
    noisy20: a chamfer's plane piece and a cylinder across the chamfer and both its planes, σ̂ = 1.86 σ;
    revolved noisy20: two pieces across the cone and the cylinder above it, 1.43 σ), and the grown faces then
    keep that compromise. Pairs are tried largest shared boundary first; returns the new labels and the fits
    left (a merged face's fit is gone: fewer fits than given means something merged).
    """
    labels = labels.copy()
    fits = dict(fits)
    pairs = _faces_adjacency(mesh)
    for _ in range(len(fits)):
        a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
        diff = a != b
        if not diff.any():
            break
        key = np.sort(np.column_stack([a[diff], b[diff]]), axis=1)
        uniq, count = np.unique(key, axis=0, return_counts=True)
        merged = False
        for (p, q) in uniq[np.argsort(-count, kind="stable")].tolist():
            fp, fq = fits.get(p), fits.get(q)
            if not (fp and fq and fp.type in _ANALYTIC and fq.type in _ANALYTIC):
                continue
            members = np.flatnonzero((labels == p) | (labels == q))
            upto = fp.type if fp.type == fq.type else _ANALYTIC[-1]
            if fp.type != fq.type and not _probe_fits(mesh, members, tolerance, upto):
                continue
            fit = _fit_members(mesh, members, _memo_vertex_normals(mesh), tolerance, p, upto)
            if fit and fit.type not in (fp.type, fq.type) and _both_exact(mesh, labels, fits, p, q, tolerance):
                continue  # (see below)
            if fit and not _misfits(fit, mesh.vertices[_vertices_of(mesh.faces, members, len(mesh.vertices))]):
                labels[labels == q] = p
                fits[p] = fit
                del fits[q]
                merged = True
                break
        if not merged:
            break
    return labels, fits


def _both_exact(mesh: Mesh, labels: np.ndarray, fits: dict, p: int, q: int, tolerance: float) -> bool:
    """Whether faces ``p`` and ``q`` both fit their own surfaces to round-off on a mesh whose vertices are exact
    (a CAD export; :func:`grow_faces`' test). Their union then is two faces even where a third type holds it
    too: on the ABC model a fillet's cylinder strip and the plane strip beside it, long triangles whose
    vertices are on three circles, merged into a sphere of about the fillet's radius."""
    from .fit._select import _residual_scale

    if not _noise_free():
        return False
    V, F = mesh.vertices, mesh.faces
    own = [_residual_scale(fits[r], V[_vertices_of(F, labels == r, len(V))]) for r in (p, q)]
    return max(own) <= EXACT_MISFIT * tolerance and _exact_vertices(mesh, labels, fits, tolerance)


def _exact_vertices(mesh: Mesh, labels: np.ndarray, fits: dict, tolerance: float) -> bool:
    """Whether the mesh's vertices lie on their surfaces to round-off, as a CAD export's do: the median robust
    residual of its analytic faces is under :data:`EXACT_RESIDUAL` tolerances (:func:`grow_faces`' test)."""
    from .fit._select import _residual_scale

    if not _noise_free():
        return False
    V, F = mesh.vertices, mesh.faces
    scales = [_residual_scale(f, V[_vertices_of(F, labels == r, len(V))]) for r, f in fits.items()
              if f.ok and f.type in _ANALYTIC]
    return bool(scales) and float(np.median(scales)) <= EXACT_RESIDUAL * tolerance


#: Bands of one round surface (:func:`merge_round_bands`): cylinders (or a cylinder and a sphere) whose radii agree
#: within BAND_RADIUS_SLACK tolerances, whose axes are more than BAND_AXIS_ANGLE apart and pass within
#: BAND_CENTRE_SHARE of the radius of each other (of the sphere's centre). Crank's ball ends: radii 0.0516-0.0527
#: (0.3-0.9 tolerances apart), axes 48-52° apart and 0.3-2.7 tolerances from each other, the sphere's centre
#: 0.29-0.30 × the radius from the cylinders' axes.
BAND_RADIUS_SLACK = 2.0
BAND_CENTRE_SHARE = 0.35
BAND_AXIS_ANGLE = np.deg2rad(10.0)


def merge_round_bands(mesh: Mesh, labels: np.ndarray, fits: dict, *, tolerance: float) -> np.ndarray:
    """Merge neighbouring cylinder (and sphere) faces that are bands of one doubly curved surface into one face.

    A coarse tessellation of a round end (crank: two ball ends of radius 0.052 in long slivers) decomposes into
    bands that each fit a cylinder within tolerance, of one radius, their axes crossing at about 50°, and a
    sphere of that radius beside them: no analytic surface holds their union (a sphere: RMS 2×, max 5× the
    tolerance; :func:`merge_same_surface` tries the pieces' own type only), a B-spline does (max 0.29× and
    0.38×). Kept apart, the edges between them are where two cylinders cross, a wandering curve across bands
    0.02 wide, and the faces' boundaries crossed themselves on their surfaces (ShapeFix split them). Groups of
    three or more such faces are merged, only when the union's own fit (any type) is within tolerance.
    Returns ``labels`` itself when nothing merged.
    """
    def centre(f):
        if f.type == "cylinder":
            return np.asarray(f.params["axis_point"], float), np.asarray(f.params["axis_dir"], float)
        return np.asarray(f.params["center"], float), None

    def same_round(f, g):
        if not (f and g and f.type in ("cylinder", "sphere") and g.type in ("cylinder", "sphere")):
            return False
        if f.type == "sphere" and g.type == "sphere":
            return False  # (merge_same_surface's case)
        if abs(float(f.params["radius"]) - float(g.params["radius"])) > BAND_RADIUS_SLACK * tolerance:
            return False
        (pf, df), (pg, dg) = centre(f), centre(g)
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

    pairs = _faces_adjacency(mesh)
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    diff = a != b
    key = np.unique(np.sort(np.column_stack([a[diff], b[diff]]), axis=1), axis=0)
    parent = {}

    def root(x):
        while parent.get(x, x) != x:
            x = parent[x]
        return x

    for p, q in key.tolist():
        if same_round(fits.get(p), fits.get(q)):
            parent[root(q)] = root(p)
    groups: dict[int, list[int]] = {}
    for x in list(parent):
        groups.setdefault(root(x), []).append(x)
    out = labels
    vn = _memo_vertex_normals(mesh)
    for r, members in groups.items():
        members = sorted(set(members) | {r})
        if len(members) < 3:
            continue  # two bands: a fillet's cylinder and its neighbour cross at an angle too
        if not _one_centre([fits[k] for k in members]):
            continue  # bands of several balls, chained (a filleted box's fillets and corners: its whole frame)
        tris = np.flatnonzero(np.isin(labels, members))
        fit = _fit_members(mesh, tris, vn, tolerance, members[0], None)
        if not fit:
            continue
        if out is labels:
            out = labels.copy()
        out[tris] = members[0]
        log.info("faces %s: bands of one round surface, merged (%s)", members, fit.type)
    return out


def _one_centre(fits) -> bool:
    """Whether the cylinders' axes and the spheres' centres of ``fits`` all pass within BAND_CENTRE_SHARE of the
    radius of one point (their least-squares meeting point): bands of one ball, not a chain of balls.

    Without it a filleted box's 12 fillets and 8 corners chain into one group by pairs (each corner is the ball
    of the three fillets at it), whose union was fitted for nothing: the 100k box's fit stage 0.8 → 5.6 s.
    """
    A, b = np.zeros((3, 3)), np.zeros(3)
    lines = []
    for f in fits:
        if f.type == "cylinder":
            p, d = np.asarray(f.params["axis_point"], float), _unit_vec(f.params["axis_dir"])
        else:
            p, d = np.asarray(f.params["center"], float), None
        proj = np.eye(3) if d is None else np.eye(3) - np.outer(d, d)
        A += proj
        b += proj @ p
        lines.append((p, proj))
    c = np.linalg.lstsq(A, b, rcond=None)[0]
    far = max(float(np.linalg.norm(proj @ (c - p))) for p, proj in lines)
    return far <= BAND_CENTRE_SHARE * float(np.median([float(f.params["radius"]) for f in fits]))


def _unit_vec(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _misfits(fit: SurfaceFit, pts: np.ndarray) -> bool:
    """Whether ``fit`` is a compromise on the points ``pts``: their robust residual scale is above
    :data:`recon.fit._select.MISFIT_SCALE` × the noise (never on a noise-free mesh, where the residuals are the
    tessellation's)."""
    from .fit._select import MISFIT_SCALE, _residual_scale

    memo = _FIT_MEMO.get()
    noise = memo.get("noise") if memo is not None else None
    return noise is not None and _residual_scale(fit, pts) > MISFIT_SCALE * noise


#: A closed form is a little off a noisy region's best fit: the probe lets it be this many tolerances off.
PROBE_SLACK = 2.0
#: Points of the union the probe looks at, at most (every k-th vertex).
PROBE_POINTS = 2000


def _probe_fits(mesh: Mesh, tris: np.ndarray, tolerance: float, upto: str) -> bool:
    """Whether some analytic type up to ``upto`` may fit the triangles ``tris``: its closed form (the
    decomposition's, from points and normals) lies within :data:`PROBE_SLACK` tolerances. Fitting every pair of
    faces of different types in full took the 100k box's fit stage from 0.5 to 4.7 s."""
    from .decompose._quickfit import quick_fit

    memo = _FIT_MEMO.get()
    # merge_same_surface starts over after every merge and probes the same pairs again
    key = ("probe", float(tolerance), upto, hashlib.sha1(np.asarray(tris, dtype=np.int64).tobytes()).digest())
    if memo is not None and key in memo:
        return memo[key]
    ids = _vertices_of(mesh.faces, tris, len(mesh.vertices))
    vn = _memo_vertex_normals(mesh)
    ids = ids[:: max(1, len(ids) // PROBE_POINTS)]  # a closed form needs no more points to be judged
    pts, nrm = mesh.vertices[ids], vn[ids]
    kinds = _ANALYTIC[: _ANALYTIC.index(upto) + 1]
    fits = any(quick_fit(kind, pts, nrm, PROBE_SLACK * tolerance, refine=False) is not None for kind in kinds)
    if memo is not None:
        memo[key] = fits
    return fits


def _grown_inside(mesh: Mesh, tris: np.ndarray, *, tolerance: float, min_share: float, max_seeds=None,
                  types=_ANALYTIC):
    """(area of the face ``tris``, the analytic regions grown inside it that reach ``min_share`` of it).

    No regions for a face under twice :data:`MIN_PART_VERTICES` vertices: too small to hold two surfaces.
    """
    V, F = mesh.vertices, mesh.faces
    total = float(mesh.face_areas[tris].sum())
    if len(_vertices_of(F, tris, len(V))) < 2 * MIN_PART_VERTICES:
        return total, []
    memo = _FIT_MEMO.get()
    # The fit stage asks again for every face each round (trim, grow, trim ...), and most faces have not
    # changed: the regions depend on nothing but the triangles and these arguments (rocker-arm2500: 29 of
    # the fit stage's 57 s went to asking again).
    key = ("grown inside", float(tolerance), float(min_share), max_seeds, tuple(types),
           hashlib.sha1(np.asarray(tris, dtype=np.int64).tobytes()).digest())
    if memo is not None and key in memo:
        return total, memo[key]
    found = split_by_fitting(V, F, tris, vnormal=_memo_vertex_normals(mesh), tolerance=tolerance,
                             min_area=min_share * total, max_seeds=max_seeds, types=types)
    if memo is not None:
        memo[key] = found
    return total, found


def split_unfitted(mesh: Mesh, labels: np.ndarray, fits: dict, *, tolerance: float) -> np.ndarray:
    """Labels with every part no surface fits split into the analytic surfaces inside it, where they cover it.

    The decomposition can leave several faces in one part: a ring of fillets meeting at a pocket's sharp
    corners is one linear part (the skeleton has no junction there), and no one surface fits it. Regions
    grown from seeds inside such a part (:func:`recon.decompose._regions.split_by_fitting`) that together
    cover :data:`SPLIT_COVER` of its area become faces of their own; the few triangles between them join
    the region they touch most. The split is kept only if every piece then fits its surface within
    tolerance. Returns ``labels`` itself when nothing was split.

    On a noise-free mesh a B-spline face is split the same way: there a B-spline holds almost any set of
    triangles within tolerance, four faces of a slot included (the ABC model), and analytic surfaces that
    cover it are the faces that were drawn.
    """
    pairs = _faces_adjacency(mesh)
    area = mesh.face_areas
    out = labels
    noise_free = _noise_free()
    exact = None  # (whether the vertices are exact: asked once, when a B-spline face has regions in it)
    for p, fit in sorted(fits.items()):
        if fit.ok and not (noise_free and fit.type == "bspline"):
            continue
        tris = np.flatnonzero(labels == p)
        total, found = _grown_inside(mesh, tris, tolerance=tolerance, min_share=SPLIT_MIN_SHARE)
        if noise_free and fit.type == "bspline" and found and exact is None:
            exact = _exact_vertices(mesh, labels, fits, tolerance)
        if exact and fit.type == "bspline" and found:
            found = found + _exact_strips(mesh, tris, found, pairs, tolerance)
        if len(found) < 2 or sum(area[r].sum() for r, _ in found) < SPLIT_COVER * total:
            continue
        trial = out.copy()
        base = int(trial.max()) + 1
        trial[tris] = -1
        for i, (r, _) in enumerate(found):
            trial[r] = base + i
        inside = np.isin(pairs[:, 0], tris) & np.isin(pairs[:, 1], tris)
        trial = _absorb(trial, pairs[inside], trial == -1)
        if (trial == -1).any():
            continue
        new = list(range(base, base + len(found)))
        pieces = _fit_parts(mesh, trial, tolerance=tolerance, only=new)
        # (on a noise-free mesh a piece within tolerance, its edges included, is a face even as a B-spline:
        # the ABC model's thin shim edge, four arcs, fits nothing whole)
        if not all(pieces[q].ok and (pieces[q].type in _ANALYTIC or noise_free and not fit.ok) for q in new):
            continue
        log.info("part %d fits no surface: split into %d (%s)", p, len(new), ", ".join(pieces[q].type for q in new))
        out = trial
    return out


def _exact_strips(mesh: Mesh, tris: np.ndarray, found: list, pairs: np.ndarray, tolerance: float) -> list:
    """On a mesh with exact vertices: the faces left in a B-spline face beside the regions ``found`` in it, where these are
    strips too thin for regions to grow in (the ABC model: a plane, then a fillet and a plane each one or two long
    triangles wide, 6 % and 0.7 % of the area). Coplanar pieces of at least :data:`MIN_PART_VERTICES` vertices are
    planes; each connected remainder of as many vertices is one surface if an analytic type fits it within
    tolerance. ``[(faces, fit)]``, or ``[]`` unless every remainder that large fits.
    """
    V, F = mesh.vertices, mesh.faces
    rest = np.setdiff1d(tris, np.concatenate([r for r, _ in found]))
    if not len(rest):
        return []
    big = lambda g: len(_vertices_of(F, g, len(V))) >= MIN_PART_VERTICES  # noqa: E731
    # (neighbours within tolerance of each other's plane chain round a finely cut fillet too: a plane must hold it)
    out = [(g, fit_plane(V[_vertices_of(F, g, len(V))], tolerance=tolerance))
           for g in _coplanar_pieces(V, F, rest, pairs, tolerance) if big(g)]
    out = [(g, s) for g, s in out if s.ok]
    flats = [g for g, _ in out]
    others = np.setdiff1d(rest, np.concatenate(flats)) if flats else rest
    if len(others):
        inside = np.isin(pairs[:, 0], others) & np.isin(pairs[:, 1], others)
        local = np.full(len(F), -1, dtype=np.int64)
        local[others] = np.arange(len(others))
        a, b = local[pairs[inside, 0]], local[pairs[inside, 1]]
        _, comp = sp.csgraph.connected_components(
            sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(len(others),) * 2), directed=False)
        vn = _memo_vertex_normals(mesh)
        for c in np.unique(comp):
            g = others[comp == c]
            if not big(g):
                continue  # (a few triangles: they join the region they touch most)
            surface = _fit_members(mesh, g, vn, tolerance, -1, _ANALYTIC[-1])
            if not (surface and surface.ok and surface.type in _ANALYTIC):
                return []
            out.append((g, surface))
    return out


def trim_to_surface(mesh: Mesh, labels: np.ndarray, fits: dict, *, tolerance: float) -> np.ndarray:
    """Labels with every B-spline (or unfitted) face that is mostly one analytic surface cut back to it, and
    every curved face that is mostly a plane cut back to the plane.

    Under noise a face can take in slivers of its neighbours (a chamfer's edge on a large plane): one plane
    no longer fits it, a B-spline does, and the plane becomes a free-form face — or a curved surface bends
    to take the slivers in within tolerance (box_chamfer noisy20: chamfers and a box face as cones and
    cylinders). When one analytic region grown inside the face (for a curved face, a plane region;
    :func:`recon.decompose._regions.split_by_fitting`) covers :data:`TRIM_COVER` of its area, the rest goes
    to the neighbouring face whose surface passes nearest; the trim is kept only if the face then fits an
    analytic surface (for a curved face, a plane) and every face that received triangles still fits its own
    type within tolerance. A piece of the rest that is a planar face of its own (:func:`_planar_pieces`: a
    chamfered box's corner triangle on the end of a chamfer, box_chamfer noisy20) becomes a face instead.
    Returns ``labels`` itself when nothing was trimmed.
    """
    pairs = _faces_adjacency(mesh)
    out = labels
    for p, fit in sorted(fits.items()):
        # a free-form face may be cut back to any analytic surface, a curved one to a plane
        simpler = _ANALYTIC if not fit.ok or fit.type == "bspline" else ("plane",) if fit.type != "plane" else ()
        if not simpler:
            continue
        tris = np.flatnonzero(out == p)
        _, found = _grown_inside(mesh, tris, tolerance=tolerance, min_share=TRIM_COVER, max_seeds=TRIM_SEEDS,
                                 types=simpler)
        if not found:
            continue
        region = found[0][0]
        rest = np.setdiff1d(tris, region)
        # the rest goes to the neighbouring face whose surface passes nearest to it
        in_rest = np.isin(pairs, rest)
        across = in_rest[:, 0] ^ in_rest[:, 1]
        outer = np.where(in_rest[across, 0], pairs[across, 1], pairs[across, 0])
        cands = [int(q) for q in np.unique(out[outer]) if q != p and fits.get(int(q)) and fits[int(q)].params]
        if not cands:  # no neighbour within tolerance to give it to: it may be a face of its own
            across = _rest_across_misfits(mesh, out, p, rest, fits, pairs, tolerance, simpler)
            if across is not None:
                log.info("face %d was a %s: cut back to its analytic surface, the rest a face of its own with "
                         "%d triangles of faces out of tolerance", p, fit.type, int((across != out).sum()) - len(rest))
                out = across
            continue
        trial = out.copy()
        # a planar piece of the rest that no neighbouring surface holds is a face of its own (a chamfered box's
        # corner triangle on the end of a chamfer): given to a neighbour, it would bend that one off its surface
        corners = _planar_pieces(mesh, rest, pairs, [fits[q] for q in cands] + [found[0][1]], tolerance)
        for piece in corners:
            trial[piece] = trial.max() + 1
        rest = np.setdiff1d(rest, np.concatenate(corners)) if corners else rest
        if len(rest):
            d = np.stack([np.abs(fits[q].distance(mesh.face_centroids[rest])) for q in cands])
            trial[rest] = np.asarray(cands)[np.argmin(d, axis=0)]
        receivers = sorted(set(trial[rest].tolist()))
        new = _fit_parts(mesh, trial, tolerance=tolerance, only=[p], upto=_ANALYTIC[-1])
        if not new[p].ok or new[p].type not in simpler:
            continue
        new.update(_receivers_fits(mesh, trial, receivers, fits, tolerance))
        if not all(new[q].ok and new[q].type == fits[q].type for q in receivers):
            # the slivers given back must not change what their face is (box_fillet noisy20: a fillet's
            # cylinder became a cone, whose face then failed and cost 2 % of the volume) — but the rest may be
            # a face of its own that a neighbour out of tolerance holds the other half of
            across = _rest_across_misfits(mesh, out, p, rest, fits, pairs, tolerance, simpler)
            if across is not None:
                log.info("face %d was a %s: cut back to a %s, the rest a face of its own with %d triangles of "
                         "faces out of tolerance", p, fit.type, new[p].type, int((across != out).sum()) - len(rest))
                out = across
            continue
        log.info("face %d was a %s: cut back to a %s, %d triangles to %d neighbours, %d planar pieces kept as faces",
                 p, fit.type, new[p].type, len(rest), len(receivers), len(corners))
        out = trial
    return out


def _receivers_fits(mesh: Mesh, labels: np.ndarray, receivers: list, fits: dict, tolerance: float) -> dict:
    """The surfaces of the faces ``receivers`` under ``labels``, for the test whether each still fits its type of
    ``fits`` within tolerance: an analytic one by the analytic types alone (:func:`_fit_parts` ``upto`` the last).

    The test's answer is the full fit's: the analytic types are tried the same way, and the full fit only goes on
    to a B-spline where none of them fits, which fails the test all the same. A trial the test refuses then costs
    no B-spline, and one it accepts costs no second fit (:func:`_fit_members` takes the full fit from this one).
    """
    analytic = [q for q in receivers if fits[q].type in _ANALYTIC]
    out = _fit_parts(mesh, labels, tolerance=tolerance, only=analytic, upto=_ANALYTIC[-1]) if analytic else {}
    rest = [q for q in receivers if fits[q].type not in _ANALYTIC]
    if rest:
        out.update(_fit_parts(mesh, labels, tolerance=tolerance, only=rest))
    return out


def _rest_across_misfits(mesh: Mesh, labels: np.ndarray, p: int, rest: np.ndarray, fits: dict, pairs: np.ndarray,
                         tolerance: float, simpler=_ANALYTIC):
    """Labels with the rest of face ``p`` (what :func:`trim_to_surface` cuts off it) made a face of its own
    together with the triangles of neighbouring faces out of tolerance that lie on the same analytic surface,
    or None.

    On a CAD tessellation of long slivers a face can lie in two parts whose slivers alternate: crank's web side
    (a plane) is 8 slivers of the face beside it (patch_83, a plane but for them: a B-spline 1.25× out of
    tolerance) and 12 of another (patch_89, a torus 1.6× out). Neither keeps them within tolerance and neither
    can take the other's, so trimming gave up. The rest's own surface (fitted to it alone) is grown over the
    triangles of the faces around it that are out of tolerance, ring by ring, while they lie on it (vertices
    within ``tolerance``, normals within :data:`GROW_ANGLE_DEG`). Kept only when the new face has a surface's
    worth of vertices (:data:`MIN_PART_VERTICES`) and fits an analytic surface within tolerance, face ``p``
    without it fits one of the types ``simpler`` within tolerance, and every face that gave triangles fits
    within tolerance without them: every face involved ends within tolerance where two did not.
    """
    from .decompose._quickfit import surface_normals

    V, F = mesh.vertices, mesh.faces
    own = _fit_members(mesh, np.sort(rest), _memo_vertex_normals(mesh), tolerance, p, _ANALYTIC[-1])
    if not own.ok or not own.params:
        return None
    misfit = [int(q) for q, f in fits.items() if q != p and not f.ok]
    if not misfit:
        return None
    cos_min = np.cos(np.deg2rad(GROW_ANGLE_DEG))
    cand = np.flatnonzero(np.isin(labels, misfit))
    d = np.abs(own.distance(V[F[cand]].reshape(-1, 3))).reshape(-1, 3).max(axis=1)
    n = surface_normals(own, mesh.face_centroids[cand])
    lies = np.zeros(len(labels), dtype=bool)
    lies[cand[(d <= tolerance) & (np.abs(np.einsum("ij,ij->i", n, mesh.face_normals[cand])) >= cos_min)]] = True
    face = np.zeros(len(labels), dtype=bool)
    face[rest] = True
    while True:  # ring by ring over the triangles that lie on the rest's surface
        a, b = face[pairs[:, 0]], face[pairs[:, 1]]
        nxt = np.concatenate([pairs[a & ~b & lies[pairs[:, 1]], 1], pairs[b & ~a & lies[pairs[:, 0]], 0]])
        if not len(nxt):
            break
        face[nxt] = True
    taken = np.flatnonzero(face & (labels != p))
    if not len(taken):
        return None
    tris = np.flatnonzero(face)
    if len(np.unique(F[tris])) < MIN_PART_VERTICES:
        return None
    trial = labels.copy()
    new = int(labels.max()) + 1
    trial[tris] = new
    givers = sorted(set(labels[taken].tolist()))
    got = _fit_parts(mesh, trial, tolerance=tolerance, only=[p, new], upto=_ANALYTIC[-1])
    if not (got[p].ok and got[p].type in simpler and got[new].ok):
        return None
    got = _fit_parts(mesh, trial, tolerance=tolerance, only=givers)
    if not all(got[q].ok for q in givers):
        return None
    return trial


def _planar_pieces(mesh: Mesh, tris: np.ndarray, pairs: np.ndarray, surfaces, tolerance: float) -> list:
    """The connected pieces of the triangles ``tris`` that are planar faces of their own: a plane holds their
    vertices (at least :data:`MIN_CORNER_VERTICES`, fewer than :data:`MIN_PART_VERTICES`: a piece any larger is a
    face the fit stage judges whole) within ``tolerance``, and each of ``surfaces`` (the fits around them) leaves
    some vertex farther than ``tolerance`` away — the test :func:`_small_faces` keeps a small piece by."""
    V, F = mesh.vertices, mesh.faces
    if len(_vertices_of(F, tris, len(V))) < MIN_CORNER_VERTICES or any(s.type in _CURVED for s in surfaces):
        return []  # next to a curved face a small flat piece is what is left of a blend (`_small_faces`)
    inside = np.isin(pairs[:, 0], tris) & np.isin(pairs[:, 1], tris)
    local = np.full(len(F), -1, dtype=np.int64)
    local[tris] = np.arange(len(tris))
    a, b = local[pairs[inside, 0]], local[pairs[inside, 1]]
    graph = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(len(tris), len(tris)))
    _, comp = sp.csgraph.connected_components(graph, directed=False)
    out = []
    for c in np.unique(comp):
        piece = tris[comp == c]
        ids = _vertices_of(F, piece, len(V))
        if not MIN_CORNER_VERTICES <= len(ids) < MIN_PART_VERTICES:
            continue
        plane = fit_plane(V[ids])
        if np.abs(plane.distance(V[ids])).max() > tolerance:
            continue
        if any(s.params and np.abs(s.distance(V[ids])).max() <= tolerance for s in surfaces):
            continue
        out.append(piece)
    return out


def grow_faces(mesh: Mesh, labels: np.ndarray, fits: dict, *, tolerance: float, dissolve: bool = False,
               givers=None) -> np.ndarray:
    """Labels with boundary triangles moved to the neighbouring face whose analytic surface they lie on.

    The decomposition draws its parts' borders before any face is fitted whole, and under noise it draws them
    badly: a part can hold strips of its neighbours (a chamfer with strips of both planes, which a cylinder
    then covers within tolerance), and a face can lie in pieces (revolved noisy20's cone over eleven parts).
    With every face fitted, a triangle *lies on* a face's analytic surface when its vertices are within
    ``tolerance`` of it and its normal within :data:`GROW_ANGLE_DEG` of the surface's. A boundary triangle
    moves to a neighbouring face it lies on

    - when it does not lie on its own face's surface, or its own face has no analytic one (a B-spline is the
      fallback: an analytic surface that holds the triangle is the simpler explanation);
    - when its own face's surface *misfits* — a robust residual above :data:`recon.fit._select.MISFIT_SCALE`
      × the noise, the mark of a compromise such as the chamfer's cylinder — and the neighbour's surface
      passes closer.

    A surface that fits at the noise level keeps what it holds: near a tangent seam a neighbour's extension
    holds a face's rim as closely as the noise allows (box_fillet noisy20: the fillets' cylinders took the
    corner spheres whole). Moves are made ring by ring over the new borders with the surfaces fixed; a
    triangle only moves to a surface that holds it closer than where it was, so it ends. A face is taken
    whole or left with enough vertices for a surface (:data:`MIN_PART_VERTICES`) — or as a planar face of its own
    that no surface around it holds (:func:`_planar_pieces`: a corner triangle a compromise cylinder over it and
    a piece of a chamfer leaves when it gives the chamfer back) — and a face that received
    triangles must still fit its own type within tolerance, or it gets none. Returns ``labels`` itself when
    nothing moved.

    With ``dissolve``, only the faces every triangle of which lies on a neighbouring face's surface give
    triangles away, whatever their own surface: such a face is pieces of its neighbours that a surface of its
    own also holds within the noise (revolved noisy20: cone pieces with a rim of the cylinder below, whose own
    cones fit them at 1.1-1.4 σ, which no merge can take in: their union with the cone or the cylinder fits
    neither). They receive none.

    With ``givers`` (faces no surface fits, from :func:`dissolve_misfits`), only those faces give triangles
    away, and each goes whole — but for debris under :data:`MIN_PART_VERTICES` vertices, which :func:`_tidy`
    places — or not at all.
    """
    from .decompose._quickfit import surface_normals
    from .fit._select import MISFIT_SCALE, _residual_scale

    V, F = mesh.vertices, mesh.faces
    pairs = _faces_adjacency(mesh)
    cos_min = np.cos(np.deg2rad(GROW_ANGLE_DEG))
    analytic = np.array(sorted(q for q, f in fits.items() if f.ok and f.type in _ANALYTIC), dtype=np.int64)
    memo = _FIT_MEMO.get()
    noise = memo.get("noise") if memo is not None else None  # None: a noise-free mesh, where no surface misfits
    ids = _vertex_sets(F, labels, len(V))
    scales = {q: _residual_scale(fits[q], V[ids(q)]) for q in analytic.tolist()}
    exact = False
    if noise is not None:
        misfits = {q: s > MISFIT_SCALE * noise for q, s in scales.items()}
    else:
        # a noise-free mesh whose vertices are exact (a CAD export: most analytic faces fit to round-off) — not
        # every mesh without noise has them (a remeshed model's lie a share of the tolerance off) — shows a
        # compromise over pieces of several faces by a residual that is a share of the tolerance
        exact = bool(scales) and float(np.median(list(scales.values()))) <= EXACT_RESIDUAL * tolerance
        misfits = {q: exact and s > EXACT_MISFIT * tolerance for q, s in scales.items()}
        log.debug("grow_faces: median residual %.3g tolerances (exact vertices: %s)",
                  float(np.median(list(scales.values()))) / tolerance if scales else float("nan"), exact)

    def on(q, tris, slack=0.0):  # each triangle's largest vertex distance to face q's surface; inf if it does not
        # lie on it (with ``slack``, by a test that much looser: a relative margin over the round-off)
        d = np.abs(fits[q].distance(V[F[tris]].reshape(-1, 3))).reshape(-1, 3)
        d = np.maximum(np.maximum(d[:, 0], d[:, 1]), d[:, 2])  # d.max(axis=1), without the reduction's setup
        n = surface_normals(fits[q], mesh.face_centroids[tris])
        cos = np.abs(np.einsum("ij,ij->i", n, mesh.face_normals[tris]))
        lies = (d <= tolerance * (1.0 + slack)) & (cos >= cos_min - slack)
        return np.where(lies, d, np.inf)

    explained = _explained_faces(labels, analytic, pairs, on) if dissolve else np.zeros(0, dtype=np.int64)
    if dissolve and not len(explained):
        return labels
    receiving = np.setdiff1d(analytic, explained)
    only_from = explained if dissolve else None if givers is None else np.asarray(sorted(givers), dtype=np.int64)
    misfit_givers = set() if givers is None else {int(g) for g in givers}
    out = labels.copy()
    # A candidate move depends on nothing but the labels of its two triangles, with the surfaces fixed: after
    # the first ring, only pairs with a triangle that just moved can offer one (crank: the first round went
    # from 40 s to ... with this, the same moves).
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
            here[own == p] = d if misfits[p] else np.where(np.isfinite(d), -1.0, np.inf)
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
    moved = out != labels
    # a remnant too small for a surface would go to the face it touches most (`_tidy`), which need not hold it
    # (box_chamfer noisy20 without this: 15 faces for 26, where the chamfers' remnants went to the planes)
    # — unless the remnant is a planar face of its own that no neighbour holds (a chamfered box's corner left
    # when a compromise surface over it and a piece of a chamfer gives the chamfer back): `_tidy` keeps it
    for p in np.unique(labels[moved]):
        rest = np.flatnonzero(out == p)
        if int(p) in misfit_givers:
            # a face no surface fits goes whole, but for debris too small for a surface (which `_tidy` places), or
            # stays whole: a larger remnant may still get a face on its own poor surface, and a piece of it may not
            # (rocker-arm: a B-spline face 2.8x out built, its remnant after giving 174 triangles away did not)
            if len(_vertices_of(F, rest, len(V))) >= MIN_PART_VERTICES:
                out[moved & (labels == p)] = p
            continue
        if len(rest) and len(_vertices_of(F, rest, len(V))) < MIN_PART_VERTICES:
            in_rest = np.isin(pairs, rest)
            across = in_rest[:, 0] ^ in_rest[:, 1]
            around = np.unique(out[np.where(in_rest[across, 0], pairs[across, 1], pairs[across, 0])])
            pieces = _planar_pieces(mesh, rest, pairs, [fits[q] for q in around.tolist() if q in fits], tolerance)
            if exact and not pieces and _drawn_flat(mesh)(rest) and len(_vertices_of(F, rest, len(V))) >= \
                    MIN_FLAT_VERTICES and np.abs(fit_plane(V[_vertices_of(F, rest, len(V))]).distance(
                        V[_vertices_of(F, rest, len(V))])).max() <= tolerance:
                pieces = [rest]  # a face a CAD export drew flat with a few large triangles (`_small_faces` keeps it)
            if sum(len(c) for c in pieces) < len(rest):
                out[moved & (labels == p)] = p
    moved = out != labels
    if not moved.any():
        return labels
    receivers = sorted(set(out[moved].tolist()))
    new = _receivers_fits(mesh, out, receivers, fits, tolerance)
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


def dissolve_misfits(mesh: Mesh, labels: np.ndarray, fits: dict, *, tolerance: float) -> np.ndarray:
    """Labels with every face that no surface fits by far given to the surfaces around and inside it.

    A face whose best surface leaves its points farther than :data:`recon.fit._types.ACCEPT_MAX_FACTOR` ×
    ``tolerance`` on average (RMS: farther than any accepted fit's largest deviation) is not a face a designer
    drew but a decomposition failure: on a CAD tessellation of long slivers, a fan of triangles that alternate
    with a neighbour's (crank: a flat bottom with eight teeth of the wall beside it, a torus 30× out of
    tolerance; a strip of slivers between two tori, a B-spline 190× out). On crank no face was built on such a
    surface (the filling failed as well), and the shell had a hole there. So

    - its triangles move, ring by ring, to the neighbouring faces whose analytic surfaces they lie on
      (:func:`grow_faces` with these faces as the only givers; a receiver must still fit its own type), when
      that leaves of it nothing but debris too small for a surface (under :data:`MIN_PART_VERTICES` vertices,
      which :func:`_tidy` absorbs). ``grow_faces`` would keep such debris and with it the whole face; a larger
      remnant is kept whole instead: a face on its own poor surface may still build where a piece of it fails;
    - when one analytic region grown inside it covers :data:`TRIM_COVER` of its area (as
      :func:`trim_to_surface` cuts back a face) and what is left beside it after the moves is too small for a
      face of its own (fewer than :data:`MIN_PART_VERTICES` vertices: debris), that region is the face.

    A face that fits no surface because it is coarse (a few large triangles across a curved face: the coarse
    fixtures) has no neighbour that holds its triangles and no debris beside one surface, and stays as it is.

    Returns ``labels`` itself when no face is that far out or nothing changed.
    """
    from .fit._types import ACCEPT_MAX_FACTOR

    far = sorted(p for p, f in fits.items()
                 if not f.ok and np.isfinite(f.deviation["rms"]) and f.deviation["rms"] > ACCEPT_MAX_FACTOR * tolerance)
    if not far:
        return labels
    out = labels.copy()
    fits = dict(fits)
    kept = {}
    for p in far:
        tris = np.flatnonzero(labels == p)
        _, found = _grown_inside(mesh, tris, tolerance=tolerance, min_share=TRIM_COVER, max_seeds=TRIM_SEEDS)
        if found:
            q = int(out.max()) + 1
            out[found[0][0]] = q
            new = _fit_parts(mesh, out, tolerance=tolerance, only=[q])[q]
            if new.ok and new.type in _ANALYTIC:
                fits[q] = new
                kept[q] = p
            else:
                out[out == q] = p
    grown = grow_faces(mesh, out, fits, tolerance=tolerance, givers=far)
    for q, p in list(kept.items()):
        # the surface inside is the face only when what is left beside it is debris too small for a face of its
        # own (crank: a flat bottom and eight teeth of the wall); a larger rest would be a face no surface fits
        rest = np.flatnonzero(grown == p)
        if len(rest) and len(_vertices_of(mesh.faces, rest, len(mesh.vertices))) >= MIN_PART_VERTICES:
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


def _explained_faces(labels: np.ndarray, analytic: np.ndarray, pairs: np.ndarray, on) -> np.ndarray:
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


#: Triangles of a face :func:`_maybe_held` looks at first, at most (an even subset).
HELD_SAMPLE = 64
#: ... and the slack of its test, relative: far above round-off, far below any real margin.
HELD_SLACK = 1e-9


def _maybe_held(tris: np.ndarray, around: list, on) -> bool:
    """False when some triangle of an even sample of ``tris`` surely lies on none of the faces ``around`` (``on``
    with :data:`HELD_SLACK`): the face is then not explained, whatever its other triangles do. A large face is
    mostly its own surface; this spares testing all its triangles against every neighbour (the 100k box: 0.07 s)."""
    if len(tris) <= HELD_SAMPLE:
        return True
    sample = tris[:: -(-len(tris) // HELD_SAMPLE)]
    held = np.zeros(len(sample), dtype=bool)
    for q in around:
        held[~held] = np.isfinite(on(q, sample[~held], HELD_SLACK))
        if held.all():
            return True
    return False


def _cut_unbounded(mesh: Mesh, labels: np.ndarray, *, tolerance: float | None = None) -> np.ndarray:
    """Labels with every closed body that one label covers cut in two (``labels`` itself if there is none).

    A face needs a boundary, and a closed body covered by one smooth part (a sphere, an ellipsoid, a coarse
    free-form part) has none: no edge bounds it, and the B-rep has nothing to build on. Cutting the body by
    the plane through its centroid across its longest principal axis gives two parts sharing one loop, the
    least a closed surface needs (OpenCascade's own sphere has a seam); each half is fitted like any part.
    """
    pairs = _faces_adjacency(mesh)
    body = _split_disconnected(np.zeros(len(labels), dtype=np.int64), pairs)
    out = labels
    if np.any(mesh.edge_face_count == 1):  # an open mesh: its boundary bounds its faces
        return labels
    for b in np.unique(body):
        tris = np.flatnonzero(body == b)
        if len(np.unique(labels[tris])) > 1:
            continue
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
    return out if out is labels else _tidy(mesh, out, tolerance=tolerance)


def _small_faces(mesh: Mesh, labels: np.ndarray, small: np.ndarray, pairs: np.ndarray, tolerance: float):
    """Keep the clusters of small pieces that are planar faces no neighbour's surface explains.

    A chamfered box's corner is a small triangle between three chamfers, often split by the decomposition
    into a junction and terminals of a triangle or two each. Joined to a chamfer it bends that chamfer off
    its plane, and the chamfer becomes a B-spline. So a connected cluster of small pieces becomes one face
    of its own when a plane holds its vertices within ``tolerance`` (at least :data:`MIN_CORNER_VERTICES`
    of them) while the surface fitted to each neighbouring part leaves some vertex farther than
    ``tolerance`` away — absorbing it anywhere would bend that face — and no neighbour is a curved analytic
    surface (next to one, such a piece is the remnant of a blend: on pocket noisy20 two of them made the
    solid invalid). A planar cluster that does lie on a
    neighbour's surface joins that neighbour (not the one it touches most). Returns the labels and the
    still-small mask (clusters placed here are no longer small).
    """
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
    # the mesh's typical one (`_drawn_flat`): such a piece is a face from 4 vertices on, next to curved faces
    # too, and a cluster of them that is not flat is judged by its flat pieces (a slot's ring of four walls).
    big = _drawn_flat(mesh) if _noise_free() else (lambda tris: False)
    clusters = []
    for c in np.unique(comp[comp >= 0]):
        tris = np.flatnonzero(comp == c)
        ids = _vertices_of(F, tris, len(V))
        if big(tris) and np.abs(fit_plane(V[ids]).distance(V[ids])).max() > tolerance:
            clusters += [g for g in _coplanar_pieces(V, F, tris, pairs, tolerance) if big(g)]
        else:
            clusters.append(tris)
    for tris in clusters:
        ids = _vertices_of(F, tris, len(V))
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
                neighbour_fits[o] = _fit_parts(mesh, labels, tolerance=tolerance, only=[o])[o]
        off = [np.abs(neighbour_fits[o].distance(V[ids])).max() if neighbour_fits[o].params else np.inf
               for o in others]
        if min(off) <= tolerance:  # it lies on a neighbour's surface: it joins that one, not the one it touches most
            labels[tris] = others[int(np.argmin(off))]
            small[tris] = False
            continue
        if not drawn and any(neighbour_fits[o].type in _CURVED for o in others):
            continue  # next to a curved face a small flat piece is what is left of a blend, not a face
        labels[tris] = labels.max() + 1
        small[tris] = False
        log.info("a planar piece of %d triangles between %d faces kept as a face of its own", len(tris), len(others))
    return labels, small


def _drawn_flat(mesh: Mesh):
    """A test of triangle sets: whether their mean area is :data:`DRAWN_AREA_RATIO` times the mesh's median
    triangle area or more (a flat face a CAD export drew with a few large triangles)."""
    limit = DRAWN_AREA_RATIO * float(np.median(mesh.face_areas))
    return lambda tris: len(tris) > 0 and float(mesh.face_areas[tris].mean()) >= limit


def _coplanar_pieces(V: np.ndarray, F: np.ndarray, tris: np.ndarray, pairs: np.ndarray, tolerance: float) -> list:
    """The triangles ``tris`` as connected pieces whose neighbouring triangles lie in one plane: two triangles
    sharing an edge join when each one's far vertex lies within ``tolerance`` of the other's plane."""
    inside = np.isin(pairs[:, 0], tris) & np.isin(pairs[:, 1], tris)
    a, b = pairs[inside, 0], pairs[inside, 1]
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

    def off(x, y):  # the largest distance of y's corners from x's plane
        return np.abs(np.einsum("ij,ikj->ik", n[x], V[F[y]] - V[F[x, 0]][:, None, :])).max(axis=1)

    flat = (off(a, b) <= tolerance) & (off(b, a) <= tolerance)
    m = len(F)
    graph = sp.coo_matrix((np.ones(int(flat.sum())), (a[flat], b[flat])), shape=(m, m))
    _, comp = sp.csgraph.connected_components(graph, directed=False)
    comp = comp[tris]
    return [tris[comp == c] for c in np.unique(comp)]


def _vertex_counts(faces: np.ndarray, labels: np.ndarray) -> np.ndarray:
    k = int(labels.max()) + 1
    n = int(faces.max()) + 1
    # distinct (label, vertex) pairs counted per label, as packed keys label · n + vertex sorted by numpy's
    # vectorised sort (np.unique on rows sorts them lexicographically: 15 s at 1M triangles; a sparse label ×
    # vertex matrix's sum_duplicates 16 ms at 100k, this 3 ms)
    key = np.repeat(labels, 3) * np.int64(n) + faces.ravel()
    key.sort()
    distinct = key[np.r_[True, key[1:] != key[:-1]]]
    return np.bincount(distinct // n, minlength=k)


def _split_disconnected(labels: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    same = labels[pairs[:, 0]] == labels[pairs[:, 1]]
    a, b = pairs[same].T
    m = len(labels)
    graph = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(m, m))
    _, comp = sp.csgraph.connected_components(graph, directed=False)
    return comp


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray, face_normals: np.ndarray, areas: np.ndarray):
    w = face_normals * areas[:, None]
    # np.add.at once per corner, into zeros: bincount adds in input order (corner 0 of every face, then 1, then 2),
    # the same sums at a tenth of the cost
    idx = faces.T.ravel()
    vn = np.stack([np.bincount(idx, weights=np.tile(w[:, j], 3), minlength=len(vertices)) for j in range(3)], axis=1)
    n = row_norms(vn)  # np.linalg.norm(axis=1), bit for bit
    return vn / np.where(n > 0, n, 1.0)[:, None]


#: A noise-free part's own normal replaces the mesh's vertex normal where the two differ by more than this: the
#: vertex lies on a sharp edge (30°, the crease a noise-free seed disc does not grow across, `SEED_CREASE_COS`).
OWN_NORMAL_COS = float(np.cos(np.deg2rad(30.0)))


def _noise_free() -> bool:
    """Whether the conversion running is on a noise-free mesh (the decomposition measured σ = 0: a CAD export)."""
    memo = _FIT_MEMO.get()
    return memo is not None and memo.get("noise") is None


def _own_normals(V: np.ndarray, tris: np.ndarray, local: np.ndarray, k: int) -> np.ndarray:
    """(k, 3) unit normals at a part's k vertices from its own triangles ``tris`` alone (area-weighted);
    ``local`` numbers their corners 0 … k − 1.

    For a noise-free mesh. Its vertices lie on the true surfaces, and on a CAD tessellation nearly all of them
    on a sharp edge (a hole's strips run from one end circle to the other), where the mesh's vertex normals
    average in the faces beyond the edge. The ABC model's holes: from the vertex normals the cylinder's axis
    came out tilted and its fit 16× out of tolerance; from their own triangles it fits to 10⁻⁹. (The
    decomposition's region fits use the same rule, :func:`recon.decompose._regions._region_normals`.)
    Only the analytic fitters get them: a B-spline over a part that is several faces parametrises better over
    the mesh's normals (pocket coarse: its mixed part's B-spline came out farther than the plane with them).
    """
    fn = np.cross(V[tris[:, 1]] - V[tris[:, 0]], V[tris[:, 2]] - V[tris[:, 0]])  # length: twice the area
    out = np.stack([np.bincount(local.ravel(), weights=np.repeat(fn[:, j], 3), minlength=k) for j in range(3)],
                   axis=1)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)


def _memo_vertex_normals(mesh: Mesh) -> np.ndarray:
    """The mesh's vertex normals, made once per conversion (:data:`_FIT_MEMO`)."""
    memo = _FIT_MEMO.get()
    vn = memo.get("vertex normals") if memo is not None else None
    if vn is None:
        vn = _vertex_normals(mesh.vertices, mesh.faces, mesh.face_normals, mesh.face_areas)
        if memo is not None:
            memo["vertex normals"] = vn
    return vn


def _fit_parts(mesh: Mesh, labels: np.ndarray, *, tolerance: float, only=None, upto: str | None = None
               ) -> dict[int, SurfaceFit]:
    """One surface per label (or per label in ``only``), fitted to the label's vertices with their normals.

    ``upto``: try only the analytic types up to this one (in :func:`recon.fit.fit_surface`'s order) and no
    B-spline — the same answer whenever the full fit would give one of those types, at a fraction of the cost.
    """
    vn = _memo_vertex_normals(mesh)
    if only is not None and len(only) * 8 < labels.max() + 1:  # a few faces: no sort of all the labels
        return {p: _fit_members(mesh, np.flatnonzero(labels == p), vn, tolerance, p, upto) for p in only}
    order = stable_argsort(labels, labels.max() + 1)
    bounds = np.searchsorted(labels[order], np.arange(labels.max() + 2))
    return {p: _fit_members(mesh, order[bounds[p] : bounds[p + 1]], vn, tolerance, p, upto)
            for p in (range(labels.max() + 1) if only is None else only)}


def _fit_members(mesh: Mesh, members: np.ndarray, vn, tolerance: float, p: int, upto: str | None) -> SurfaceFit:
    """The surface of the triangles ``members`` (ascending ids), made once per conversion (:data:`_FIT_MEMO`)."""
    memo = _FIT_MEMO.get()
    if memo is None:
        return _fit_triangles(mesh.vertices, mesh.faces[members], vn, tolerance, p, upto)
    digest = hashlib.sha1(np.asarray(members, dtype=np.int64).tobytes()).digest()
    key = (float(tolerance), upto, digest)
    if key not in memo:
        # The full fit and the fit of every analytic type (upto the last) try the same analytic types in the same
        # way, and differ only where none fits (then the full fit goes on to a B-spline): one's analytic fit
        # within tolerance is the other's (rocker-arm2500: 13 faces fitted twice, once by each).
        other = memo.get((float(tolerance), _ANALYTIC[-1] if upto is None else None, digest)) \
            if upto in (None, _ANALYTIC[-1]) else None
        if other is not None and other.ok and other.type in _ANALYTIC:
            memo[key] = other
        else:
            memo[key] = _fit_triangles(mesh.vertices, mesh.faces[members], vn, tolerance, p, upto)
    return memo[key]


def _fit_triangles(V, tris, vn, tolerance: float, p: int, upto: str | None = None) -> SurfaceFit:
    """The surface of one part: its triangles ``tris`` (k, 3) (vertex ids into ``V``); ``p`` names it in the log."""
    ids, local = _unique_inverse(tris.ravel(), len(V))  # np.unique(tris, return_inverse=True)
    memo = _FIT_MEMO.get()
    noise = memo.get("noise") if memo is not None else None
    if (MIN_FLAT_VERTICES if _noise_free() else MIN_CORNER_VERTICES) <= len(ids) < MIN_PART_VERTICES:  # `_small_faces`
        plane = fit_plane(V[ids], tolerance=tolerance)
        if plane.ok:
            return plane
    if len(ids) < MIN_PART_VERTICES:
        return SurfaceFit("plane", {}, {"max": np.nan, "rms": np.nan, "p99": np.nan}, len(ids), False,
                          f"{len(ids)} vertices: too few for a surface")
    local = local.reshape(-1, 3)
    nrm = vn[ids]
    if noise is None:  # where the part's own triangles turn the normal by more than a crease's angle, theirs
        own = _own_normals(V, tris, local, len(ids))
        crease = np.einsum("ij,ij->i", own, nrm) < OWN_NORMAL_COS
        nrm = np.where(crease[:, None], own, nrm)
    if upto is not None:
        return fit_surface(V[ids], nrm, tolerance=tolerance, types=_ANALYTIC[: _ANALYTIC.index(upto) + 1],
                           allow_bspline=False, faces=local, sigma=noise)
    fit = fit_surface(V[ids], nrm, tolerance=tolerance, faces=local, sigma=noise, bspline_normals=vn[ids])
    if not fit.params:  # nothing at all could be fitted: the B-spline must carry it
        log.warning("part %d: no surface fits (%s)", p, fit.reason)
    return fit


def convert(
    mesh: Mesh | str | os.PathLike,
    *,
    tolerance: float | None = None,
    scale: float | None = None,
    deviation: bool = True,
    progress: Progress | None = None,
    jobs: int | None = None,
) -> Conversion:
    """Reconstruct a B-rep from a triangle mesh.

    Parameters
    ----------
    mesh : Mesh or path
        A cleaned :class:`recon.mesh.Mesh`, or a mesh file (STL, OBJ, PLY, OFF, 3MF, GLB).
    tolerance : float, optional
        Model units. A surface type is accepted for a part when its points lie within it (99th percentile,
        max within twice it); edges are kept as lines/circles within it. Default: max(4σ, 10⁻⁴ · diagonal)
        with σ the mesh's estimated noise (:func:`recon.fit.default_tolerance`).
    scale : float, optional
        Feature scale of the decomposition (model units); default estimated from the mesh.
    deviation : bool
        Measure the deviation between the mesh and the result (both ways) for the report.
    progress : callable(stage, fraction), optional
        Called with a stage name from :data:`STAGES` and 0.0 when it starts, 1.0 when it ends.
    jobs : int, optional
        Processes the decomposition and the curve network's placement may use (default: the cores available; see
        :func:`recon.decompose.decompose`, :func:`recon.brep.build_solid`).

    Returns
    -------
    Conversion
    """
    from .brep import build_solid  # the CAD kernel loads only when a B-rep is wanted
    from .curves import curve_network

    def step(name, frac):
        if progress is not None:
            progress(name, frac)

    times: dict[str, float] = {}
    t = time.perf_counter()
    step("load", 0.0)
    if isinstance(mesh, (str, os.PathLike)):
        mesh = load_mesh(mesh)
    elif not isinstance(mesh, Mesh):
        if isinstance(mesh, tuple) and len(mesh) == 2:
            mesh = clean_mesh(*mesh)
        else:
            raise InputError(f"convert: `mesh` must be a Mesh, a path or (vertices, faces), got {type(mesh).__name__}")
    times["load"] = time.perf_counter() - t
    step("load", 1.0)

    t = time.perf_counter()
    step("decompose", 0.0)
    dec = decompose(mesh, scale=scale, jobs=jobs)
    times["decompose"] = time.perf_counter() - t
    step("decompose", 1.0)

    if tolerance is None:
        tolerance = getattr(dec, "tolerance", None) or max(4.0 * float(dec.noise), 1e-4 * mesh.diagonal)
        log.info("tolerance %.4g", tolerance)
    elif not tolerance > 0:
        raise InputError(f"convert: `tolerance` must be > 0, got {tolerance!r}")

    t = time.perf_counter()
    step("fit", 0.0)
    labels, fits = _faces_and_fits(mesh, dec, tolerance)
    times["fit"] = time.perf_counter() - t
    step("fit", 1.0)

    t = time.perf_counter()
    step("brep", 0.0)
    kinds = _face_kinds(dec, labels)
    network = curve_network(mesh.vertices, mesh.faces, labels)
    try:
        areas = np.bincount(labels, weights=mesh.face_areas, minlength=labels.max() + 1)
        brep = build_solid(network, fits, tolerance=tolerance, part_kinds=kinds,
                           part_areas={p: float(a) for p, a in enumerate(areas)}, jobs=jobs)
    except BrepError:
        raise
    times["brep"] = time.perf_counter() - t
    step("brep", 1.0)

    dev, dev_error = None, None
    if deviation:
        from .deviation import deviation as measure

        t = time.perf_counter()
        step("deviation", 0.0)
        try:
            dev = measure(mesh.vertices, mesh.faces, brep.occ, names=_face_names(brep))
        except ReconError as err:  # the B-rep is written all the same; the report says why it has no deviation
            log.warning("deviation not measured: %s", err)
            dev_error = str(err)
        times["deviation"] = time.perf_counter() - t
        step("deviation", 1.0)

    report = _report(mesh, dec, labels, fits, brep, dev, times, tolerance, dev_error)
    return Conversion(report, mesh, dec, labels, fits, brep)


def _one_blas_thread():
    """A context in which BLAS and LAPACK run on one thread (threadpoolctl).

    The fit stage's least-squares fits take an SVD of a Jacobian of up to 2,000 × 7 every iteration: OpenBLAS
    splits one that size over its threads, and on a shared machine waking and joining them costs more than the
    SVD (2,000 × 7: 0.1 ms on one thread, 1-3 ms on two with the other core busy). The blocks each thread computes
    are the ones one thread computes in turn: the same results (crank's and every bench mesh's fits bit for bit).
    """
    return threadpool_limits(limits=1, user_api="blas")


def _faces_and_fits(mesh: Mesh, dec: Decomposition, tolerance: float) -> tuple[np.ndarray, dict]:
    """The fit stage: the face label of every triangle and the surface of every face."""
    with _one_blas_thread():
        return _faces_and_fits_in(mesh, dec, tolerance)


def _faces_and_fits_in(mesh: Mesh, dec: Decomposition, tolerance: float) -> tuple[np.ndarray, dict]:
    # On a noisy mesh the tolerance is the noise's 4σ; on a noise-free one (the decomposition measures σ = 0:
    # casting, the clean fixtures) it is a floor and the residuals are the tessellation's, not noise.
    token = _FIT_MEMO.set({"noise": tolerance / SIGMAS_PER_TOLERANCE if dec.noise > 0 else None})
    try:
        labels = face_labels(mesh, dec, tolerance=tolerance)
        fits = _fit_parts(mesh, labels, tolerance=tolerance)
        merged, left = merge_same_surface(mesh, labels, fits, tolerance=tolerance)
        if len(left) < len(fits):  # (the labels are not renumbered: their max need not drop)
            log.info("%d faces merged with a neighbour on the same surface", len(fits) - len(left))
            labels = _tidy(mesh, merged, tolerance=tolerance)
            fits = _fit_parts(mesh, labels, tolerance=tolerance)
        split = split_unfitted(mesh, labels, fits, tolerance=tolerance)
        if split is not labels:
            labels = _tidy(mesh, split, tolerance=tolerance)
            fits = _fit_parts(mesh, labels, tolerance=tolerance)
        labels, fits = _trimmed(mesh, labels, fits, tolerance)
        for _ in range(GROW_ROUNDS):
            grown = grow_faces(mesh, labels, fits, tolerance=tolerance)
            if grown is labels:
                break
            labels = _tidy(mesh, grown, tolerance=tolerance)
            fits = _fit_parts(mesh, labels, tolerance=tolerance)
            labels, fits = _trimmed(mesh, labels, fits, tolerance)
            merged, left = merge_same_surface(mesh, labels, fits, tolerance=tolerance)
            if len(left) < len(fits):
                log.info("%d faces merged with a neighbour on the same surface", len(fits) - len(left))
                labels = _tidy(mesh, merged, tolerance=tolerance)
                fits = _fit_parts(mesh, labels, tolerance=tolerance)
        dissolved = dissolve_misfits(mesh, labels, fits, tolerance=tolerance)
        if dissolved is not labels:
            labels = _tidy(mesh, dissolved, tolerance=tolerance)
            fits = _fit_parts(mesh, labels, tolerance=tolerance)
            merged, left = merge_same_surface(mesh, labels, fits, tolerance=tolerance)
            if len(left) < len(fits):
                log.info("%d faces merged with a neighbour on the same surface", len(fits) - len(left))
                labels = _tidy(mesh, merged, tolerance=tolerance)
                fits = _fit_parts(mesh, labels, tolerance=tolerance)
        dissolved = grow_faces(mesh, labels, fits, tolerance=tolerance, dissolve=True)
        if dissolved is not labels:
            labels = _tidy(mesh, dissolved, tolerance=tolerance)
            fits = _fit_parts(mesh, labels, tolerance=tolerance)
        banded = merge_round_bands(mesh, labels, fits, tolerance=tolerance)
        if banded is not labels:
            labels = _tidy(mesh, banded, tolerance=tolerance)
            fits = _fit_parts(mesh, labels, tolerance=tolerance)
        cut = _cut_unbounded(mesh, labels, tolerance=tolerance)
        if cut is not labels:
            labels = cut
            fits = _fit_parts(mesh, labels, tolerance=tolerance)
        return labels, fits
    finally:
        _FIT_MEMO.reset(token)


def _trimmed(mesh: Mesh, labels: np.ndarray, fits: dict, tolerance: float) -> tuple[np.ndarray, dict]:
    trimmed = trim_to_surface(mesh, labels, fits, tolerance=tolerance)
    if trimmed is labels:
        return labels, fits
    labels = _tidy(mesh, trimmed, tolerance=tolerance)
    return labels, _fit_parts(mesh, labels, tolerance=tolerance)


def _face_names(brep) -> list[str]:
    """The record name of every face of ``brep.occ``, in the deviation report's face order (``faces_of``); a face
    no record holds (none expected) keeps the deviation's own ``face_i``."""
    from .brep._step_read import faces_of

    named = [(r.face, r.name) for r in brep.faces if r.face is not None]
    names = []
    for i, face in enumerate(faces_of(brep.occ)):
        names.append(next((name for f, name in named if f.IsSame(face)), f"face_{i}"))
    return names


def _face_kinds(dec: Decomposition, labels: np.ndarray) -> dict[int, str]:
    """Kind of each face label: "patch" if it holds a smooth patch, else the kind most of its triangles came from."""
    kinds_of_part = np.array([p.kind for p in dec.parts])
    out = {}
    orig = np.asarray(dec.labels)
    for p in range(labels.max() + 1):
        votes = Counter(kinds_of_part[orig[labels == p]].tolist())
        # A face that holds any patch is a patch that absorbed a sharp edge strip, not a blend.
        out[p] = "patch" if votes["patch"] else votes.most_common(1)[0][0]
    return out


def _report(mesh, dec, labels, fits, brep, dev, times, tolerance, dev_error=None) -> dict:
    """The conversion's figures as strict JSON data (no NaN or infinity: None where a figure does not exist), with
    the verdict of :func:`recon.verdict.judge` on the result in memory (the command line judges the written file)."""
    from .verdict import judge, strict_json

    diag = float(mesh.diagonal)
    val = brep.validity
    faces = []
    for r in brep.faces:
        fit = fits.get(r.part)
        faces.append(
            {
                "name": r.name,
                "part": int(r.part),
                "kind": r.kind,
                "surface": r.surface_type,
                "status": r.status,
                "built": r.face is not None,
                "area": float(r.area),
                # a filled face has no fit of its own: its figures are NaN, which JSON has no word for
                "fit_max": float(fit.deviation["max"]) if fit is not None else None,
                "fit_rms": float(fit.deviation["rms"]) if fit is not None else None,
            }
        )
    report = {
        "mesh": {
            "triangles": int(len(mesh.faces)),
            "input_triangles": int(mesh.n_input_faces),
            "diagonal": diag,
            "open": bool(mesh.report.boundary_edges > 0),  # boundary edges: a shell is the right answer
            "cleaning": mesh.report.summary(),
        },
        "tolerance": float(tolerance),
        "decomposition": dec.counts(),
        "faces_by_type": dict(Counter(r.surface_type for r in brep.faces)),
        "n_faces": int(val.n_faces),
        "validity": {
            "ok": bool(brep.ok),
            "shape_type": val.shape_type,
            "valid": bool(val.valid),
            "closed": bool(val.closed),
            "free_edges": int(val.free_edges),
            "volume": float(val.volume),
            "n_solids": int(val.n_solids),
            "n_shells": int(val.n_shells),
        },
        "warnings": list(brep.warnings),
        "seconds": {k: round(v, 4) for k, v in times.items()},
        "faces": faces,
    }
    if dev is not None:
        report["deviation"] = dev.to_json()
        report["warnings"].extend(dev.notes)
        missing = sum(r.face is None for r in brep.faces)
        if missing:
            report["warnings"].append(
                f"deviation is measured to the {len(brep.faces) - missing} faces that exist; {missing} parts have none"
            )
    if dev_error:
        report["deviation_error"] = dev_error
        report["warnings"].append(f"deviation not measured: {dev_error}")
    report = strict_json(report)
    report["verdict"] = judge(report, mesh, labels, source="the result in memory",
                              deviation_error=dev_error).to_json()
    return report
