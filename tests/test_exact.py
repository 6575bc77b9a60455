"""Exact-vertex reconstruction (recon/segment/_exact.py): a CAD export's mesh, whose vertices lie on the true
surfaces to round-off, gives the true faces, types and solid.

Every expected number is analytic (a cube's volume, a prism's, a cylinder's radius) or the corpus part's own ground
truth (its face count and types from its STEP); the meshes are drawn the way CAD programs draw them: planes by their
boundary alone, a cylinder as one strip of quads.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

import recon
from recon.mesh import clean_mesh
from recon.segment._exact import exact_tessellation, roundoff

CUBE_V = np.array([[x, y, z] for x in (0.0, 10.0) for y in (0.0, 10.0) for z in (0.0, 10.0)])
#: the 6 quads of the cube, outward (counter-clockwise seen from outside)
CUBE_QUADS = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def _fan(poly):
    return [(poly[0], poly[i], poly[i + 1]) for i in range(1, len(poly) - 1)]


def _convert(mesh):
    return recon.convert(mesh, jobs=1)


def _assert_exact_solid(c, faces: dict, volume: float):
    rep = c.report
    assert "exact_vertices" in rep, "the exact path did not run"
    assert rep["faces_by_type"] == faces
    assert rep["validity"]["ok"] and rep["validity"]["closed"]
    assert rep["validity"]["volume"] == pytest.approx(volume, rel=1e-9)
    assert rep["verdict"]["ok"] is True


def test_cube_of_12_triangles_is_6_planes_of_volume_1000():
    tris = np.array([t for q in CUBE_QUADS for t in _fan(q)])
    c = _convert((CUBE_V, tris))
    _assert_exact_solid(c, {"plane": 6}, 1000.0)


def _write_obj(path, V, polys):
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in V]
    lines += ["f " + " ".join(str(i + 1) for i in p) for p in polys]
    path.write_text("\n".join(lines) + "\n")


def test_quad_faced_obj_cube(tmp_path):
    path = tmp_path / "cube.obj"
    _write_obj(path, CUBE_V, CUBE_QUADS)
    _assert_exact_solid(_convert(str(path)), {"plane": 6}, 1000.0)


def test_hexagonal_prism_of_n_gons(tmp_path):
    r, h = 10.0, 7.0
    a = np.arange(6) * np.pi / 3
    ring = np.c_[r * np.cos(a), r * np.sin(a)]
    V = np.r_[np.c_[ring, np.zeros(6)], np.c_[ring, np.full(6, h)]]
    polys = [tuple(range(5, -1, -1)), tuple(range(6, 12))]
    polys += [(i, (i + 1) % 6, 6 + (i + 1) % 6, 6 + i) for i in range(6)]
    path = tmp_path / "hex.obj"
    _write_obj(path, V, polys)
    _assert_exact_solid(_convert(str(path)), {"plane": 8}, 1.5 * np.sqrt(3) * r * r * h)


def _cylinder_export(r: float, h: float, n: int):
    """A cylinder as CAD programs export it: one strip of n quads, each cap a fan over its boundary."""
    a = np.arange(n) * 2 * np.pi / n
    ring = np.c_[r * np.cos(a), r * np.sin(a)]
    V = np.r_[np.c_[ring, np.zeros(n)], np.c_[ring, np.full(n, h)]]
    tris = []
    for i in range(n):
        j = (i + 1) % n
        tris += [(i, j, n + j), (i, n + j, n + i)]
    tris += _fan(list(range(n - 1, -1, -1))) + _fan(list(range(n, 2 * n)))
    return V.astype(np.float32).astype(float), np.array(tris)  # float32 coordinates, as a binary STL holds them


def test_cylinder_export_is_one_cylinder_and_two_planes():
    r, h = 12.5, 30.0
    c = _convert(_cylinder_export(r, h, 24))
    rep = c.report
    assert "exact_vertices" in rep
    assert rep["faces_by_type"] == {"cylinder": 1, "plane": 2}
    assert rep["validity"]["ok"] and rep["verdict"]["ok"] is True
    (cyl,) = [f for f in c.fits.values() if f.type == "cylinder"]
    eps = roundoff(c.mesh.vertices)
    assert abs(cyl.params["radius"] - r) <= eps  # the vertices are on it to float32 round-off
    # the solid is the true cylinder, not the polygonal prism the triangles enclose
    assert rep["validity"]["volume"] == pytest.approx(np.pi * r * r * h, rel=1e-6)


def test_noisy_or_dense_meshes_do_not_take_the_exact_path():
    V, F = _cylinder_export(12.5, 30.0, 24)
    rng = np.random.default_rng(0)
    noisy = clean_mesh(V + rng.normal(scale=0.03, size=V.shape), F)  # σ 0.1 % of the diagonal, a scan's
    assert not exact_tessellation(noisy, roundoff(noisy.vertices))
    # a remeshed plane has vertices inside it: split every cube face into a 4 x 4 grid
    g = np.linspace(0.0, 10.0, 5)
    verts, tris = [], []
    for axis in range(3):
        for side in (0.0, 10.0):
            base = len(verts)
            for u in g:
                for v in g:
                    p = [0.0, 0.0, 0.0]
                    p[axis], p[(axis + 1) % 3], p[(axis + 2) % 3] = side, u, v
                    verts.append(p)
            for i in range(4):
                for j in range(4):
                    a, b = base + i * 5 + j, base + (i + 1) * 5 + j
                    c2, d = b + 1, a + 1
                    tris += [(a, b, c2), (a, c2, d)] if side else [(a, c2, b), (a, d, c2)]
    dense = clean_mesh(np.array(verts), np.array(tris))
    assert not exact_tessellation(dense, roundoff(dense.vertices))


@pytest.mark.parametrize("seed", [29, 2, 8])
def test_corpus_export_seeds_give_their_true_faces(seed, tmp_path):
    from bench.corpus.truth import materialise

    truth = materialise(seed, "export", tmp_path)
    c = _convert(str(truth.mesh))
    rep = c.report
    assert "exact_vertices" in rep
    assert rep["n_faces"] == truth.meta["faces"]
    assert rep["faces_by_type"] == dict(Counter(truth.meta["face_types"]))
    assert rep["validity"]["ok"]
    # every face within round-off of the true one: the volumes differ by at most the area times the round-off
    bound = truth.meta["area"] * roundoff(c.mesh.vertices)
    assert abs(rep["validity"]["volume"] - truth.meta["volume"]) <= bound
