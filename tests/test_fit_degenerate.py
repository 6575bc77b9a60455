"""Fits on corrupted input: a degenerate element (a zero-area triangle, a zero normal) is left out of what it
cannot tell, and the fit stays finite without a numpy warning."""

from __future__ import annotations

import warnings

import numpy as np

from recon.fit import fit_bspline_surface
from recon.segment import vertex_normals


def test_bspline_point_with_a_zero_normal_is_fitted_as_the_others_decide():
    """A vertex whose only triangle has no area (a corrupted mesh: a corner repeated) has no normal — its area-weighted
    vertex normal is zero. The fit leaves it out of the height-field test, with no division by its zero length: the
    same fit to the last bit as when the repeated corner is given its twin's normal."""
    g = np.linspace(-1.0, 1.0, 6)
    x, y = np.meshgrid(g, g, indexing="ij")
    grid = np.column_stack([x.ravel(), y.ravel(), 0.05 * (x**2 + y**2).ravel()])
    idx = np.arange(36).reshape(6, 6)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    P = np.vstack([grid, grid[14]])  # vertex 36 repeats vertex 14
    F = np.r_[np.column_stack([a, b, c]), np.column_stack([a, c, d]), [[14, 36, 15]]]  # the last has zero area
    fn = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])
    area = np.linalg.norm(fn, axis=1)
    assert area[-1] == 0.0
    normals = vertex_normals(P, F, fn / np.where(area > 0, area, 1.0)[:, None], area / 2)
    assert not normals[36].any() and np.all(np.linalg.norm(normals[:36], axis=1) > 0.99)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        fit = fit_bspline_surface(P, normals, faces=F, tolerance=1e-3)
    assert fit, fit.reason
    assert np.isfinite(np.array(fit.params["control_points"])).all() and np.isfinite(fit.deviation["max"])
    twin = normals.copy()
    twin[36] = normals[14]
    same = fit_bspline_surface(P, twin, faces=F, tolerance=1e-3)
    np.testing.assert_array_equal(np.array(fit.params["control_points"]), np.array(same.params["control_points"]))
