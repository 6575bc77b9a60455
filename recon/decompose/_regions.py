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
   patch (:func:`recon.decompose._blends._free_forms`).

Tolerances: ``tolerance`` is a distance (default ``max(4 σ, 5e-4 · diagonal)``, see :data:`TOL_FLOOR`);
``angle`` the largest normal deviation a triangle of the surface shows under the noise.

Modules: :mod:`._regionfit` (fits of triangle sets, the tolerance), :mod:`._growing` (seeds and growth),
:mod:`._compete` (regions competing for triangles, refits, merges), :mod:`._blends` (steps 4–5),
:mod:`._worker` (the second process).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .._array import row_norms, unique_inverse
from .._tolerance import SIGMAS_PER_TOLERANCE
from ..features import NOISE_FACTOR
from ..fit import ANALYTIC_FITTERS, SurfaceFit
from ..mesh import stable_argsort
from ._blends import MIN_SPLIT_COVER, _blends, _free_forms
from ._compete import _compete, _merge, _refit
from ._growing import SEED_CREASE_COS, _seed_regions
from ._regionfit import TOL_FLOOR, _Ctx, _fit_input, _fit_key, _FitInput, _noise_tolerance
from ._topology import topology, unique
from ._worker import _Worker

__all__ = ["Regions", "fitted_regions", "split_by_fitting"]

log = logging.getLogger(__name__)

#: Surface types of blends (a planar chamfer stays in the critical region unless its own smooth component fits).
CURVED = ("sphere", "cylinder")
#: Distance tolerance of the patches' first growth into the critical region, in tolerances (4σ → 1.5σ).
STRICT = 0.375
#: Border refinement passes.
REFINE_PASSES = 4
#: Fewest triangles for which :func:`fitted_regions` starts a second process (``jobs`` ≥ 2): on smaller meshes
#: the start and the messages cost more than growing two seeds at once saves (bench/decompose.md).
PARALLEL_MIN_TRIANGLES = 20_000
#: Seeds of :func:`split_by_fitting` may grow across creases up to this angle (degrees): a facet of a
#: 12-sided cylinder turns by 30°, and the chords of a small fillet turn by that much.
SPLIT_ANGLE_DEG = 30.0


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



def fitted_regions(
    V, F, *, adj, pairs, edges, smooth, priority, vnormal, area, tolerance, noise, angle, min_area, diag, fnormal=None,
    corners=None, centroid=None, jobs: int = 1,
) -> Regions:
    """Patches as regions of fitted surfaces, by the steps of the module notes.

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
        Processes: from 2 on, seeds grow two at a time (:func:`recon.decompose._growing._seed_regions`), with the
        same result.
    """
    m = len(F)
    if fnormal is None:
        cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        fnormal = cr / np.maximum(row_norms(cr, keepdims=True), 1e-300)
    # seed discs stop at facet creases only where the noise makes no such angles
    noisy = not SIGMAS_PER_TOLERANCE * noise < TOL_FLOOR * diag
    crease = -2.0 if noisy else SEED_CREASE_COS
    ctx = _Ctx(V, F, adj, pairs, edges, fnormal, vnormal, tolerance, angle, diag, corners, centroid, area=area,
               crease=crease)
    # where the noise sets the tolerance, the feature window (NOISE_FACTOR σ̂) is the finest scale at which two seeds
    # see different surfaces: a seed that far from one grown too small is not tried (bench/scan.md, issue 23)
    ctx.retire = NOISE_FACTOR * noise if noisy else 0.0
    comp_faces, comp_areas = _smooth_components(smooth, pairs, area, min_area)
    if tolerance is None:
        tolerance = _noise_tolerance(ctx, comp_faces, noise, diag)
        ctx.tol = tolerance
    # the second process of _seed_regions, forked now that the context is complete (its tolerance is set)
    ctx.worker = _Worker.start(ctx) if jobs > 1 and m >= PARALLEL_MIN_TRIANGLES else None
    try:
        # fits of face sets (by type) that step 3's refits would repeat: a region that did not change since its last fit
        memo: dict = {}
        label, fits = _component_regions(ctx, comp_faces, comp_areas, priority, min_area, area, memo)
        label, fits = _blend_regions(ctx, label, fits, priority, min_area, area, memo)
        label, fits = _competing_regions(ctx, label, fits, memo)
        label, fits, blend = _blends_and_free_forms(ctx, label, fits, area, min_area)
        log.info(
            "%d fitted regions (%s), %d blends, %d of %d triangles unclaimed",
            len(fits), ", ".join(sorted({f.type for f in fits})), int(blend.sum()), int((label < 0).sum()), m,
        )
    finally:
        if ctx.worker is not None:
            ctx.worker.close()
        ctx.worker = None
    return Regions(label=label, fits=tuple(fits), blend=blend, tolerance=float(tolerance), angle=float(angle))


def _free_fit(n_points: int) -> SurfaceFit:
    """The fit of a free-form region: no analytic surface (the B-spline fits it later)."""
    return SurfaceFit("free", {}, {"max": np.nan, "rms": np.nan, "p99": np.nan}, n_points)


