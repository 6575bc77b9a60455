"""Mesh loading and cleaning: formats, welding, dropping, orientation, components, bad input, real meshes."""

import numpy as np
import pytest
import trimesh

from recon import InputError, MeshError, clean_mesh, input_labels, load_mesh
from recon.mesh import read_triangles


def _cube():
    """Unit cube, 8 vertices, 12 outward triangles, volume 1."""
    box = trimesh.creation.box(extents=(1, 1, 1))
    return np.asarray(box.vertices, float), np.asarray(box.faces, np.int64)


def _sphere():
    s = trimesh.creation.icosphere(subdivisions=2)  # 162 V, 320 F, closed, genus 0
    return np.asarray(s.vertices, float), np.asarray(s.faces, np.int64)


def _same_triangles(mesh, ref_triangles, atol=0.0):
    """Every cleaned triangle equals its source triangle up to a cyclic shift (same orientation)."""
    got = mesh.vertices[mesh.faces]
    ref = ref_triangles[mesh.source_face]
    err = np.min([np.abs(got - np.roll(ref, k, axis=1)).max(axis=(1, 2)) for k in range(3)], axis=0)
    return bool((err <= atol).all())


def _canonical(mesh):
    """Order-free description of the geometry: sorted rows of sorted corner coordinates."""
    tri = np.sort(mesh.vertices[mesh.faces].reshape(-1, 3, 3).round(12), axis=1).reshape(-1, 9)
    return tri[np.lexsort(tri.T[::-1])]


# -- formats --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("ext", ["stl", "stl_ascii", "obj", "ply", "off", "3mf", "glb"])
def test_every_format_round_trips(tmp_path, ext):
    v, f = _sphere()
    f = f[np.random.default_rng(1).permutation(len(f))]  # an order trimesh would not produce itself
    src = trimesh.Trimesh(v, f, process=False)
    path = tmp_path / ("m." + ext.replace("_ascii", ""))
    src.export(path, file_type=ext)
    mesh = load_mesh(path)
    assert len(mesh.faces) == 320
    assert np.array_equal(mesh.source_face, np.arange(320))
    assert mesh.area == pytest.approx(src.area, rel=1e-6)  # STL/3MF/GLB store float32
    assert mesh.report.closed and mesh.report.flipped_faces == 0
    assert _same_triangles(mesh, v[f], atol=1e-6)


def test_scene_objects_concatenate_in_file_order_with_instances(tmp_path):
    bv, bf = _cube()
    sv, sf = _sphere()
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.Trimesh(bv, bf, process=False), geom_name="box")
    scene.add_geometry(trimesh.Trimesh(sv, sf, process=False), geom_name="ball",
                       transform=trimesh.transformations.translation_matrix([5, 0, 0]))
    path = tmp_path / "two.glb"
    scene.export(path)
    mesh = load_mesh(path)
    assert mesh.n_input_faces == 12 + 320
    assert mesh.report.components == 2
    # the box is the file's first geometry: its 12 triangles come first and form component 0
    assert np.array_equal(mesh.component[:12], np.zeros(12))
    assert np.array_equal(mesh.component[12:], np.ones(320))
    assert mesh.vertices[mesh.faces[12:]].mean(axis=(0, 1))[0] == pytest.approx(5, abs=1e-3)


def test_obj_keeps_face_order_across_objects_and_materials(tmp_path):
    path = tmp_path / "two.obj"
    path.write_text(
        "o first\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl red\nf 1 2 3 4\n"
        "o second\nv 0 0 1\nv 1 0 1\nv 0 1 1\nusemtl blue\nf 5/1 6/2 7/3\nusemtl red\nf -3 -1 -2\n"
    )
    v, f = read_triangles(path)
    # quad -> fan (0,1,2),(0,2,3) in place; relative indices -3,-1,-2 are vertices 5,7,6 (1-based)
    assert f.tolist() == [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 5]]


