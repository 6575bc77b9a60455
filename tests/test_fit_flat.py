"""A quadric too flat to tell from a plane over its points is a plane; one whose curvature the points show stays.

The fitters call a sphere or cylinder whose sagitta L²/(8R) over the patch diagonal L is under the tolerance (4σ̂ of
its residuals without one) degenerate: a plane. The rule alone decides (no radius cap in patch diagonals), so a
cylinder or sphere far larger than its patch stays one wherever its sagitta is far above the noise.
"""

from __future__ import annotations

import numpy as np
import pytest

from recon.fit import fit_sphere, fit_surface

RNG_SEED = 7
N = 1600  # points per patch: a 40 × 40 grid


def _grid(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, n), np.linspace(-0.5, 0.5, n))
    return u.ravel(), v.ravel()


def _cap(radius: float, sigma: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """A unit square's worth of a sphere of ``radius`` (sagitta over the diagonal √2: 1/(4R)) with noise σ along z."""
    x, y = _grid()
    z = radius - np.sqrt(radius**2 - x**2 - y**2)
    pts = np.column_stack([x, y, z + rng.normal(0.0, sigma, x.size)])
    nrm = np.column_stack([-x, -y, radius - z]) / radius
    return pts, nrm


def _strip(radius: float, sigma: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """A unit-wide strip of a cylinder of ``radius`` about the y axis (sagitta 1/(8R)), noise σ along z."""
    x, y = _grid()
    z = radius - np.sqrt(radius**2 - x**2)
    pts = np.column_stack([x, y, z + rng.normal(0.0, sigma, x.size)])
    nrm = np.column_stack([-x, np.zeros_like(x), radius - z]) / radius
    return pts, nrm


@pytest.mark.parametrize("sigma", [1e-3, 3e-3])
def test_a_plane_with_noise_is_a_plane_not_a_large_sphere(sigma):
    # a noisy plane: the sphere through it has a sagitta of the order of the noise, which 4σ̂ does not resolve
    rng = np.random.default_rng(RNG_SEED)
    x, y = _grid()
    pts = np.column_stack([x, y, rng.normal(0.0, sigma, x.size)])
    assert not fit_sphere(pts, tolerance=4 * sigma)
    fit = fit_surface(pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)), tolerance=4 * sigma, sigma=sigma)
    assert fit and fit.type == "plane"


def test_a_sphere_whose_sagitta_is_within_4_sigma_is_a_plane():
    # R = 100 over a unit square: sagitta 1/(4R) = 2.5e-3 < 4σ = 4e-3 (and the tolerance, 4σ): a plane holds it
    rng = np.random.default_rng(RNG_SEED)
    pts, nrm = _cap(100.0, 1e-3, rng)
    sphere = fit_sphere(pts, nrm, tolerance=4e-3)
    assert not sphere and "plane" in sphere.reason
    fit = fit_surface(pts, nrm, tolerance=4e-3, sigma=1e-3)
    assert fit and fit.type == "plane"


@pytest.mark.parametrize("radius", [5.0, 20.0])
def test_a_large_cylinder_whose_sagitta_is_far_above_the_noise_stays_a_cylinder(radius):
    # R = 20 over a unit-wide strip: sagitta 1/(8R) = 6.25e-3, 31 × σ = 2e-4 and 7.8 × the tolerance 4σ
    rng = np.random.default_rng(RNG_SEED)
    sigma = 2e-4
    pts, nrm = _strip(radius, sigma, rng)
    fit = fit_surface(pts, nrm, tolerance=4 * sigma, sigma=sigma)
    assert fit and fit.type == "cylinder"
    # the radius from a sagitta s known to ~σ/√n: δR/R = δs/s, far below 5 % here
    assert abs(fit.params["radius"] - radius) < 0.05 * radius


@pytest.mark.parametrize("radius", [5.0, 20.0])
def test_a_large_sphere_whose_sagitta_is_far_above_the_noise_stays_a_sphere(radius):
    # R = 20 over a unit square: sagitta over the diagonal 1/(4R) = 0.0125, 62 × σ
    rng = np.random.default_rng(RNG_SEED)
    sigma = 2e-4
    pts, nrm = _cap(radius, sigma, rng)
    fit = fit_surface(pts, nrm, tolerance=4 * sigma, sigma=sigma)
    assert fit and fit.type == "sphere"
    assert abs(fit.params["radius"] - radius) < 0.05 * radius


def test_a_noise_free_cylinder_of_radius_far_above_the_part_stays_a_cylinder():
    # noise-free (σ̂ ~ round-off): only the tolerance limits; R = 50 over a unit strip: sagitta 2.5e-3 = 25 × 1e-4
    rng = np.random.default_rng(RNG_SEED)
    pts, nrm = _strip(50.0, 0.0, rng)
    fit = fit_surface(pts, nrm, tolerance=1e-4)
    assert fit and fit.type == "cylinder"
    assert abs(fit.params["radius"] - 50.0) < 0.01 * 50.0
