"""Curve fits against known lines, circles (full and arcs) and splines.

Bounds are 5 × the Cramér–Rao standard deviation, σ² (JᵀJ)⁻¹ with J the Jacobian of the residuals of the
noise-free points in a minimal parametrisation (see tests/test_fit_surfaces.py). A curve point has two
residual components across the curve (noise σ per coordinate), so both are stacked.
"""

from __future__ import annotations

import numpy as np
import pytest

from recon.errors import FitError
from recon.fit import fit_bspline_curve, fit_circle, fit_curve, fit_line
from recon._array import perpendicular_frame
from bench.synthetic import add_noise, random_rotation

SIGMA = 0.01
TOL = 4 * SIGMA


def _crlb(residual, theta, sigma=SIGMA, h=1e-6):
    theta = np.asarray(theta, float)
    cols = []
    for i in range(len(theta)):
        e = np.zeros_like(theta)
        e[i] = h
        cols.append((residual(theta + e) - residual(theta - e)) / (2 * h))
    j = np.column_stack(cols)
    return sigma**2 * np.linalg.inv(j.T @ j)


def _tilt(d0, a, b):
    e1, e2 = perpendicular_frame(d0)
    d = d0 + a * e1 + b * e2
    return d / np.linalg.norm(d)


def test_line_recovers_direction():
    rng = np.random.default_rng(1)
    d = random_rotation(rng)[:, 0]
    p0 = rng.uniform(-10, 10, 3)
    t = np.linspace(0, 15, 60)
    clean = p0 + np.outer(t, d)
    fit = fit_curve(add_noise(clean, SIGMA, rng), tolerance=TOL)
    assert fit and fit.type == "line"
    e1, e2 = perpendicular_frame(d)

    def residual(x):  # the two offsets across a line through p0 + s e1 + t e2 along the tilted direction
        dd = _tilt(d, x[0], x[1])
        w = clean - (p0 + x[2] * e1 + x[3] * e2)
        w = w - np.outer(w @ dd, dd)
        return np.r_[w @ e1, w @ e2]

    cov = _crlb(residual, [0, 0, 0, 0])
    angle = np.arccos(min(1.0, abs(np.dot(fit.params["direction"], d))))
    assert angle <= 5 * np.sqrt(cov[0, 0] + cov[1, 1])
    assert np.dot(fit.params["direction"], d) > 0  # from the first point to the last
    assert np.linalg.norm(np.array(fit.params["start"]) - p0) < 5 * SIGMA
    assert np.linalg.norm(np.array(fit.params["end"]) - clean[-1]) < 5 * SIGMA


def _circle_points(rng, radius, a0, a1, n, endpoint=True):
    rot = random_rotation(rng)
    centre = rng.uniform(-10, 10, 3)
    a = np.linspace(a0, a1, n, endpoint=endpoint)
    clean = centre + radius * (np.outer(np.cos(a), rot[:, 0]) + np.outer(np.sin(a), rot[:, 1]))
    return clean, centre, rot[:, 2]


def _circle_cov(clean, centre, normal, radius):
    e1, e2 = perpendicular_frame(normal)

    def residual(x):
        nn = _tilt(normal, x[0], x[1])
        w = clean - (centre + x[2:5])
        h = w @ nn
        rho = np.linalg.norm(w - np.outer(h, nn), axis=1)
        return np.r_[rho - x[5], h]

    return _crlb(residual, [0, 0, 0, 0, 0, radius])


def test_full_circle():
    rng = np.random.default_rng(2)
    clean, centre, normal = _circle_points(rng, 7.0, 0, 2 * np.pi, 120, endpoint=False)
    fit = fit_curve(add_noise(clean, SIGMA, rng), tolerance=TOL, closed=True)
    assert fit and fit.type == "circle" and fit.params["full"]
    # a full circle of n points: σ_r = σ/√n exactly (the radial residuals average)
    assert abs(fit.params["radius"] - 7.0) <= 5 * SIGMA / np.sqrt(120)
    # centre: variance 2σ²/n per in-plane coordinate and σ²/n across the plane, so E|Δc|² = 5σ²/n
    assert np.linalg.norm(np.array(fit.params["center"]) - centre) <= 5 * SIGMA * np.sqrt(5 / 120)
    assert fit.params["end_angle"] == pytest.approx(2 * np.pi)