@pytest.mark.parametrize("ext", ["off", "ply"])
def test_mixed_polygons_keep_file_order(tmp_path, ext):
    pts = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n"
    polys = "3 0 1 4\n4 0 1 2 3\n3 1 2 4\n"
    if ext == "off":
        text = "OFF\n5 3 0\n" + pts + polys
    else:
        text = ("ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                "element face 3\nproperty list uchar int vertex_indices\nend_header\n" + pts + polys)
    path = tmp_path / ("mixed." + ext)
    path.write_text(text)
    _, f = read_triangles(path)
    assert f.tolist() == [[0, 1, 4], [0, 1, 2], [0, 2, 3], [1, 2, 4]]


# -- cleaning -------------------------------------------------------------------------------------------------


def test_unwelded_stl_cube_welds_to_8_vertices_and_unit_volume(tmp_path):
    v, f = _cube()
    path = tmp_path / "cube.stl"
    trimesh.Trimesh(v, f, process=False).export(path)
    assert len(read_triangles(path)[0]) == 36  # STL stores three vertices per triangle
    mesh = load_mesh(path)
    assert len(mesh.vertices) == 8 and len(mesh.faces) == 12
    assert mesh.report.welded_vertices == 28
    assert mesh.report.closed and mesh.report.components == 1
    assert mesh.volume == 1.0  # ±0.5 is exact in float32 and float64
    assert len(mesh.vertices) - len(mesh.edges_unique) + len(mesh.faces) == 2  # Euler, genus 0


def test_weld_joins_jittered_copies_across_grid_cells():
    v, f = _cube()
    tri = v[f].reshape(-1, 3) + np.random.default_rng(0).uniform(-1e-9, 1e-9, (36, 3))
    mesh = clean_mesh(tri, np.arange(36).reshape(12, 3))  # default tolerance 1e-6 * sqrt(3)
    assert len(mesh.vertices) == 8 and mesh.report.closed
    exact = clean_mesh(tri, np.arange(36).reshape(12, 3), weld_tolerance=0)
    assert len(exact.vertices) == 36 and exact.report.boundary_edges == 36


def test_permutation_gives_same_geometry_and_source_face_follows():
    v, f = _sphere()
    perm = np.random.default_rng(7).permutation(len(f))
    a = clean_mesh(v, f)
    b = clean_mesh(v, f[perm])
    assert np.array_equal(_canonical(a), _canonical(b))
    assert b.volume == pytest.approx(a.volume, rel=1e-12)
    # b's triangle i came from input triangle b.source_face[i], which is original triangle perm[...]
    assert _same_triangles(b, v[f][perm])
    assert np.array_equal(np.sort(perm[b.source_face]), np.arange(len(f)))


def test_duplicates_and_degenerates_are_counted_and_dropped():
    v, f = _cube()
    v = np.vstack([v, (v[0] + v[1]) / 2])  # an edge midpoint for a zero-area triangle
    extra = np.array([
        f[0], f[3][[1, 2, 0]], f[5],  # three same-orientation copies (one rotated)
        [0, 0, 2],  # repeated index
        [0, 8, 1],  # three distinct collinear corners
    ])
    mesh = clean_mesh(v, np.vstack([f, extra]))
    r = mesh.report
    assert (r.duplicate_faces, r.degenerate_faces, r.double_wall_faces) == (3, 2, 0)
    assert len(mesh.faces) == 12 and len(mesh.vertices) == 8  # the midpoint is no longer used
    assert np.array_equal(mesh.source_face, np.arange(12))  # the first copies are kept
    assert mesh.report.closed and mesh.volume == pytest.approx(1.0, abs=1e-12)


def test_double_wall_fin_cancels_but_flipped_copy_is_kept_once():
    v, f = _cube()
    a, b = f[0][0], f[0][1]  # an edge of the cube
    v = np.vstack([v, [3.0, 3.0, 3.0]])
    fin = np.array([[a, b, 8], [a, 8, b]])  # same triangle both ways: zero thickness
    mesh = clean_mesh(v, np.vstack([f, fin]))
    r = mesh.report
    assert (r.double_wall_faces, r.input_non_manifold_edges, r.non_manifold_edges) == (2, 1, 0)
    assert r.closed and len(mesh.faces) == 12
    # the reversed copy of a cube face would leave a hole if both went: keep the first
    mesh = clean_mesh(*_cube()[:1], np.vstack([f, f[4][::-1]]))
    assert (mesh.report.duplicate_faces, mesh.report.double_wall_faces) == (1, 0)
    assert mesh.report.closed and mesh.volume == pytest.approx(1.0, abs=1e-12)


def test_flipped_triangles_are_reoriented_outward():
    v, f = _sphere()
    rng = np.random.default_rng(3)
    bad = rng.random(len(f)) < 0.3
    g = f.copy()
    g[bad] = g[bad][:, ::-1]
    mesh = clean_mesh(v, g)
    assert mesh.report.flipped_faces == bad.sum()
    assert mesh.report.inconsistent_edges == 0
    assert _same_triangles(mesh, v[f])  # exactly the original outward orientation
    assert mesh.volume == pytest.approx(trimesh.Trimesh(v, f).volume, rel=1e-12)
    inside_out = clean_mesh(v, f[:, ::-1])
    assert inside_out.report.flipped_faces == len(f) and inside_out.volume > 0


def test_two_disjoint_cubes_are_two_components():
    v, f = _cube()
    mesh = clean_mesh(np.vstack([v, v + 2]), np.vstack([f, f + 8]))
    assert mesh.report.components == 2
    assert np.bincount(mesh.component).tolist() == [12, 12]
    assert mesh.volume == pytest.approx(2.0, abs=1e-12)


def test_open_mesh_reports_its_boundary_edges():
    v, f = _cube()
    mesh = clean_mesh(v, f[2:])  # one square side (two triangles) removed: a hole with 4 edges
    assert mesh.report.boundary_edges == 4 and not mesh.report.closed
    assert mesh.report.non_manifold_edges == 0 and mesh.report.flipped_faces == 0
    assert len(mesh.face_adjacency) == (3 * 10 - 4) // 2  # every non-boundary edge gives one pair


def test_non_manifold_edge_loads_and_is_reported():
    v = np.array([[0, 0, 0], [0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, -1, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4]])  # three triangles on edge 0-1
    mesh = clean_mesh(v, f)
    r = mesh.report
    assert (r.non_manifold_edges, r.boundary_edges, r.components) == (1, 6, 1)
    assert len(mesh.faces) == 3 and len(mesh.face_adjacency) == 0


def test_moebius_strip_orients_all_but_one_edge():
    # A band of n quads whose ends are glued with a half twist: orientable nowhere globally, and its
    # dual graph is one cycle, so exactly one edge stays inconsistent.
    n = 12
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(t), np.sin(t), np.zeros(n)], axis=1)
    w = np.stack([np.cos(t / 2) * np.cos(t), np.cos(t / 2) * np.sin(t), np.sin(t / 2)], axis=1) * 0.3
    v = np.vstack([ring + w, ring - w])
    faces = []
    for i in range(n):
        j = (i + 1) % n
        a, b = i, i + n
        c, d = (j, j + n) if j else (n, 0)  # the twist swaps the two rails
        faces += [[a, b, d], [a, d, c]]
    mesh = clean_mesh(v, np.array(faces))
    assert mesh.report.inconsistent_edges == 1
    assert mesh.report.boundary_edges == 2 * n


