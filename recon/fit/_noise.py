"""Local estimates on a point sample: normals by k-NN PCA, the noise level σ, and the default tolerance."""

from __future__ import annotations

import logging

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.spatial import cKDTree
from scipy.special import gammaincinv

from .._tolerance import tolerance_for
from ..errors import FitError
from .._array import HELPER_COS, as_points, extent

__all__ = ["estimate_normals", "noise_sigma", "ring_noise", "default_tolerance"]

log = logging.getLogger(__name__)


def _neighbourhoods(points: np.ndarray, k: int) -> np.ndarray:
    k = min(k, len(points))
    _, idx = cKDTree(points).query(points, k=k)
    return points[idx] - points[idx].mean(axis=1, keepdims=True)


def estimate_normals(points, *, k: int = 12) -> np.ndarray:
    """Unoriented unit normals by PCA of each point's ``k`` nearest neighbours.

    Parameters
    ----------
    points : (n, 3) float
    k : int
        Neighbourhood size (including the point itself).

    Returns
    -------
    (n, 3) float
        The direction of least variance of each neighbourhood. The sign is arbitrary: the fitters only use
        normals through sign-invariant relations (n nᵀ, normal *lines*, tangent planes).
    """
    pts = as_points(points, min_count=3, error=FitError)
    nb = _neighbourhoods(pts, k)
    cov = np.einsum("nki,nkj->nij", nb, nb)
    _, vec = np.linalg.eigh(cov)
    return vec[:, :, 0]


def noise_sigma(points: npt.ArrayLike, normals: npt.ArrayLike | None = None, *, k: int = 20) -> float:
    """Estimate the noise σ of points sampled from a smooth surface.

    Each point's ``k`` nearest neighbours are fitted, in their PCA frame (or the frame of the given normal),
    by a quadric height field ``z = a x² + b xy + c y² + d x + e y + f`` — a quadric rather than the plain
    local plane, because on a curved patch a plane's residual is dominated by the sagitta (ρ²/2R), not
    the noise. The residual RMS is corrected for the 6 fitted coefficients (× sqrt(k / (k − 6))) and the
    median over all points is returned, so edges and outliers do not matter.

    Parameters
    ----------
    points : (n, 3) float
    normals : (n, 3) float, optional
        Used as each neighbourhood's height direction instead of its PCA normal.
    k : int
        Neighbourhood size, ≥ 10.

    Returns
    -------
    float
        σ in the units of ``points``.
    """
    pts = as_points(points, min_count=10, error=FitError)
    if k < 10:
        raise FitError(f"`k` must be ≥ 10 for a quadric fit, got {k}")
    nb = _neighbourhoods(pts, k)
    k = nb.shape[1]
    if normals is None:
        _, vec = np.linalg.eigh(np.einsum("nki,nkj->nij", nb, nb))
        frame = vec[:, :, [2, 1, 0]]  # columns: two tangent directions, then the normal (least variance)
    else:
        nrm = as_points(normals, "normals", error=FitError)
        if len(nrm) != len(pts):
            raise FitError(f"`normals` must have one row per point ({len(pts)}), got {len(nrm)}")
        nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
        helper = np.where(np.abs(nrm[:, :1]) < HELPER_COS, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
        t1 = np.cross(nrm, helper)
        t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
        frame = np.stack([t1, np.cross(nrm, t1), nrm], axis=2)
    local = np.einsum("nki,nij->nkj", nb, frame)
    x, y, z = local[..., 0], local[..., 1], local[..., 2]
    design = np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=2)  # (n, k, 6)
    scale = np.sqrt(np.mean(x * x + y * y, axis=1))[:, None, None]
    design = design / np.concatenate([scale**2] * 3 + [scale] * 2 + [np.ones_like(scale)], axis=2)
    ata = np.einsum("nki,nkj->nij", design, design) + 1e-12 * np.eye(6)
    atz = np.einsum("nki,nk->ni", design, z)
    coef = np.linalg.solve(ata, atz[..., None])[..., 0]
    res = z - np.einsum("nki,ni->nk", design, coef)
    rms = np.sqrt(np.sum(res * res, axis=1) / (k - 6))
    sigma = float(np.median(rms))
    log.debug("noise_sigma: %.3g from %d neighbourhoods of %d points", sigma, len(pts), k)
    return sigma