def test_open_polyline_around_a_circle_is_full():
    rng = np.random.default_rng(3)
    clean, _, _ = _circle_points(rng, 4.0, 0, 2 * np.pi, 90, endpoint=False)
    fit = fit_curve(add_noise(clean, SIGMA, rng), tolerance=TOL)
    assert fit.type == "circle" and fit.params["full"]


@pytest.mark.parametrize("reverse", [False, True])
def test_arc_recovers_radius_and_sweep(reverse):
    rng = np.random.default_rng(4)
    clean, centre, normal = _circle_points(rng, 6.0, 0.4, 0.4 + np.deg2rad(100), 50)
    noisy = add_noise(clean, SIGMA, rng)
    if reverse:
        clean, noisy = clean[::-1], noisy[::-1]
    fit = fit_curve(noisy, tolerance=TOL)
    assert fit and fit.type == "circle" and not fit.params["full"]
    cov = _circle_cov(clean, centre, normal, 6.0)
    assert abs(fit.params["radius"] - 6.0) <= 5 * np.sqrt(cov[5, 5])
    assert np.sum((np.array(fit.params["center"]) - centre) ** 2) <= 25 * np.trace(cov[2:5, 2:5])
    # sweep: measured between the first and last noisy points, each off by ~σ/r in angle
    assert fit.params["end_angle"] - fit.params["start_angle"] == pytest.approx(np.deg2rad(100), abs=10 * SIGMA / 6.0)
    # counter-clockwise about the returned normal from the first point to the last
    circle = fit.curve
    ends = circle.evaluate([fit.params["start_angle"], fit.params["end_angle"]])
    assert np.linalg.norm(ends[0] - noisy[0]) < 5 * SIGMA
    assert np.linalg.norm(ends[1] - noisy[-1]) < 5 * SIGMA


def test_spline_curve_recovers_shape():
    rng = np.random.default_rng(5)
    x = np.linspace(0, 10, 150)
    clean = np.column_stack([x, np.sin(x), 0.1 * x**1.5])
    fit = fit_curve(add_noise(clean, SIGMA, rng), tolerance=TOL)
    assert fit and fit.type == "bspline"
    # the noise-free curve lies within the tolerance of the fit everywhere
    assert fit.distance(clean).max() <= TOL
    assert fit.deviation["p99"] <= TOL


def test_closed_spline_curve():
    rng = np.random.default_rng(6)
    a = np.linspace(0, 2 * np.pi, 160, endpoint=False)
    clean = np.column_stack([(3 + np.cos(3 * a)) * np.cos(a), (3 + np.cos(3 * a)) * np.sin(a), np.sin(2 * a)])
    fit = fit_curve(add_noise(clean, SIGMA, rng), tolerance=TOL, closed=True)
    assert fit and fit.type == "bspline" and fit.params["periodic"]
    assert fit.distance(clean).max() <= TOL
    # periodic: the curve closes on itself
    t0, t1 = fit.curve.domain
    ends = fit.curve.evaluate([t0, t1])
    assert np.linalg.norm(ends[0] - ends[1]) < 1e-9


def test_types_are_not_over_promoted():
    """A line is not a circle, a circle not a spline (the simplest type within tolerance wins)."""
    rng = np.random.default_rng(7)
    clean, _, _ = _circle_points(rng, 50.0, 0, 0.02, 20)  # 1 mm of a 50 mm circle: sagitta 2.5 µm ≪ tol
    assert fit_curve(add_noise(clean, SIGMA, rng), tolerance=TOL).type == "line"
    clean, _, _ = _circle_points(rng, 5.0, 0, 2.0, 40)
    assert fit_curve(add_noise(clean, SIGMA, rng), tolerance=TOL).type == "circle"


def test_curve_misuse_and_failures():
    with pytest.raises(FitError, match="points"):
        fit_curve(np.zeros((4, 2)), tolerance=0.1)
    with pytest.raises(FitError, match="tolerance"):
        fit_curve(np.zeros((4, 3)), tolerance=0.0)
    line = np.column_stack([np.linspace(0, 1, 10), np.zeros(10), np.zeros(10)])
    assert not fit_circle(line)  # collinear: falsy, not an exception
    assert fit_line(line).deviation["max"] < 1e-12
    with pytest.raises(FitError, match="degree"):
        fit_bspline_curve(line, tolerance=0.1, degree=7)
