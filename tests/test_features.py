"""Feature measure: analytic values on planes and cylinders, noise estimate, invariance."""

import numpy as np
import pytest

from recon.decompose._synthetic import rounded_box
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
