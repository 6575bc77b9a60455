"""Ground truth of the committed fixtures, checked against the true solid (its JSON and its STEP)."""

import importlib.util
import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import trimesh

from recon.errors import InputError
from recon.fixtures import FIXTURE_DIR, VARIANTS, list_fixtures, load_fixture, weld

PARTS = ("box_fillet", "box_chamfer", "plate_holes", "revolved", "lofted", "prism", "pocket")


def _edges(fx):
    e = np.linalg.norm(fx.vertices[fx.faces[:, [1, 2, 0]]] - fx.vertices[fx.faces], axis=2)
    return e  # (m, 3): edge lengths per triangle


def _distance_to_surface(points, face):
    """Distance from points (k, 3) to the labelled face's (untrimmed) analytic surface; None for free-form faces."""
    p = {k: np.asarray(v, dtype=float) for k, v in face.params.items()}
    if face.type == "plane":
        return np.abs((points - p["point"]) @ p["normal"])
    if face.type == "sphere":
        return np.abs(np.linalg.norm(points - p["center"], axis=1) - p["radius"])
    if face.type in ("cylinder", "cone", "torus"):
        origin = p["apex"] if face.type == "cone" else p["point"] if face.type == "cylinder" else p["center"]
        q = points - origin
        t = q @ p["axis"]
        rho = np.linalg.norm(q - t[:, None] * p["axis"], axis=1)
        if face.type == "cylinder":
            return np.abs(rho - p["radius"])
        if face.type == "torus":
            return np.abs(np.hypot(rho - p["major_radius"], t) - p["minor_radius"])
        a = float(p["semi_angle"])  # cone: distance to the generatrix line in the (rho, t) half-plane
        return np.abs(rho * math.copysign(math.cos(a), a) - t * abs(math.sin(a)))
    return None


def _min_curvature_radius(face, points):
    """Smallest principal radius of curvature of the face's surface near ``points`` (inf for planes)."""
    p = face.params
    if face.type == "plane":
        return np.full(len(points), np.inf)
    if face.type in ("cylinder", "sphere"):
        return np.full(len(points), p["radius"])
    if face.type == "torus":
        return np.full(len(points), min(p["minor_radius"], p["major_radius"] - p["minor_radius"]))
    if face.type == "cone":
        q = points - np.asarray(p["apex"])
        axis = np.asarray(p["axis"])
        rho = np.linalg.norm(q - (q @ axis)[:, None] * axis, axis=1)
        return rho / math.cos(p["semi_angle"])
    if face.type == "bspline":  # sampled by the generator over the face's UV box
        return np.full(len(points), p["min_curvature_radius"])
    raise AssertionError(face.type)


@pytest.fixture(scope="module", params=PARTS)
def clean(request):
    return load_fixture(request.param, "clean")


def _sag(fx):
    """(m,) bound on how far each triangle strays from its true surface: ℓ²/(2R), ℓ its longest edge.

    A triangle with vertices on a surface lies in the cap its circumcircle cuts off; for the scan-like triangles
    here the circumradius is below ℓ, so the cap is at most ℓ²/(2R) deep (R the smallest radius of curvature).
    """
    centroids = fx.vertices[fx.faces].mean(axis=1)
    longest = _edges(fx).max(axis=1)
    sag = np.full(len(fx.faces), np.nan)
    for face in fx.true_faces:
        if face.type != "other":
            sel = fx.labels == face.index
            sag[sel] = longest[sel] ** 2 / (2 * _min_curvature_radius(face, centroids[sel]))
    return sag


def test_all_parts_and_variants_are_committed():
    assert set(list_fixtures()) == {(p, v) for p in PARTS for v in VARIANTS}


def test_box_fillet_has_26_true_faces():
    fx = load_fixture("box_fillet")
    assert len(fx.true_faces) == 26
    assert Counter(fx.face_types) == {"plane": 6, "cylinder": 12, "sphere": 8}
    radii = {f.params["radius"] for f in fx.true_faces if f.type != "plane"}
    assert radii == {5.0}


def test_loader_keeps_the_stl_triangle_order(clean):
    raw = trimesh.load(clean.stl_path, process=False, force="mesh")
    corners = np.asarray(raw.vertices)[np.asarray(raw.faces)]
    np.testing.assert_array_equal(clean.vertices[clean.faces], corners)
    assert len(clean.labels) == len(clean.faces)
    assert clean.vertices.dtype == np.float64 and clean.faces.dtype == np.int64


