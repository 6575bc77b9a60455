"""Feature measure: analytic values on planes and cylinders, noise estimate, invariance."""

import numpy as np
import pytest

from bench.synthetic import rounded_box
from recon.errors import MeshError
from recon.features import feature_field


def test_plane_is_zero_and_fillet_is_critical():
    V, F, L = rounded_box(size=(20, 16, 12), radius=3.0, spacing=0.5)
    ff = feature_field((V, F))
    fm = ff.face_measure(F)
    # centre of a plane, far (> 4 scales) from any fillet: the normal variance of a plane is 0
    c = V[F].mean(axis=1)
    centre = (L == 5) & (np.abs(c[:, 0]) < 3) & (np.abs(c[:, 1]) < 2)
    assert centre.any() and fm[centre].max() < 1e-3  # 20x below the smooth/critical threshold 0.02
    # on a cylinder of radius R the variance in a window of std s is about (s/R)^2 (twice smoothed: less)
    mid = (L >= 6) & (L < 18)
    s = ff.scale
    assert 0.3 * (s / 3.0) ** 2 < np.median(fm[mid]) < 1.5 * (s / 3.0) ** 2


def test_noise_estimate_tracks_sigma():
    for sigma in (0.05, 0.1):
        V, F, _ = rounded_box(size=(30, 30, 30), radius=0.0, spacing=1.0, sigma=sigma)
        ff = feature_field((V, F))
        assert 0.7 * sigma < ff.noise < 1.4 * sigma


def test_noise_of_an_exact_tessellation_is_zero():
    # every vertex lies on the box and flat neighbours are coplanar: the faceting is no noise
    V, F, _ = rounded_box(size=(20, 16, 12), radius=3.0, spacing=2.0)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    assert feature_field((V, F)).noise < 1e-9 * diag


@pytest.mark.parametrize("part", ["lofted", "revolved"])
def test_noise_of_a_coarse_cad_export_is_zero(part):
    """The coarse lofted and revolved fixtures are OpenCascade tessellations (their vertices on the true STEP),
    mostly of curved faces: the lower quartile of the hinge heights is the chords' sagitta, not noise, and their
    planar faces' facets are coplanar, which noise never makes them. Also after a rigid motion and scaling."""
    from recon.features import hinge_pairs
    from recon.fixtures import load_fixture
    from recon.mesh import load_mesh

    mesh = load_mesh(load_fixture(part, "coarse").stl_path)
    V, F = mesh.vertices, mesh.faces
    h1, h2 = hinge_pairs(F, len(V))
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    h = np.abs(np.einsum("ij,ij->i", V[np.roll(F, 1, axis=1).ravel()[h2]] - V[F.ravel()[h1]], n[h1 // 3]))
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    assert np.percentile(h, 25) > 1e-4 * diag  # what the lower quartile alone would have taken for noise
    assert feature_field((V, F)).noise == 0.0
    q, _ = np.linalg.qr(np.random.default_rng(3).normal(size=(3, 3)))
    assert feature_field((0.01 * V @ q.T + [40, -30, 7], F)).noise == 0.0
    # the same mesh with noise of σ = 0.05 % of the diagonal has no flat hinge left
    rng = np.random.default_rng(4)
    noisy = V + rng.normal(scale=5e-4 * diag, size=V.shape)
    assert feature_field((noisy, F)).noise > 0.0


def test_rigid_motion_and_scaling_invariance():
    V, F, _ = rounded_box(size=(20, 16, 12), radius=3.0, spacing=1.0)
    a = feature_field((V, F))
    q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))
    b = feature_field((2.5 * V @ q.T + [5, -3, 7], F))
    assert b.scale == pytest.approx(2.5 * a.scale, rel=1e-3)  # CG stops at a relative residual of 1e-4
    assert np.abs(a.measure - b.measure).max() < 1e-3


def test_bad_input():
    with pytest.raises(MeshError, match="faces"):
        feature_field((np.zeros((3, 3)), np.zeros((0, 3), int)))
    with pytest.raises(MeshError, match="scale"):
        V, F, _ = rounded_box(size=(4, 4, 4), radius=1.0, spacing=1.0)
        feature_field((V, F), scale=-1.0)
