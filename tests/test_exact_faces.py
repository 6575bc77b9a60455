"""The exact-vertex faces (recon/segment/_exact.py) of parts tessellated by OpenCascade at CAD export settings: the
true face count and types, from the vertices alone (no B-rep built: these check the segmentation only).

Expected numbers are the parts' own (a filleted cylinder: 1 cylinder, 2 tori, 2 planes) or the corpus part's ground
truth from its STEP.
"""

from __future__ import annotations

from collections import Counter

import build123d as bd
import numpy as np
import pytest

from recon.mesh import clean_mesh, load_mesh
from recon.segment._exact import exact_faces, plane_atoms, roundoff
from recon.segment._exact_freeform import impossible_types

#: the run's tolerance as recon picks it for a noise-free mesh: 1e-4 of the diagonal
TOL_SHARE = 1e-4


def _faces(mesh):
    eps = roundoff(mesh.vertices)
    found = exact_faces(mesh, TOL_SHARE * float(mesh.diagonal), plane_atoms(mesh, eps))
    assert found is not None, "the exact path gave up"
    return found


def _export(solid, chord: float, angle: float):
    """``solid`` tessellated as the corpus's ``export`` regime does (OCC, chord ``chord`` of the diagonal)."""
    from bench.corpus.regimes import make_fixtures

    bb = solid.bounding_box()
    diag = (bb.max - bb.min).length
    v, t = make_fixtures().occ_mesh(solid, deflection=chord * diag, angular=angle)[:2]
    return clean_mesh(np.asarray(v, float), np.asarray(t))


@pytest.mark.parametrize("chord, angle", [(1e-3, 0.5), (1e-3, 0.3)])
def test_filleted_cylinder_is_one_cylinder_two_tori_two_planes(chord, angle):
    """The side's strips next to a fillet lie on a cylinder along the torus's minor circle too: the torus, proven by
    more vertices, takes them back (before: the exact path gave up on it)."""
    solid = bd.fillet(bd.Cylinder(27, 20).edges(), 2)
    found = _faces(_export(solid, chord, angle))
    assert dict(Counter(f.type for f in found.fits.values())) == {"cylinder": 1, "torus": 2, "plane": 2}


def test_slot_prism_is_two_cylinders_and_four_planes():
    solid = bd.extrude(bd.SlotOverall(60, 20), 5)
    found = _faces(_export(solid, 1e-3, 0.5))
    assert dict(Counter(f.type for f in found.fits.values())) == {"cylinder": 2, "plane": 4}


def test_a_notch_drawn_as_three_quads_is_its_cylinder_not_a_sphere_nor_planes():
    """Export seed 20: a cylinder's short arc drawn as three quads was seeded as the simplest surface holding its two
    arcs of vertices, a sphere (two coaxial circles of one radius lie on a sphere), whose chords lie 12x farther from it
    than the cylinder's; judged by that sphere's sag the three quads were dropped as planes (11 faces for 9). Judged
    by the best type, the cylinder (its quads' edges are rulings on it), they are the notch's face."""
    solid = bd.Box(20, 20, 3) - bd.Cylinder(3, 3) - bd.Pos(14.5, 0, 0) * bd.Cylinder(4.7, 3)
    assert len(solid.faces()) == 9
    found = _faces(_export(solid, 2e-3, 0.5))
    assert dict(Counter(f.type for f in found.fits.values())) == {"cylinder": 2, "plane": 7}


@pytest.mark.parametrize("seed", [6, 19, 20, 35, 36, 56, 78, 122])
def test_corpus_seeds_get_their_true_faces_and_types(seed, tmp_path):
    """Parts whose faces the first seeds split or merged with a neighbour's strips: a slot's side with the end strips
    of its half-cylinders (36), cylinders along a torus (19), fillet chains (6), a cylinder drawn as a sphere (56), two
    counterbore arcs of three quads dropped as planes (20), a pocket rim's fillet tori drawn as ~30 bands each of
    cones, cylinders and spheres (35: 88 faces of 35 before its bands were joined), a chamfered polygon prism whose
    10 corner faces are one triangle each (78: the path gave up, taking them for pieces of a free-form face), a loft's
    wall of 3,152 triangles whose B-spline missed the tolerance on the coarse grid and whose flat pairs stayed planes
    (122: the path gave up)."""
    found, true, meta = _corpus_faces(seed, tmp_path)
    assert int(found.labels.max()) + 1 == meta["faces"]
    assert dict(Counter(f.type for f in found.fits.values())) == dict(Counter(meta["face_types"]))
    for p in range(int(found.labels.max()) + 1):  # every face is one true face
        assert len(np.unique(true[found.labels == p])) == 1
    assert not [n for n in found.notes if "not proven" in n]