def test_clean_mesh_is_closed_with_the_true_volume_and_area(clean):
    mesh = trimesh.Trimesh(clean.vertices, clean.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert abs(mesh.volume / clean.volume - 1) < 0.01
    assert abs(mesh.area / clean.area - 1) < 0.01
    assert abs(sum(f.area for f in clean.true_faces) / clean.area - 1) < 1e-9


@pytest.mark.parametrize("variant", ["clean", "coarse"])
@pytest.mark.parametrize("part", PARTS)
def test_labels_lie_on_their_true_faces(part, variant):
    """Each triangle's centroid is on its labelled analytic surface, up to the chord sag (see ``_sag``)."""
    fx = load_fixture(part, variant)
    centroids = fx.vertices[fx.faces].mean(axis=1)
    sag = _sag(fx)
    checked = 0
    for face in fx.true_faces:
        sel = fx.labels == face.index
        dist = _distance_to_surface(centroids[sel], face)
        if dist is None:
            continue
        assert np.all(dist <= sag[sel] + 1e-5 * fx.diagonal), (face.index, face.type, dist.max())
        checked += sel.sum()
    assert checked > 0


def test_planar_triangles_face_outward(clean):
    """Triangle normals agree with the true outward plane normal (orientation and JSON normals are right)."""
    v, f = clean.vertices, clean.faces
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    for face in clean.true_faces:
        if face.type == "plane":
            assert np.all(n[clean.labels == face.index] @ np.asarray(face.params["normal"]) > 0.999)


def test_bspline_labels_lie_on_their_true_face():
    """The free-form face has no analytic distance: measure against the STEP face with OpenCascade (a sample)."""
    from build123d import Vertex, import_step

    fx = load_fixture("lofted")
    solid = import_step(fx.step_path)
    faces = solid.faces()
    assert [str(fc.geom_type).split(".")[-1].lower() for fc in faces] == list(fx.face_types)
    (bspline,) = [f.index for f in fx.true_faces if f.type == "bspline"]
    rng = np.random.default_rng(0)
    tris = rng.choice(np.flatnonzero(fx.labels == bspline), 30, replace=False)  # ~80 ms a point
    centroids = fx.vertices[fx.faces[tris]].mean(axis=1)
    longest = _edges(fx)[tris].max(axis=1)
    dist = np.array([faces[bspline].distance(Vertex(*c)) for c in centroids])
    # JSON min_curvature_radius 5.6 mm ≈ 10²/18 at the ends of the top ellipse (the loft's tightest section)
    radius = fx.true_faces[bspline].params["min_curvature_radius"]
    assert 5.0 < radius < 10.0
    assert np.all(dist <= longest**2 / (2 * radius) + 1e-5 * fx.diagonal), dist.max()


@pytest.mark.parametrize("part", PARTS)
def test_step_is_the_true_solid(part):
    from build123d import import_step

    fx = load_fixture(part, "coarse")
    solid = import_step(fx.step_path)
    assert solid.is_valid
    assert len(solid.faces()) == len(fx.true_faces)
    assert solid.volume == pytest.approx(fx.volume, rel=1e-6)


@pytest.mark.parametrize("part", PARTS)
def test_every_true_face_has_triangles(part):
    for variant in VARIANTS:
        fx = load_fixture(part, variant)
        assert set(np.unique(fx.labels)) == set(range(len(fx.true_faces))), variant


@pytest.mark.parametrize("variant", ["noisy05", "noisy20"])
@pytest.mark.parametrize("part", PARTS)
def test_noise_rms_matches_sigma(part, variant):
    clean, fx = load_fixture(part), load_fixture(part, variant)
    np.testing.assert_array_equal(fx.faces, clean.faces)
    np.testing.assert_array_equal(fx.labels, clean.labels)
    sigma = {"noisy05": 0.0005, "noisy20": 0.002}[variant] * clean.diagonal
    assert fx.info["sigma"] == pytest.approx(sigma)
    d = fx.vertices - clean.vertices
    rms = math.sqrt(np.mean(np.sum(d**2, axis=1)))
    assert abs(rms / sigma - 1) < 0.10
    # displaced along the area-weighted vertex normal: the tangential part is only float32 rounding
    v, f = clean.vertices, clean.faces
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for j in range(3):
        np.add.at(n, f[:, j], fn)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    tangential = d - np.sum(d * n, axis=1, keepdims=True) * n
    assert np.sqrt(np.mean(np.sum(tangential**2, axis=1))) < 0.05 * sigma


def test_clean_triangles_are_scan_like(clean):
    e = _edges(clean)
    ratio = e.max(axis=1) / e.min(axis=1)
    assert np.percentile(ratio, 95) < 3.0  # measured 1.5-1.7 (fixtures/README.md)
    h = clean.info["h"]
    assert np.percentile(e, 1) > 0.3 * h and np.percentile(e, 99) < 4 / 3 * h + 1e-9


@pytest.mark.parametrize("part", PARTS)
def test_coarse_has_few_large_triangles_and_is_closed(part):
    clean, coarse = load_fixture(part), load_fixture(part, "coarse")
    assert len(coarse.faces) < len(clean.faces) / 8
    mesh = trimesh.Trimesh(coarse.vertices, coarse.faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    # the volume between mesh and solid is at most Σ area × sag over the triangles of analytic faces
    # (plus float32 rounding of the STL coordinates, < 1e-6 of the diagonal)
    bound = float(np.sum(mesh.area_faces * _sag(coarse))) + mesh.area * 1e-6 * coarse.diagonal
    assert abs(mesh.volume - coarse.volume) <= bound


@pytest.mark.parametrize("part", PARTS)
def test_open_has_one_hole_of_the_stated_size(part):
    clean, fx = load_fixture(part), load_fixture(part, "open")
    mesh = trimesh.Trimesh(fx.vertices, fx.faces, process=False)
    boundary = mesh.edges_sorted[trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)]
    loops = trimesh.graph.connected_components(boundary)
    assert len(boundary) > 0 and len(loops) == 1
    # removed: triangles whose centroid is within r of the centre, on one flat or curved face
    r, ell = fx.info["hole_radius"], _edges(clean).max()
    removed = trimesh.Trimesh(clean.vertices, clean.faces, process=False).area - mesh.area
    assert math.pi * (r - ell) ** 2 <= removed <= math.pi * (r + ell) ** 2
    hole_nodes = np.unique(boundary)
    assert np.all(np.linalg.norm(fx.vertices[hole_nodes] - fx.info["hole_centre"], axis=1) < r + ell)


def test_weld_merges_duplicates_in_first_use_order():
    corners = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0], [0, 1, 0]]], dtype=float)
    v, f = weld(corners)
    np.testing.assert_array_equal(f, [[0, 1, 2], [1, 3, 2]])
    np.testing.assert_array_equal(v[f], corners)
    with pytest.raises(InputError, match="corners"):
        weld(np.zeros((2, 3)))