def test_input_labels_scatter_back_with_minus_one_for_dropped():
    v, f = _cube()
    g = np.vstack([f[:6], [[0, 0, 1]], f[6:], f[:1]])  # a degenerate at 6, a duplicate at 13
    mesh = clean_mesh(v, g)
    labels = input_labels(mesh, np.arange(len(mesh.faces)) + 10)
    assert labels.shape == (14,)
    assert labels.tolist() == list(range(10, 16)) + [-1] + list(range(16, 22)) + [-1]
    with pytest.raises(InputError, match="labels"):
        input_labels(mesh, np.zeros(3, int))


def test_derived_data_on_a_closed_sphere():
    v, f = _sphere()
    mesh = clean_mesh(v, f)
    m = len(mesh.faces)
    assert len(mesh.edges_unique) == 3 * m // 2 and len(mesh.face_adjacency) == 3 * m // 2
    assert len(mesh.vertices) - len(mesh.edges_unique) + m == 2
    ea = mesh.edges_unique[mesh.face_adjacency_edge]
    for k, (p, q) in enumerate(mesh.face_adjacency[:50]):  # the shared edge is in both triangles
        assert set(ea[k]) <= set(mesh.faces[p]) & set(mesh.faces[q])
    vf = mesh.vertex_faces
    assert sorted(set(np.diff(vf.offsets))) == [5, 6]  # icosphere valences
    assert vf[0].tolist() == np.flatnonzero((mesh.faces == 0).any(axis=1)).tolist()
    assert np.allclose(np.linalg.norm(mesh.face_normals, axis=1), 1)
    assert (np.einsum("ij,ij->i", mesh.face_normals, mesh.face_centroids) > 0).all()  # outward
    assert mesh.diagonal == pytest.approx(2 * np.sqrt(3), rel=1e-9)  # unit sphere: bbox [-1, 1]^3
    assert mesh.to_trimesh().volume == pytest.approx(mesh.volume, rel=1e-12)
    e = mesh.edges_unique
    assert mesh.mean_edge_length == pytest.approx(np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1).mean())


# -- bad input --------------------------------------------------------------------------------------------


