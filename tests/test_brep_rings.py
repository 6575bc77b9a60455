"""ring_contains is matplotlib's point-in-path test on the same numbers: the same answer for every point, those on
the ring's vertices and edges included (it replaced ``matplotlib.path.Path.contains_points`` in the B-rep distance)."""

import numpy as np

from recon.brep import _rings
from recon.brep._rings import ring_contains

import matplotlib.path as mpath  # the reference (recon's preview still uses matplotlib)


def _same(ring, pts):
    want = mpath.Path(ring).contains_points(pts)
    got = ring_contains(ring, pts)
    assert got.dtype == bool and np.array_equal(got, want)


def test_random_rings_and_points_match_matplotlib():
    rng = np.random.default_rng(7)
    for n in (3, 4, 7, 40, 300):
        for _ in range(5):
            ring = rng.random((n, 2))  # self-intersecting rings too: the crossing parity is the rule for both
            _same(ring, rng.random((2000, 2)) * 1.4 - 0.2)


def test_points_on_vertices_and_edges_match_matplotlib():
    # a grid-aligned ring with its points on the grid: every tie of the comparisons (a point on a vertex, on a
    # horizontal or vertical edge, level with a vertex) occurs
    ring = np.array([[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]], dtype=float)
    g = np.arange(-1, 6, 0.5)
    pts = np.array([[x, y] for x in g for y in g])
    _same(ring, pts)
    _same(ring[::-1], pts)
    _same(np.vstack([ring, ring[:1]]), pts)  # an explicitly closed ring: the same answer


def test_degenerate_inputs_match_matplotlib():
    pts = np.array([[0.5, 0.5], [np.nan, 0.5], [0.5, np.inf], [2.0, 2.0]])
    _same(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]), pts)
    _same(np.array([[0.0, 0.0], [1.0, 1.0]]), pts)  # fewer than 3 vertices: nothing inside
    _same(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]), np.zeros((0, 2)))


def test_large_inputs_are_chunked_with_the_same_answer(monkeypatch):
    monkeypatch.setattr(_rings, "_PAIRS", 997)  # many batches of edges, one edge alone above the batch size too
    rng = np.random.default_rng(3)
    t = np.linspace(0, 2 * np.pi, 3000, endpoint=False)
    ring = np.c_[0.5 + 0.4 * np.cos(t), 0.5 + 0.4 * np.sin(3 * t) * np.sin(t)]
    _same(ring, rng.random((5000, 2)))