def test_unknown_part_or_variant_is_an_input_error():
    with pytest.raises(InputError, match="part"):
        load_fixture("teapot")
    with pytest.raises(InputError, match="variant"):
        load_fixture("prism", "wet")


def _generator():
    path = Path(__file__).resolve().parent.parent / "fixtures" / "make_fixtures.py"
    spec = importlib.util.spec_from_file_location("make_fixtures", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_generator_subdivision_stays_conforming_and_on_the_solid():
    """The --large path (1:4 subdivision with projection) on the coarse prism: closed, exact volume, 4× triangles."""
    mf = _generator()
    solid = mf.build_part("prism")
    table = mf.face_table(solid)
    h = mf.COARSE_FACTOR * mf.h_for(sum(f["area"] for f in table), mf.TARGET_TRIANGLES)
    V, T, L, kind, owner, feature, fp, ep = mf.scanlike_mesh(solid, table, h, iterations=2)
    V2, T2, L2, *_ = mf.subdivide(V, T, L, kind, owner, feature, fp, ep)
    mesh = trimesh.Trimesh(V2, T2, process=False)
    assert len(T2) == 4 * len(T) and mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(solid.volume, rel=1e-9)  # planar faces: subdivision is exact
    assert np.array_equal(np.bincount(L2), 4 * np.bincount(L))