def test_two_quads_a_cylinder_holds_are_planes_where_the_only_curved_faces_are_tori_no_exporter_drew(tmp_path):
    """Export seed 112: a 45° chamfer quad and its neighbour quad (3 parallel lines of vertices lie on a cylinder) are
    planes when their chords sag more than the well-drawn curved faces' (the weak-face rule); that limit came from
    three-ring tori whose chords sag 1.08 (the wall and chamfer of a boss taken as one, split into their bands later),
    so the cylinders (sag 1.02) were kept: 11 faces of 13. Such tori set no limit: 13 of 13, each one true face."""
    found, true, meta = _corpus_faces(112, tmp_path)
    assert int(found.labels.max()) + 1 == meta["faces"] == 13
    assert dict(Counter(f.type for f in found.fits.values())) == dict(Counter(meta["face_types"]))
    for p in range(int(found.labels.max()) + 1):
        assert len(np.unique(true[found.labels == p])) == 1


def test_a_split_band_tangent_to_a_fillet_leaves_the_count_proven(tmp_path):
    """Export seed 126: four split bands (cylinders) meet fillet tori with no turn at all (0.00°, against ring sections
    of 8.2°); the guard that leaves a count open where a band meets a neighbour as smoothly as a profile drawn in rings
    turns (seed 128: 7.67° against 4.0°) took those blend edges for such rings: 37 of 37 faces, count open, exit 1.
    A join within the fits' round-off tilts is a tangent edge: the count is proven."""
    found, true, meta = _corpus_faces(126, tmp_path)
    assert int(found.labels.max()) + 1 == meta["faces"] == 37
    for p in range(int(found.labels.max()) + 1):
        assert len(np.unique(true[found.labels == p])) == 1
    assert not found.open_count


def test_a_variable_fillet_cut_into_pieces_at_kinks_is_not_given_as_faces(tmp_path):
    """Export seed 30: a variable-radius fillet (one B-spline face) that the second pass cut into 6 cylinders and 4
    planes of 1-3 triangles, meeting at kinks of 4.5-11 degrees a blend cannot have: 16 faces for 7, which recon wrote
    with exit 0. Faces the loose rims made, with kinks left, are not proven: the path gives up and the decomposition
    takes the mesh (the command then gives the 7 faces, as before the second pass)."""
    from bench.corpus.truth import materialise

    truth = materialise(30, "export", tmp_path)
    mesh = load_mesh(str(truth.mesh))
    eps = roundoff(mesh.vertices)
    assert exact_faces(mesh, TOL_SHARE * float(mesh.diagonal), plane_atoms(mesh, eps)) is None


def test_a_face_the_loose_rims_made_is_kept_where_its_turn_is_the_fits_own_tilt(tmp_path):
    """Export seed 39: the second pass finds a cone of 12 triangles (rims within the tolerance) that a plane of one
    triangle meets tangentially; the turn there, 1.7e-4 rad, is above the triangle's round-off tilt but under the
    tilt of a surface fitted through rims missing by the tolerance (2 tol over the cone's reach, >= 4.9e-4 rad), so it is
    not a kink: the path gives the true 31 faces, each one true face, where it gave up (and the decomposition 17)."""
    found, true, meta = _corpus_faces(39, tmp_path)
    assert int(found.labels.max()) + 1 == meta["faces"]
    for p in range(int(found.labels.max()) + 1):
        assert len(np.unique(true[found.labels == p])) == 1


