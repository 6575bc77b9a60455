"""Curve network from labelled meshes: topology counts with exact answers, invariances, awkward inputs."""

import numpy as np
import pytest
import trimesh

from recon.fit import fit_edge_curve
from recon.network import OUTSIDE, curve_network, meeting_point, network_geometry
from recon.errors import InputError


def _box():
    m = trimesh.creation.box((2.0, 3.0, 4.0))
    n = m.face_normals
    axis = np.argmax(np.abs(n), axis=1)
    labels = axis * 2 + (n[np.arange(len(n)), axis] > 0)
    return np.asarray(m.vertices), np.asarray(m.faces), labels.astype(np.int64)


def _annulus(r_in=1.0, r_out=2.0, height=1.0):
    m = trimesh.creation.annulus(r_min=r_in, r_max=r_out, height=height, sections=48)
    n = m.face_normals
    c = m.triangles_center
    rad = np.hypot(c[:, 0], c[:, 1])
    labels = np.where(n[:, 2] > 0.9, 0, np.where(n[:, 2] < -0.9, 1, np.where(rad > 0.5 * (r_in + r_out), 2, 3)))
    return np.asarray(m.vertices), np.asarray(m.faces), labels.astype(np.int64), m


def _edge_uses(net):
    uses = {}
    for j in range(len(net.loop_part)):
        for r in net.loop(j).tolist():
            uses.setdefault(abs(r) - 1, []).append((int(net.loop_part[j]), int(np.sign(r))))
    return uses


def test_box_network_counts():
    v, f, lab = _box()
    net = curve_network(v, f, lab)
    # A box: 8 corners where 3 faces meet, 12 edges, 6 faces each bounded by one loop of 4 edges.
    assert net.n_vertices == 8
    assert net.n_edges == 12
    assert net.parts.tolist() == list(range(6))
    assert len(net.loop_part) == 6 and net.loop_outer.all()
    assert all(len(net.loop(j)) == 4 for j in range(6))
    # Every edge is used by exactly its two parts, once forward and once reversed (watertight topology).
    for e, uses in _edge_uses(net).items():
        assert sorted(p for p, _ in uses) == sorted(net.edge_parts[e].tolist())
        assert sorted(s for _, s in uses) == [-1, 1]
    # Each loop is closed: every edge ends where the next one starts.
    for j in range(6):
        refs = net.loop(j)
        ends = [net.edge_vertices[abs(r) - 1][::1 if r > 0 else -1] for r in refs]
        assert all(ends[i][1] == ends[(i + 1) % 4][0] for i in range(4))
    # Polylines start and end at their network vertices.
    for e in range(net.n_edges):
        a, b = net.edge_vertices[e]
        assert np.array_equal(net.polyline(e)[0], net.points[a])
        assert np.array_equal(net.polyline(e)[-1], net.points[b])


def test_box_network_invariant_under_face_permutation():
    v, f, lab = _box()
    perm = np.random.default_rng(0).permutation(len(f))
    a = curve_network(v, f, lab)
    b = curve_network(v, f[perm], lab[perm])
    assert (a.n_vertices, a.n_edges) == (b.n_vertices, b.n_edges)
    assert sorted(map(tuple, a.edge_parts.tolist())) == sorted(map(tuple, b.edge_parts.tolist()))


def test_hole_loop_is_inner():
    v, f, lab, mesh = _annulus()
    net = curve_network(v, f, lab)
    # Top, bottom, outer wall, hole wall; four circles, each a closed edge on one anchor vertex.
    assert net.n_edges == 4 and net.n_vertices == 4
    assert np.all(net.edge_vertices[:, 0] == net.edge_vertices[:, 1])
    top = net.part_loops(0)
    assert len(top) == 2
    outer, inner = top
    assert net.loop_outer[outer] and not net.loop_outer[inner]
    radius = lambda j: np.hypot(*net.polyline(abs(net.loop(j)[0]) - 1)[:, :2].T).mean()  # noqa: E731
    assert radius(outer) == pytest.approx(2.0, rel=1e-9)
    assert radius(inner) == pytest.approx(1.0, rel=1e-9)


