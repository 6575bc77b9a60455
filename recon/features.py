"""A noise-robust feature measure on a triangle mesh: normal variation at a scale.

The measure plays the role of the smooth/critical classification of Wekel & Hellwich [TW13] that §4 of
the paper builds on: smooth patches are where it is low, the critical region (fillets, sharp edges,
corners) where it is high.

How it is computed (all sparse, no per-vertex Python):

1. Vertex normals are smoothed by heat diffusion on the surface — implicit Euler steps of
   ``(M + t L) x = M b`` with the lumped mass matrix ``M`` and the cotangent Laplacian ``L`` (negative
   cotangents clipped to zero so the smoothing keeps the maximum principle on skinny triangles).
   Heat diffusion at time ``t = s² / 2`` is a geodesic Gaussian of standard deviation ``s``: a scale in
   length units, independent of the tessellation, that does not leak across thin walls like a
   Euclidean ball would.
2. The feature measure is the weighted variance of those smoothed normals in the same window,
   ``1 - |mean normal|²`` (the trace of the normal covariance: 0 on a plane, about ``(s/R)²`` on a
   cylinder of radius ``R``, close to ``1 - cos α`` across an edge of dihedral angle ``α``).
   Smoothing first averages noise out; the variance then measures the geometry, not the noise.

The scale ``s`` defaults to a few mean edge lengths, more when the estimated noise is larger.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import MeshError
from ._array import row_norms
from .mesh._topology import stable_argsort
from .fit import ring_noise

__all__ = ["FeatureField", "feature_field", "mesh_arrays", "heat_smooth"]

log = logging.getLogger(__name__)

#: Default scale in mean edge lengths on a clean mesh.
EDGE_FACTOR = 1.5
#: Default scale in estimated noise standard deviations (noise averages out over the window).
NOISE_FACTOR = 10.0


@dataclass(frozen=True)
class FeatureField:
    """Per-vertex feature measure and the scale it was computed at.

    Attributes
    ----------
    measure : (n,) float
        Normal variance ``1 - |mean normal|²`` of the smoothed normals in a window of ``scale``; 0 … 1.
    normals : (n, 3) float
        Unit vertex normals smoothed at ``scale``.
    scale : float
        Standard deviation of the geodesic Gaussian window (mesh length units).
    noise : float
        Estimated standard deviation of the vertex noise normal to the surface (mesh length units).
    mean_edge : float
        Mean edge length of the mesh.
    """

    measure: np.ndarray
    normals: np.ndarray
    scale: float
    noise: float
    mean_edge: float

    def face_measure(self, faces: np.ndarray) -> np.ndarray:
        """(m,) float: the largest vertex measure of each triangle (a triangle touching a feature is critical)."""
        return self.measure[faces].max(axis=1)


def mesh_arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) float64 and faces (m, 3) int64 of anything mesh-like, validated.

    Parameters
    ----------
    mesh : object with ``vertices`` and ``faces``, or a ``(vertices, faces)`` pair
    """
    if isinstance(mesh, tuple) and len(mesh) == 2:
        vertices, faces = mesh
    else:
        try:
            vertices, faces = mesh.vertices, mesh.faces
        except AttributeError:
            raise MeshError("`mesh` must have `vertices` and `faces` (or be a (vertices, faces) pair)") from None
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise MeshError(f"`mesh.vertices` must be (n, 3), got shape {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise MeshError(f"`mesh.faces` must be (m, 3) with m > 0, got shape {faces.shape}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError("`mesh.faces` index vertices that do not exist")
    if not np.isfinite(vertices).all():
        raise MeshError("`mesh.vertices` contain NaN or infinite coordinates")
    return vertices, faces


class FaceGeometry:
    """Per-face arrays that several steps of the feature field and the decomposition need, formed once:
    ``cross`` (m, 3) = (v1 − v0) × (v2 − v0), its length ``norm`` (m,) (twice the area) and the unit normal
    ``unit`` (m, 3) (``cross / max(norm, 1e-300)``). The same operations as each step made on its own."""

    def __init__(self, vertices, faces, *, cross=None, centroid=None):
        """``cross``, ``centroid``: those arrays when the caller has them (a :class:`recon.mesh.Mesh` caches them
        for the stages after the decomposition)."""
        if cross is None:
            cross = np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]])
        self.cross = cross
        self.norm = row_norms(self.cross)
        self._unit = None
        self._vf = (vertices, faces)
        self._corners = None
        self._centroid = centroid

    @property
    def corners(self) -> np.ndarray:
        """(m, 3, 3) corner coordinates ``vertices[faces]``."""
        if self._corners is None:
            self._corners = self._vf[0][self._vf[1]]
        return self._corners

    @property
    def centroid(self) -> np.ndarray:
        """(m, 3) ``corners.mean(axis=1)``, bit for bit: numpy adds the three corners in order and divides by 3,
        here by columns (its reduction over an axis of 3 costs ~5x as much)."""
        if self._centroid is None:
            c = self.corners
            self._centroid = ((c[:, 0] + c[:, 1]) + c[:, 2]) / 3
        return self._centroid

    @property
    def area(self) -> np.ndarray:
        return 0.5 * self.norm

    @property
    def unit(self) -> np.ndarray:
        if self._unit is None:
            self._unit = self.cross / np.maximum(self.norm[:, None], 1e-300)
        return self._unit