def _bad_files(tmp_path):
    cases = {}
    cases["missing"] = (tmp_path / "nope.stl", InputError, "no such file")
    p = tmp_path / "empty.stl"
    p.write_bytes(b"")
    cases["empty"] = (p, MeshError, "empty")
    p = tmp_path / "shape.step"
    p.write_text("ISO-10303-21;")
    cases["unknown format"] = (p, InputError, r"\.stl, \.obj, \.ply, \.off, \.3mf, \.glb")
    p = tmp_path / "garbage.glb"
    p.write_bytes(b"\x00\x01 not a gltf at all" * 10)
    cases["corrupt glb"] = (p, MeshError, "cannot read as GLB")
    p = tmp_path / "garbage.ply"
    p.write_bytes(b"this is not a ply file\n" * 5)
    cases["corrupt ply"] = (p, MeshError, "cannot read as PLY")
    p = tmp_path / "trunc.off"
    p.write_text("OFF\n4 2 0\n0 0 0\n1 0 0\n")
    cases["truncated off"] = (p, MeshError, "truncated")
    p = tmp_path / "nan.off"
    p.write_text("OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n")
    cases["nan"] = (p, MeshError, "NaN or infinite")
    p = tmp_path / "points.obj"
    p.write_text("v 0 0 0\nv 1 0 0\n")
    cases["no triangles"] = (p, MeshError, "no triangles")
    p = tmp_path / "flat.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n")
    cases["no triangles after cleaning"] = (p, MeshError, "no triangles left after cleaning")
    p = tmp_path / "badindex.off"
    p.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    cases["index out of range"] = (p, MeshError, "outside 0..2")
    return cases


CASES = ["missing", "empty", "unknown format", "corrupt glb", "corrupt ply", "truncated off", "nan",
         "no triangles", "no triangles after cleaning", "index out of range"]


@pytest.mark.parametrize("case", CASES)
def test_bad_input_raises_one_line_naming_the_file(tmp_path, case):
    path, kind, match = _bad_files(tmp_path)[case]
    with pytest.raises(kind, match=match) as info:
        load_mesh(path)
    msg = str(info.value)
    assert str(path) in msg and "\n" not in msg


def test_bad_arrays_and_tolerance_name_the_argument():
    v, f = _cube()
    with pytest.raises(MeshError, match="vertices must be an"):
        clean_mesh(v[:, :2], f)
    with pytest.raises(MeshError, match="faces must be an"):
        clean_mesh(v, f.astype(float))
    with pytest.raises(InputError, match="weld_tolerance"):
        clean_mesh(v, f, weld_tolerance=-1)


# -- real meshes nobody here made (shared/meshes/README.md) ----------------------------------------------

REAL = [  # file, input triangles, kept vertices, components, genus per Euler (None: not checked), input NM edges
    ("fandisk.off", 14454, 7229, 1, 0, 0),
    ("fandisk-b.off", 12946, 6475, 1, None, 0),
    ("fandisk-b_noisy0.1.off", 12946, 6475, 1, None, 0),
    ("joint.off", None, 20902, 1, 2, 0),
    ("rocker-arm2500.off", None, 2500, 1, 1, 0),
    ("rocker-arm.off", None, 10044, 1, 1, 0),
    ("block.off", None, None, 1, 3, 0),
    ("casting.off", None, None, 1, 9, 0),
    # README says genus 3, which is the raw file's naive Euler count (chi = -4) with its 12 zero-thickness
    # flaps: each flap (2 copies, 2 hinge edges, 1 free edge) adds +1 to chi. Without them the surface is a
    # closed 2-manifold (no pinched vertex) with chi = -4 - 12 = -16, genus 9.
    ("crank.off", 100028, None, 1, 9, 24),
    ("abc_00000050.stl", 7614, None, 3, None, 0),
]


@pytest.mark.parametrize("name,n_faces,n_vertices,components,genus,input_nm", REAL, ids=[r[0] for r in REAL])
def test_real_meshes_load(shared_meshes, name, n_faces, n_vertices, components, genus, input_nm):
    path = shared_meshes / name
    mesh = load_mesh(path)
    r = mesh.report
    if n_faces is not None:
        assert r.n_input_faces == n_faces
    if n_vertices is not None:
        assert len(mesh.vertices) == n_vertices
    assert r.components == components
    assert r.input_non_manifold_edges == input_nm
    assert r.closed and r.inconsistent_edges == 0 and mesh.volume > 0
    if genus is not None:
        euler = len(mesh.vertices) - len(mesh.edges_unique) + len(mesh.faces)
        assert euler == 2 - 2 * genus