def test_open_mesh_boundary_edges_have_outside():
    v, f, lab = _box()
    keep = lab != 5
    net = curve_network(v, f[keep], lab[keep])
    # Removing one face leaves its 4 edges as open boundary: parts [p, OUTSIDE].
    assert net.n_edges == 12 and net.n_vertices == 8
    assert int(np.sum(net.edge_parts[:, 1] == OUTSIDE)) == 4
    assert not np.any(net.edge_parts[:, 0] == OUTSIDE)


def test_nonmanifold_edge_reported_and_skipped():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.0]])
    f = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    net = curve_network(v, f, np.array([0, 1, 2]))
    assert net.nonmanifold.tolist() == [[0, 1]]


@pytest.mark.parametrize(
    "args",
    [
        (np.zeros((3, 2)), np.array([[0, 1, 2]]), np.array([0])),
        (np.zeros((3, 3)), np.array([[0, 1, 3]]), np.array([0])),
        (np.zeros((3, 3)), np.array([[0, 1, 2]]), np.array([0, 1])),
        (np.zeros((3, 3)), np.array([[0, 1, 2]]), np.array([-2])),
        (np.zeros((3, 3)), np.empty((0, 3), int), np.empty(0, int)),
    ],
)
def test_bad_input_raises(args):
    with pytest.raises(InputError):
        curve_network(*args)


def test_fit_edge_curve_recovers_line_circle_and_pins_spline():
    t = np.linspace(0, 1, 20)
    line = np.outer(t, [3.0, 4.0, 0.0]) + [1, 2, 3]
    c = fit_edge_curve(line, closed=False, tolerance=1e-6)
    assert c.kind == "line" and c.residual < 1e-12

    ang = np.linspace(0.2, 1.7, 30)
    arc = np.stack([5 + 2.5 * np.cos(ang), -1 + 2.5 * np.sin(ang), np.full_like(ang, 7.0)], 1)
    c = fit_edge_curve(arc, closed=False, tolerance=1e-6)
    assert c.kind == "circle"
    assert c.circle.radius == pytest.approx(2.5, rel=1e-9)
    assert np.allclose(c.circle.center, [5, -1, 7], atol=1e-9)
    assert c.t1 - c.t0 == pytest.approx(1.5, abs=1e-9)

    helix = np.stack([np.cos(3 * t), np.sin(3 * t), 2 * t], 1)
    c = fit_edge_curve(helix, closed=False, tolerance=1e-4)
    assert c.kind == "bspline" and c.residual <= 1e-4
    ctrl = c.spline.control_points
    assert np.array_equal(ctrl[0], helix[0]) and np.array_equal(ctrl[-1], helix[-1])


def test_meeting_point_of_three_planes():
    normals = np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 1.0, 1.0]]) / np.array([[1], [1], [np.sqrt(3)]])
    offsets = np.array([1.0, 2.0, 6.0 / np.sqrt(3)])  # x = 1, y = 2, x + y + z = 6 → (1, 2, 3)

    def project(part, pts):
        n = normals[part]
        return pts - np.outer(pts @ n - offsets[part], n), np.broadcast_to(n, pts.shape)

    x, gap = meeting_point([0.7, 2.4, 2.5], [0, 1, 2], project)
    assert np.allclose(x, [1, 2, 3], atol=1e-6)
    assert gap < 1e-6


