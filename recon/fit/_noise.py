"""Local estimates on a point sample: normals by k-NN PCA, the noise level σ, and the default tolerance."""

from __future__ import annotations

import logging

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from .._tolerance import tolerance_for
from ..errors import FitError
from .._array import HELPER_COS, as_points

__all__ = ["estimate_normals", "noise_sigma", "default_tolerance"]

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
