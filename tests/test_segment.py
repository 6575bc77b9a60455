"""The segment stage's passes, each alone, in the context :func:`recon.convert` runs them in (the noise the
decomposition measures decides the mode), and the loop that runs them."""

import numpy as np
import pytest
import trimesh

from recon.decompose import decompose
from recon.fit import residual_scale
from recon.segment import (PASSES, Pass, Rounds, SegmentContext, describe, dissolve_misfits, fit_parts, grow_faces,
                           merge_round_bands, merge_same_surface, refine, segment, tidy, trim_to_surface)
from recon.segment._merge import one_centre
from recon.segment._split import exact_strips


def _context(mesh, tolerance):
    """The context convert() would run the passes in on ``mesh``: noise-free when the decomposition measures σ = 0
    (every mesh built here is: their vertices lie on their surfaces, or within a share of the tolerance)."""
    return SegmentContext.of(mesh, tolerance, sigma=decompose(mesh).noise)


def _box_with_strip_on_top():
    """A 30 x 20 x 10 box labelled by its true faces, except the +x side's triangles within 1 mm of the top edge,
    given to the top face. Returns the mesh, the true labels, those labels, and the top and side ids."""
    from recon.mesh import clean_mesh

    box = trimesh.creation.box(extents=(30, 20, 10)).subdivide_to_size(1.0)
    mesh = clean_mesh(box.vertices, box.faces)
    n = mesh.face_normals
    truth = np.argmax(np.abs(n), axis=1) * 2 + (n[np.arange(len(n)), np.argmax(np.abs(n), axis=1)] > 0)
    labels = truth.copy()
    top, side = int(truth[np.argmax(n[:, 2])]), int(truth[np.argmax(n[:, 0])])
    labels[(labels == side) & (mesh.face_centroids[:, 2] > 5.0 - 1.0)] = top
    return mesh, truth, labels, top, side


def test_a_face_that_took_in_a_sliver_is_cut_back_to_its_plane():
    """A box face that took in the strip of its neighbour along their edge fits no plane (a B-spline, or
    nothing); cut back to the plane grown inside it, the strip returns to the neighbour it lies on, and
    every face is one plane of the box again."""
    mesh, truth, labels, top, side = _box_with_strip_on_top()
    ctx = _context(mesh, 1e-3)
    fits = fit_parts(labels, ctx)
    assert not (fits[top].ok and fits[top].type == "plane")
    trimmed = trim_to_surface(labels, fits, ctx)
    np.testing.assert_array_equal(trimmed, truth)


def test_a_face_split_between_two_faces_out_of_tolerance_becomes_one():
    """Crank's web side, in a box: the +x side's triangles alternate, a third of them given to the top (which then
    fits no plane) and the rest to a face that also holds the whole +y side (two planes at a right angle: out of
    tolerance too). Neither face can take the other's share of the side, so the top could not be cut back to its
    plane. Grown over the faces out of tolerance on the side's own plane, the top's rest and the other face's
    share are one face, the top and the +y side are what is left: every face is one plane of the box again."""
    mesh, truth, _, top, side = _box_with_strip_on_top()
    n, c = mesh.face_normals, mesh.face_centroids
    front = int(truth[np.argmax(n[:, 1])])  # the +y side
    labels = truth.copy()
    teeth = (truth == side) & (np.floor(c[:, 1]) % 3 == 0)
    labels[teeth] = top
    other = int(truth.max()) + 1
    labels[((truth == side) & ~teeth) | (truth == front)] = other
    ctx = _context(mesh, 1e-3)
    fits = fit_parts(labels, ctx)
    assert not (fits[top].ok and fits[top].type == "plane") and not fits[other].ok
    trimmed = trim_to_surface(labels, fits, ctx)
    # the same partition as the box's faces (the side's face has a new id)
    pairs = np.unique(np.column_stack([truth, trimmed]), axis=0)
    assert len(pairs) == len(np.unique(truth)) == len(np.unique(trimmed))
    refit = fit_parts(trimmed, ctx)
    assert all(f.ok and f.type == "plane" for f in refit.values() if f.n_points)