def test_edge_spline_through_zigzag_points_stays_near_them():
    """Projected edge points zigzag by a few noise levels on noisy meshes, unevenly spaced. A least-squares
    spline with a control point per data point and uniform knots overshot by up to 1e12 times the zigzag
    between such points (box_fillet noisy20: plane faces bounded by edges thousands of mm long). With knots
    at data quantiles, at least three points per span and a small penalty it stays within a few amplitudes."""
    from scipy.interpolate import BSpline

    rng = np.random.default_rng(3)
    for _ in range(50):
        x = np.sort(rng.uniform(0, 20, 30))
        x[0], x[-1] = 0.0, 20.0
        pts = np.column_stack([x, rng.normal(0, 0.3, 30), np.zeros(30)])
        c = fit_edge_curve(pts, closed=False, tolerance=1e-3)
        assert c.kind == "bspline"
        p = c.spline
        y = BSpline(p.knots, p.control_points, p.degree)(np.linspace(0, 1, 2000))[:, 1]
        assert np.abs(y).max() <= 2.5 * np.abs(pts[:, 1]).max()
        # The residual reported is the curve's real distance from the points, not a 1e-13 interpolation claim.
        assert c.residual >= 0.05


def _crosses_itself(xy) -> bool:
    """Whether the 2D polyline ``xy`` has two non-adjacent segments that properly intersect."""
    a, b = xy[:-1], xy[1:]

    def orient(p, q, r):
        return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

    for i in range(len(a) - 2):
        p, q = a[i], b[i]
        r, s = a[i + 2 :], b[i + 2 :]
        hit = (orient(p, q, r) * orient(p, q, s) < 0) & (orient(r, s, p) * orient(r, s, q) < 0)
        if hit.any():
            return True
    return False


def test_edge_spline_never_loops_back():
    """Six projected points of a short edge of rocker-arm2500 (scaled to a unit chord; tolerance likewise):
    the cubic fitted to them looped, and the face it bounded was a self-intersecting wire. The curve
    through them must not cross itself (seen in the plane of the points)."""
    from scipy.interpolate import BSpline

    pts = np.array([[0.0, 0.0, 0.0], [-0.2284, -0.2957, -0.0366], [-0.299, -0.4522, -0.5694],
                    [-0.268, 0.247, -1.0951], [-0.2836, -0.1997, -0.8314], [-0.1894, -0.623, -0.7589]])
    c = fit_edge_curve(pts, closed=False, tolerance=0.12)
    p = c.spline
    q = BSpline(p.knots, p.control_points, p.degree)(np.linspace(0, 1, 400))
    _, _, vt = np.linalg.svd(pts - pts.mean(axis=0))
    assert not _crosses_itself((q - pts.mean(axis=0)) @ vt[:2].T)
    assert np.allclose(q[[0, -1]], pts[[0, -1]])


def _square_prism_on_cylinder(radius=1.0, height=1.0):
    """A square prism whose 4 vertical edges lie on a cylinder of ``radius`` about z: each side is one part, top 4,
    bottom 5. Its rims are single mesh chords, the coarsest a CAD tessellation gives, of quarter-circle edges."""
    ang = np.deg2rad([45.0, 135.0, 225.0, 315.0])
    ring = np.column_stack([radius * np.cos(ang), radius * np.sin(ang)])
    v = np.vstack([np.column_stack([ring, np.zeros(4)]), np.column_stack([ring, np.full(4, height)])])
    faces, labels = [], []
    for k in range(4):
        a, b = k, (k + 1) % 4
        faces += [[a, b, b + 4], [a, b + 4, a + 4]]
        labels += [k, k]
    faces += [[4, 5, 6], [4, 6, 7], [0, 2, 1], [0, 3, 2]]
    labels += [4, 4, 5, 5]
    return v, np.array(faces), np.array(labels)


def _prism_projector(radius, height):
    """The projector onto ``_square_prism_on_cylinder``'s surfaces: parts 0-3 the cylinder, 4 and 5 the planes
    z = height (top) and z = 0 (bottom)."""

    def project(part, pts):
        if part >= 4:  # the planes z = height (top) and z = 0 (bottom)
            z = height if part == 4 else 0.0
            return np.column_stack([pts[:, :2], np.full(len(pts), z)]), np.tile([0.0, 0.0, 1.0], (len(pts), 1))
        e = pts[:, :2] / np.linalg.norm(pts[:, :2], axis=1)[:, None]
        return np.column_stack([radius * e, pts[:, 2]]), np.column_stack([e, np.zeros(len(pts))])

    return project


