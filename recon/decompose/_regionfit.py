"""Fits of triangle sets for the region growing: the shared context, a fit's input points and normals, which
triangles a surface accepts, and the distance tolerance measured on the first fits (§ "fit consistency")."""

from __future__ import annotations

import hashlib
import logging

import numpy as np

from .._array import row_norms, row_sums, unique_inverse
from .._tolerance import MESH_FLOOR, tolerance_for
from ..fit import ANALYTIC_FITTERS, MAD_TO_SIGMA, SurfaceFit, quick_fit, surface_normals

log = logging.getLogger(__name__)

#: Fewest vertices a region needs to count (a fit on fewer is not evidence of a surface).
MIN_REGION_VERTICES = 12
#: Fits run on at most this many vertices (an even subset of a larger region).
MAX_FIT_POINTS = 3000
#: Floor of the distance tolerance, as a share of the bounding-box diagonal (see recon._tolerance.MESH_FLOOR).
TOL_FLOOR = MESH_FLOOR


class _Ctx:
    """Mesh arrays shared by the growing steps, and their state: the tolerance, the components' first fits
    (:func:`_noise_tolerance`), the seed order and the second process (:mod:`._worker`), once there are any."""

    def __init__(self, V, F, adj, pairs, edges, fnormal, vnormal, tol, angle, diag, xyz=None, centroid=None, *,
                 area, crease: float):
        self.V, self.F, self.adj, self.pairs, self.edges = V, F, adj, pairs, edges
        self.fn, self.vn = fnormal, vnormal
        self.tol, self.cos = tol, float(np.cos(angle))
        # a hundred-thousandth of the diagonal: round-off margin (scales with part size)
        self.eps = 1e-5 * diag
        # (m, 3, 3) corner coordinates: one gather per distance test instead of two; the centroids are their
        # mean (by columns: the same sums, in order, divided by 3)
        self.xyz = V[F] if xyz is None else xyz
        self.centroid = ((self.xyz[:, 0] + self.xyz[:, 1]) + self.xyz[:, 2]) / 3 if centroid is None else centroid
        # area-weighted normals by coordinate (what _region_normals sums): each bincount reads one contiguous row
        self.wfn_t = np.ascontiguousarray((area[:, None] * fnormal).T)
        #: cosine of the largest dihedral angle a seed disc grows across (:func:`recon.decompose._growing._seed_disc`)
        self.crease = crease
        #: after a seed's region stays under the least area, seeds within this distance of it are not tried
        #: (:func:`recon.decompose._growing._seed_regions`); 0: only the region's own triangles
        self.retire = 0.0
        self.comp_fits: dict = {}
        self.seed_order = None
        self.worker = None


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
    noisy).

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
    # ctx.wfn_t[j] == area * ctx.fn[:, j], kept by coordinate: each bincount reads one contiguous row
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
    sigma = MAD_TO_SIGMA * float(np.median(np.abs(r - np.median(r))))
    log.info("noise from fitted faces: sigma %.4g (first estimate %.4g)", sigma, noise)
    return tolerance_for(sigma, diag, floor=TOL_FLOOR)


def _fit_key(kind: str, faces: np.ndarray):
    """Memo key of a polished fit of ``kind`` on the sorted triangle set ``faces``
    (see :func:`recon.decompose._compete._refit`)."""
    return kind, hashlib.blake2b(faces.tobytes(), digest_size=16).digest()