def test_a_strip_given_to_a_neighbour_returns_to_the_face_it_lies_on():
    """The same strip given to the top face: the top then fits no plane (a B-spline carries it), the side's
    plane holds every triangle of the strip (on it, normal along it), so growing the faces over their borders
    gives the strip back and every face is one plane of the box again."""
    mesh, truth, labels, top, side = _box_with_strip_on_top()
    ctx = _context(mesh, 1e-3)
    fits = fit_parts(labels, ctx)
    assert fits[top].type == "bspline" and fits[side].type == "plane"
    np.testing.assert_array_equal(grow_faces(labels, fits, ctx), truth)


def _plane_and_fillet(offset=0.0, h=0.02, R=1.0, w=0.06):
    """A noise-free strip of the plane z = 0 (arc length s <= 0) running into a cylinder of radius 1 tangent to it
    along x = 0, labelled 0 (plane) and 1 (cylinder) except the triangles within ``w`` of the tangent line: part 2,
    which a plane holds within 1e-3 only as a compromise (vertices up to 0.75e-3 off it). ``offset``: every other
    vertex moved along z by this much (a mesh whose vertices are not exact). Returns the mesh, truth, labels."""
    from recon.mesh import clean_mesh

    s = np.arange(-0.5, 0.5 + h / 2, h)
    y = np.arange(0.0, 0.4 + h / 2, h)
    S, Y = np.meshgrid(s, y, indexing="ij")
    V = np.column_stack([np.where(S <= 0, S, R * np.sin(S / R)).ravel(), Y.ravel(),
                         np.where(S <= 0, 0.0, R - R * np.cos(S / R)).ravel()])
    V[::2, 2] += offset
    ny = len(y)
    quads = [(i * ny + j, (i + 1) * ny + j, (i + 1) * ny + j + 1, i * ny + j + 1)
             for i in range(len(s) - 1) for j in range(ny - 1)]
    faces = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    mesh = clean_mesh(V, faces)
    c = mesh.face_centroids
    arc = np.where(c[:, 0] <= 0, c[:, 0], R * np.arctan2(c[:, 0], R - c[:, 2]))
    truth = (arc > 0).astype(np.int64)
    labels = truth.copy()
    labels[np.abs(arc) < w] = 2
    return mesh, truth, labels


def test_on_exact_vertices_a_compromise_surface_gives_its_triangles_to_the_faces_they_lie_on():
    """On a CAD export every vertex lies on its true surface: the plane and the cylinder fit their parts to
    round-off, while the part across their tangent line fits a plane at 0.47 tolerances (robust residual). That
    residual is the mark of a compromise over two faces (the ABC model: strips of two fillets and a 2-triangle
    plane, one sphere at 0.8 tolerances), so its triangles go to the surfaces that hold them exactly: every
    triangle gets its true face. Where the vertices are not exact (every other one 0.1 tolerances off), a
    residual of a share of the tolerance is no such mark, and nothing moves."""
    tolerance = 1e-3
    mesh, truth, labels = _plane_and_fillet()
    ctx = _context(mesh, tolerance)
    fits = fit_parts(labels, ctx)
    assert [fits[q].type for q in range(3)] == ["plane", "cylinder", "plane"] and fits[2].ok
    assert max(fits[0].deviation["max"], fits[1].deviation["max"]) < 1e-12
    assert residual_scale(fits[2], mesh.vertices[np.unique(mesh.faces[labels == 2])]) > 0.4 * tolerance
    np.testing.assert_array_equal(grow_faces(labels, fits, ctx), truth)

    mesh, truth, labels = _plane_and_fillet(offset=0.1 * tolerance)
    ctx = _context(mesh, tolerance)
    fits = fit_parts(labels, ctx)
    assert all(fits[q].ok for q in range(3))
    assert grow_faces(labels, fits, ctx) is labels