def _laplacian(vertices, faces, geom: FaceGeometry | None = None, sides=None):
    """Clipped cotangent Laplacian L (n, n) and lumped mass diagonal (n,).

    ``sides``: the three ``p[:, k + 1] - p[:, k]`` (k = 0, 1, 2, indices mod 3) of ``p = vertices[faces]``, when the
    caller has them (:func:`_sides`)."""
    n = len(vertices)
    p = geom.corners if geom is not None else vertices[faces]  # (m, 3, 3)
    cots = []
    for k in range(3):
        a = sides[k] if sides is not None else p[:, (k + 1) % 3] - p[:, k]
        b = p[:, (k + 2) % 3] - p[:, k]
        # k = 0: (v1 − v0) × (v2 − v0), the face's own cross product
        cross = geom.norm if k == 0 and geom is not None else row_norms(np.cross(a, b))
        cots.append(np.einsum("ij,ij->i", a, b) / np.maximum(cross, 1e-300))
    cot = np.clip(np.stack(cots, axis=1), 0.0, 10.0)  # angle at vertex k weighs the opposite edge
    i = np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0]])
    j = np.concatenate([faces[:, 2], faces[:, 0], faces[:, 1]])
    w = 0.5 * np.concatenate([cot[:, 0], cot[:, 1], cot[:, 2]])
    W = sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([i, j]), np.concatenate([j, i]))), shape=(n, n)).tocsr()
    L = sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W
    area = geom.area if geom is not None else 0.5 * row_norms(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    mass = np.bincount(faces.ravel(), weights=np.repeat(area / 3.0, 3), minlength=n)
    # isolated or degenerate vertices keep their value instead of making the system singular
    mass = np.maximum(mass, max(float(area.mean()), 1e-300) * 1e-9)
    return L.tocsr(), mass


def heat_smooth(values: np.ndarray, L, mass: np.ndarray, scale: float, *, steps: int = 3, rtol: float = 1e-4) -> np.ndarray:
    """Geodesic Gaussian smoothing of per-vertex values by implicit heat diffusion.

    Parameters
    ----------
    values : (n,) or (n, k) float
    L : (n, n) sparse
        Laplacian (positive semi-definite).
    mass : (n,) float
        Lumped vertex areas.
    scale : float
        Standard deviation of the Gaussian (length); diffusion time ``scale² / 2`` split into ``steps``.
    rtol : float
        Relative residual at which the conjugate gradients stop (smoothing needs no more than 1e-4).

    Returns
    -------
    (n,) or (n, k) float
    """
    return _smooth(values, mass, _system(L, mass, scale, steps), steps, rtol)


def _system(L, mass, scale, steps):
    """The implicit step's matrix ``M + dt L`` (CSR) and its inverse diagonal."""
    dt = 0.5 * scale**2 / steps
    A = (sp.diags(mass) + dt * L).tocsr()
    return A, 1.0 / A.diagonal()


def _smooth(values, mass, system, steps: int = 3, rtol: float = 1e-4):
    """:func:`heat_smooth` with its :func:`_system` formed by the caller (the feature field smooths twice at one
    scale: one matrix for both)."""
    x = np.asarray(values, dtype=np.float64)
    one = x.ndim == 1
    x = x.reshape(len(x), -1).copy()
    A, inv_diag = system
    for _ in range(steps):
        x = _block_pcg(A, mass[:, None] * x, x, inv_diag, rtol)
    return x[:, 0] if one else x


def _block_pcg(A, B, X, inv_diag, rtol, maxiter=1000):
    """Jacobi-preconditioned conjugate gradients on all columns at once (one sparse product per iteration).

    The updates run in place in buffers kept across iterations (the same operations on the same values as
    ``X += alpha * P``, ``P = Z + beta * P``, ...: bit-identical), so an iteration allocates only the product.
    """
    R = B - A @ X
    n, k = R.shape
    # the per-row and per-column factors spelt out to the full (n, k) shape: an elementwise product of two
    # arrays of one shape (the same products) runs its inner loop over all n k values, a broadcast one over k
    dg = np.repeat(inv_diag[:, None], k, axis=1)
    Z = dg * R
    P = Z.copy()
    tmp = np.empty_like(R)

    def times_columns(c, M, out):  # np.multiply(c, M, out=out) for c (k,) and C-ordered M, out (n, k)
        if M.flags.c_contiguous and out.flags.c_contiguous:
            np.multiply(np.tile(c, n), M.reshape(-1), out=out.reshape(-1))
        else:
            np.multiply(c, M, out=out)

    rz = np.einsum("ij,ij->j", R, Z)
    stop = rtol * np.maximum(np.linalg.norm(B, axis=0), 1e-300)
    # np.linalg.norm(R, axis=0) is the root of np.add.reduce(R * R, axis=0), which numpy sums row by row in order
    # (the inner loop runs over the k columns: ~40 ns a row). For k >= 2 einsum forms the same products and sums
    # them in the same order at a third of the cost (checked for k = 2..8, n = 1..10^6); for one column the two
    # differ (numpy's 1-D sums are pairwise), so that keeps the reduction.
    multi = R.shape[1] >= 2
    for it in range(maxiter):
        if multi:
            sq = np.einsum("ij,ij->j", R, R)
        else:
            np.multiply(R, R, out=tmp)
            sq = np.add.reduce(tmp, axis=0)
        if (np.sqrt(sq) <= stop).all():
            break
        AP = A @ P
        alpha = rz / np.maximum(np.einsum("ij,ij->j", P, AP), 1e-300)
        times_columns(alpha, P, tmp)
        X += tmp
        times_columns(alpha, AP, AP)
        R -= AP
        np.multiply(dg, R, out=Z)
        rz_new = np.einsum("ij,ij->j", R, Z)
        times_columns(rz_new / np.maximum(rz, 1e-300), P, P)
        np.add(Z, P, out=P)
        rz = rz_new
    else:
        log.debug("heat_smooth: CG reached %d iterations", maxiter)
    return X


def _vertex_normals(vertices, faces, geom: FaceGeometry | None = None):
    fn = geom.cross if geom is not None else np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]],
                                                      vertices[faces[:, 2]] - vertices[faces[:, 0]])
    # area-weighted (the cross product's length is twice the area). bincount adds in input order, corner 0 of
    # every face, then 1, then 2: the same sums as np.add.at once per corner, at a tenth of the cost
    idx = faces.T.ravel()
    return np.stack([np.bincount(idx, weights=np.tile(fn[:, j], 3), minlength=len(vertices)) for j in range(3)], axis=1)