def test_coarse_chords_are_refined_onto_the_surfaces_edge():
    radius, height, tol = 1.0, 1.0, 1e-3

    project = _prism_projector(radius, height)

    v, f, labels = _square_prism_on_cylinder(radius, height)
    net = curve_network(v, f, labels)
    rims = [e for e in range(net.n_edges) if max(net.edge_parts[e]) >= 4]
    assert len(rims) == 8 and all(len(net.polyline(e)) == 2 for e in rims)
    geo = network_geometry(net, project, tolerance=tol)
    for e in rims:
        c = geo.curves[e]
        assert c.kind == "circle"
        assert abs(c.circle.radius - radius) <= tol
        assert abs(c.t1 - np.pi / 2) <= 1e-2
        pts = geo.polyline(e)
        assert np.max(np.abs(np.hypot(pts[:, 0], pts[:, 1]) - radius)) <= tol
    # Not refined, each rim stays the chord: 1 - cos 45° = 0.29 of the radius inside the cylinder.
    plain = network_geometry(net, project, tolerance=tol, refine=())
    assert all(plain.curves[e].kind == "line" for e in rims)


def test_two_processes_place_the_network_as_one_does():
    """Differential: the edges placed by two processes (the second forked, each taking the next edge) are the ones
    one process places, bit for bit. (What the second process fails on is placed by the first: see
    tests/test_parallel.py.)"""
    radius, height, tol = 1.0, 1.0, 1e-3

    project = _prism_projector(radius, height)

    v, f, labels = _square_prism_on_cylinder(radius, height)
    net = curve_network(v, f, labels)
    one = network_geometry(net, project, tolerance=tol, jobs=1)
    two = network_geometry(net, project, tolerance=tol, jobs=2)
    np.testing.assert_array_equal(two.coords, one.coords)
    np.testing.assert_array_equal(two.offsets, one.offsets)
    np.testing.assert_array_equal(two.edge_gap, one.edge_gap)
    assert [c.kind for c in two.curves] == [c.kind for c in one.curves]
    for a, b in zip(one.curves, two.curves):
        for k in ("start", "end", "residual", "t0", "t1"):
            np.testing.assert_array_equal(getattr(b, k), getattr(a, k))
        for part, names in (("circle", ("center", "normal", "radius", "x_dir")),
                            ("spline", ("degree", "knots", "control_points"))):
            assert (getattr(a, part) is None) == (getattr(b, part) is None)
            if getattr(a, part) is not None:
                for k in names:
                    np.testing.assert_array_equal(getattr(getattr(b, part), k), getattr(getattr(a, part), k))