#: Vertices whose rings are fitted (an even stride through the vertex order: deterministic): the lower quartile
#: of 15k per-vertex values has a relative standard error of about 1 % (ν ≈ 13 degrees of freedom each).
RING_SAMPLES = 15_000
#: The quantile of the per-vertex values returned: low, so that crease vertices (whose 2-ring no quadric fits) do
#: not count as long as they hold under three quarters of the area.
RING_QUANTILE = 0.25
#: Fewest residual degrees of freedom (ring vertices − 6 coefficients) for a vertex to count: below it one
#: vertex's RMS is too noisy (ν = 4: its lower quartile is 0.62 σ, its upper 1.29 σ).
RING_MIN_DOF = 4
#: A ring fitted to this share of the diagonal is exact: its vertices lie on one quadric up to the file's round-off
#: (a text format with 6 significant digits rounds at 1e-6 of the size; as recon.features.EXACT_HINGE).
RING_EXACT = 1e-6
#: A mesh with at least this share of its rings exact is noise-free (σ = 0): noise leaves no ring on its quadric
#: (P(χ²_ν / ν < 10⁻⁶) ≈ 0 for ν ≥ 4), a CAD export's planes and a fine mesh's flat faces put every ring of theirs
#: on it; as recon.features.EXACT_SHARE for hinges.
RING_EXACT_SHARE = 0.02
#: Sample vertices fitted per batch (the padded arrays are batch × widest ring in the batch).
_RING_BATCH = 2048


def _adjacency(faces: np.ndarray, n_vertices: int) -> sp.csr_matrix:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return sp.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                         shape=(n_vertices, n_vertices)).tocsr()


def _grow(ring: sp.csr_matrix, adj: sp.csr_matrix) -> sp.csr_matrix:
    """The next ring: ``ring``'s vertices and their neighbours, as a sorted 0/1 matrix."""
    out = (ring @ adj + ring).tocsr()
    out.data[:] = 1.0
    out.sort_indices()
    return out