def test_a_face_no_surface_fits_is_given_to_the_surfaces_around_it():
    """A strip 2 mm either side of the box's top +x edge is one part, with a dent in it (one vertex on the edge
    pushed in by 0.28 mm): no surface fits it (RMS far above the tolerance). Its triangles lie on the top's and
    the side's planes except the 8 around the dent; growing the faces over their borders gave the strip up
    whole or not at all, and the dent would be left, so nothing moved (crank: a B-spline 190x out of tolerance
    over slivers of two tori got no face). Dissolved, the strip goes to the planes it lies on, the dent is left
    for `_tidy`, and the labels are the box's true faces everywhere else."""
    from recon.mesh import clean_mesh

    mesh, truth, _, top, side = _box_with_strip_on_top()
    c = mesh.face_centroids
    strip = ((truth == top) & (c[:, 0] > 13.0)) | ((truth == side) & (c[:, 2] > 3.0))
    labels = truth.copy()
    labels[strip] = truth.max() + 1
    V = mesh.vertices.copy()
    on_edge = np.flatnonzero((np.abs(V[:, 0] - 15.0) < 1e-9) & (np.abs(V[:, 2] - 5.0) < 1e-9))
    dent = on_edge[np.argmin(np.abs(V[on_edge, 1]))]
    V[dent] -= [0.2, 0.0, 0.2]
    mesh = clean_mesh(V, mesh.faces)
    tolerance = 1e-3
    ctx = _context(mesh, tolerance)
    fits = fit_parts(labels, ctx)
    strip_id = int(truth.max() + 1)
    assert not fits[strip_id].ok and fits[strip_id].deviation["rms"] > 2 * tolerance
    assert grow_faces(labels, fits, ctx) is labels
    dissolved = dissolve_misfits(labels, fits, ctx)
    around = np.isin(mesh.faces, dent).any(axis=1)
    np.testing.assert_array_equal(dissolved[~around], truth[~around])
    assert len(np.unique(tidy(dissolved, ctx))) == 6




def _ball_in_three_lunes():
    """A unit sphere (exact vertices) cut into three lunes by longitude, each "fitted" as a cylinder of its radius
    through the centre, the axes 60° apart in the equator plane (a round end's bands, as on crank)."""
    from recon.fit import SurfaceFit
    from recon.mesh import clean_mesh

    ball = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    mesh = clean_mesh(ball.vertices, ball.faces)
    c = mesh.face_centroids
    labels = (np.floor((np.arctan2(c[:, 1], c[:, 0]) + np.pi) / (2 * np.pi / 3)).astype(np.int64)) % 3
    exact = {"max": 0.0, "rms": 0.0, "p99": 0.0}

    def cylinder(angle, radius=1.0):
        axis = [float(np.cos(angle)), float(np.sin(angle)), 0.0]
        return SurfaceFit("cylinder", {"axis_point": [0.0, 0.0, 0.0], "axis_dir": axis, "radius": radius}, exact, 100)

    return mesh, labels, cylinder


def test_bands_of_one_ball_fitted_as_crossing_cylinders_become_one_face():
    """Three lunes of a sphere, each a cylinder of the sphere's radius whose axis crosses the others at 60° through
    the centre: one round surface in bands. Merged, because a sphere fits the union (its vertices lie on it)."""
    mesh, labels, cylinder = _ball_in_three_lunes()
    assert np.bincount(labels).min() > 50
    fits = {k: cylinder(np.deg2rad(60.0 * k)) for k in range(3)}
    merged = merge_round_bands(labels, fits, _context(mesh, 1e-3))
    assert np.unique(merged).tolist() == [0]