def _unit(v):
    return v / np.maximum(row_norms(v, keepdims=True), 1e-300)


def estimate_noise(vertices, faces, L, mass, mean_edge: float, *, vertex_normals=None, geom: FaceGeometry | None = None,
                   hinge_pairs=None) -> float:
    """Robust estimate of the vertex noise standard deviation normal to the surface.

    0 on an exact tessellation (see *hinge*). Otherwise the larger of two estimates, each biased low where the other
    is not (bench/noise.md):

    - the smaller of *hinge* and *offset*, each blind to something the other sees:

      - *hinge*: across every interior edge, the distance of the far vertex of one triangle from the
        other triangle's plane. On a noisy flat area that is ``z_d − z_a − z_b + z_c`` (standard deviation
        2σ); across a feature it is large, and on a faceted CAD tessellation (exact vertices, coplanar
        neighbours) it is 0 — the tessellation's chordal error is not noise. Lower quartile, so features
        and curvature (a quarter of the edges or more) do not count.
      - *offset*: each vertex's offset from a lightly smoothed surface (one edge length) along the smoothed
        normal, lower quartile. It needs no manifold edge pairing, but sees the curvature and the faceting.

      On dense scans with σ ≳ h/4 it reads 0.35–0.8 σ (the hinge's face normals tilt with the noise).
    - *ring* (:func:`recon.fit.ring_noise`): the area-weighted lower quartile of the residual of a quadric fitted to
      each vertex's 2-ring, at most :data:`HINGE_CAP` times the hinge estimate. 0.9–1.0 σ on the scans; lower than
      the first on decimated real scans, whose large flat triangles carry QEM-averaged vertices.

    ``vertex_normals`` (:func:`_vertex_normals`), ``geom`` and ``hinge_pairs`` (see :func:`_hinge_noise`), when the
    caller has them.
    """
    hinge = _hinge_noise(vertices, faces, geom, hinge_pairs)
    if hinge == 0.0:
        return 0.0  # an exact tessellation: min(offset, 0) is 0 whatever the offset (a smoothing saved, 0.1 s at 100k)
    s = 1.0 * mean_edge
    vn = _vertex_normals(vertices, faces, geom) if vertex_normals is None else vertex_normals
    both = heat_smooth(np.hstack([vertices - vertices.mean(axis=0), vn]), L, mass, s)
    smooth_x = both[:, :3] + vertices.mean(axis=0)
    nrm = _unit(both[:, 3:])
    d = np.einsum("ij,ij->i", vertices - smooth_x, nrm)
    # The lower quartile of |d| (0.3186 sigma for a Gaussian) rather than the median: features inflate
    # |d| near them and can cover a third of the vertices of a small part. The offset also carries the
    # noise of the neighbours the smoothing averaged: on noisy planes with a known sigma the estimate
    # came out 0.75-0.85x sigma at this window, hence the 1.2.
    offset = float(1.2 * np.percentile(np.abs(d - np.median(d)), 25) / 0.3186)
    ring = ring_noise(vertices, faces, vertex_normals=vn)
    if hinge is None:
        return max(offset, ring)
    # an underestimate is what shatters a decomposition (every fit "not within tolerance"): the larger one is kept
    return max(min(offset, hinge), min(ring, HINGE_CAP * hinge))