def _ring_rms(vertices: np.ndarray, centre: np.ndarray, nbr: np.ndarray, mask: np.ndarray,
              normal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Residual sum of squares, point count, predicted truncation sum of squares and RMS radius of a quadric height
    field fitted to each padded ring (``nbr`` (c, w) vertex indices, ``mask`` the real ones) in the frame of
    ``normal`` at ``centre``."""
    nrm = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    helper = np.where(np.abs(nrm[:, :1]) < HELPER_COS, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    t1 = np.cross(nrm, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    frame = np.stack([t1, np.cross(nrm, t1), nrm], axis=2)
    w = mask.astype(float)
    local = np.einsum("nki,nij->nkj", vertices[nbr] - vertices[centre][:, None, :], frame) * w[..., None]
    x, y, z = local[..., 0], local[..., 1], local[..., 2]
    count = w.sum(axis=1)
    # coordinates in units of the ring's RMS radius: the normal equations stay well conditioned at any size
    radius = np.sqrt(np.sum(x * x + y * y, axis=1) / count)
    scale = np.where(radius > 0, radius, 1.0)[:, None]
    x, y = x / scale, y / scale
    design = np.stack([x * x, x * y, y * y, x, y, w], axis=2)
    ata = np.einsum("nki,nkj->nij", design, design) + 1e-9 * np.eye(6)
    coef = np.linalg.solve(ata, np.einsum("nki,nk->ni", design, z)[..., None])[..., 0]
    res = z - np.einsum("nki,ni->nk", design, coef)
    ssr = np.sum(res * res, axis=1)
    # The quadric's truncation error: a sphere or cylinder of the fitted principal curvatures κ₁, κ₂ rises above
    # the osculating quadric Q = (κ₁x² + κ₂y²)/2 by κ_max Q²/2 (exact to 4th order: κ³r⁴/8, κ³x⁴/8); what of it the
    # quadric cannot absorb over this ring is sampling, not noise. The fitted curvature carries the noise: its
    # coefficients are shrunk by their own variance (s² tr (AᵀA)⁻¹ of the quadratic block), so that a curvature
    # the noise alone could make predicts no truncation.
    var = ssr / np.maximum(count - 6, 1) * np.trace(np.linalg.inv(ata)[:, :3, :3], axis1=1, axis2=2)
    shrink = np.clip(1.0 - var / np.maximum(np.sum(coef[:, :3] ** 2, axis=1), 1e-300), 0.0, 1.0)[:, None]
    a, b, c = shrink * coef[:, 0:1], shrink * coef[:, 1:2], shrink * coef[:, 2:3]
    quad = a * x * x + b * x * y + c * y * y
    kmax = (np.abs(a + c) + np.sqrt((a - c) ** 2 + b * b)) / scale**2  # the larger |eigenvalue| of [[2a, b], [b, 2c]]
    trunc = 0.5 * kmax * quad * quad * w
    tcoef = np.linalg.solve(ata, np.einsum("nki,nk->ni", design, trunc)[..., None])[..., 0]
    tres = trunc - np.einsum("nki,ni->nk", design, tcoef)
    return ssr, count, np.sum(tres * tres, axis=1), radius


def _ring_quartile(v: np.ndarray, vn: np.ndarray, area: np.ndarray, sample: np.ndarray, ring: sp.csr_matrix,
                   exact: float) -> tuple[float, float, float] | None:
    """(σ², RMS ring radius), both the area-weighted :data:`RING_QUANTILE` over the ``sample`` vertices of the rows of
    ``ring``, and the share of those vertices whose ring's residual RMS is at most ``exact``; None when no vertex has
    :data:`RING_MIN_DOF` degrees of freedom."""
    size = np.diff(ring.indptr)
    normal = ring @ vn
    # a ring whose normals cancel (a sliver sheet folded onto itself) has no height direction
    keep = np.flatnonzero((size >= 6 + RING_MIN_DOF) & (np.linalg.norm(normal, axis=1) > 0) & (area[sample] > 0))
    keep = keep[np.argsort(size[keep], kind="stable")]  # batches of like sizes: little padding
    values, radii, rms = [], [], []
    for start in range(0, len(keep), _RING_BATCH):
        rows = keep[start:start + _RING_BATCH]
        offs = np.arange(int(size[rows].max()))
        mask = offs[None, :] < size[rows][:, None]
        idx = np.where(mask, ring.indptr[rows][:, None] + np.minimum(offs[None, :], size[rows][:, None] - 1), 0)
        ssr, count, tss, radius = _ring_rms(v, sample[rows], ring.indices[idx], mask, normal[rows])
        # the q-quantile of χ²_ν is 2 P⁻¹(ν/2, q): dividing by it puts every vertex's q-quantile at σ², whatever its ν
        values.append(np.maximum(ssr - tss, 0.0) / (2.0 * gammaincinv((count - 6) / 2.0, RING_QUANTILE)))
        radii.append(radius)
        rms.append(np.sqrt(ssr / count))
    if not values:
        return None
    vals, rad, wts = np.concatenate(values), np.concatenate(radii), area[sample[keep]]
    share = float(np.mean(np.concatenate(rms) <= exact))
    fin = np.isfinite(vals)  # a degenerate ring (coincident vertices) has no fit
    if not fin.any():
        return None
    vals, rad, wts = vals[fin], rad[fin], wts[fin]

    def quantile(x):
        # over the surface's area, not its vertices: a scan sampled densely on its fillets would otherwise be
        # measured on them alone, where noise comparable with the radius reads low (bench/noise.md)
        order = np.argsort(x, kind="stable")
        cum = np.cumsum(wts[order])
        return float(x[order][min(np.searchsorted(cum, RING_QUANTILE * cum[-1]), len(x) - 1)])

    return quantile(vals), quantile(rad), share


def ring_noise(vertices: npt.ArrayLike, faces: npt.ArrayLike, *, vertex_normals: npt.ArrayLike | None = None,
               samples: int = RING_SAMPLES) -> float:
    """Estimate the noise σ of a triangle mesh's vertices along the surface normal, from each vertex's 2-ring.

    At up to ``samples`` vertices (an even stride through the vertex order), a quadric height field
    ``z = a x² + b xy + c y² + d x + e y + f`` is fitted to the vertex's 2-ring in its local frame (the normal: the
    sum of the area-weighted vertex normals over the ring). Its residual sum of squares over ν = n − 6 degrees of
    freedom (n ring vertices), less the truncation error its own curvature predicts (:func:`_ring_rms`), is
    σ² χ²_ν / ν for Gaussian noise on a smooth patch; each vertex's value is divided by the lower quartile of
    χ²_ν / ν (so that, whatever its ν, its lower quartile is σ²) and the lower quartile over the surface's area is
    taken: crease vertices, whose ring no quadric fits, and outliers then do not count while they hold under three
    quarters of it. A mesh where at least :data:`RING_EXACT_SHARE` of the rings are fitted exactly (RMS ≤
    :data:`RING_EXACT` of the diagonal) is noise-free: 0.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    vertex_normals : (n, 3) float, optional
        Area-weighted vertex normals (any length), when the caller has them.
    samples : int
        Most vertices fitted.

    Returns
    -------
    float
        σ in the units of ``vertices``; 0.0 when no vertex has a 2-ring of at least 6 + RING_MIN_DOF vertices, and
        ≈ 0 (round-off) on an exact or noise-free fine tessellation.
    """
    v = as_points(vertices, "vertices", min_count=1, error=FitError)
    f = np.asarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3 or (f.size and (f.min() < 0 or f.max() >= len(v))):
        raise FitError(f"`faces` must be (m, 3) indices into `vertices`, got shape {f.shape}")
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    area = np.bincount(f.ravel(), weights=np.repeat(0.5 * np.linalg.norm(cross, axis=1), 3), minlength=len(v)) / 3
    if vertex_normals is None:
        vn = np.stack([np.bincount(f.ravel(), weights=np.repeat(cross[:, j], 3), minlength=len(v)) for j in range(3)],
                      axis=1)
    else:
        vn = as_points(vertex_normals, "vertex_normals", error=FitError)
        if len(vn) != len(v):
            raise FitError(f"`vertex_normals` must have one row per vertex ({len(v)}), got {len(vn)}")
    used = np.unique(f)
    sample = used[np.linspace(0, len(used) - 1, min(samples, len(used))).astype(np.int64)] if len(used) else used
    adj = _adjacency(f, len(v))
    one = _grow(sp.csr_matrix((np.ones(len(sample)), (np.arange(len(sample)), sample)), shape=(len(sample), len(v))),
                adj)
    q2 = _ring_quartile(v, vn, area, sample, _grow(one, adj), RING_EXACT * extent(v))
    if q2 is None:
        return 0.0
    if q2[2] >= RING_EXACT_SHARE:
        return 0.0
    return float(np.sqrt(q2[0]))


def default_tolerance(points, normals=None, *, sigma: float | None = None) -> float:
    """The default fitting tolerance: ``max(4·σ, 1e-4 · bounding-box diagonal)`` (:func:`recon._tolerance.tolerance_for`).

    4σ: the 99th percentile of |N(0, σ)| is 2.58σ, so a fit of the right type passes the acceptance rule
    (p99 ≤ tol, max ≤ 2·tol; see :func:`recon.fit.within_tolerance`) with room for its own parameter error,
    and the max over 10⁵ points (≈ 4.9σ) stays under 2·tol = 8σ. The floor keeps a noise-free
    (tessellated CAD) mesh from demanding agreement at the level of float round-off.

    Parameters
    ----------
    points : (n, 3) float
    normals : (n, 3) float, optional
        Passed to :func:`noise_sigma`.
    sigma : float, optional
        A known noise level; estimated by :func:`noise_sigma` when omitted.
    """
    pts = as_points(points, min_count=10, error=FitError)
    if sigma is None:
        sigma = noise_sigma(pts, normals)
    diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    return tolerance_for(sigma, diag)