def test_a_variable_fillet_and_its_end_chamfers_held_by_one_bspline_are_not_given_as_faces(tmp_path):
    """Export seed 99: one B-spline held a variable fillet, the two chamfers at its ends and a sliver beside one of them
    (4 true faces; creases of 22-47° between the fillet and the chamfers, the sliver tangent to its chamfer) within
    the tolerance: 52 faces for 55, which recon wrote with exit 0. Cut at its sharpest edges, the piece's sides'
    own B-splines turn by 24° at the shared vertices (the triangles there by 29°): a crease, so the count is not
    proven and the path gives up."""
    from bench.corpus.truth import materialise

    truth = materialise(99, "export", tmp_path)
    mesh = load_mesh(str(truth.mesh))
    eps = roundoff(mesh.vertices)
    assert exact_faces(mesh, TOL_SHARE * float(mesh.diagonal), plane_atoms(mesh, eps)) is None


def test_a_variable_fillet_cut_into_a_cone_and_planes_takes_its_end_quads_through_loose_rims(tmp_path):
    """Export seed 65: a variable-radius fillet (one B-spline face of 8 triangles, 9 vertices) lies on a cone: 7 of its
    vertices to round-off, the end quads' other 2, which the planes beside them hold to round-off, within 9.1
    round-offs (the run's tolerance is 50). The first pass left the end quads planes at a kink (26 faces, "not
    proven"); the second, where a vertex a found face holds may miss its neighbour by the tolerance, joins them to the
    cone: the true 24 faces, each one true face. (The vertices prove the partition; the fillet's surface is still a
    cone for a B-spline.)"""
    found, true, meta = _corpus_faces(65, tmp_path)
    assert int(found.labels.max()) + 1 == meta["faces"]
    for p in range(int(found.labels.max()) + 1):  # every face is one true face
        assert len(np.unique(true[found.labels == p])) == 1


def _corpus_faces(seed: int, tmp_path):
    """The exact path's faces of an export seed, the true face of every triangle and the part's metadata."""
    from bench.corpus.truth import materialise

    truth = materialise(seed, "export", tmp_path)
    found = _faces(load_mesh(str(truth.mesh)))
    true = np.load(truth.mesh.with_suffix(".labels.npy"))
    assert len(true) == len(found.labels)  # the loader keeps an exported mesh's triangles in order
    return found, true, truth.meta


@pytest.mark.parametrize("seed", [151, 164])
def test_a_variable_fillet_in_coincidental_pieces_tangent_to_its_plane_is_one_bspline(seed, tmp_path):
    """Export seeds 151 (blended, 7 faces) and 164 (prismatic, 18): one variable fillet was cut into cylinders,
    cones and tori that hold a few of its rows to round-off, with single triangles between them; the pieces along
    its plane border that plane tangentially only where the blend does, so they were taken for a true face tangent to
    it and not joined (the path gave up). Their surfaces meet the plane at a kink (700-10,000 times round-off's
    tilt): the pieces join, and one B-spline holds the fillet whole. Every face is one true face."""
    found, true, meta = _corpus_faces(seed, tmp_path)
    assert int(found.labels.max()) + 1 == meta["faces"]
    assert dict(Counter(f.type for f in found.fits.values())) == dict(Counter(meta["face_types"]))
    for p in range(int(found.labels.max()) + 1):
        assert len(np.unique(true[found.labels == p])) == 1
    assert not found.open_count


def test_pieces_of_one_torus_meeting_across_the_meshs_own_creases_are_one_face(tmp_path):
    """Export seed 116: a fillet round a slot's top (r 0.86 on R 42.7) drawn one or two triangles across turns by more
    than a crease between its own pieces; each torus piece and the short cylinders between them hold their vertices
    to round-off, and one torus holds each whole true face (within 1.9e-6, round-off 2.8e-4), but only pieces across
    no crease were asked to join: the path gave up on their kinks (exit 1, an open shell). Joined by the surface test
    alone: 72 of 72 faces, each one true face, of the true types, the count proven."""
    found, true, meta = _corpus_faces(116, tmp_path)
    assert int(found.labels.max()) + 1 == meta["faces"] == 72
    assert dict(Counter(f.type for f in found.fits.values())) == dict(Counter(meta["face_types"]))
    for p in range(int(found.labels.max()) + 1):
        assert len(np.unique(true[found.labels == p])) == 1
    assert not found.open_count


