"""Spikes (a scanner's outliers): found from their own ring, moved back, and nothing else touched."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from recon.mesh import clean_mesh, move_spikes
from recon.mesh._spikes import find_spikes

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "data"


def _noisy(mesh: trimesh.Trimesh, sigma: float, seed: int) -> trimesh.Trimesh:
    rng = np.random.default_rng(seed)
    v = mesh.vertices + rng.normal(0.0, sigma, (len(mesh.vertices), 1)) * mesh.vertex_normals
    return trimesh.Trimesh(v, mesh.faces, process=False)


def _flat(mesh: trimesh.Trimesh) -> np.ndarray:
    """Vertices whose two-ring's triangles all turn less than 10° from their normal: off creases (a spike on a
    crease is not told from the crease: its ring is not planar)."""
    turn = np.zeros(len(mesh.vertices))
    cos = np.einsum("ij,ij->i", np.repeat(mesh.face_normals, 3, axis=0), mesh.vertex_normals[mesh.faces.ravel()])
    np.maximum.at(turn, mesh.faces.ravel(), np.arccos(np.clip(cos, -1, 1)))
    near = turn.copy()
    for a, b in mesh.edges_unique:
        near[a], near[b] = max(near[a], turn[b]), max(near[b], turn[a])
    return near < np.radians(10.0)


def _spiked(mesh: trimesh.Trimesh, count: int, height: float, seed: int):
    """``count`` vertices off creases, none sharing a triangle, pushed out along their normals by ``height``."""
    rng = np.random.default_rng(seed)
    chosen: list[int] = []
    taken = ~_flat(mesh)
    for i in rng.permutation(len(mesh.vertices)):
        ring = mesh.vertex_neighbors[i]
        if not taken[i] and not taken[ring].any():
            chosen.append(int(i))
            taken[i], taken[ring] = True, True
        if len(chosen) == count:
            break
    v = mesh.vertices.copy()
    v[chosen] += height * mesh.vertex_normals[chosen]
    return trimesh.Trimesh(v, mesh.faces, process=False), np.sort(chosen)


def _box(divisions: int = 24) -> trimesh.Trimesh:
    """A 10 × 10 × 10 box of ~equal triangles (subdivided faces), closed."""
    box = trimesh.creation.box((10.0, 10.0, 10.0))
    for _ in range(int(np.log2(divisions))):
        box = box.subdivide()
    return box


def _mesh(m: trimesh.Trimesh):
    return clean_mesh(m.vertices, m.faces)


@pytest.mark.parametrize("sigma", [0.0, 0.005, 0.02])
def test_spikes_on_a_noisy_box_found_exactly(sigma):
    """Spikes 1-2 % of the diagonal (the scan10-outliers regime) on a box with noise σ up to 0.1 % of the diagonal:
    exactly the spiked vertices are found, and moving them puts each back within a few σ of its face."""
    clean = _box()
    noisy = _noisy(clean, sigma, seed=1)
    diag = float(np.linalg.norm(clean.extents))
    spiked, chosen = _spiked(noisy, 8, 0.015 * diag, seed=2)
    mesh = _mesh(spiked)
    found, _ = find_spikes(mesh)
    np.testing.assert_array_equal(found, chosen)  # (clean_mesh keeps a closed mesh's vertex order)
    moved, report = move_spikes(mesh)
    assert report.to_json(diag)["count"] == 8
    assert np.all(report.offsets >= 0.015 * diag - 6 * sigma)  # at least the spike's height (less the noise)
    # back on the box: the box's surface is max |coordinate| = 5 (a corner spike would be refused: a ring on a crease)
    back = np.abs(moved.vertices[chosen]).max(axis=1)
    assert np.all(np.abs(back - 5.0) <= 6 * sigma + 1e-9)
    untouched = np.setdiff1d(np.arange(len(mesh.vertices)), chosen)
    np.testing.assert_array_equal(moved.vertices[untouched], mesh.vertices[untouched])


@pytest.mark.parametrize("make", [
    lambda: _box(),  # corners and creases: rings off a plane, fans flat on their faces
    lambda: trimesh.creation.icosphere(subdivisions=4, radius=5.0),  # offset h²/2R, every vertex alike
    lambda: trimesh.creation.cylinder(radius=2.0, height=20.0, sections=64),  # long thin triangles, fans
    lambda: trimesh.creation.annulus(r_min=1.0, r_max=3.0, height=0.2, sections=48),  # thin walls
])
def test_no_spike_on_clean_meshes(make):
    found, _ = find_spikes(_mesh(make()))
    assert len(found) == 0


def test_no_spike_in_gaussian_noise_alone():
    """8 σ: a 20,000-vertex noisy sphere (noise σ 0.1 % of the diagonal, h ≈ 1.3 %) has no vertex taken for one."""
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=5.0)
    found, _ = find_spikes(_mesh(_noisy(sphere, 0.01, seed=3)))
    assert len(found) == 0


def test_a_spiked_fixture_converts_to_the_clean_ones_faces(tmp_path):
    """Three spikes on the noisy plate with holes made one of its 7 planes a B-spline and failed both max rules; moved
    back, the result has the clean run's faces and types, and the report says how many moved and how far."""
    from recon import convert

    base = trimesh.load(FIXTURES / "plate_holes_noisy05.stl")  # welded: an STL holds a copy per triangle
    diag = float(np.linalg.norm(base.extents))
    spiked, chosen = _spiked(base, 3, 0.015 * diag, seed=4)
    clean = convert((base.vertices, base.faces), deviation=False)
    result = convert((spiked.vertices, spiked.faces), deviation=False)
    assert result.report["faces_by_type"] == clean.report["faces_by_type"]
    assert result.report["mesh"]["spikes"]["count"] == len(chosen) == 3
    assert result.report["mesh"]["spikes"]["max_moved_pct"] == pytest.approx(1.5, rel=0.1)
    assert any("spikes" in w for w in result.report["warnings"])
    assert "spikes" not in clean.report["mesh"]
    json.dumps(result.report)  # strict JSON


def test_an_exported_mesh_keeps_its_exact_corners():
    """An exported part's corner (a fan of long triangles) can stand off its ring's plane like a spike (corpus export
    seed 8: one vertex 0.3 % of the diagonal off, its fan turning 55°); such a mesh has exact vertices (39 % of its
    triangle pairs coplanar to round-off), so the conversion moves nothing."""
    from bench.corpus import regimes
    from bench.corpus.parts import part
    from recon.pipeline import SCAN_COPLANAR_SHARE, _move_spikes
    from recon.segment import coplanar_pairs, roundoff

    solid, _ = part(8)
    v, t, _ = regimes.tessellate(solid, "export", 8)
    mesh = clean_mesh(v, t)
    assert len(find_spikes(mesh)[0]) >= 1  # what the ring alone says
    assert coplanar_pairs(mesh, roundoff(mesh.vertices)).mean() >= SCAN_COPLANAR_SHARE
    kept, report = _move_spikes(mesh)
    assert kept is mesh and len(report.vertices) == 0
