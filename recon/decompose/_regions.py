"""Smooth patches by fitting: which triangles one analytic surface covers within tolerance.

The feature measure only *seeds* the patches. What decides their extent is geometry at the part's own scale,
not the triangle size:

1. every smooth component of the feature measure is fitted (plane < sphere < cylinder < cone < torus, the
   simplest type within tolerance, :mod:`recon.fit`); a component no single surface covers (two faces joined
   through a blend the measure saw as smooth) is split by region growing from its flattest triangles, each
   region growing while its triangles stay on its surface (§ "fit consistency");
2. all regions then grow into the critical region at once, a triangle going to the neighbouring region it
   fits best (vertex distance within tolerance, normal within the noise's angle) — this puts the boundary
   where the surface actually ends instead of a few smoothing windows short of it;
3. what is still unclaimed is searched for the blend surfaces (fillet cylinders, corner spheres, tori) the
   same way, and triangles on the borders between regions move to the neighbour whose surface is closer;
4. a curved region tangent to two or more neighbours is a *blend*: it goes back to the critical region, whose
   skeleton (§2–3) makes it a linear part or a junction. A curved region meeting its neighbours at sharp
   edges (a through hole, a boss) is a primary face and stays a patch;
5. a free-form face curved everywhere at the smoothing window's scale (a loft) has no smooth component and
   comes out of 2–4 as many small tangent curved regions, all "blends": a connected set of them that meets
   the faces around it at sharp edges, is smooth inside and has one B-spline's topology is one free-form
   patch (:func:`_free_forms`).

Tolerances: ``tolerance`` is a distance (default ``max(4 σ, 5e-4 · diagonal)``, see :data:`TOL_FLOOR`);
``angle`` the largest normal deviation a triangle of the surface shows under the noise.
"""

from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .._parallel import Failure, Worker
from .._tolerance import MESH_FLOOR, SIGMAS_PER_TOLERANCE, tolerance_for
from ..errors import FitError
from ..fit import SurfaceFit
from ..fit._select import ANALYTIC_FITTERS
from .._array import row_norms, row_sums, unique_inverse
from ._quickfit import quick_fit, surface_normals
from ..mesh._topology import stable_argsort
from ._topology import unique

__all__ = ["Regions", "fitted_regions", "split_by_fitting"]

ANALYTIC_FITTERS_ORDER = tuple(ANALYTIC_FITTERS)

log = logging.getLogger(__name__)

#: Fewest distinct vertices a seed must hold before it is fitted.
SEED_VERTICES = 16
#: On a noise-free mesh a seed disc does not grow across a dihedral angle above 30° (a facet of a 12-sided
#: cylinder turns by 30°). Not on noisy meshes, where the noise makes such angles (bench/decompose.md).
SEED_CREASE_COS = float(np.cos(np.deg2rad(30.0)))
#: Fewest vertices a region needs to count (a fit on fewer is not evidence of a surface).
MIN_REGION_VERTICES = 12
#: A region is refitted each time it has grown by this factor.
REFIT_GROWTH = 1.6
#: Two surfaces meeting at less than this angle (degrees) along their shared border are tangent (a blend).
TANGENT_DEG = 20.0
#: Share of a component that split regions must cover for the split to be kept (else: one free-form patch).
MIN_SPLIT_COVER = 0.5
#: A primary region enclosed by a free-form component and tangent to it is part of it when it has less than this
#: share of the component's area: a stray fit on a free-form face covers a few % of it (bench/decompose.md).
ISLAND_SHARE = 0.2
#: A free-form face is one that the analytic fitters could only tile: at least this many curved regions in it.
MIN_TILES = 3
#: ... and it is smooth: at most this share of the borders between its tiles (in mesh edges) meet at TANGENT_DEG or
#: more: a free-form face's tiles meet tangentially but for noise, analytic faces at creases (bench/decompose.md).
MAX_CREASE_SHARE = 0.1
#: Surface types of blends (a planar chamfer stays in the critical region unless its own smooth component fits).
CURVED = ("sphere", "cylinder")
#: Distance tolerance of the patches' first growth into the critical region, in tolerances (4σ → 1.5σ).
STRICT = 0.375
#: Surface types whose seed discs get a least-squares fit when the closed form is only near: none — a seed is
#: judged by its closed form; least squares on near misses rescued seeds straddling two surfaces (bench/decompose.md).
SEED_REFINE = ()
#: Fits run on at most this many vertices (an even subset of a larger region).
MAX_FIT_POINTS = 3000
#: Border refinement passes.
REFINE_PASSES = 4
#: Floor of the distance tolerance, as a share of the bounding-box diagonal (see recon._tolerance.MESH_FLOOR).
TOL_FLOOR = MESH_FLOOR
#: Fewest triangles for which :func:`fitted_regions` starts a second process (``jobs`` ≥ 2): on smaller meshes
#: the start and the messages cost more than growing two seeds at once saves (bench/decompose.md).
PARALLEL_MIN_TRIANGLES = 20_000


@dataclass(frozen=True)
class Regions:
    """Triangles covered by fitted surfaces.

    Attributes
    ----------
    label : (m,) int
        Region of each triangle, −1 where no region claims it.
    fits : tuple of SurfaceFit
        Surface of each region (``type == "free"`` with empty params for an unfittable smooth component).
    blend : (k,) bool
        The region is a blend (curved and tangent to two or more neighbours).
    tolerance : float
    angle : float
        Normal tolerance in radians.
    """

    label: np.ndarray
    fits: tuple
    blend: np.ndarray
    tolerance: float
    angle: float


class _Ctx:
    """Mesh arrays shared by the growing steps."""

    def __init__(self, V, F, adj, pairs, edges, fnormal, vnormal, tol, angle, diag, xyz=None, centroid=None):
        self.V, self.F, self.adj, self.pairs, self.edges = V, F, adj, pairs, edges
        self.fn, self.vn = fnormal, vnormal
        self.tol, self.cos = tol, float(np.cos(angle))
        self.eps = 1e-5 * diag
        # (m, 3, 3) corner coordinates: one gather per distance test instead of two; the centroids are their
        # mean (by columns: the same sums, in order, divided by 3)
        self.xyz = V[F] if xyz is None else xyz
        self.centroid = ((self.xyz[:, 0] + self.xyz[:, 1]) + self.xyz[:, 2]) / 3 if centroid is None else centroid


def _fit(
    ctx: _Ctx, faces: np.ndarray, types=tuple(ANALYTIC_FITTERS), *, polish: bool = True, refine=tuple(ANALYTIC_FITTERS)
) -> SurfaceFit | None:
    """Simplest analytic surface through the vertices of ``faces`` within tolerance, or None (see :func:`quick_fit`).

    ``polish``: refine by least squares when the closed form is within tolerance; ``refine``: the types refined
    also when it is only near (for the many seed discs only the cheap ones, :data:`SEED_REFINE`).
    """
    return _fit_input(ctx, _FitInput(ctx, faces), types, polish=polish, refine=refine)


