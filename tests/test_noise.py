"""The mesh noise estimate :func:`recon.fit.ring_noise` against known σ, and ≈ 0 on exact meshes.

Bounds: the estimate is the lower quartile of ≥ 10k per-vertex values, each σ² χ²_ν / χ²_ν(¼) with ν ≈ 13; a
quartile of n values has a relative standard error of about √(¼·¾/n) / (f(q)·q) ≈ 1 % on σ² (½ % on σ) at n = 10⁴,
so 5 % on σ is over 5 standard errors, room for the quadric's small truncation and frame errors at σ ≤ h/2.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from recon.errors import FitError
from recon.fit import ring_noise


def _grid(n: int = 120, h: float = 1.0):
    """A flat n × n grid of right triangles with spacing ``h`` in z = 0, normals +z."""
    x, y = np.meshgrid(np.arange(n) * h, np.arange(n) * h)
    v = np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    return v, np.r_[np.c_[a, b, d], np.c_[a, d, c]], np.tile([0.0, 0.0, 1.0], (n * n, 1))


def _cylinder(radius: float, h: float = 1.0, rows: int = 100):
    """A closed-around cylinder band of near-equilateral triangles (edge ≈ ``h``), axis z; its unit normals."""
    nth = int(round(2 * np.pi * radius / h))
    th = np.linspace(0, 2 * np.pi, nth, endpoint=False)
    t, z = np.meshgrid(th, np.arange(rows) * h * np.sqrt(3) / 2)
    t = t + (np.arange(rows)[:, None] % 2) * np.pi / nth  # odd rows shifted half a step
    nrm = np.c_[np.cos(t).ravel(), np.sin(t).ravel(), np.zeros(t.size)]
    v = nrm * radius + np.c_[np.zeros(t.size), np.zeros(t.size), z.ravel()]
    i = np.arange(nth * rows).reshape(rows, nth)
    j = np.roll(i, -1, axis=1)
    f = [np.c_[i[r], j[r], i[r + 1]] if r % 2 == 0 else np.c_[i[r], j[r], j[r + 1]] for r in range(rows - 1)]
    f += [np.c_[j[r], j[r + 1], i[r + 1]] if r % 2 == 0 else np.c_[i[r], j[r + 1], i[r + 1]] for r in range(rows - 1)]
    return v, np.vstack(f), nrm


def _sphere(subdivisions: int = 5, radius: float = 1.0):
    m = trimesh.creation.icosphere(subdivisions, radius=radius)
    v = np.asarray(m.vertices, float)
    return v, np.asarray(m.faces), v / np.linalg.norm(v, axis=1, keepdims=True)


def _mean_edge(v, f) -> float:
    return float(np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=2).mean())


@pytest.mark.parametrize("ratio", [0.01, 0.1, 0.5])
@pytest.mark.parametrize("shape, seed", [(_grid, 1), (_sphere, 2)])
def test_plane_and_sphere_with_known_sigma(shape, seed, ratio):
    """The sphere: R = 1 at h ≈ 0.04, so a quadric fitted to a plane-sized ring would see the sagitta ρ²/2R ≈ 3e-3 ≫ σ."""
    v, f, n = shape()
    sigma = ratio * _mean_edge(v, f)
    noisy = v + n * np.random.default_rng(seed).normal(0.0, sigma, (len(v), 1))
    assert ring_noise(noisy, f) == pytest.approx(sigma, rel=0.05)


@pytest.mark.parametrize("radius", [6.0, 20.0])
@pytest.mark.parametrize("ratio", [0.1, 0.5])
def test_cylinder_with_known_sigma(radius, ratio):
    v, f, n = _cylinder(radius)
    sigma = ratio * _mean_edge(v, f)
    noisy = v + n * np.random.default_rng(3).normal(0.0, sigma, (len(v), 1))
    assert ring_noise(noisy, f) == pytest.approx(sigma, rel=0.05)


def test_scale_and_motion_invariant_and_deterministic():
    v, f, n = _sphere()
    noisy = v + n * np.random.default_rng(4).normal(0.0, 0.004, (len(v), 1))
    q, _ = np.linalg.qr(np.random.default_rng(5).normal(size=(3, 3)))
    a = ring_noise(noisy, f)
    assert ring_noise(noisy, f) == a
    assert ring_noise(30.0 * noisy @ q.T + [5.0, -2.0, 7.0], f) == pytest.approx(30.0 * a, rel=1e-6)


@pytest.mark.parametrize("mesh", ["plane", "sphere"])
def test_zero_on_exact_meshes(mesh):
    """Vertices exactly on the surface: a plane's rings fit exactly, a sphere's residual is the quadric's truncation
    (κ³ρ⁴/8), which the estimate subtracts; what is left is round-off."""
    v, f, _ = {"plane": _grid, "sphere": _sphere}[mesh]()
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    assert ring_noise(v, f) <= 1e-9 * diag


@pytest.mark.parametrize("radius", [6.0, 20.0])
def test_near_zero_on_an_exact_cylinder(radius):
    """A circle's height is κx²/2 + κ³x⁴/8 + κ⁵x⁶/16 + …: with the 4th-order term subtracted, what a 2-ring
    (radius ρ ≤ 2h) leaves is at most the 6th-order term κ⁵ρ⁶/16."""
    v, f, _ = _cylinder(radius)
    h = _mean_edge(v, f)
    assert ring_noise(v, f) <= (2 * h) ** 6 / radius**5 / 16


@pytest.mark.parametrize("part", ["box_chamfer", "box_fillet", "lofted", "plate_holes", "pocket", "prism", "revolved"])
def test_zero_on_clean_fixtures_and_known_sigma_on_noisy(part):
    """The clean and open fixtures are noise-free fine meshes (vertices on the true faces): 0. The noisy ones carry
    σ = 0.05 % and 0.2 % of the diagonal along the normals on ~2,500 vertices, and up to half of their area lies
    within a 2-ring of a crease (prism: a 2h band on both sides of every edge), whose rings no quadric fits: the
    lower quartile then reads at most the median of the rest, √(χ²₁₃(½) / χ²₁₃(¼)) = 1.15 σ; and 5 % for 5 standard
    errors at n ≈ 2,500."""
    from scipy.stats import chi2

    from recon.fixtures import load_fixture
    from recon.mesh import load_mesh

    high = np.sqrt(chi2.ppf(0.5, 13) / chi2.ppf(0.25, 13)) * 1.05
    for variant in ("clean", "open", "noisy05", "noisy20"):
        fx = load_fixture(part, variant)
        mesh = load_mesh(fx.stl_path)
        got = ring_noise(mesh.vertices, mesh.faces)
        if variant in ("clean", "open"):
            assert got <= 1e-9 * fx.diagonal
        else:
            sigma = {"noisy05": 5e-4, "noisy20": 2e-3}[variant] * fx.diagonal
            assert 0.95 * sigma <= got <= high * sigma


def test_rejects_bad_faces():
    v, f, _ = _grid(10)
    with pytest.raises(FitError):
        ring_noise(v, f + len(v))