def _smooth_components(smooth, pairs, area, min_area: float) -> tuple[list, list]:
    """The components of the smooth triangles of at least ``min_area``, largest first: their triangles and areas."""
    m = len(smooth)
    keep = smooth[pairs[:, 0]] & smooth[pairs[:, 1]]
    p = pairs[keep]
    gph = sp.coo_matrix((np.ones(len(p), np.int8), (p[:, 0], p[:, 1])), shape=(m, m))
    n_comp, comp = connected_components(gph, directed=False)
    comp_area = np.bincount(comp, weights=area * smooth, minlength=m)
    # a stable sort of the n_comp areas alone gives them in the same order as of all m (the rest of comp_area is
    # zeros, which a positive min_area leaves out), selected without a Python pass over all m entries
    cand = np.argsort(-comp_area[:n_comp] if min_area > 0 else -comp_area, kind="stable")
    order = cand[comp_area[cand] >= min_area]
    # [np.flatnonzero((comp == c) & smooth) for c in order], from one sort instead of a pass over the mesh each
    sm = np.flatnonzero(smooth)
    by_comp = sm[stable_argsort(comp[sm], n_comp)]
    bounds = np.searchsorted(comp[by_comp], np.arange((n_comp if min_area > 0 else m) + 1))
    return [by_comp[bounds[c] : bounds[c + 1]] for c in order], [comp_area[c] for c in order]


def _component_regions(ctx: _Ctx, comp_faces, comp_areas, priority, min_area, area, memo) -> tuple[np.ndarray, list]:
    """Step 1: one surface per smooth component, or its split by fit-consistent growing from seeds, or (when the
    split covers too little of it) one free-form patch."""
    label = np.full(len(ctx.F), -1, np.int64)
    fits: list = []
    for i, (faces, comp_area) in enumerate(zip(comp_faces, comp_areas)):
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
        allowed = np.zeros(len(ctx.F), bool)
        allowed[faces] = True
        allowed &= label < 0
        found = _seed_regions(ctx, allowed, priority, min_area, area, memo=memo)
        covered = sum(area[f].sum() for f, _ in found)
        if covered < MIN_SPLIT_COVER * comp_area:
            # no analytic surface explains most of it: a free-form face (a loft), kept whole
            label[faces] = len(fits)
            fits.append(_free_fit(len(faces)))
            log.info("smooth component of %.4g area fits no analytic surface: kept as a free-form patch", comp_area)
            continue
        for f_, fit_ in found:
            label[f_] = len(fits)
            fits.append(fit_)
    ctx.comp_fits = {}
    log.debug("regions from smooth components: %d", len(fits))
    return label, fits


def _blend_regions(ctx: _Ctx, label, fits: list, priority, min_area, area, memo) -> tuple[np.ndarray, list]:
    """Step 2: the blends, curved surfaces inside the critical region, found before the patches grow far into it
    so that the border between a face and its fillet is decided by comparing the two surfaces; then the flat areas
    the smoothing window called critical (a face narrower than the window, a chamfer).

    The patches first take what lies on them well within the noise (a fillet is tangent to its faces: within the
    full tolerance they would reach far into it and leave the fillet too narrow to be found)."""
    label = _compete(ctx, label, fits, np.ones(len(ctx.F), bool), strict=STRICT)
    for types in (CURVED, ("plane",)):
        found = _seed_regions(ctx, label < 0, priority, min_area, area, types=types, memo=memo)
        for f_, fit_ in found:
            label[f_] = len(fits)
            fits.append(fit_)
    return label, fits


def _competing_regions(ctx: _Ctx, label, fits: list, memo) -> tuple[np.ndarray, list]:
    """Step 3: every region grows over what is left, each triangle to the neighbour that fits it best; then border
    triangles move to the neighbour whose surface is clearly closer, refitting in between; then neighbours one
    surface fits together merge."""
    everywhere = np.ones(len(ctx.F), bool)
    label = _compete(ctx, label, fits, everywhere)
    for _ in range(REFINE_PASSES):
        fits = _refit(ctx, label, fits, memo)
        new = _compete(ctx, label, fits, everywhere, swap=True)
        new = _compete(ctx, new, fits, everywhere)
        if (new == label).all():
            break
        label = new
    return _merge(ctx, label, fits)


def _blends_and_free_forms(ctx: _Ctx, label, fits: list, area, min_area: float):
    """Steps 4–5: drop what became too small and find the blends; the free-form faces the fitters tiled with
    curved pieces become one free region each (the B-spline fits it). Returns (label, fits, blend)."""
    ra = np.bincount(label[label >= 0], weights=area[label >= 0], minlength=len(fits))
    alive = np.flatnonzero(ra >= min_area)
    label, fits = _keep(label, fits, alive)
    blend = _blends(ctx, label, fits) if fits else np.zeros(0, bool)
    free = _free_forms(ctx, label, fits, blend, area, min_area) if fits else []
    if free:
        for faces, give in free:
            label[faces] = len(fits)
            fits.append(_free_fit(len(faces)))
            for q, tris in give.items():
                label[tris] = q
        blend = np.r_[blend, np.zeros(len(free), bool)]
        alive = unique(label[label >= 0])
        label, fits = _keep(label, fits, alive)
        blend = blend[alive]
        log.info("%d free-form faces tiled by curved regions: kept whole", len(free))
    return label, fits, blend


def _keep(label, fits: list, alive) -> tuple[np.ndarray, list]:
    """The regions ``alive`` (sorted ids) renumbered 0, 1, ...; the triangles of the others become unclaimed (−1)."""
    lut = np.full(len(fits) + 1, -1, np.int64)
    lut[alive] = np.arange(len(alive))
    return lut[label], [fits[i] for i in alive]  # −1 maps through the last slot


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
    # fillets are often a few triangles wide: these seeds may cross the facets' creases
    ctx = _Ctx(v, f, adj, pairs, topo.edges, fn, vnormal[ids], tolerance, np.deg2rad(SPLIT_ANGLE_DEG), diag,
               area=area, crease=-2.0)
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
