"""Creases inside a free-form face (recon/segment/_exact_crease.py): two smooth patches meeting at a known crease
angle are told from one smooth patch whose triangles turn by as much, from exact vertices on a coarse grid.

Export seed 99 (a variable fillet and the chamfers at its ends, creases of 24-49°, one B-spline holding all four
faces within the tolerance) is the corpus case; the exact path now gives up there instead of writing 52 faces for 55.
"""

from __future__ import annotations

import numpy as np
import pytest

from recon.segment._exact import _bspline_through
from recon.segment._exact_crease import crease_inside


def _grid(z, xs, ys):
    """A height field z(x, y) triangulated over the grid ``xs`` × ``ys`` (every vertex exact on it)."""
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), z(X, Y).ravel()])
    ny = len(ys)
    F = []
    for i in range(len(xs) - 1):
        for j in range(ny - 1):
            a, b, c, d = i * ny + j, (i + 1) * ny + j, (i + 1) * ny + j + 1, i * ny + j + 1
            F += [[a, b, c], [a, c, d]]
    return V, np.array(F)


def _pairs(F):
    edges = {}
    for t, f in enumerate(F):
        for k in range(3):
            edges.setdefault(tuple(sorted((int(f[k]), int(f[(k + 1) % 3])))), []).append(t)
    return np.array([ts for ts in edges.values() if len(ts) == 2])


def _normals(V, F):
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


#: a cylinder-like bend across y (radius 20, rows 2.25 apart: ~6° between rows), the same on both sides of x = 0
def _bend(Y):
    return 20.0 - np.sqrt(400.0 - Y ** 2)


XS, YS = np.linspace(-12, 12, 9), np.linspace(-9, 9, 9)


def _crease(V, F):
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    return crease_inside(V, F, _normals(V, F), np.arange(len(F)), _pairs(F),
                         lambda tris: _bspline_through(V, F, tris, 1e-4 * diag))


@pytest.mark.parametrize("degrees", [24.0, 40.0])
def test_two_patches_meeting_at_a_crease_are_told_apart(degrees):
    """Each side turns by ``degrees`` / 2 from the bend's normal at y = 0: the crease is ``degrees`` there, a little
    less where the bend tilts both normals (the median over the shared vertices is found to within 3°)."""
    k = np.tan(np.radians(degrees) / 2)
    V, F = _grid(lambda X, Y: _bend(Y) + k * np.abs(X) + 0.01 * X ** 2, XS, YS)
    shared = V[np.abs(V[:, 0]) < 1e-9]
    g = shared[:, 1] / np.sqrt(400.0 - shared[:, 1] ** 2)  # dz/dy
    n1, n2 = np.column_stack([-k + 0 * g, -g, 1 + 0 * g]), np.column_stack([k + 0 * g, -g, 1 + 0 * g])
    true = np.median(np.arccos(np.einsum("ij,ij->i", n1, n2) / np.linalg.norm(n1, axis=1) / np.linalg.norm(n2, axis=1)))
    found = _crease(V, F)
    assert found is not None
    assert abs(np.degrees(found) - np.degrees(true)) < 3


def test_one_smooth_patch_turning_as_much_holds_no_crease():
    """The same grid on one smooth surface whose triangles turn by up to 37° across x = 0 (a bend of radius 4 there,
    columns 3 apart): the sides' B-splines differ by at most 12° at the cut, a third of the triangles' dihedral."""
    V, F = _grid(lambda X, Y: _bend(Y) + np.sqrt(16.0 + X ** 2), XS, YS)
    n = _normals(V, F)
    P = _pairs(F)
    assert np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n[P[:, 0]], n[P[:, 1]]), -1, 1)).max()) > 24
    assert _crease(V, F) is None