def test_a_fillet_corner_of_thirteen_vertices_is_its_torus(tmp_path):
    """Export seed 48: a torus of 14 triangles (13 vertices) came out as 2 cylinders, a sphere and 2 planes, because
    its torus fit stopped on the evaluation budget at a spindle torus; continued, it holds them to round-off. (A cone
    of 3 quads there is still taken as a cylinder: the count and the faces are right, one type is not.)"""
    found, true, meta = _corpus_faces(48, tmp_path)
    assert int(found.labels.max()) + 1 == meta["faces"]
    for p in range(int(found.labels.max()) + 1):
        assert len(np.unique(true[found.labels == p])) == 1


def test_impossible_types_never_reject_the_true_surface():
    """Points exactly on a sphere, a cylinder, a cone, a torus (to float32 round-off): the proof rules out no type
    whose family holds them, and rules out the sphere and the quadrics for the torus."""
    rng = np.random.default_rng(0)
    u, v = rng.uniform(0, 2 * np.pi, 200), rng.uniform(0, np.pi, 200)
    sphere = 7.0 * np.c_[np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)]
    cyl = np.c_[3.0 * np.cos(u), 3.0 * np.sin(u), rng.uniform(0, 10, 200)]
    z = rng.uniform(1, 10, 200)
    cone = np.c_[0.5 * z * np.cos(u), 0.5 * z * np.sin(u), z]
    torus = np.c_[(10 + 2 * np.cos(v * 2)) * np.cos(u), (10 + 2 * np.cos(v * 2)) * np.sin(u), 2 * np.sin(v * 2)]
    for P, kind in ((sphere, "sphere"), (cyl, "cylinder"), (cone, "cone"), (torus, "torus")):
        P = (P + [5.0, -3.0, 2.0]).astype(np.float32).astype(float)
        eps = roundoff(P)
        assert kind not in impossible_types(P, eps)
    assert {"sphere", "cylinder", "cone"} <= impossible_types(torus.astype(np.float32).astype(float), roundoff(torus))



def test_a_finely_drawn_torus_grows_as_one_region(tmp_path):
    """Export seed 10 (a whole torus, R 34.85 / r 6.79 on a tilted axis, ~14k triangles) was 211 grown regions: a
    seed's three rings pin a torus only to within round-off, the grow refitted only to more complex types, and a torus
    has none. Refitted as the same type each time the region doubles, one region holds nearly all the atoms that no
    region before it took (before: the largest held 40 %)."""
    import recon.segment._exact as E
    from bench.corpus.truth import materialise

    mesh = load_mesh(str(materialise(10, "export", tmp_path).mesh))
    eps, sag = roundoff(mesh.vertices), E.SAG_SHARE * float(mesh.diagonal)
    at = E._Atoms.of(mesh, plane_atoms(mesh, eps))
    regions = E.grow_curved(at, eps, sag)
    sizes = sorted((len(r) for r, _ in regions), reverse=True)
    assert all(f.type == "torus" for _, f in regions)
    assert sizes[0] >= 0.9 * len(at.tris), sizes[:5]
    assert [f.type for f in _faces(mesh).fits.values()] == ["torus"]


def test_a_narrow_chamfer_band_tangent_to_a_sphere_is_its_cone():
    """Export seeds 53 and 112: a chamfer band of two rings lies on a cone and on a sphere centred on the axis; where the
    band is square to the sphere's radius (a 45° chamfer as far from the centre along the axis as across it) its
    0.3 mm rulings sag off that sphere by ℓ²/8R ≈ 2e-4, under the round-off, so both hold every edge and the sphere
    came first. The cone holds its rulings as closely as its own vertices (to 1e-6), the sphere only to its sag."""
    solid = bd.chamfer(bd.Cylinder(42.39, 84.78).edges(), 0.21)
    found = _faces(_export(solid, 1e-3, 0.5))
    assert Counter(f.type for f in found.fits.values()) == Counter(f.geom_type.name.lower() for f in solid.faces())