def hinge_pairs(faces, n_vertices: int, order=None) -> tuple[np.ndarray, np.ndarray]:
    """The two half-edges (``3 f + k`` runs from ``faces[f, k]`` to ``faces[f, (k + 1) % 3]``) of every edge with
    exactly two triangles, the smaller index first, in the order of the edges' keys ``lo · n + hi``.

    ``order``: the stable argsort of those keys, when the caller has it (:func:`recon.decompose._topology.topology`).
    """
    start = faces.ravel()
    end = np.roll(faces, -1, axis=1).ravel()
    key = np.minimum(start, end) * np.int64(n_vertices) + np.maximum(start, end)
    if order is None:
        order = stable_argsort(key, n_vertices * n_vertices)
    ks = key[order]
    pair = np.flatnonzero(ks[1:] == ks[:-1])
    # only edges with exactly two triangles (a non-manifold fan would pair arbitrary triangles)
    single = np.ones(len(pair), bool)
    single &= (pair + 2 >= len(ks)) | (ks[np.minimum(pair + 2, len(ks) - 1)] != ks[pair])
    single &= (pair == 0) | (ks[np.maximum(pair - 1, 0)] != ks[pair])
    pair = pair[single]
    return order[pair], order[pair + 1]


#: The noise is at most this many times the hinge estimate (:func:`_hinge_noise`): that reads at least 0.23 σ on every
#: scan regime (σ up to 0.5 % of the diagonal, about h/2; bench/noise.md), so a ring estimate beyond 5× it is shape
#: the 2-ring quadrics missed where most rings straddle a crease (a coarse CAD export without flat hinges), not noise.
HINGE_CAP = 5.0
#: A hinge (see :func:`_hinge_noise`) at most this share of the diagonal high is flat: its four vertices lie in one
#: plane up to the file's round-off (a text format with 6 significant digits rounds at 1e-6 of the size).
EXACT_HINGE = 1e-6
#: A mesh with at least this share of its hinges flat is noise-free (σ = 0): noise puts no four vertices in one
#: plane, a CAD export puts every facet of a plane in it (flat shares measured in bench/evidence.md). Noise of
#: σ ≲ 1e-5 of the diagonal would read as none; the tolerance's floor (5e-4 of it) is far above such noise.
EXACT_SHARE = 0.02