@pytest.mark.parametrize("case", ["parallel axes", "radii 5 tolerances apart", "axes far apart", "two bands"])
def test_bands_that_are_not_one_round_surface_stay_apart(case):
    """Each condition of a round surface in bands alone unmet: coaxial pieces (merge_same_surface's case), other
    radii, axes that miss each other by far more than the radius' share, or only two bands (a fillet and its
    neighbour cross at an angle too). Nothing merges: the labels come back unchanged, as the same array."""
    mesh, labels, cylinder = _ball_in_three_lunes()
    fits = {k: cylinder(np.deg2rad(60.0 * k)) for k in range(3)}
    if case == "parallel axes":
        fits = {k: cylinder(0.0) for k in range(3)}
    elif case == "radii 5 tolerances apart":
        fits[1] = cylinder(np.deg2rad(60.0), radius=1.005)
    elif case == "axes far apart":
        f = fits[1]
        fits[1] = type(f)(f.type, {**f.params, "axis_point": [0.0, 0.0, 0.5]}, f.deviation, f.n_points)
    else:
        labels = np.where(labels == 2, 1, labels)
        fits = {0: fits[0], 1: fits[1]}
    assert merge_round_bands(labels, fits, _context(mesh, 1e-3)) is labels


def test_a_filleted_box_frame_is_not_one_ball():
    """A box corner's three fillet cylinders and its sphere meet in one point (the corner's centre): one ball's
    bands by their geometry (the union's fit decides). Chained with the next corner's they do not: the box's
    12 fillets and 8 corners are one group by pairs, and fitting their union cost the 100k box 5 s for nothing."""
    from recon.fit import SurfaceFit

    exact = {"max": 0.0, "rms": 0.0, "p99": 0.0}
    a, b, c, r = 10.0, 5.0, 2.0, 1.0

    def cylinder(point, axis):
        return SurfaceFit("cylinder", {"axis_point": point, "axis_dir": axis, "radius": r}, exact, 100)

    def sphere(centre):
        return SurfaceFit("sphere", {"center": centre, "radius": r}, exact, 100)

    corner = [cylinder([0, b, c], [1, 0, 0]), cylinder([a, 0, c], [0, 1, 0]), cylinder([a, b, 0], [0, 0, 1]),
              sphere([a, b, c])]
    assert one_centre(corner)
    assert not one_centre(corner + [cylinder([a, -b, 0], [0, 0, 1]), sphere([a, -b, c])])




def test_on_exact_vertices_two_faces_are_not_merged_into_a_third_type():
    """A plane running into a cylinder of radius 1, both exact to round-off: at a tolerance of 0.02 a sphere holds
    their union too (the ABC model: a fillet's cylinder strip and the plane strip beside it, long triangles with
    their vertices on three circles, became one sphere). On exact vertices two faces that each fit their own
    surface to round-off are two faces: they stay a plane and a cylinder."""
    mesh, truth, _ = _plane_and_fillet()
    ctx = _context(mesh, 0.02)
    fits = fit_parts(truth, ctx)
    assert [fits[0].type, fits[1].type] == ["plane", "cylinder"]
    assert merge_same_surface(truth, fits, ctx) is truth




def test_thin_strips_left_in_a_b_spline_face_are_their_own_surfaces_on_exact_vertices():
    """A CAD export's long triangles: a plane (25 facets) runs into a fillet of radius 0.05 (8 facets of 11.25°)
    and on into a vertical plane strip (8 facets of 0.005), each facet one pair of triangles 0.4 long. Regions
    grow in the plane only: the fillet and the strip are one triangle pair wide. What is left beside the plane
    is the strip, whose triangles are coplanar (a plane), and the fillet (a cylinder of radius 0.05), both
    exact — the ABC model's two B-spline faces were such a plane, fillet and strip."""
    from recon.fit import fit_plane
    from recon.mesh import clean_mesh

    r = 0.05
    t = np.deg2rad(np.arange(11.25, 90.1, 11.25))
    profile = ([(u, 0.0) for u in np.arange(-0.5, 0.0, 0.02)] + [(0.0, 0.0)]
               + [(r * np.sin(a), r - r * np.cos(a)) for a in t] + [(r, r + 0.005 * k) for k in range(1, 9)])
    n = len(profile)
    V = np.array([(u, y, z) for y in (0.0, 0.4) for (u, z) in profile])
    F = np.array([tri for i in range(n - 1) for tri in ((i, i + 1, n + i + 1), (i, n + i + 1, n + i))])
    mesh = clean_mesh(V, F)
    c = mesh.face_centroids
    plane, strip = np.flatnonzero(c[:, 2] < 1e-12), np.flatnonzero(np.isclose(c[:, 0], r))
    fillet = np.setdiff1d(np.arange(len(F)), np.concatenate([plane, strip]))
    assert (len(plane), len(fillet), len(strip)) == (50, 16, 16)
    tolerance = 5e-4
    found = [(plane, fit_plane(mesh.vertices[np.unique(mesh.faces[plane])], tolerance=tolerance))]
    out = exact_strips(np.arange(len(F)), found, _context(mesh, tolerance))
    assert [s.type for _, s in out] == ["plane", "cylinder"]
    np.testing.assert_array_equal(out[0][0], strip)
    np.testing.assert_array_equal(out[1][0], fillet)
    assert out[1][1].params["radius"] == pytest.approx(r, rel=1e-9)


