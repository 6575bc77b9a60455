"""A working copy at the scale the noise allows (issue 23): a scan's triangles, much smaller than its noise can resolve,
decimated to the coarsest mesh the decomposition's feature window still sees in full.

The decomposition smooths the normals in a geodesic window of ``max(EDGE_FACTOR · h, NOISE_FACTOR · σ)``
(:mod:`recon.features`). On a dense noisy scan the noise term wins: nothing narrower than ``NOISE_FACTOR · σ`` is told
apart from the noise, so triangles of ``(NOISE_FACTOR / EDGE_FACTOR) · σ`` keep that window as it is while the
decomposition, the fits and the B-rep work on ``(h_w / h)²`` times fewer triangles. Quadric-error decimation
(``fast_simplification``, what ``trimesh.simplify_quadric_decimation`` calls) keeps the copy dense where the surface
bends. It does not average the noise out (the copy's vertices lie as far from the true surface as the input's: a
noisy box, bench/scan.md); what the copy changes is the noise relative to a triangle. The copy is decomposed as any
mesh: its own noise estimate (1.2–1.6× the true σ on the corpus's scans: the decimation's error adds to the noise) sets its window and the
tolerance of its fits, which are fits to its points (the input's σ̂ there made 2–3× the faces on scan20, bench/scan.md).

The copy must itself be a surface the acceptance rule would accept for the input: the 99th percentile of the
input vertices' distances to it at most the tolerance (:data:`recon._tolerance.SIGMAS_PER_TOLERANCE` σ by default,
or the user's); a copy farther off is made again with twice the triangles (never coarser than the tolerance allows).

Imports the mesh and features stages only; :func:`recon.convert` calls :func:`working_copy` before it decomposes.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ._array import row_norms
from ._tolerance import MESH_FLOOR, tolerance_for
from .features import EDGE_FACTOR, NOISE_FACTOR, FaceGeometry, _laplacian, _vertex_normals, estimate_noise
from .mesh import Mesh, clean_mesh

__all__ = ["WorkingCopy", "working_copy", "working_edge", "USE_RATIO", "EDGE_SIGMAS"]

log = logging.getLogger(__name__)

#: The copy's edge length in noise σ: the feature window is ``NOISE_FACTOR · σ`` wide once the noise dominates, and
#: ``EDGE_FACTOR · h_w`` of a copy with this edge is that same window: the copy loses nothing the window resolves.
EDGE_SIGMAS = NOISE_FACTOR / EDGE_FACTOR
#: The copy is made when its edge is at least this many times the input's mean edge h (at most half the triangles):
#: below that the decimation and the label transfer save less than they cost, and the 5k-triangle fixtures
#: (σ ≤ h/10, h_w < h) and every exact CAD export (σ = 0) keep their own triangles.
USE_RATIO = float(np.sqrt(2.0))
#: Quadric decimation stops at this many triangles at least: fewer cannot hold the faces of a part (a box's 12
#: triangles hold 6 faces, a part of 20 faces needs rows of triangles across each).
MIN_TRIANGLES = 2000
#: Tries at twice the triangles each when the copy strays beyond the tolerance (2⁴ = 16× the first target: the input's
#: own size from any copy worth making, whose target is ≤ 1/2 of it; then the input is used as it is).
RETRIES = 4


@dataclass(frozen=True)
class WorkingCopy:
    """The decimated mesh recon decomposes and fits instead of the input, and the map back to the input.

    Attributes
    ----------
    mesh : Mesh
        The copy, cleaned.
    of_input : (m_input,) int
        For every triangle of the input mesh, the copy's triangle nearest its centroid (labels go back through it).
    sigma, h, edge, tolerance : float
        The input's estimated noise σ̂ and mean edge h, the copy's target edge ``EDGE_SIGMAS · σ̂`` and the tolerance
        the copy was checked against.
    deviation_p99 : float
        99th percentile of the input vertices' distances to the copy (≤ ``tolerance``).
    seconds : float
        What estimating the noise, decimating and checking took.
    """

    mesh: Mesh
    of_input: np.ndarray
    sigma: float
    h: float
    edge: float
    tolerance: float
    deviation_p99: float
    seconds: float = 0.0

    def input_labels(self, labels: np.ndarray) -> np.ndarray:
        """(m_input,) int: the label of the copy's triangle nearest each input triangle."""
        return np.asarray(labels)[self.of_input]

    def to_json(self) -> dict:
        return {"triangles": int(len(self.mesh.faces)), "sigma": float(self.sigma), "input_mean_edge": float(self.h),
                "edge": float(self.edge), "mean_edge": float(self.mesh.mean_edge_length),
                "tolerance": float(self.tolerance), "deviation_p99": float(self.deviation_p99),
                "seconds": round(float(self.seconds), 4)}