class _FitInput:
    """The points (and, on first use, normals) a fit of ``faces`` runs on, shared by several fits of one face set."""

    def __init__(self, ctx: _Ctx, faces: np.ndarray):
        self.faces = faces
        self.corners = ctx.F[faces].ravel()
        self.verts, self.inv = unique_inverse(self.corners, len(ctx.V))
        self.enough = len(self.verts) >= MIN_REGION_VERTICES
        self._nrm = None
        self._step = -(-len(self.verts) // MAX_FIT_POINTS) if len(self.verts) > MAX_FIT_POINTS else 1
        self.pts = ctx.V[self.verts[:: self._step]] if self.enough else None

    def normals(self, ctx: _Ctx) -> np.ndarray:
        if self._nrm is None:
            self._nrm = _region_normals(ctx, self.faces, self.inv, len(self.verts), self._step, self.corners,
                                        self.verts[:: self._step])
        return self._nrm


def _fit_input(
    ctx: _Ctx, fi: _FitInput, types=tuple(ANALYTIC_FITTERS), *, polish: bool = True, refine=tuple(ANALYTIC_FITTERS)
) -> SurfaceFit | None:
    """:func:`_fit` on prepared input. A plane's closed form needs no normals: a plain plane test skips them."""
    if not fi.enough:
        return None
    for kind in ANALYTIC_FITTERS:
        if kind in types:
            # the plane's closed form ignores the normals; only the least-squares fitter would use them
            nrm = None if kind == "plane" and not polish and kind not in refine else fi.normals(ctx)
            fit = quick_fit(kind, fi.pts, nrm, ctx.tol, polish=polish, refine=kind in refine)
            if fit is not None:
                return fit
    return None


def _region_normals(ctx: _Ctx, faces: np.ndarray, inv: np.ndarray, k: int, step: int = 1, corner_v=None,
                    verts=None) -> np.ndarray:
    """(⌈k / step⌉, 3) unit normals at every ``step``-th of the k vertices of ``faces`` (the fit's subset) from
    those triangles alone (area-weighted).

    ``inv`` (3 len(faces),) numbers the corners of ``faces`` by vertex, 0 … k − 1 (``np.unique``'s inverse).
    Only the corners at the subset's vertices are summed, in the same order: the same sums as over all of them.

    The smoothed vertex normals mix the faces meeting at a sharp edge, and on a CAD tessellation every vertex
    lies on such an edge (a boss's strips run from its top circle to its foot): their axis came out tilted
    by 20°. Normals from the region's own triangles see only the surface being fitted; they replace the
    smoothed normal where the two differ by more than the noise's angle (elsewhere the smoothed one is less
    noisy: raw normals alone cost box_fillet noisy20 88 → 85 % recovered).

    ``corner_v`` (``ctx.F[faces].ravel()``) and ``verts`` (the subset's vertex ids), when the caller has them.
    """
    if corner_v is None:
        corner_v = ctx.F[faces].ravel()
    if step > 1:
        keep = np.flatnonzero(inv % step == 0)
        inv, corner_v, corner_f = inv[keep] // step, corner_v[keep], faces[keep // 3]
        k = -(-k // step)
    else:
        corner_f = np.repeat(faces, 3)
    # ctx.wfn_t[j] == ctx.fa * ctx.fn[:, j], kept by coordinate: each bincount reads one contiguous row
    wn = ctx.wfn_t[:, corner_f]
    out = np.stack([np.bincount(inv, weights=wn[j], minlength=k) for j in range(3)], axis=1)
    out /= np.maximum(row_norms(out, keepdims=True), 1e-300)
    # where the smoothed normal agrees (within the noise's angle) it is the better one: less noisy
    if verts is None:
        verts = np.empty(k, np.int64)
        verts[inv] = corner_v
    sm = ctx.vn[verts]
    agree = np.abs(np.einsum("ij,ij->i", sm, out)) >= ctx.cos
    out[agree] = sm[agree]
    return out


def _normals_at(fit: SurfaceFit, pts: np.ndarray, eps: float = 0.0) -> np.ndarray:
    """(n, 3) unit normals of the fitted surface at (near) ``pts``."""
    return surface_normals(fit, pts)


def _error(ctx: _Ctx, fit: SurfaceFit, faces: np.ndarray, *, strict: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Per face: RMS vertex distance to ``fit`` in tolerances, and whether the face is accepted.

    ``strict`` < 1 shrinks the distance tolerance (the first, cautious growth of the patches).
    """
    d = np.abs(fit.distance(ctx.xyz[faces].reshape(-1, 3))).reshape(-1, 3)
    n = _normals_at(fit, ctx.centroid[faces], ctx.eps)
    cos = np.abs(np.einsum("ij,ij->i", n, ctx.fn[faces]))
    # d.max(axis=1) and (d * d).mean(axis=1) by columns: the same maxima, sums (in order) and division by 3
    ok = (np.maximum(np.maximum(d[:, 0], d[:, 1]), d[:, 2]) <= strict * ctx.tol) & (cos >= ctx.cos)
    err = np.sqrt(row_sums(d * d) / 3) / ctx.tol + (1.0 - cos) / max(1.0 - ctx.cos, 1e-12)
    return err, ok


def _accept(ctx: _Ctx, fit: SurfaceFit, faces: np.ndarray) -> np.ndarray:
    """``_error(ctx, fit, faces)[1]`` (which faces the surface accepts), the normals only where the distance passes."""
    d = np.abs(fit.surface.distance(ctx.xyz[faces].reshape(-1, 3))).reshape(-1, 3)
    ok = np.maximum(np.maximum(d[:, 0], d[:, 1]), d[:, 2]) <= ctx.tol  # d.max(axis=1), without the reduction's setup
    idx = np.flatnonzero(ok)
    if len(idx):
        near = faces[idx]
        n = surface_normals(fit, ctx.centroid[near])
        ok[idx] = np.abs(np.einsum("ij,ij->i", n, ctx.fn[near])) >= ctx.cos
    return ok


def _noise_tolerance(ctx: _Ctx, comp_faces: list, noise: float, diag: float) -> float:
    """:func:`recon._tolerance.tolerance_for` (floor :data:`TOL_FLOOR`) with σ the robust spread of the vertices about
    the largest smooth components' fits.

    The residual of a fitted face is the noise and nothing else; local estimators (smoothing, k-NN quadrics)
    also see the features and the tessellation when the triangles are large compared with the features.
    """
    ctx.tol = tolerance_for(noise, diag, floor=TOL_FLOOR)
    res = []
    total = sum(len(f) for f in comp_faces)
    used = 0
    # the components' fit inputs and fits, for the caller: the same components are fitted again at the final
    # tolerance (the same fit when the tolerance came out the same, e.g. at the floor)
    ctx.comp_fits = {}
    for i, faces in enumerate(comp_faces[:8]):
        fi = _FitInput(ctx, faces)
        fit = _fit_input(ctx, fi, polish=True)
        ctx.comp_fits[i] = (ctx.tol, fi, fit)
        if fit is not None:
            res.append(fit.distance(ctx.V[fi.verts]))
        used += len(faces)
        if used > 0.5 * total and res:
            break
    if not res:
        return ctx.tol
    r = np.concatenate(res)
    sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    log.info("noise from fitted faces: sigma %.4g (first estimate %.4g)", sigma, noise)
    return tolerance_for(sigma, diag, floor=TOL_FLOOR)


def _fit_key(kind: str, faces: np.ndarray):
    """Memo key of a polished fit of ``kind`` on the sorted triangle set ``faces`` (see :func:`_refit`)."""
    return kind, hashlib.blake2b(faces.tobytes(), digest_size=16).digest()


def _grow_one(ctx: _Ctx, faces: np.ndarray, fit: SurfaceFit, allowed: np.ndarray, fi: _FitInput | None = None,
              memo: dict | None = None):
    """Grow one region ring by ring over ``allowed`` triangles that stay on its surface; refit as it grows.

    ``faces`` sorted and unique. Bookkeeping is in the region's own size (the mesh is only touched through the
    ``inreg`` mask), so the many small seeds of a large mesh do not cost a pass over the mesh per ring. ``fi``:
    the fit input ``fit`` was made from, if it is that of ``faces``. ``memo`` (:func:`_refit`'s): when the region's
    last fit was made on its final triangles, it is what a refit of that type on them gives.
    """
    made_on = -1  # size of the region the current fit was polished on (by a refit or a stall's fit)
    inreg = np.zeros(len(ctx.F), bool)
    inreg[faces] = True
    members = [faces]
    frontier = faces
    size = fitted_size = len(faces)
    # fi: the fit input of the last fit; a region that stalls right after it is fitted again on the same triangles
    while len(frontier):
        nb = ctx.adj[frontier].ravel()
        nb = nb[nb >= 0]
        nb = unique(nb[allowed[nb] & ~inreg[nb]])
        if len(nb):
            nb = nb[_accept(ctx, fit, nb)]
        inreg[nb] = True
        if len(nb):
            members.append(nb)
        frontier = nb
        size += len(nb)  # nb is unique and was outside the region
        if size >= REFIT_GROWTH * fitted_size or not len(frontier):
            if size == fitted_size:
                # stalled: under noise a small region of a gently curved face fits a plane (or a sphere) within
                # tolerance, and stops where the curvature shows; a later type may carry it on
                region = np.sort(np.concatenate(members)) if len(members) > 1 else members[0]
                members = [region]
                later = ANALYTIC_FITTERS_ORDER[ANALYTIC_FITTERS_ORDER.index(fit.type) + 1 :]
                # a region with no free neighbour left cannot be carried on by any surface: the (polished) fits
                # of the later types are only made when there is something for them to accept
                nb = ctx.adj[region].ravel()
                nb = nb[nb >= 0]
                nb = unique(nb[allowed[nb] & ~inreg[nb]])
                if not len(nb) or not later:
                    break
                if fi is None or len(fi.faces) != len(region):  # the region only grows: same size, same triangles
                    fi = _FitInput(ctx, region)
                new = _fit_input(ctx, fi, later, polish=True)
                if new is None or not _accept(ctx, new, nb).any():
                    break
                fit = new
                made_on = len(region)
                frontier = region
                continue
            region = np.sort(np.concatenate(members))  # == np.flatnonzero(inreg)
            members = [region]
            fi = _FitInput(ctx, region)
            # the same type first, then any other (the same type failed on this input: not tried twice)
            new = _fit_input(ctx, fi, (fit.type,), polish=True) or _fit_input(
                ctx, fi, tuple(k for k in ANALYTIC_FITTERS if k != fit.type), polish=True
            )
            fitted_size = size
            if new is not None:
                fit = new
                made_on = len(region)
                frontier = region  # the new surface may accept triangles the old one refused
    region = np.sort(np.concatenate(members)) if len(members) > 1 else members[0]
    if memo is not None and made_on == len(region):
        # the fit of fit.type alone on these triangles is this one: _fit_input tries the types in order and
        # returns the first that fits, each by the same quick_fit call
        memo[_fit_key(fit.type, region)] = fit
    return region, fit


def _seed_regions(ctx: _Ctx, allowed, priority, min_area: float, area, *, types=tuple(ANALYTIC_FITTERS),
                  max_seeds: int | None = None, memo: dict | None = None):
    """Regions grown from seeds inside ``allowed``, flattest seed first. Returns a list of (faces, fit).

    ``max_seeds``: try at most this many seed discs (default: until every triangle was tried).

    With a second process (``ctx.worker``, see :class:`_Worker`) the next seed grows there while this one grows
    here, speculatively: its result is kept only when it is the one growing them one after the other gives
    (:func:`_speculation_holds`), so the regions do not depend on the number of processes.
    """
    m = len(ctx.F)
    free = allowed.copy()
    tried = ~allowed
    out = []
    incore = np.zeros(m, bool)
    cached = getattr(ctx, "seed_order", None)  # the same priority in every call of one decomposition: sorted once
    if cached is not None and cached[0] is priority:
        order = cached[1]
    else:
        order = np.argsort(priority, kind="stable")
        ctx.seed_order = (priority, order)
    order = order[allowed[order]]
    worker = getattr(ctx, "worker", None)
    pos = 0
    seeds = 0

    def settle(core, result):
        tried[core] = True  # a failed seed is not retried from inside its own disc (nor right next to it)
        nb = ctx.adj[core].ravel()
        tried[nb[nb >= 0]] = True
        if result is None:
            return
        faces, fit = result
        tried[faces] = True  # grown too small: a seed inside would grow the same small region again
        if area[faces].sum() >= min_area:
            free[faces] = False
            out.append((faces, fit))

    while True:
        seed, pos = _next_seed(order, pos, free, tried)
        if seed is None or (max_seeds is not None and seeds >= max_seeds):
            break
        seeds += 1
        core = _seed_disc(ctx, seed, free, incore)
        fi = _FitInput(ctx, core)
        fit = _seed_fit(ctx, fi, types)
        spec = None
        if worker is not None and worker.alive and fit is not None and (max_seeds is None or seeds < max_seeds):
            spec = _speculate(ctx, worker, order, pos, free, tried, core, fit, types)
        result = None if fit is None else _grow_one(ctx, core, fit, free, fi, memo)
        settle(core, result)
        if spec is None:
            continue
        got = spec.get()
        if not _speculation_holds(spec, got, free, tried):
            continue
        seeds += 1
        pos = spec.pos
        if memo is not None:
            memo.update(got[2])
        settle(got[0], got[1])
    return out


def _next_seed(order: np.ndarray, pos: int, free: np.ndarray, tried: np.ndarray):
    """The first triangle of ``order[pos:]`` free and not tried, and the position after it (None when none is)."""
    while pos < len(order):
        # found a block of the order at a time (the masks change only when a seed is taken, so a block's test
        # stays valid up to the first hit)
        block = order[pos : pos + 512]
        hit = np.flatnonzero(free[block] & ~tried[block])
        if not len(hit):
            pos += len(block)
            continue
        return block[hit[0]], pos + int(hit[0]) + 1
    return None, pos


def _seed_disc(ctx: _Ctx, seed, free: np.ndarray, incore: np.ndarray) -> np.ndarray:
    """The seed disc: breadth-first rings over ``free`` triangles until it holds enough vertices (sorted).
    ``incore``: an all-false scratch mask, left all false."""
    core = np.array([seed])
    incore[seed] = True
    while len(unique(ctx.F[core])) < SEED_VERTICES:
        src = np.repeat(core, 3)
        nb = ctx.adj[core].ravel()
        ok = nb >= 0
        src, nb = src[ok], nb[ok]
        # not across a crease: on a coarse tessellation 16 vertices reach over a face's edges
        ok = free[nb] & ~incore[nb] & (np.einsum("ij,ij->i", ctx.fn[src], ctx.fn[nb]) >= ctx.crease)
        nb = unique(nb[ok])
        if not len(nb):
            break
        incore[nb] = True
        core = np.sort(np.concatenate([core, nb]))  # == np.flatnonzero(incore), without a pass over the mesh
    incore[core] = False
    return core


def _seed_fit(ctx: _Ctx, fi: _FitInput, types) -> SurfaceFit | None:
    """The surface a seed disc starts growing on, or None."""
    if "plane" not in types and _fit_input(ctx, fi, ("plane",), polish=False, refine=()) is not None:
        return None  # flat: not the curved surface looked for (a huge radius would fit it too)
    return _fit_input(ctx, fi, types, refine=SEED_REFINE)


def _grow_seed(ctx: _Ctx, seed, free: np.ndarray, types, incore: np.ndarray | None = None):
    """One seed from start to end: its disc, and its (faces, fit) or None, and the memo entries growing made."""
    core = _seed_disc(ctx, seed, free, np.zeros(len(ctx.F), bool) if incore is None else incore)
    fi = _FitInput(ctx, core)
    fit = _seed_fit(ctx, fi, types)
    memo: dict = {}
    return core, (None if fit is None else _grow_one(ctx, core, fit, free, fi, memo)), memo


def _compete(ctx: _Ctx, label, fits: list, allowed, *, swap: bool = False, strict: float = 1.0) -> np.ndarray:
    """Grow all regions at once over ``allowed`` unlabelled triangles (each to the best-fitting neighbour).

    With ``swap``, labelled border triangles also move to a neighbouring region whose surface fits them better.
    """
    label = label.copy()
    f, g = ctx.pairs[:, 0], ctx.pairs[:, 1]
    K = np.int64(len(fits) + 1)
    key = None
    for _ in range(10000):
        if swap:
            lf, lg = label[f], label[g]
            sel = (lf != lg) & (lf >= 0) & (lg >= 0)
            cand = np.concatenate([g[sel], f[sel]])
            creg = np.concatenate([lf[sel], lg[sel]])
            key = unique(cand * K + creg)
        elif key is None:
            lf, lg = label[f], label[g]
            a = (lf >= 0) & (lg < 0) & allowed[g]
            b = (lg >= 0) & (lf < 0) & allowed[f]
            cand = np.concatenate([g[a], f[b]])
            creg = np.concatenate([lf[a], lg[b]])
            key = unique(cand * K + creg)
        if not len(key):
            break
        cand, creg = key // K, key % K
        err = np.full(len(cand), np.inf)
        for r in unique(creg):
            if fits[r].type == "free":
                continue
            sel = creg == r
            e, ok = _error(ctx, fits[r], cand[sel], strict=strict)
            err[sel] = np.where(ok, e, np.inf)
        if swap:
            own = np.full(len(cand), np.inf)
            cur = label[cand]
            for r in unique(cur):
                if fits[r].type == "free":
                    own[cur == r] = -np.inf  # free-form patches keep their triangles
                    continue
                sel = cur == r
                own[sel] = _error(ctx, fits[r], cand[sel])[0]
            err = np.where(err < 0.8 * own, err, np.inf)  # a clear improvement only: no flip-flopping
        good = np.isfinite(err)
        if not good.any():
            break
        all_cand = cand
        cand, creg, err = cand[good], creg[good], err[good]
        o = np.lexsort((err, cand))
        first = np.r_[True, cand[o][1:] != cand[o][:-1]]
        taken = cand[o][first]
        label[taken] = creg[o][first]
        if swap:
            break  # one pass; the caller refits between passes
        # the next pass's (candidate, region) pairs without a pass over the mesh: labels are only ever given here, so
        # they are this pass's pairs whose candidate is still unlabelled, and the taken triangles' unlabelled allowed
        # neighbours with the taken triangle's region (the same set as from the pairs: the same sorted keys)
        nb = ctx.adj[taken]
        reg = np.repeat(label[taken], 3)
        nb = nb.ravel()
        ok = nb >= 0
        nb, reg = nb[ok], reg[ok]
        ok = (label[nb] < 0) & allowed[nb]
        key = unique(np.concatenate([key[label[all_cand] < 0], nb[ok] * K + reg[ok]]))
    return label


class _Speculation:
    """The seed growing in the worker, and what must hold for its result to be the sequential one."""

    def __init__(self, seed, pos: int, skipped: np.ndarray, worker: "_Worker"):
        self.seed, self.pos, self.skipped, self.worker = seed, pos, skipped, worker

    def get(self):
        """The worker's ``(core, result, memo)``, or None when it gave none (see :meth:`_Worker.get`)."""
        return self.worker.get()


def _speculate(ctx: _Ctx, worker, order, pos, free, tried, core, fit, types) -> _Speculation | None:
    """Start the seed after the one at ``core`` (being grown on ``fit``) in the worker, guessing that the
    triangles ``fit`` accepts will be the current seed's region (the next seeds in order mostly lie on it)."""
    tried = tried.copy()
    tried[core] = True
    nb = ctx.adj[core].ravel()
    tried[nb[nb >= 0]] = True
    skipped = []
    while pos < len(order):
        block = order[pos : pos + 4096]
        idx = np.flatnonzero(free[block] & ~tried[block])
        if len(idx):
            off = np.flatnonzero(~_accept(ctx, fit, block[idx]))
            if len(off):
                k = int(idx[off[0]])
                skipped.append(block[idx[: off[0]]])
                seed = block[k]
                if not worker.submit("grow", seed, free, types):
                    return None
                return _Speculation(seed, pos + k + 1, np.concatenate(skipped), worker)
            skipped.append(block[idx])
        pos += len(block)
    return None


def _speculation_holds(spec: _Speculation, got, free, tried) -> bool:
    """Whether the worker's seed, grown on the masks from before the current seed grew, is what growing it after
    that one gives (``free``, ``tried``: the masks after it). It is when the seed is the next one in order now
    and neither its disc nor its region reach into what the current seed took: its growth then read only
    triangles whose state did not change (one that would have joined it from there shows as an overlap).
    ``got`` None (the worker gave no answer) never holds: the seed is then grown here, in its turn."""
    if got is None:
        return False
    core, result, _ = got
    if tried[spec.seed] or not free[spec.seed] or not tried[spec.skipped].all():
        return False
    return bool(free[core].all() and (result is None or free[result[0]].all()))


#: How long the parent waits for the worker's answer to one job before it stops the worker and does the work
#: itself (a worker that died answers at once: its end of the pipe closes). A job is one seed's growth or half a
#: refinement pass's fits, a few seconds on the largest meshes: this bounds a hung worker's cost (bench/decompose.md).
WORKER_TIMEOUT = 120.0


def _grow_job(ctx: _Ctx, seed, free, types):
    return _grow_seed(ctx, seed, free, types)


def _fits_job(ctx: _Ctx, jobs):
    return [_fit(ctx, faces, (kind,), polish=True) for faces, kind in jobs]


#: What the worker can be asked to do: name -> function(ctx, *args).
_JOBS = {"grow": _grow_job, "fits": _fits_job}


class _Worker:
    """The decomposition's second process (:class:`recon._parallel.Worker` holding the context, serving
    :data:`_JOBS`): :meth:`submit`, then :meth:`get`.

    It can never stall the parent nor change the result: when it dies, fails a job or gives no answer within
    :data:`WORKER_TIMEOUT`, :meth:`get` returns None, the worker is stopped for good, and the callers do the work
    themselves, as with one process. (A process forked from a threaded one can deadlock in the child on a lock
    another thread held at the fork; the timeout bounds what that costs.)
    """

    def __init__(self, ctx: _Ctx):
        self._worker = Worker(ctx, _JOBS, name="recon-decompose")

    @property
    def alive(self) -> bool:
        return self._worker.alive

    @staticmethod
    def available() -> bool:
        """Whether a second process can be had here: with fork (Linux) or spawn (elsewhere), see
        :func:`recon._parallel.start_method`."""
        return True

    @classmethod
    def start(cls, ctx: _Ctx) -> "_Worker | None":
        """A worker, or None where none can be had (then one process does all): inside a daemonic process (which
        may not have children), or when starting it fails."""
        try:
            return cls(ctx)
        except OSError as err:
            log.warning("decomposition: no second process (%s), going on in one", err or type(err).__name__)
            return None

    def submit(self, name: str, *args) -> bool:
        """Send a job of :data:`_JOBS`; False when the worker is gone (nothing was sent)."""
        was = self._worker.alive
        sent = self._worker.submit(name, *args)
        if was and not sent:
            self._stop()
        return sent

    def get(self):
        """The answer to the job submitted last, or None (the caller then does it itself)."""
        if not self._worker.alive:
            return None
        got = self._worker.get(WORKER_TIMEOUT)
        if isinstance(got, Failure):
            self._stop()
            return None
        return got

    def _stop(self) -> None:
        log.warning("decomposition: second process stopped, going on in one: %s", self._worker.stopped)

    def close(self) -> None:
        self._worker.close()


def _refit(ctx: _Ctx, label: np.ndarray, fits: list, memo: dict | None = None) -> list:
    """Refit every region on its current triangles. ``memo`` keeps the fits of face sets seen before: between
    refinement passes most regions do not change, and the same fit on the same triangles is the same result.
    With ``ctx.worker`` about half of the fits (by size) are made there."""
    out = list(fits)
    order = stable_argsort(label + 1, len(fits) + 1)  # (the order of label itself: -1 marks no region)
    bounds = np.searchsorted(label[order], np.arange(len(fits) + 1))
    todo = []
    for r, fit in enumerate(fits):
        if fit.type == "free":
            continue
        faces = np.sort(order[bounds[r] : bounds[r + 1]])  # == np.flatnonzero(label == r), one sort for all
        if len(faces):
            key = None
            if memo is not None:
                key = _fit_key(fit.type, faces)
            if key is not None and key in memo:
                new = memo[key]
                if new is not None:
                    out[r] = new
            else:
                todo.append((r, faces, fit.type, key))
    worker = getattr(ctx, "worker", None)
    there = []
    if worker is not None and worker.alive and len(todo) > 1:
        # the larger half of the work to the worker, by a greedy split on the points each fit runs on
        load = [0, 0]
        for item in sorted(todo, key=lambda t: -min(len(t[1]), 2 * MAX_FIT_POINTS)):
            side = int(load[1] < load[0])
            load[side] += min(len(item[1]), 2 * MAX_FIT_POINTS) + 100  # + a fit's fixed cost, in points
            if side:
                there.append(item)
        moved = {id(t) for t in there}
        todo = [t for t in todo if id(t) not in moved]
        if not worker.submit("fits", [(faces, kind) for _, faces, kind, _ in there]):
            todo, there = todo + there, []
    done = [(t, _fit(ctx, t[1], (t[2],), polish=True)) for t in todo]
    if there:
        got = worker.get()
        if got is None:  # the worker gave no answer: its share here, in the same order
            got = [_fit(ctx, t[1], (t[2],), polish=True) for t in there]
        done += list(zip(there, got))
    for (r, _, _, key), new in done:
        if key is not None:
            memo[key] = new
        if new is not None:
            out[r] = new
    return out


def _merge(ctx: _Ctx, label: np.ndarray, fits: list):
    """Merge neighbouring regions of one type whose union one surface of that type still fits."""
    fits = list(fits)
    tried = set()
    while True:
        f, g = ctx.pairs[:, 0], ctx.pairs[:, 1]
        lf, lg = label[f], label[g]
        sel = (lf >= 0) & (lg >= 0) & (lf != lg)
        a, b = np.minimum(lf[sel], lg[sel]), np.maximum(lf[sel], lg[sel])
        key, cnt = np.unique(a * np.int64(len(fits)) + b, return_counts=True)
        merged = False
        for kk in key[np.argsort(-cnt, kind="stable")]:
            ra, rb = int(kk // len(fits)), int(kk % len(fits))
            if (ra, rb) in tried or fits[ra].type != fits[rb].type or fits[ra].type == "free":
                continue
            tried.add((ra, rb))
            union = np.flatnonzero((label == ra) | (label == rb))
            fit = _fit(ctx, union, (fits[ra].type,), polish=True)
            if fit is not None:
                label[label == rb] = ra
                fits[ra] = fit
                merged = True
                break
        if not merged:
            return label, fits


def _blends(ctx: _Ctx, label: np.ndarray, fits: list) -> np.ndarray:
    """Curved regions whose surface is tangent to that of two or more neighbouring regions."""
    k = len(fits)
    f, g, e = ctx.pairs[:, 0], ctx.pairs[:, 1], ctx.pairs[:, 2]
    lf, lg = label[f], label[g]
    sel = (lf >= 0) & (lg >= 0) & (lf != lg)
    lf, lg, e = lf[sel], lg[sel], e[sel]
    mid = 0.5 * (ctx.V[ctx.edges[e, 0]] + ctx.V[ctx.edges[e, 1]])
    tangent = np.zeros((k, k), bool)
    lo, hi = np.minimum(lf, lg), np.maximum(lf, lg)
    key = lo * np.int64(k) + hi
    for kk in unique(key):
        a, b = int(kk // k), int(kk % k)
        if fits[a].type == "free" or fits[b].type == "free":
            continue
        s = key == kk
        na = _normals_at(fits[a], mid[s], ctx.eps)
        nb = _normals_at(fits[b], mid[s], ctx.eps)
        ang = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", na, nb)), 0, 1)))
        if np.median(ang) < TANGENT_DEG:
            tangent[a, b] = tangent[b, a] = True
    curved = np.array([fit.type not in ("plane", "free") for fit in fits], bool)
    blend = curved & (tangent.sum(axis=1) >= 2)
    for r in np.flatnonzero(blend):
        if fits[r].type == "cylinder" and _turn(ctx, fits[r], np.flatnonzero(label == r)) > np.pi:
            blend[r] = False  # a cylinder round more than half a turn is no fillet (those are < 180°)
    return blend


def _turn(ctx: _Ctx, fit: SurfaceFit, faces: np.ndarray) -> float:
    """The angle (radians) a region covers about its cylinder's axis: a full turn less its widest gap."""
    d = np.asarray(fit.params["axis_dir"], float)
    q = ctx.centroid[faces] - np.asarray(fit.params["axis_point"], float)
    u = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(d, u)
    ang = np.sort(np.arctan2(q @ w, q @ u))
    gaps = np.diff(np.r_[ang, ang[0] + 2 * np.pi])
    return float(2 * np.pi - gaps.max()) if len(ang) > 1 else 0.0


def _angles(n: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Angles in degrees between the unsigned unit normals ``n`` and ``m`` (k, 3)."""
    return np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", n, m)), 0.0, 1.0)))


def _tangent_pairs(ctx: _Ctx, label, fits, prim) -> list:
    """Pairs (a, b), a < b, of neighbouring primary regions whose surfaces meet at under TANGENT_DEG."""
    f, g, e = ctx.pairs[:, 0], ctx.pairs[:, 1], ctx.pairs[:, 2]
    pp = np.flatnonzero(prim[f] & prim[g] & (label[f] != label[g]))
    mid = 0.5 * (ctx.V[ctx.edges[e[pp], 0]] + ctx.V[ctx.edges[e[pp], 1]])
    pa, pb = np.minimum(label[f[pp]], label[g[pp]]), np.maximum(label[f[pp]], label[g[pp]])
    tangent = []
    k = len(fits)  # np.unique of the (pa, pb) rows as integer keys: the same lexicographic order
    key = unique(pa * np.int64(k) + pb)
    for a, b in zip((key // k).tolist(), (key % k).tolist()):
        s = (pa == a) & (pb == b)
        if np.median(_angles(surface_normals(fits[a], mid[s]), surface_normals(fits[b], mid[s]))) < TANGENT_DEG:
            tangent.append((a, b))
    return tangent


def _islands(ctx: _Ctx, label, fits, prim, comp, area, tangent) -> dict:
    """{primary region: the components it joins} for the primaries that are pieces of a free-form component.

    A primary region tangent all round to the non-primary triangles it borders (median angle < TANGENT_DEG
    between its surface's normal and their smoothed normals) and small beside them (under ISLAND_SHARE of the
    largest component it touches) is a patch that an analytic surface happened to cover on a free-form face
    (the lofted side's stray cylinders: about 1 % of it each). A primary tangent to a primary that is not an
    island (a face and its fillet's neighbour) is not one either. The raw triangle normals would carry the
    noise (σ = 0.2 % of the diagonal turns them by 10–20°): the smoothed vertex normals stand in for them.
    """
    f, g, e = ctx.pairs[:, 0], ctx.pairs[:, 1], ctx.pairs[:, 2]
    bf, bg = prim[f] & ~prim[g], prim[g] & ~prim[f]
    ptri, otri, bedge = np.r_[f[bf], g[bg]], np.r_[g[bf], f[bg]], np.r_[e[bf], e[bg]]
    other = ctx.vn[ctx.edges[bedge, 0]] + ctx.vn[ctx.edges[bedge, 1]]
    other /= np.maximum(row_norms(other, keepdims=True), 1e-300)
    preg = label[ptri]
    comp_area = np.bincount(comp[comp >= 0], weights=area[comp >= 0], minlength=len(label))
    reg_area = np.bincount(label[label >= 0], weights=area[label >= 0], minlength=len(fits))
    island = {}
    for r in unique(preg):
        s = preg == r
        at = 0.5 * (ctx.V[ctx.edges[bedge[s], 0]] + ctx.V[ctx.edges[bedge[s], 1]])
        ang = _angles(surface_normals(fits[r], at), other[s])
        cs = unique(comp[otri[s]])
        if np.median(ang) < TANGENT_DEG and reg_area[r] < ISLAND_SHARE * comp_area[cs].max():
            island[int(r)] = cs
    changed = True
    while changed:
        changed = False
        for a, b in tangent:
            if (a in island) != (b in island):
                island.pop(a, None)
                island.pop(b, None)
                changed = True
    return island


def _topology_of(ctx: _Ctx, faces: np.ndarray, mesh_border: np.ndarray) -> tuple[int, int, int]:
    """Euler characteristic, boundary loops, and how many of those run along the mesh's own border (holes)."""
    tri = ctx.F[faces]
    ed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    nv = len(ctx.V)
    # the unique rows (each sorted: min, max) as integer keys (the same lexicographic order): np.unique(axis=0)
    # is ~10x slower, np.sort(axis=1) of pairs ~5x slower than their min and max
    uk, cnt = np.unique(np.minimum(ed[:, 0], ed[:, 1]) * np.int64(nv) + np.maximum(ed[:, 0], ed[:, 1]),
                        return_counts=True)
    chi = len(unique(tri)) - len(uk) + len(faces)
    uk = uk[cnt == 1]
    be = np.stack([uk // nv, uk % nv], axis=1)
    if not len(be):
        return chi, 0, 0
    _, loop = connected_components(sp.coo_matrix((np.ones(len(be)), (be[:, 0], be[:, 1])), shape=(nv, nv)),
                                   directed=False)
    loop_of = loop[be[:, 0]]
    holes = unique(loop_of[np.isin(be[:, 0] * np.int64(nv) + be[:, 1], mesh_border)])
    return chi, len(unique(loop_of)), len(holes)


def _crease_share(label, fits, inside, f, g, mid) -> float:
    """Share of the mesh edges between two fitted regions inside ``inside`` where their surfaces meet at
    TANGENT_DEG or more (median over each pair's shared border). ``mid(idx)``: the pairs' edge midpoints at ``idx``."""
    both = np.flatnonzero(inside[f] & inside[g] & (label[f] != label[g]) & (label[f] >= 0) & (label[g] >= 0))
    la, lb = np.minimum(label[f[both]], label[g[both]]), np.maximum(label[f[both]], label[g[both]])
    sharp = measured = 0
    k = len(fits)  # np.unique of the (la, lb) rows as integer keys: the same lexicographic order
    key = unique(la * np.int64(k) + lb)
    for x, y in zip((key // k).tolist(), (key % k).tolist()):
        if fits[x].type == "free" or fits[y].type == "free":
            continue  # no surface to measure; a free region of step 1 is smooth by construction
        sel = both[(la == x) & (lb == y)]
        measured += len(sel)
        at = mid(sel)
        if np.median(_angles(surface_normals(fits[x], at), surface_normals(fits[y], at))) >= TANGENT_DEG:
            sharp += len(sel)
    return sharp / max(measured, 1)


def _free_forms(ctx: _Ctx, label: np.ndarray, fits: list, blend: np.ndarray, area: np.ndarray, min_area: float):
    """The free-form faces among the critical region and the blends: a list of ((k,) triangles, {region: triangles
    it hands to that region}) (see :func:`_rounded_edges`).

    Step 1 keeps a smooth component no analytic surface explains as one free-form patch, but a free-form face
    curved everywhere at the scale of the smoothing window (the lofted side: 0.6 % of it smooth on the clean
    mesh) has no smooth component: the seeds tile it with small cylinders, each tangent to its neighbours and so
    a "blend", and the skeleton cuts the lot into some forty parts. What tells it from a network of fillets is
    how it meets the faces around it: a fillet is tangent to the faces it joins, this face meets them at sharp
    edges. A connected set of non-primary triangles (critical or blend, joined through :func:`_islands`) is
    one face when

    (a) it meets at least one primary region, and every one at an angle ≥ TANGENT_DEG (median over the border);
    (b) it is one B-spline's worth of topology: genus 0 with one or two boundary loops besides the mesh's own
        holes (a disk, or a band that the periodic fit closes round);
    (c) curved regions cover at least MIN_SPLIT_COVER of its area (step 1's rule) and at least MIN_TILES of
        them: the analytic fitters could only tile it;
    (d) its area is at least ``min_area``;
    (e) it is smooth inside: at most MAX_CREASE_SHARE of the borders between its tiles are sharp (a chain of
        analytic faces with creases between them, revolved/noisy20's side, is not one free-form face).
    """
    m, k = len(label), len(fits)
    f, g, e = ctx.pairs[:, 0], ctx.pairs[:, 1], ctx.pairs[:, 2]
    # a free-form region of step 1 is a piece of whatever free-form face it lies in
    is_primary = ~blend & np.array([ft.type != "free" for ft in fits], bool)
    prim = (label >= 0) & is_primary[np.maximum(label, 0)]
    keep = ~prim[f] & ~prim[g]
    _, comp = connected_components(sp.coo_matrix((np.ones(int(keep.sum()), np.int8), (f[keep], g[keep])), shape=(m, m)),
                                   directed=False)
    comp = np.where(prim, -1, comp)
    tangent = _tangent_pairs(ctx, label, fits, prim)
    island = _islands(ctx, label, fits, prim, comp, area, tangent)
    reg_area = np.bincount(label[label >= 0], weights=area[label >= 0], minlength=k)
    # components joined through islands: a graph on components (nodes 0..m-1) and islands (nodes m + region)
    group = np.arange(m + k)
    if island:
        a = np.concatenate([np.full(len(cs), m + r) for r, cs in island.items()])
        b = np.concatenate(list(island.values()))
        _, group = connected_components(sp.coo_matrix((np.ones(len(a), np.int8), (a, b)), shape=(m + k, m + k)),
                                        directed=False)
    merged = np.where(comp >= 0, group[np.maximum(comp, 0)], -1)
    for r in island:
        merged[label == r] = group[m + r]
    nv = len(ctx.V)
    inner = np.zeros(len(ctx.edges), bool)
    inner[e] = True
    mesh_border = ctx.edges[~inner, 0] * np.int64(nv) + ctx.edges[~inner, 1]
    ea, eb = ctx.edges[e, 0], ctx.edges[e, 1]

    def mid(idx):  # (0.5 * (V[a] + V[b]))[idx] of the pairs' edges, only at the rows asked for (the same values)
        return 0.5 * (ctx.V[ea[idx]] + ctx.V[eb[idx]])

    def smooth_n(idx):  # the edges' mean smoothed normal, likewise (row by row: the same values)
        n_ = ctx.vn[ea[idx]] + ctx.vn[eb[idx]]
        n_ /= np.maximum(row_norms(n_, keepdims=True), 1e-300)
        return n_

    curved_region = np.array([ft.type != "plane" for ft in fits], bool)
    out = []
    for c in unique(merged[merged >= 0]):
        faces = np.flatnonzero(merged == c)
        a = float(area[faces].sum())
        lab = label[faces]
        curved = (lab >= 0) & curved_region[np.maximum(lab, 0)]
        tiles = len(unique(lab[curved]))
        if a < min_area or tiles < MIN_TILES or area[faces[curved]].sum() < MIN_SPLIT_COVER * a:
            continue
        inside = merged == c
        # (a): the primary regions it borders, each by its median angle. Inside, the normal is that of the tile
        # the border triangle lies on where it has one (the smoothed normals blur a tangent border with a small
        # radius: revolved/noisy05's torus met its plane at 19.5° by them), else the smoothed one
        border = np.flatnonzero(inside[f] != inside[g])
        out_tri = np.where(inside[f[border]], g[border], f[border])
        in_tri = np.where(inside[f[border]], f[border], g[border])
        own = smooth_n(border)
        for r in unique(label[in_tri]):
            if r >= 0 and fits[r].type != "free":
                sel = label[in_tri] == r
                own[sel] = surface_normals(fits[r], mid(border[sel]))
        angles = {}
        for r in unique(label[out_tri]):
            if r < 0:  # cannot happen (unclaimed triangles are in some component); count it as tangent
                angles[-1] = 0.0
                continue
            sel = label[out_tri] == r
            angles[int(r)] = float(np.median(_angles(surface_normals(fits[r], mid(border[sel])), own[sel])))
        chi, loops, holes = _topology_of(ctx, faces, mesh_border)
        crease = _crease_share(label, fits, inside, f, g, mid)
        ok = (bool(angles) and min(angles.values()) >= TANGENT_DEG and chi == 2 - loops and loops - holes in (1, 2)
              and crease <= MAX_CREASE_SHARE)
        log.debug("free-form candidate: %d triangles, area %.4g, %d curved tiles, chi %d, %d loops (%d holes), "
                  "border angles %s, %.3f of the tile borders sharp: %s", len(faces), a, tiles, chi, loops, holes,
                  {r: round(v, 1) for r, v in angles.items()}, crease, ok)
        if ok:
            out.append(_rounded_edges(ctx, label, fits, faces, angles, tangent, a, reg_area))
    return out


def _rounded_edges(ctx: _Ctx, label, fits, faces, angles, tangent, group_area, reg_area):
    """The free-form face's triangles with the slivers the noise rounded along its sharp edges, and what of
    them goes to the face on the other side: ``(faces, {region: triangles})``.

    Under noise a sharp edge looks like a small fillet, and a curved region may cover it (lofted/noisy20: a
    19-triangle cylinder of radius 2 along the top edge). A fillet is tangent to both faces it joins; a small
    curved region tangent to one primary only and meeting the free-form face at a sharp angle is that rounded
    edge: its triangles on the tangent primary's surface (within tolerance) go to that primary, the rest to
    the free-form face.
    """
    give = {}
    extra = []
    for r in angles:
        if r < 0 or fits[r].type == "plane" or reg_area[r] >= ISLAND_SHARE * group_area:
            continue
        partners = [b if a == r else a for a, b in tangent if r in (a, b)]
        if len(partners) != 1:
            continue
        q = partners[0]
        tris = np.flatnonzero(label == r)
        on_q = _accept(ctx, fits[q], tris)
        give[q] = np.r_[give.get(q, np.zeros(0, np.int64)), tris[on_q]]
        extra.append(tris[~on_q])
    return np.sort(np.concatenate([faces, *extra])), give


def fitted_regions(
    V, F, *, adj, pairs, edges, smooth, priority, vnormal, area, tolerance, noise, angle, min_area, diag, fnormal=None,
    corners=None, centroid=None, jobs: int = 1,
) -> Regions:
    """Patches as regions of fitted surfaces (see the module notes).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    adj : (m, 3) int
        Neighbouring triangle across each edge, −1 on a border.
    pairs : (p, 3) int
        Adjacent triangles (f, g, undirected edge).
    edges : (E, 2) int
    smooth : (m,) bool
        Triangles the feature measure calls smooth.
    priority : (m,) float
        Seed order (lowest first): the feature measure.
    vnormal : (n, 3) float
        Unit vertex normals for the fitters.
    area : (m,) float
    tolerance : float or None
        Distance tolerance; None: ``max(4 σ, TOL_FLOOR · diag)`` with σ measured on the fitted smooth components.
    noise : float
        A first noise estimate (used to fit the components that measure σ).
    angle, min_area, diag : float
    fnormal : (m, 3) float, optional
        Unit face normals ``cross / max(|cross|, 1e-300)`` (:class:`recon.features.FaceGeometry`), when the caller
        has them.
    corners, centroid : (m, 3, 3), (m, 3) float, optional
        ``V[F]`` and its mean over the corners, when the caller has them.
    jobs : int
        Processes: from 2 on, seeds grow two at a time (:func:`_seed_regions`), with the same result.
    """
    m = len(F)
    if fnormal is None:
        cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        fnormal = cr / np.maximum(row_norms(cr, keepdims=True), 1e-300)
    fn = fnormal
    ctx = _Ctx(V, F, adj, pairs, edges, fn, vnormal, tolerance, angle, diag, corners, centroid)
    ctx.fa = area
    ctx.wfn_t = np.ascontiguousarray((area[:, None] * fn).T)  # area-weighted normals (what _region_normals sums)
    ctx.crease = SEED_CREASE_COS if SIGMAS_PER_TOLERANCE * noise < TOL_FLOOR * diag else -2.0
    label = np.full(m, -1, np.int64)
    fits: list = []

    # 1. smooth components: one surface each, or split by fit-consistent growing
    keep = smooth[pairs[:, 0]] & smooth[pairs[:, 1]]
    p = pairs[keep]
    gph = sp.coo_matrix((np.ones(len(p), np.int8), (p[:, 0], p[:, 1])), shape=(m, m))
    n_comp, comp = connected_components(gph, directed=False)
    comp_area = np.bincount(comp, weights=area * smooth, minlength=m)
    # the components of at least min_area, largest first: a stable sort of the n_comp areas alone gives them in the
    # same order (the rest of comp_area is zeros, which a positive min_area leaves out), selected without a Python
    # pass over all m entries
    cand = np.argsort(-comp_area[:n_comp] if min_area > 0 else -comp_area, kind="stable")
    order = cand[comp_area[cand] >= min_area]
    # [np.flatnonzero((comp == c) & smooth) for c in order], from one sort instead of a pass over the mesh each
    sm = np.flatnonzero(smooth)
    by_comp = sm[stable_argsort(comp[sm], n_comp)]
    bounds = np.searchsorted(comp[by_comp], np.arange((n_comp if min_area > 0 else m) + 1))
    comp_faces = [by_comp[bounds[c] : bounds[c + 1]] for c in order]
    ctx.comp_fits = {}
    if tolerance is None:
        tolerance = _noise_tolerance(ctx, comp_faces, noise, diag)
        ctx.tol = tolerance
    # the second process of _seed_regions, forked now that the context is complete (its tolerance is set)
    ctx.worker = _Worker.start(ctx) if jobs > 1 and m >= PARALLEL_MIN_TRIANGLES else None
    try:
        # fits of face sets (by type) that step 3's refits would repeat: a region that did not change since its last fit
        memo: dict = {}
        for i, (c, faces) in enumerate(zip(order, comp_faces)):
            tol0, fi, fit0 = ctx.comp_fits.get(i, (None, None, None))
            if fi is not None and tol0 == ctx.tol:
                fit = fit0  # the noise estimate's fit of this component, at this same tolerance
            else:
                fit = _fit_input(ctx, fi if fi is not None else _FitInput(ctx, faces))
            if fit is not None:
                label[faces] = len(fits)
                fits.append(fit)
                memo[_fit_key(fit.type, faces)] = fit  # _fit tries the types in order: this is fit.type's fit alone
                continue
            allowed = np.zeros(m, bool)
            allowed[faces] = True
            allowed &= label < 0
            found = _seed_regions(ctx, allowed, priority, min_area, area, memo=memo)
            covered = sum(area[f].sum() for f, _ in found)
            if covered < MIN_SPLIT_COVER * comp_area[c]:
                # no analytic surface explains most of it: a free-form face (a loft), kept whole
                label[faces] = len(fits)
                fits.append(SurfaceFit("free", {}, {"max": np.nan, "rms": np.nan, "p99": np.nan}, len(faces)))
                log.info("smooth component of %.4g area fits no analytic surface: kept as a free-form patch", comp_area[c])
                continue
            for f_, fit_ in found:
                label[f_] = len(fits)
                fits.append(fit_)
        ctx.comp_fits = {}
        log.debug("regions from smooth components: %d", len(fits))

        # 2. the blends: curved surfaces inside the critical region, found before the patches grow far into it so
        #    that the border between a face and its fillet is decided by comparing the two surfaces. The patches
        #    first take what lies on them well within the noise (a fillet is tangent to its faces: within the full
        #    tolerance they would reach far into it and leave the fillet too narrow to be found)
        label = _compete(ctx, label, fits, np.ones(m, bool), strict=STRICT)
        found = _seed_regions(ctx, label < 0, priority, min_area, area, types=CURVED, memo=memo)
        for f_, fit_ in found:
            label[f_] = len(fits)
            fits.append(fit_)
        #    then flat areas the smoothing window called critical (a face narrower than the window, a chamfer)
        found = _seed_regions(ctx, label < 0, priority, min_area, area, types=("plane",), memo=memo)
        for f_, fit_ in found:
            label[f_] = len(fits)
            fits.append(fit_)

        # 3. grow every region over what is left, each triangle to the neighbour that fits it best; then move
        #    border triangles to the neighbour whose surface is clearly closer, refitting in between
        everywhere = np.ones(m, bool)
        label = _compete(ctx, label, fits, everywhere)
        for _ in range(REFINE_PASSES):
            fits = _refit(ctx, label, fits, memo)
            new = _compete(ctx, label, fits, everywhere, swap=True)
            new = _compete(ctx, new, fits, everywhere)
            if (new == label).all():
                break
            label = new

        label, fits = _merge(ctx, label, fits)

        # 4. drop what became too small, renumber, find the blends
        ra = np.bincount(label[label >= 0], weights=area[label >= 0], minlength=len(fits))
        alive = np.flatnonzero(ra >= min_area)
        lut = np.full(len(fits) + 1, -1, np.int64)
        lut[alive] = np.arange(len(alive))
        label = lut[label]  # −1 maps through the last slot
        fits = [fits[i] for i in alive]
        blend = _blends(ctx, label, fits) if fits else np.zeros(0, bool)
        # 5. free-form faces the fitters tiled with curved pieces: one free region each (the B-spline fits it)
        free = _free_forms(ctx, label, fits, blend, area, min_area) if fits else []
        if free:
            for faces, give in free:
                label[faces] = len(fits)
                fits.append(SurfaceFit("free", {}, {"max": np.nan, "rms": np.nan, "p99": np.nan}, len(faces)))
                for q, tris in give.items():
                    label[tris] = q
            blend = np.r_[blend, np.zeros(len(free), bool)]
            alive = unique(label[label >= 0])
            lut = np.full(len(fits) + 1, -1, np.int64)
            lut[alive] = np.arange(len(alive))
            label = lut[label]
            fits, blend = [fits[i] for i in alive], blend[alive]
            log.info("%d free-form faces tiled by curved regions: kept whole", len(free))
        log.info(
            "%d fitted regions (%s), %d blends, %d of %d triangles unclaimed",
            len(fits), ", ".join(sorted({f.type for f in fits})), int(blend.sum()), int((label < 0).sum()), m,
        )
    finally:
        if ctx.worker is not None:
            ctx.worker.close()
        ctx.worker = None
    return Regions(label=label, fits=tuple(fits), blend=blend, tolerance=float(tolerance), angle=float(angle))


#: Seeds of :func:`split_by_fitting` may grow across creases up to this angle (degrees): a facet of a
#: 12-sided cylinder turns by 30°, and the chords of a small fillet turn by that much.
SPLIT_ANGLE_DEG = 30.0


def split_by_fitting(V, F, faces, *, vnormal, tolerance: float, min_area: float, max_seeds: int | None = None,
                     types=tuple(ANALYTIC_FITTERS)) -> list:
    """The analytic surfaces that cover ``faces``, as regions grown from seeds inside them.

    For a part no one surface fits: a ring of four fillets meeting at a pocket's sharp corners is one linear
    part, and four cylinders. Seeds are taken deepest inside the part first (away from its border, where it
    meets its neighbours), each grown ring by ring while its triangles stay within ``tolerance`` of its
    surface and their normals within :data:`SPLIT_ANGLE_DEG` of its normal. Fillets are often a few
    triangles wide, so unlike the decomposition's seeds these may cross the facets' creases.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
    faces : (k,) int
        The part's triangles.
    vnormal : (n, 3) float
        Unit vertex normals.
    tolerance, min_area : float
        Distance tolerance; least area a region must reach to count.
    max_seeds : int, optional
        Seed discs to try at most (the deepest first); default all.
    types : sequence of str
        The analytic types a seed may be fitted with (a region may still change type as it grows).

    Returns
    -------
    list of (faces (j,) int, SurfaceFit)
        Regions in the order they were found; triangles of ``faces`` in none of them are not covered.
    """
    from ._topology import topology

    faces = np.asarray(faces, dtype=np.int64)
    ids, local = unique_inverse(F[faces].ravel(), len(V))  # np.unique(F[faces], return_inverse=True)
    v, f = V[ids], local.reshape(-1, 3)
    topo = topology(f, len(v))
    adj = np.where(topo.twin >= 0, topo.twin // 3, -1).reshape(-1, 3)
    h = np.flatnonzero(topo.twin > np.arange(len(topo.twin)))
    pairs = np.stack([h // 3, topo.twin[h] // 3, topo.half_edge[h]], axis=1)
    cr = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    area = 0.5 * row_norms(cr)
    fn = cr / np.maximum(2.0 * area[:, None], 1e-300)
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    ctx = _Ctx(v, f, adj, pairs, topo.edges, fn, vnormal[ids], tolerance, np.deg2rad(SPLIT_ANGLE_DEG), diag)
    ctx.fa = area
    ctx.wfn_t = np.ascontiguousarray((area[:, None] * fn).T)
    ctx.crease = -2.0
    # depth: rings from the part's border inwards; the deepest triangles seed first
    depth = np.full(len(f), -1, np.int64)
    ring = np.flatnonzero((adj < 0).any(axis=1))
    d = 0
    while len(ring):
        depth[ring] = d
        nb = adj[ring].ravel()
        nb = unique(nb[nb >= 0])
        ring = nb[depth[nb] < 0]
        d += 1
    found = _seed_regions(ctx, np.ones(len(f), bool), -depth.astype(float), min_area, area, max_seeds=max_seeds,
                          types=types)
    return [(faces[r], fit) for r, fit in found]
