"""The binary STL reader gives exactly the arrays trimesh gave (``load_scene(process=False)``), so the cleaned mesh
and everything after it are the same; what it does not take (ASCII, a wrong length, non-finite corners) trimesh
still reads."""

import numpy as np
import pytest

from recon.mesh import _load, load_mesh, read_triangles


def _write_binary(path, corners, header=b"recon test"):
    tri = np.zeros(len(corners), dtype=_load._STL_DTYPE)
    tri["vertices"] = corners
    tri["normals"] = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    tri["attributes"] = np.arange(len(corners)) % 7
    path.write_bytes(header.ljust(80, b" ")[:80] + np.uint32(len(corners)).tobytes() + tri.tobytes())
    return path


def _by_trimesh(path, monkeypatch):
    with monkeypatch.context() as m:
        m.setattr(_load, "_binary_stl", lambda p: None)
        return read_triangles(path)


def _corners(seed, n=500):
    rng = np.random.default_rng(seed)
    return (rng.normal(size=(n, 3, 3)) * 10 ** rng.uniform(-3, 3)).astype(np.float32)


@pytest.mark.parametrize("header", [b"recon test", b"solid but binary"])
def test_binary_stl_reads_as_trimesh_did(tmp_path, monkeypatch, header):
    path = _write_binary(tmp_path / "m.stl", _corners(1), header)
    v, f = read_triangles(path)
    tv, tf = _by_trimesh(path, monkeypatch)
    assert v.dtype == tv.dtype == np.float64 and f.dtype == tf.dtype == np.int64
    assert np.array_equal(v, tv) and np.array_equal(f, tf)


def test_a_cad_export_cleans_to_the_same_mesh(tmp_path, monkeypatch):
    # a closed box drawn as 12 triangles, as a CAD program exports it
    box = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], np.float32)
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    tris = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    path = _write_binary(tmp_path / "box.stl", box[tris] * np.float32(37.1))
    fast = load_mesh(path)
    with monkeypatch.context() as m:
        m.setattr(_load, "_binary_stl", lambda p: None)
        slow = load_mesh(path)
    assert np.array_equal(fast.vertices, slow.vertices) and np.array_equal(fast.faces, slow.faces)
    assert np.array_equal(fast.source_face, slow.source_face) and len(fast.faces) == 12


def test_what_the_binary_reader_does_not_take_goes_to_trimesh(tmp_path):
    good = _write_binary(tmp_path / "good.stl", _corners(2, 4))
    assert _load._binary_stl(good) is not None
    bad = _corners(3, 4)
    bad[1, 2, 0] = np.nan
    assert _load._binary_stl(_write_binary(tmp_path / "nan.stl", bad)) is None
    longer = tmp_path / "longer.stl"
    longer.write_bytes(good.read_bytes() + b"\0")
    assert _load._binary_stl(longer) is None
    ascii_stl = tmp_path / "a.stl"
    ascii_stl.write_text("solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n"
                         "endfacet\nendsolid a\n")
    assert _load._binary_stl(ascii_stl) is None
    v, f = read_triangles(ascii_stl)
    assert v.shape == (3, 3) and f.tolist() == [[0, 1, 2]]