def noise_and_edge(mesh: Mesh) -> tuple[float, float]:
    """The input's estimated noise σ̂ (:func:`recon.features.estimate_noise`, as the decomposition estimates it) and
    its mean edge length h."""
    V, F = mesh.vertices, mesh.faces
    geom = FaceGeometry(V, F)
    h = float(mesh.mean_edge_length)
    L, mass = _laplacian(V, F, geom)
    sigma = estimate_noise(V, F, L, mass, h, vertex_normals=_vertex_normals(V, F, geom), geom=geom)
    return float(sigma), h


def working_edge(sigma: float, h: float) -> float | None:
    """The copy's target edge ``EDGE_SIGMAS · σ̂``, or None when it is under ``USE_RATIO · h`` (the input is used)."""
    edge = EDGE_SIGMAS * sigma
    return edge if edge >= USE_RATIO * h else None


def working_copy(mesh: Mesh, tolerance: float | None = None) -> WorkingCopy | None:
    """The working copy of ``mesh`` (module docstring), or None when the input's own triangles are the right scale.

    Parameters
    ----------
    mesh : Mesh
    tolerance : float, optional
        The user's tolerance; default ``tolerance_for(σ̂, diagonal, floor=MESH_FLOOR)``, the decomposition's rule.
    """
    t = time.perf_counter()
    if len(mesh.faces) < 2 * MIN_TRIANGLES or mesh.report.components != 1:
        return None  # a copy would be at its floor already; several bodies: the label transfer could cross them
    sigma, h = noise_and_edge(mesh)
    edge = working_edge(sigma, h)
    if edge is None:
        log.info("working copy: not used (σ̂ %.4g, h %.4g: edge %.4g < %.2f h)", sigma, h, EDGE_SIGMAS * sigma, USE_RATIO)
        return None
    tol = float(tolerance) if tolerance is not None else tolerance_for(sigma, mesh.diagonal, floor=MESH_FLOOR)
    target = max(MIN_TRIANGLES, int(len(mesh.faces) * (h / edge) ** 2))
    for _ in range(RETRIES + 1):
        if target >= len(mesh.faces) // 2:
            break
        copy = _decimated(mesh, target)
        if copy is not None:
            p99 = _distance_p99(mesh.vertices, copy)
            log.info("working copy: %d → %d triangles (σ̂ %.4g, h %.4g, edge %.4g), input→copy p99 %.4g (tol %.4g)",
                     len(mesh.faces), len(copy.faces), sigma, h, edge, p99, tol)
            if p99 <= tol:
                return WorkingCopy(copy, _nearest_faces(mesh, copy), sigma, h, edge, tol, p99,
                                   time.perf_counter() - t)
        target *= 2
    log.info("working copy: not used (no copy of under half the triangles within the tolerance %.4g)", tol)
    return None


def _decimated(mesh: Mesh, target: int) -> Mesh | None:
    """Quadric decimation to ``target`` triangles, cleaned; None when it is not one closed/open body as the input."""
    import fast_simplification

    v, f = fast_simplification.simplify(mesh.vertices, mesh.faces, target_count=int(target))
    copy = clean_mesh(v, f)
    rep, inp = copy.report, mesh.report
    if rep.components != 1 or rep.non_manifold_edges or rep.boundary_edges > inp.boundary_edges:
        log.info("working copy: decimation to %d triangles changed the topology (%s)", target, rep.summary())
        return None
    return copy


def _distance_p99(points: np.ndarray, copy: Mesh) -> float:
    """99th percentile of the points' distances to ``copy``: to the plane of the nearest copy vertex's normal (the copy's
    triangles are a few σ wide and the noise σ: the plane's sag over one edge is far under the tolerance)."""
    normals = _vertex_normals(copy.vertices, copy.faces)
    normals = normals / np.maximum(row_norms(normals, keepdims=True), 1e-300)
    _, idx = cKDTree(copy.vertices).query(points)
    d = np.abs(np.einsum("ij,ij->i", points - copy.vertices[idx], normals[idx]))
    return float(np.percentile(d, 99))


def _nearest_faces(mesh: Mesh, copy: Mesh) -> np.ndarray:
    """For every triangle of ``mesh``, the triangle of ``copy`` whose centroid is nearest its centroid."""
    _, idx = cKDTree(copy.face_centroids).query(mesh.face_centroids)
    return np.asarray(idx, dtype=np.int64)