@pytest.mark.parametrize("chord", [1e-4, 1e-3])
def test_a_cylinder_wall_and_its_chamfer_on_three_rings_are_not_given_as_one_torus(chord):
    """A boss of one band (two rings) with a 0.5 chamfer (one band more): any three circles about one axis lie on a
    torus, and the path took the wall and the chamfer as one (9 faces of 10, given as proven; export seed 169 the same:
    8 of 9, exit 0). The export's own rings refute that torus: its meridian turns by 45° across the chamfer's band,
    where a ring's sections turn by 360° / n (n ≥ 13 at 0.5 rad), and sags far more than their chords. So the bands
    are two faces: the wall's cylinder and the chamfer's cone, 10 of 10, the count proven."""
    solid = bd.chamfer((bd.Box(70, 60, 6) + bd.Pos(0, 0, 5.5) * bd.Cylinder(30, 5)).edges().sort_by(bd.Axis.Z)[-1], 0.5)
    assert len(solid.faces()) == 10
    mesh = _export(solid, chord, 0.5)
    eps = roundoff(mesh.vertices)
    found = exact_faces(mesh, TOL_SHARE * float(mesh.diagonal), plane_atoms(mesh, eps))
    assert found is not None and not found.open_count
    assert Counter(f.type for f in found.fits.values()) == Counter(f.geom_type.name.lower() for f in solid.faces())


def test_an_open_count_never_exits_0(tmp_path):
    """Export seed 141 through the whole pipeline: a plane ring 0.0058 wide that a fillet's torus holds to round-off
    leaves the count open (12 or 13 faces: it gave 12 with exit 0). The decomposition's result fails a rule, so the
    exact faces are the answer, with the face_count rule failing and the reason in the report: exit 1."""
    from bench.corpus.truth import materialise
    from recon import convert

    result = convert(str(materialise(141, "export", tmp_path).mesh))
    assert not result.verdict.ok and "face_count" in [r.rule for r in result.verdict.failed]
    assert result.report["exact_vertices"]["open_count"] and result.report["n_faces"] == 12


def test_a_two_band_fillet_tangent_to_its_neighbours_is_the_face(tmp_path):
    """Export seed 114 (revolved, 19 true faces): a fillet drawn as two bands lies on three rings like 169's wall and
    chamfer, but meets the faces beside it tangentially (the torus's normal at its outer rings is theirs, to the
    triangles' round-off tilt), where a wall and its chamfer meet theirs at creases: it is the face, and the path
    gives the true count (it gave up on it when every three-ring torus was unproven)."""
    from bench.corpus.truth import materialise
    from recon.segment._exact_rings import RING_SPREAD, rings

    truth = materialise(114, "export", tmp_path)
    mesh = load_mesh(str(truth.mesh))
    eps = roundoff(mesh.vertices)
    found = exact_faces(mesh, TOL_SHARE * float(mesh.diagonal), plane_atoms(mesh, eps))
    assert found is not None and len(found.fits) == truth.meta["faces"] == 19
    three = [p for p, f in found.fits.items() if f.type == "torus" and rings(
        mesh.vertices[np.unique(mesh.faces[found.labels == p])], np.asarray(f.params["center"], float),
        np.asarray(f.params["axis_dir"], float), RING_SPREAD * eps) == 3]
    assert three  # the case the rule is about


def test_rings_counts_the_circles_of_a_revolved_polyline():
    """Points on 3 circles about the z axis (two bands) are 3 rings; 4 circles 4; round-off-sized jitter does not
    split a ring."""
    from recon.segment._exact_rings import rings

    a = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    circle = lambda r, z: np.c_[r * np.cos(a), r * np.sin(a), np.full_like(a, z)]  # noqa: E731
    three = np.vstack([circle(30, 0), circle(30, 5), circle(29.5, 5.5)])
    jitter = np.random.default_rng(0).uniform(-1e-6, 1e-6, three.shape)
    assert rings(three + jitter, np.zeros(3), np.array([0, 0, 1.0]), 1e-5) == 3
    assert rings(np.vstack([three, circle(29, 5.7)]), np.zeros(3), np.array([0, 0, 1.0]), 1e-5) == 4


