"""recon._tolerance: the one rule for the default tolerance, and every stage calling it."""

import numpy as np
import pytest

from recon._tolerance import FIT_FLOOR, MESH_FLOOR, SIGMAS_PER_TOLERANCE, tolerance_for


def test_the_rule_is_four_sigma_above_its_floor():
    assert tolerance_for(0.25, 10.0) == 1.0  # 4 × 0.25 over 1e-4 × 10
    assert tolerance_for(0.0, 10.0) == pytest.approx(FIT_FLOOR * 10.0)
    assert tolerance_for(0.0, 10.0, floor=MESH_FLOOR) == pytest.approx(5e-3)
    assert SIGMAS_PER_TOLERANCE == 4.0


def test_the_fitting_default_is_the_rule():
    from recon.fit import default_tolerance

    pts = np.random.default_rng(0).uniform(0.0, [30.0, 20.0, 10.0], size=(500, 3))
    diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    assert default_tolerance(pts, sigma=0.05) == tolerance_for(0.05, diag) == 0.2
    assert default_tolerance(pts, sigma=0.0) == tolerance_for(0.0, diag) == FIT_FLOOR * diag


def test_the_decomposition_floor_is_the_mesh_floor():
    from recon.decompose._regions import TOL_FLOOR

    assert TOL_FLOOR == MESH_FLOOR