def _hinge_noise(vertices, faces, geom: FaceGeometry | None = None, pairs=None) -> float | None:
    """Noise from the out-of-plane height of each triangle's neighbour across an edge (see :func:`estimate_noise`);
    0 when at least :data:`EXACT_SHARE` of the hinges are flat (:data:`EXACT_HINGE`).

    ``pairs``: :func:`hinge_pairs` of the mesh, when the caller has them."""
    h1, h2 = hinge_pairs(faces, len(vertices)) if pairs is None else pairs
    if len(h1) < 8:
        return None
    start = faces.ravel()
    opp = np.roll(faces, 1, axis=1).ravel()  # the vertex opposite half-edge k
    fn = geom.unit if geom is not None else _unit(
        np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]]))
    f1 = h1 // 3
    h = np.abs(np.einsum("ij,ij->i", vertices[opp[h2]] - vertices[start[h1]], fn[f1]))
    diag = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    if np.mean(h <= EXACT_HINGE * diag) >= EXACT_SHARE:
        return 0.0
    # 0.3186 = Φ⁻¹(0.625), the lower quartile of |N(0, 1)|: the quartile read in units of σ
    return float(np.percentile(h, 25) / 0.3186 / 2.0)


def feature_field(mesh, *, scale: float | None = None, noise: float | None = None) -> FeatureField:
    """Feature measure per vertex at a scale tied to the sampling and the noise.

    Parameters
    ----------
    mesh : object with ``vertices`` (n, 3) and ``faces`` (m, 3), or a ``(vertices, faces)`` pair
    scale : float, optional
        Window standard deviation in mesh units. Default: ``max(1.5 · mean edge, 10 · noise)``.
    noise : float, optional
        Vertex noise standard deviation, if known; estimated from the mesh otherwise.

    Returns
    -------
    FeatureField
    """
    vertices, faces = mesh_arrays(mesh)
    return _feature_field(vertices, faces, scale=scale, noise=noise)


def _feature_field(vertices, faces, *, scale=None, noise=None, geom: FaceGeometry | None = None, pairs=None) -> FeatureField:
    """:func:`feature_field` of validated arrays; ``geom`` (:class:`FaceGeometry`) and ``pairs``
    (:func:`hinge_pairs`) when the caller has them (the decomposition forms them once for all its steps)."""
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise MeshError(f"`scale` must be a positive number, got {scale!r}")
    if geom is None:
        geom = FaceGeometry(vertices, faces)
    p = geom.corners
    # the edges 0-1, 1-2, 2-0 of every face (the Laplacian's side vectors; a difference and its negative have the
    # same length): the mean over all 3 m of them, in that order
    sides = [p[:, 1] - p[:, 0], p[:, 2] - p[:, 1], p[:, 0] - p[:, 2]]
    mean_edge = float(np.concatenate([row_norms(x) for x in sides]).mean())
    if not mean_edge > 0:
        raise MeshError("`mesh` has only zero-length edges")
    if geom is None:
        geom = FaceGeometry(vertices, faces)
    L, mass = _laplacian(vertices, faces, geom, sides)
    vn = _vertex_normals(vertices, faces, geom)  # the noise estimate's and the field's (the same sums)
    if noise is None:
        noise = estimate_noise(vertices, faces, L, mass, mean_edge, vertex_normals=vn, geom=geom, hinge_pairs=pairs)
    if scale is None:
        scale = max(EDGE_FACTOR * mean_edge, NOISE_FACTOR * noise)
    system = _system(L, mass, scale, 3)  # heat_smooth's default steps
    n1 = _unit(_smooth(vn, mass, system))
    mean = _smooth(n1, mass, system)
    measure = np.clip(1.0 - np.einsum("ij,ij->i", mean, mean), 0.0, 1.0)
    log.info("feature field: %d vertices, mean edge %.4g, noise %.4g, scale %.4g", len(vertices), mean_edge, noise, scale)
    return FeatureField(measure=measure, normals=n1, scale=float(scale), noise=float(noise), mean_edge=mean_edge)
