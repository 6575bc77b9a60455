"""The working copy of a dense noisy scan (recon._working, issue 23): when it is made, how coarse, and what it gives."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from recon._working import EDGE_SIGMAS, USE_RATIO, noise_and_edge, working_copy, working_edge
from recon.mesh import clean_mesh, load_mesh

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "data"

#: The noisy box: 12 × 9 × 6, triangles of edge ≤ 0.25 (41k), noise σ along the normals a quarter of the mean edge,
#: 0.3 % of the diagonal: a scan's regime (σ comparable to a triangle), where the copy has 3× fewer triangles.
HALF = np.array([6.0, 4.5, 3.0])
SIGMA = 0.05


@pytest.fixture(scope="module")
def noisy_box():
    m = trimesh.creation.box(extents=2 * HALF).subdivide_to_size(0.25)
    m.merge_vertices()
    rng = np.random.default_rng(0)
    v = m.vertices + m.vertex_normals * rng.normal(scale=SIGMA, size=(len(m.vertices), 1))
    return clean_mesh(v, m.faces)


def _box_distance(points):
    """Signed distance of points to the true box."""
    q = np.abs(points) - HALF
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def test_rule_is_a_function_of_sigma_and_h():
    # the copy's edge is EDGE_SIGMAS σ̂; it is made only when that is at least USE_RATIO · h (half the triangles)
    assert working_edge(0.0, 1.0) is None  # an exact CAD export: σ = 0
    assert working_edge(0.1, 1.0) is None  # a 5k-triangle fixture: σ ≤ h / 10
    h = 1.0
    sigma = USE_RATIO * h / EDGE_SIGMAS
    assert working_edge(sigma, h) == pytest.approx(EDGE_SIGMAS * sigma)
    assert working_edge(0.99 * sigma, h) is None


@pytest.mark.parametrize("name", ["box_fillet_clean", "box_fillet_noisy20", "revolved_noisy20", "plate_holes_noisy05"])
def test_not_used_on_the_fixtures(name):
    # σ ≤ 0.1 h on every 5k-triangle fixture (edge/h ≤ 0.61 < √2, bench/scan.md): their own triangles are used
    mesh = load_mesh(FIXTURES / f"{name}.stl")
    sigma, h = noise_and_edge(mesh)
    assert EDGE_SIGMAS * sigma < USE_RATIO * h
    assert working_copy(mesh) is None


def test_copy_of_a_noisy_box(noisy_box):
    sigma, h = noise_and_edge(noisy_box)
    # the noise estimate on a regular grid at σ = h/4 reads 0.9–1.0 σ (bench/corpus/RESULTS.md)
    assert 0.85 * SIGMA <= sigma <= 1.15 * SIGMA
    work = working_copy(noisy_box)
    assert work is not None
    assert work.edge == pytest.approx(EDGE_SIGMAS * sigma)
    # quadric decimation to m (h / edge)² triangles: the copy's mean edge is the target edge up to the triangles'
    # shapes (a regular grid's edges and QEM's are not the same mix of sides and diagonals)
    assert 0.8 * work.edge <= work.mesh.mean_edge_length <= 1.25 * work.edge
    assert len(work.mesh.faces) <= len(noisy_box.faces) / USE_RATIO**2
    # the copy follows the true surface: the input's distances to it are the noise's (p99 of |N(0, σ)| = 2.58 σ)
    assert 2.2 * SIGMA <= work.deviation_p99 <= 3.0 * SIGMA <= work.tolerance
    assert np.percentile(np.abs(_box_distance(work.mesh.vertices)), 99) <= 3.0 * SIGMA
    assert work.mesh.report.closed and work.mesh.report.components == 1
    # every input triangle is labelled by a copy triangle within one copy edge of it
    gap = np.linalg.norm(noisy_box.face_centroids - work.mesh.face_centroids[work.of_input], axis=1)
    assert gap.max() <= work.mesh.mean_edge_length * 1.5


def test_copy_is_deterministic(noisy_box):
    a, b = working_copy(noisy_box), working_copy(noisy_box)
    assert a is not None and b is not None
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices) and np.array_equal(a.mesh.faces, b.mesh.faces)
    assert np.array_equal(a.of_input, b.of_input)


def test_user_tolerance_below_the_noise_keeps_the_input(noisy_box):
    # no copy is closer to the input than its noise (p99 ≈ 2.58 σ): a tolerance of 2 σ admits none
    assert working_copy(noisy_box, tolerance=2.0 * SIGMA) is None


@pytest.mark.slow
def test_convert_a_noisy_box(noisy_box):
    import recon

    res = recon.convert(noisy_box, jobs=1)
    rep = res.report
    assert rep["working_copy"]["triangles"] < len(noisy_box.faces) / 2
    assert rep["mesh"]["triangles"] == len(noisy_box.faces)  # measured and judged on the input
    assert len(res.labels) == len(noisy_box.faces)
    assert rep["validity"]["valid"] and rep["validity"]["closed"] and rep["validity"]["n_solids"] == 1
    planes = [f for f in rep["faces"] if f["surface"] == "plane"]
    # the copy bevels the creases; a strip narrower than the feature window that the planes hold is not a face
    assert len(planes) == 6 and len(rep["faces"]) == 6
    # each side's plane is fitted to the n input vertices it covers (noise σ along it): its offset is off by σ/√n
    # (n: the smallest side's share of the vertices), so the volume by at most the area times 3 such errors
    area, n = 2 * (12 * 9 + 12 * 6 + 9 * 6), len(noisy_box.vertices) * (9 * 6) / (2 * (12 * 9 + 12 * 6 + 9 * 6))
    assert abs(rep["validity"]["volume"] - 12 * 9 * 6) <= area * 3 * SIGMA / np.sqrt(n)
    # the six sides, each a plane of its true area less at most a band one copy edge wide shared with the strips the
    # copy bevels along its creases (half of it each side), and more by at most the tolerance around its rim
    edge, tol = rep["working_copy"]["mean_edge"], rep["tolerance"]
    sides = sorted([(a * b, 2 * (a + b)) for a, b in [(12, 9), (12, 9), (12, 6), (12, 6), (9, 6), (9, 6)]])
    for f, (area, rim) in zip(sorted(planes, key=lambda f: f["area"]), sides):
        assert area - edge * rim / 2 <= f["area"] <= area + tol * rim
    # the result fits the mesh as the true box does (issue 23: mesh→ours p95 ≤ 1.1 × mesh→true p95)
    true_p95 = float(np.percentile(np.abs(_box_distance(noisy_box.vertices)), 95))
    assert rep["deviation"]["mesh_to_shape"]["p95"] <= 1.1 * true_p95