@pytest.mark.parametrize("inner, outer, noted", [(10 - 0.006, 10.0, True), (10 - 0.8, 10 + 0.8, False)])
def test_a_flat_ring_on_a_torus_is_noted_only_where_its_radii_are_not_mirrored(inner, outer, noted):
    """A flat ring of two circles at one height, all of it one plane atom of a torus face (R 10, r 1). Beside the top
    circle and 0.006 wide it lies on the torus to round-off only (export seed 141: a 0.0058-wide plane ring taken by
    its fillet's torus): the count is noted as not proven. A chord band across the tube's top has radii averaging R:
    a torus's own band, no note."""
    from types import SimpleNamespace

    from recon.segment._exact_rings import flat_rings

    a = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    height = 1.0 if noted else np.sqrt(1 - 0.8**2)  # on the tube: the top circle, or the two mirrored across it
    V = np.vstack([np.c_[r * np.cos(a), r * np.sin(a), np.full_like(a, height)] for r in (inner, outer)])
    n = len(a)
    F = np.array([t for i in range(n) for t in ((i, (i + 1) % n, n + i), ((i + 1) % n, n + (i + 1) % n, n + i))])
    torus = SimpleNamespace(type="torus", params={"center": [0, 0, 0], "axis_dir": [0, 0, 1], "major_radius": 10.0,
                                                  "minor_radius": 1.0})
    note = flat_rings(V, F, np.zeros(len(F), int), {0: torus}, np.zeros(len(F), int), 1e-5)
    assert bool(note) == noted


def test_a_plane_ring_narrower_than_the_roundoff_lets_a_torus_hold_is_noted(tmp_path):
    """Export seed 141: a plane ring 0.0058 wide tangent to a fillet's torus (r 0.77) lies on it within 0.09 eps; the
    torus takes it (12 faces of 13). The faces are right to round-off, so the path keeps them and says the count is
    open (the verdict's face_count rule: exit 1, where it gave 12 of 13 with exit 0)."""
    from bench.corpus.truth import materialise

    truth = materialise(141, "export", tmp_path)
    mesh = load_mesh(str(truth.mesh))
    eps = roundoff(mesh.vertices)
    found = exact_faces(mesh, TOL_SHARE * float(mesh.diagonal), plane_atoms(mesh, eps))
    assert found is not None
    assert [n for n in found.open_count if "flat ring" in n] and not [n for n in found.notes if "flat ring" in n]


def test_a_loft_wall_drawn_by_its_two_sections_is_held_between_them(tmp_path):
    """Export seed 163 (lofted, 4 true faces, 646 triangles) draws its loft's wall by the two sections alone: every
    vertex of the wall is on a rim. A B-spline through those vertices is free between them (it lay 0.4-0.7 mm off the
    wall's triangles, 0.68 % of the diagonal off the true part: exit 1); with the chords' guides it lies no farther
    from the true part at the triangles' centroids than the triangles themselves do."""
    from bench.corpus.truth import materialise
    from recon.brep._distance import BrepDistance
    from recon.brep._step_read import read_step
    from recon.fit._bspline_surface import BSplineSurface

    found, _, meta = _corpus_faces(163, tmp_path)
    assert len(found.fits) == meta["faces"] == 4
    wall = [p for p, f in found.fits.items() if f.type == "bspline"]
    assert len(wall) == 1
    mesh = load_mesh(str(materialise(163, "export", tmp_path).mesh))
    centroids = mesh.vertices[mesh.faces[found.labels == wall[0]]].mean(axis=1)
    surface = BSplineSurface.from_params(found.fits[wall[0]].params)
    uv = surface.closest_parameters(centroids, None, iterations=20, grid=200)
    true = BrepDistance(read_step(str(materialise(163, "export", tmp_path).step))[0], rng=np.random.default_rng(0))
    ours = np.abs(true.signed_distance(surface.evaluate(uv[:, 0], uv[:, 1]))[0])
    theirs = np.abs(true.signed_distance(centroids)[0])
    assert ours.max() <= theirs.max()
