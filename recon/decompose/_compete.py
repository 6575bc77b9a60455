"""Regions competing for triangles: all grow at once, each triangle to the neighbour whose surface fits it best;
border triangles move to a clearly closer surface; regions are refitted between passes and merged where one
surface fits their union."""

from __future__ import annotations

import numpy as np

from ..mesh import stable_argsort
from ._regionfit import MAX_FIT_POINTS, _Ctx, _error, _fit, _fit_key
from ._topology import unique


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
    worker = ctx.worker
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
