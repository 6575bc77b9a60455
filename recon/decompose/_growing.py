"""Regions grown from seeds: a seed disc fitted, then grown ring by ring over the triangles that stay on its surface
(refitted as it grows), seeds taken in order of the feature measure; with a second process (:mod:`._worker`) the
next seed grows there, speculatively."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..fit import ANALYTIC_FITTERS, SurfaceFit
from ._regionfit import _accept, _Ctx, _fit_input, _fit_key, _FitInput
from ._topology import unique

ANALYTIC_FITTERS_ORDER = tuple(ANALYTIC_FITTERS)

#: Fewest distinct vertices a seed must hold before it is fitted.
SEED_VERTICES = 16
#: On a noise-free mesh a seed disc does not grow across a dihedral angle above 30° (a facet of a 12-sided
#: cylinder turns by 30°). Not on noisy meshes, where the noise makes such angles (bench/decompose.md).
SEED_CREASE_COS = float(np.cos(np.deg2rad(30.0)))
#: A region is refitted each time it has grown by this factor.
REFIT_GROWTH = 1.6
#: Surface types whose seed discs get a least-squares fit when the closed form is only near: none — a seed is
#: judged by its closed form; least squares on near misses rescued seeds straddling two surfaces (bench/decompose.md).
SEED_REFINE = ()


def _grow_one(ctx: _Ctx, faces: np.ndarray, fit: SurfaceFit, allowed: np.ndarray, fi: _FitInput | None = None,
              memo: dict | None = None):
    """Grow one region ring by ring over ``allowed`` triangles that stay on its surface; refit as it grows.

    ``faces`` sorted and unique. Bookkeeping is in the region's own size (the mesh is only touched through the
    ``inreg`` mask), so the many small seeds of a large mesh do not cost a pass over the mesh per ring. ``fi``:
    the fit input ``fit`` was made from, if it is that of ``faces``. ``memo`` (that of
    :func:`recon.decompose._compete._refit`): when the region's last fit was made on its final triangles, it is
    what a refit of that type on them gives.
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

    ``max_seeds``: try at most this many seed discs (default: until every triangle was tried). A region that grows
    to less than ``min_area`` is dropped, and no seed is taken within ``ctx.retire`` of it (:func:`_near`).

    With a second process (``ctx.worker``, a :class:`recon.decompose._worker._Worker`) the next seed grows there
    while this one grows
    here, speculatively: its result is kept only when it is the one growing them one after the other gives
    (:func:`_speculation_holds`), so the regions do not depend on the number of processes.
    """
    m = len(ctx.F)
    free = allowed.copy()
    tried = ~allowed
    out = []
    incore = np.zeros(m, bool)
    cached = ctx.seed_order  # the same priority in every call of one decomposition: sorted once
    if cached is not None and cached[0] is priority:
        order = cached[1]
    else:
        order = np.argsort(priority, kind="stable")
        ctx.seed_order = (priority, order)
    order = order[allowed[order]]
    worker = ctx.worker
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
        elif ctx.retire > 0:
            # under noise a seed within the noise's window of it sees the same surface at the scale the noise
            # resolves: it regrows (most of) the same too-small region
            tried[_near(ctx, faces, free, ctx.retire)] = True

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


def _near(ctx: _Ctx, faces: np.ndarray, free: np.ndarray, radius: float) -> np.ndarray:
    """The ``free`` triangles connected to ``faces`` through free triangles whose centroids lie within ``radius`` of
    a centroid of ``faces`` (rings over ``ctx.adj``: along the surface, not across a thin wall)."""
    tree = cKDTree(ctx.centroid[faces])
    seen = np.zeros(len(ctx.F), bool)
    seen[faces] = True
    out = [faces]
    frontier = faces
    while len(frontier):
        nb = ctx.adj[frontier].ravel()
        nb = unique(nb[nb >= 0])
        nb = nb[free[nb] & ~seen[nb]]
        seen[nb] = True
        nb = nb[tree.query(ctx.centroid[nb])[0] <= radius]
        out.append(nb)
        frontier = nb
    return np.concatenate(out)


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


class _Speculation:
    """The seed growing in the worker, and what must hold for its result to be the sequential one."""

    def __init__(self, seed, pos: int, skipped: np.ndarray, worker: "recon.decompose._worker._Worker"):
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