def test_a_curve_that_strays_from_points_and_surfaces_is_the_polyline():
    """Crank's torus/plane edge, made of a plane (x = 0) and a cylinder about an axis along y that cuts it in two
    lines, z = 0 and z = 1, and bulges 11.6 tolerances through it between them. The mesh (flat, in the plane) puts
    the edge across the gap: a chord from (0, 0, 1) down to (0, 0, 0), then 0.03 along y. No point near the
    chord's middle lies on both surfaces, so it is not refined onto them, and the quadratic through the 3 points
    bows far out sideways (more than STRAY_FACTOR tolerances from the chords) while lying off both surfaces as much
    as the chord does. The edge is a polyline: the mesh's points, and (since the chord lies 11.6 tolerances off the
    cylinder, past the sewing tolerance) points midway between the two surfaces along the chord: nothing sideways,
    nothing the surfaces or the mesh do not show, and within the sewing tolerance of both."""
    from scipy.interpolate import BSpline

    from recon.network._placement import STRAY_FACTOR

    tol = 1e-3
    bulge = 11.6 * tol
    a = (0.25 - bulge**2) / (2 * bulge)  # (a + bulge)² = a² + 0.5²: the cylinder through z = 0 and z = 1 at x = 0
    r = a + bulge

    def project(part, pts):
        if part == 0:  # the plane x = 0
            return np.column_stack([np.zeros(len(pts)), pts[:, 1:]]), np.tile([1.0, 0.0, 0.0], (len(pts), 1))
        w = np.column_stack([pts[:, 0] + a, pts[:, 2] - 0.5])
        e = w / np.linalg.norm(w, axis=1)[:, None]
        on = np.column_stack([r * e[:, 0] - a, pts[:, 1], r * e[:, 1] + 0.5])
        return on, np.column_stack([e[:, 0], np.zeros(len(pts)), e[:, 1]])

    # (y, z) in the plane x = 0: part 1 the strip right of the chord, part 0 the L around it
    yz = np.array([[0, 1], [0, 0], [0.03, 0], [0.03, 1], [-0.5, 1], [-0.5, -0.5], [0.03, -0.5]], dtype=float)
    v = np.column_stack([np.zeros(len(yz)), yz])
    faces = np.array([[1, 2, 3], [1, 3, 0], [4, 5, 1], [4, 1, 0], [5, 6, 1], [1, 6, 2]])
    labels = np.array([1, 1, 0, 0, 0, 0])
    net = curve_network(v, faces, labels)
    (e,) = [k for k in range(net.n_edges) if sorted(net.edge_parts[k]) == [0, 1]]
    assert len(net.polyline(e)) == 3
    geo = network_geometry(net, project, tolerance=tol)
    pts = geo.polyline(e)
    smooth = fit_edge_curve(pts, closed=False, tolerance=tol)
    curve = BSpline(smooth.spline.knots, smooth.spline.control_points, smooth.spline.degree)
    assert np.max(np.abs(curve(np.linspace(0, 1, 101))[:, 1])) > STRAY_FACTOR * tol  # it bows out along y
    c = geo.curves[e]
    assert c.kind == "bspline" and c.spline.degree == 1
    np.testing.assert_allclose(c.spline.control_points, pts)
    # every point of it is between y = 0 and 0.03 (no sideways bow), and within the sewing tolerance of both surfaces
    edge = BSpline(c.spline.knots, c.spline.control_points, 1)(np.linspace(0, 1, 101))
    assert edge[:, 1].min() >= -1e-12 and edge[:, 1].max() <= 0.03 + 1e-12
    for part in (0, 1):
        assert np.max(np.linalg.norm(project(part, edge)[0] - edge, axis=1)) <= STRAY_FACTOR * tol
    assert np.max(np.linalg.norm(project(1, pts)[0] - pts, axis=1)) < bulge  # nearer the cylinder than the chord


def test_a_chord_is_not_refined_onto_another_stretch_of_its_edge():
    """Crank's patch_103: a plane cuts a sphere in a circle, and one edge runs along the circle's arc, then back
    across a chord of it (the tessellation's long triangle). The chord's midpoint, moved onto both surfaces,
    lands on the circle's nearest point — on the arc the edge has already run along, half a radius away, within
    the half-chord a refinement may move. Inserted, the polyline went back over itself and the plane's face
    crossed itself. The chord stays a chord; the arc's own chords are refined."""
    from recon.network._placement import _refined

    h = 2.0
    R = np.hypot(1.0, h)  # the sphere about (0, 0, h) through the unit circle in z = 0

    def project(part, pts):
        if part == 0:
            return np.column_stack([pts[:, :2], np.zeros(len(pts))]), np.tile([0.0, 0.0, 1.0], (len(pts), 1))
        w = pts - [0.0, 0.0, h]
        e = w / np.linalg.norm(w, axis=1)[:, None]
        return np.array([0.0, 0.0, h]) + R * e, e

    ang = np.deg2rad(np.r_[np.arange(280, 200, -10), 330, 320])
    pts = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(len(ang))])
    out = _refined(pts, 0, 1, project, tolerance=1e-3, iterations=6, max_points=64)
    assert len(out) > len(pts)  # the arc's chords (sagitta 0.0038) got points on the circle
    i = int(np.flatnonzero(np.all(np.isclose(out, pts[7]), axis=1))[0])  # the 210° point, where the chord starts
    np.testing.assert_allclose(out[i + 1], pts[8])  # the chord to 330° has no point inserted
