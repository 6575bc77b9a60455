"""Blends and free-form faces among the fitted regions: a curved region tangent to two or more neighbours is a
blend (it goes back to the critical region); a connected set of blends and critical triangles meeting the faces
around it at sharp edges, smooth inside, with one B-spline's topology, is one free-form face."""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .._array import x_or_y_helper, row_norms
from ..fit import SurfaceFit, surface_normals
from ._regionfit import _accept, _Ctx, _normals_at
from ._topology import unique

log = logging.getLogger(__name__)

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
    u = np.cross(d, x_or_y_helper(d))
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
    (stray cylinders of about 1 % of a free-form face each). A primary tangent to a primary that is not an
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
    curved everywhere at the scale of the smoothing window has no smooth component: the seeds tile it with small cylinders, each tangent to its neighbours and so
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
        analytic faces with creases between them is not one free-form face).
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
        # radius into an angle), else the smoothed one
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

    Under noise a sharp edge looks like a small fillet, and a curved region may cover it (a thin cylinder
    along the edge). A fillet is tangent to both faces it joins; a small
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