# -- the loop ---------------------------------------------------------------------------------------------------


def test_the_context_is_noise_free_exactly_when_the_decomposition_measures_no_noise():
    mesh = _box_with_strip_on_top()[0]
    assert SegmentContext.of(mesh, 1e-3, sigma=0.0).noise_free
    noisy = SegmentContext.of(mesh, 1e-3, sigma=2.5e-4)
    assert not noisy.noise_free and noisy.noise == pytest.approx(1e-3 / 4)  # the tolerance is 4σ


def test_the_passes_are_data_in_the_order_they_run():
    lines = describe().splitlines()
    assert len(lines) == len(PASSES)
    names = [s.name if isinstance(s, Pass) else [p.name for p in s.passes] for s in PASSES]
    assert names[:3] == ["merge_same_surface", "split_unfitted", "trim_to_surface"]
    assert names[3] == ["grow_faces", "trim_to_surface", "merge_same_surface"] and PASSES[3].times == 3
    assert names[-1] == "cut_unbounded"
    assert all(isinstance(s, Rounds) or s.name in line for s, line in zip(PASSES, lines))


def _counting(name, result):
    calls = []

    def run(labels, fits, ctx):
        calls.append(name)
        return result(labels)

    run.__name__ = name
    return Pass(run), calls


def test_a_pass_that_changes_nothing_leaves_labels_and_fits_as_they_are():
    mesh, truth, _, _, _ = _box_with_strip_on_top()
    ctx = _context(mesh, 1e-3)
    fits = fit_parts(truth, ctx)
    same, calls = _counting("same", lambda labels: labels)
    labels, out = refine(truth, fits, ctx, passes=(same, Rounds(3, (same, same))))
    assert labels is truth and out is fits
    assert len(calls) == 2  # the rounds end after their first pass changed nothing


def test_a_pass_that_changes_the_labels_is_tidied_and_refitted():
    """A pass that gives a box face a second label on half its triangles: the loop refits, and a second round's
    first pass changing nothing ends the rounds. A label on triangles that are not connected is one per piece."""
    mesh, truth, _, top, _ = _box_with_strip_on_top()
    ctx = _context(mesh, 1e-3)
    x = mesh.face_centroids[:, 0]
    state = {"n": 0}

    def split_top(labels):
        state["n"] += 1
        if state["n"] > 1:
            return labels
        out = labels.copy()
        out[(labels == top) & (x > 0)] = labels.max() + 1
        return out

    split, calls = _counting("split_top", split_top)
    labels, fits = refine(truth, fit_parts(truth, ctx), ctx, passes=(Rounds(3, (split,)),))
    assert calls == ["split_top", "split_top"]
    assert len(np.unique(labels)) == 7 == len(fits)
    assert all(f.ok and f.type == "plane" for f in fits.values())


def test_segment_of_a_box_is_its_six_planes():
    """The whole stage on an exact box: six faces, the box's own, each a plane within round-off."""
    mesh, truth, _, _, _ = _box_with_strip_on_top()
    labels, fits = segment(mesh, decompose(mesh), tolerance=1e-3)
    assert len(np.unique(np.column_stack([truth, labels]), axis=0)) == 6 == len(fits)
    assert all(f.type == "plane" and f.deviation["max"] < 1e-9 for f in fits.values())
