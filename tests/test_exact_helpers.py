"""The speed helpers that stand in for numpy calls give the numpy calls' results bit for bit.

Each replaces a general numpy routine by the same floating-point operations in the same order (see their
docstrings); the decomposition's results depend on every bit, so these compare bytes, not values.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.synthetic import rounded_box
from recon.decompose._topology import topology, unique
from recon.features import FaceGeometry, _laplacian, _system, hinge_pairs, heat_smooth
from recon._array import col_means, col_sums, extent, row_norms, row_sums
from recon.fit._types import median, percentile
from recon.mesh import clean_mesh
from recon.mesh._clean import _extremes
from recon.mesh._topology import stable_argsort, unique_edges, unique_rows


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _arrays(seed: int, n: int, k: int = 3):
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((n, k)) * rng.choice([1e-8, 1.0, 1e8], size=(n, k))
    return [x, x[::2], np.asfortranarray(x), x[::-1]]


@pytest.mark.parametrize("n", [0, 1, 2, 7, 8, 9, 100, 1025, 20000])
def test_row_norms_and_sums_are_numpys(n):
    for x in _arrays(n, n):
        assert _same(row_norms(x), np.linalg.norm(x, axis=1))
        assert _same(row_norms(x, keepdims=True), np.linalg.norm(x, axis=1, keepdims=True))
        assert _same(row_sums(x), x.sum(axis=1))
        assert _same(row_sums(x * x) / 3, (x * x).mean(axis=1))
    special = np.array([[np.nan, 1.0, 2.0], [np.inf, -np.inf, 1.0], [-0.0, -0.0, -0.0], [1e200, 1e200, 1.0]])
    with np.errstate(over="ignore", invalid="ignore"):
        assert np.array_equal(row_norms(special), np.linalg.norm(special, axis=1), equal_nan=True)
        assert np.array_equal(row_sums(special), special.sum(axis=1), equal_nan=True)


@pytest.mark.parametrize("n", [1, 2, 7, 8, 9, 100, 1025, 20000])
@pytest.mark.parametrize("k", [2, 3, 6])
def test_column_sums_means_and_extent_are_numpys(n, k):
    for x in _arrays(n, 3 * n, k) + [_arrays(n, 3 * n, k)[0][::3]]:
        assert _same(col_sums(x), x.sum(axis=0))
        assert _same(col_means(x), x.mean(axis=0))
        assert extent(x) == float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))


def test_median_and_percentile_are_numpys():
    rng = np.random.default_rng(3)
    for n in list(range(1, 40)) + [99, 100, 401, 3000]:
        for t in range(6):
            a = rng.standard_normal(n) * rng.choice([1e-9, 1.0, 1e9], size=n)
            if t % 3 == 0:
                a = np.round(a)  # ties
            if t == 4:
                a[: n // 2] = -0.0
            assert _same(median(a), np.median(a))
            for q in (25, 90, 99):
                assert _same(percentile(np.abs(a), q), np.percentile(np.abs(a), q))
    b = np.array([1.0, np.nan, 3.0])
    assert np.isnan(median(b)) and np.isnan(percentile(b, 90))


def test_unique_is_numpys():
    rng = np.random.default_rng(5)
    for n in (0, 1, 2, 50, 3000):
        x = rng.integers(-20, 5000, n)
        assert _same(unique(x), np.unique(x))
        assert _same(unique(x.reshape(-1, 1)), np.unique(x.reshape(-1, 1)))


def test_stable_argsort_and_unique_rows_are_numpys():
    rng = np.random.default_rng(7)
    for n in (0, 1, 2, 9, 3000, 100_000):
        for upper in (1, 2, 50, 2**20, 2**45, 2**62):
            x = rng.integers(0, upper, n)
            assert _same(stable_argsort(x), np.argsort(x, kind="stable"))
            assert _same(stable_argsort(x, upper), np.argsort(x, kind="stable"))
        for upper, d in ((3, 2), (5000, 2), (800_000, 3)):  # the last too wide to pack with the index
            keys = rng.integers(0, upper, (n, d))
            packed = np.zeros(n, np.int64)
            for j in range(d):
                packed = packed * upper + keys[:, j]
            _, first, inverse = np.unique(packed, return_index=True, return_inverse=True)
            got = unique_rows(keys, upper)
            assert _same(got[0], first.astype(np.int64)) and _same(got[1], inverse.astype(np.int64))


def test_unique_edges_and_extremes_are_what_they_replace():
    V, F = _mesh()
    he = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lo, hi = he.min(axis=1), he.max(axis=1)
    _, first, inverse = np.unique(lo * len(V) + hi, return_index=True, return_inverse=True)
    edges, face_edges, count = unique_edges(F, len(V))
    assert _same(edges, np.column_stack([lo[first], hi[first]]))
    assert _same(face_edges, inverse.reshape(-1, 3).astype(np.int64))
    assert _same(count, np.bincount(inverse).astype(np.int64))
    for x in _arrays(11, 5000):
        lo, hi = _extremes(x)
        assert _same(lo, x.min(axis=0)) and _same(hi, x.max(axis=0))


def _mesh():
    V, F, _ = rounded_box(size=(4.0, 3.0, 2.0), radius=0.5, spacing=0.25)
    return V, F


def test_mesh_face_arrays_are_numpys_and_shared_with_face_geometry():
    V, F = _mesh()
    mesh = clean_mesh(V, F)
    V, F = mesh.vertices, mesh.faces
    v = V[F]
    cr = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    area = 0.5 * np.linalg.norm(cr, axis=1)
    assert _same(mesh.face_cross, cr)
    assert _same(mesh.face_areas, area)
    assert _same(mesh.face_normals, cr / (2.0 * area)[:, None])
    assert _same(mesh.face_centroids, v.mean(axis=1))
    g = FaceGeometry(V, F, cross=mesh.face_cross, centroid=mesh.face_centroids)
    ref = FaceGeometry(V, F)
    for name in ("cross", "norm", "unit", "centroid", "corners"):
        assert _same(getattr(g, name), getattr(ref, name))


def test_fit_stage_groupings_are_what_they_replace():
    from recon.fit._select import _chord_midpoints
    from recon.segment._labels import vertex_counts, vertex_sets, vertices_of

    V, F = _mesh()
    labels = np.random.default_rng(2).integers(0, 7, len(F))
    ids = vertex_sets(F, labels, len(V))
    for q in range(7):
        assert _same(ids(q), vertices_of(F, labels == q, len(V)))
    pairs = np.unique(np.column_stack([np.repeat(labels, 3), F.ravel()]), axis=0)
    assert np.array_equal(vertex_counts(F, labels), np.bincount(pairs[:, 0], minlength=7))
    f = F[:500]
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    key = np.unique(edges[:, 0] * len(V) + edges[:, 1])
    assert _same(_chord_midpoints(V, f), 0.5 * (V[key // len(V)] + V[key % len(V)]))


def test_topology_and_hinge_pairs_match_the_sorting_they_replace():
    V, F = _mesh()
    topo = topology(F, len(V))
    start, end = F.ravel(), np.roll(F, -1, axis=1).ravel()
    key = np.minimum(start, end) * np.int64(len(V)) + np.maximum(start, end)
    uniq, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    assert _same(topo.half_edge, inv)
    assert _same(topo.edges, np.stack([uniq // len(V), uniq % len(V)], axis=1))
    order = np.argsort(inv, kind="stable")
    two = counts[inv[order]] == 2
    twin = np.full(len(key), -1, np.int64)
    twin[order[two][0::2]], twin[order[two][1::2]] = order[two][1::2], order[two][0::2]
    assert _same(topo.twin, twin)
    h1, h2 = hinge_pairs(F, len(V))
    assert _same(h1, topo.twin_pairs[0]) and _same(h2, topo.twin_pairs[1])


def test_face_geometry_is_what_each_step_computed():
    V, F = _mesh()
    g = FaceGeometry(V, F)
    cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    assert _same(g.cross, cr)
    assert _same(g.area, 0.5 * np.linalg.norm(cr, axis=1))
    assert _same(g.unit, cr / np.maximum(np.linalg.norm(cr, axis=1, keepdims=True), 1e-300))
    assert _same(g.centroid, V[F].mean(axis=1))
    L0, m0 = _laplacian(V, F)
    L1, m1 = _laplacian(V, F, g)
    assert _same(m0, m1) and _same(L0.data, L1.data) and _same(L0.indices, L1.indices)


def _reference_pcg(A, B, X, inv_diag, rtol, maxiter=1000):
    """The block PCG as it was written before its reductions were replaced (np.linalg.norm of the residual)."""
    R = B - A @ X
    Z = inv_diag[:, None] * R
    P = Z.copy()
    rz = np.einsum("ij,ij->j", R, Z)
    stop = rtol * np.maximum(np.linalg.norm(B, axis=0), 1e-300)
    for _ in range(maxiter):
        if (np.linalg.norm(R, axis=0) <= stop).all():
            break
        AP = A @ P
        alpha = rz / np.maximum(np.einsum("ij,ij->j", P, AP), 1e-300)
        X = X + alpha * P
        R = R - alpha * AP
        Z = inv_diag[:, None] * R
        rz_new = np.einsum("ij,ij->j", R, Z)
        P = Z + (rz_new / np.maximum(rz, 1e-300)) * P
        rz = rz_new
    return X


@pytest.mark.parametrize("k", [1, 2, 3, 6])
def test_heat_smoothing_is_the_reference_pcg(k):
    V, F = _mesh()
    L, mass = _laplacian(V, F)
    values = np.random.default_rng(k).standard_normal((len(V), k))
    got = heat_smooth(values[:, 0] if k == 1 else values, L, mass, 0.4)
    A, inv_diag = _system(L, mass, 0.4, 3)
    x = values.copy()
    for _ in range(3):
        x = _reference_pcg(A, mass[:, None] * x, x, inv_diag, 1e-4)
    assert _same(got, x[:, 0] if k == 1 else x)
