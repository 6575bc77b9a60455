"""Holes (an occluded scan's missing patches): small boundary loops closed over, open sides left open."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from recon.mesh import boundary_loops, clean_mesh, close_holes


def _sphere(sigma: float = 0.0, seed: int = 0) -> trimesh.Trimesh:
    """The unit sphere, 5,120 triangles (edge h ≈ 0.075), with noise σ along the radius."""
    s = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    v = s.vertices * (1.0 + np.random.default_rng(seed).normal(0.0, sigma, (len(s.vertices), 1)))
    return trimesh.Trimesh(v, s.faces, process=False)


#: Two caps removed: 2.5 % and 1.5 % of the sphere's area, a share an occluded scan misses (issue 23: 1-3 %).
CAPS = ((np.array([0.0, 0.0, 1.0]), 0.95), (np.array([1.0, 0.0, 0.0]), 0.97))


def _holed(s: trimesh.Trimesh):
    centre = s.triangles_center / np.linalg.norm(s.triangles_center, axis=1, keepdims=True)
    cut = np.zeros(len(s.faces), dtype=bool)
    for axis, cos in CAPS:
        cut |= centre @ axis > cos
    return clean_mesh(s.vertices, s.faces[~cut]), float(s.area_faces[cut].sum())


@pytest.mark.parametrize("sigma", [0.0, 0.002])
def test_sphere_holes_closed_on_the_sphere(sigma):
    mesh, removed = _holed(_sphere(sigma))
    assert len(boundary_loops(mesh)) == 2
    out, rep = close_holes(mesh)
    assert (rep.loops, rep.closed) == (2, 2)
    assert out.report.boundary_edges == 0 and out.report.non_manifold_edges == 0
    assert (out.edge_face_count == 2).all()  # watertight and manifold
    # the input's arrays are a prefix of the result's: its triangles keep their indices
    np.testing.assert_array_equal(out.vertices[: len(mesh.vertices)], mesh.vertices)
    np.testing.assert_array_equal(out.faces[: len(mesh.faces)], mesh.faces)
    assert rep.added.sum() == len(out.faces) - len(mesh.faces) and not rep.added[: len(mesh.faces)].any()
    h = mesh.mean_edge_length
    # a quadric fitted over the hole and FIT_RINGS rings round it (radius ρ ≈ 0.31 + 3h) misses the sphere by at most
    # its quartic term ρ⁴/8; the fitted ring's noise averages down, a vertex's own noise is at most 3σ
    rho = np.sqrt(1 - CAPS[0][1] ** 2) + 3 * h
    off = np.abs(np.linalg.norm(out.vertices[rep.input_vertices:], axis=1) - 1.0)
    assert off.max() <= rho**4 / 8 + 3 * sigma
    # area: both triangulate the same caps at the same h; a cover off the sphere by δ changes its area by ≤ 2δ/R
    # (the area of a sphere of radius 1 + δ), and each triangulation's chords cut ≤ h²/4 of it
    assert abs(rep.area_added - removed) <= (2 * off.max() + h**2 / 4) * removed + 3 * sigma * removed
    assert out.volume > 0  # outward, as the input was
    assert abs(out.volume - 4 / 3 * np.pi) <= 0.01 * 4 / 3 * np.pi  # the icosphere's own chord deficit is 0.5 %


def test_box_without_top_left_open():
    box = trimesh.creation.box((10.0, 10.0, 10.0))
    for _ in range(3):
        box = box.subdivide()
    mesh = clean_mesh(box.vertices, box.faces[box.triangles_center[:, 2] < 4.99])
    out, rep = close_holes(mesh)
    assert (rep.loops, rep.closed) == (1, 0)
    assert out is mesh  # nothing closed: the mesh as it was (a shell is the right answer)


@pytest.mark.parametrize("sigma", [0.0, 0.02])
@pytest.mark.parametrize("centre", [(0.0, 5.0, 5.0), (5.0, 5.0, 5.0)], ids=["edge", "corner"])
def test_box_hole_across_an_edge_or_corner_lands_on_the_box(centre, sigma):
    """A patch cut across the box's top edge (two faces) or a corner (three) is covered by the faces' extensions to
    their crease: the cover lies on the box to within the noise (3σ: the rings' planes average it down), watertight."""
    box = trimesh.creation.box((10.0, 10.0, 10.0))
    for _ in range(4):
        box = box.subdivide()
    v = box.vertices + np.random.default_rng(1).normal(0.0, sigma, box.vertices.shape)
    cut = np.linalg.norm(box.triangles_center - np.asarray(centre), axis=1) < 1.5
    mesh = clean_mesh(v, box.faces[~cut])
    out, rep = close_holes(mesh)
    assert (rep.loops, rep.closed) == (1, 1)
    assert (out.edge_face_count == 2).all()
    new = out.vertices[rep.input_vertices:]
    inside = np.min(5.0 - np.abs(new), axis=1)  # distance to the nearest face for a point inside the box
    outside = np.max(np.abs(new) - 5.0, axis=1)  # (at least) the distance for one outside
    off = np.where(outside > 0, outside, inside)
    assert np.abs(off).max() <= 3 * sigma + 1e-9


def test_closed_mesh_untouched_and_deterministic():
    s = _sphere()
    mesh = clean_mesh(s.vertices, s.faces)
    out, rep = close_holes(mesh)
    assert out is mesh and rep.closed == 0 and rep.loops == 0
    holed, _ = _holed(_sphere(0.002))
    a, ra = close_holes(holed)
    b, rb = close_holes(holed)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.faces, b.faces)
    np.testing.assert_array_equal(ra.added, rb.added)


def test_inward_open_mesh_closed_outward():
    """An open mesh wound inward (the cleaning keeps an open part's winding) comes out closed and outward."""
    s = _sphere()
    mesh, _ = _holed(trimesh.Trimesh(s.vertices, s.faces[:, ::-1], process=False))
    assert mesh.volume < 0
    out, rep = close_holes(mesh)
    assert rep.closed == 2 and (out.edge_face_count == 2).all() and out.volume > 0


def test_convert_closes_a_hole_and_measures_the_input_only():
    """recon.convert on a noisy box with a hole across an edge: a valid closed solid, the hole in the report, the
    deviation mesh→shape counted over the input's vertices only, and the verdict's rules all hold."""
    from recon import convert

    box = trimesh.creation.box((10.0, 10.0, 10.0))
    for _ in range(4):
        box = box.subdivide()
    v = box.vertices + np.random.default_rng(2).normal(0.0, 0.01, box.vertices.shape)
    cut = np.linalg.norm(box.triangles_center - [0.0, 5.0, 5.0], axis=1) < 1.5
    mesh = clean_mesh(v, box.faces[~cut])
    conv = convert(mesh)
    rep = conv.report
    assert rep["mesh"]["holes"]["closed"] == 1 and rep["mesh"]["triangles"] == len(mesh.faces)
    assert rep["validity"]["shape_type"] == "solid" and rep["validity"]["ok"]
    assert rep["n_faces"] == 6
    assert rep["deviation"]["mesh_to_shape"]["count"] == len(mesh.vertices)
    assert conv.verdict.ok, conv.verdict
    added = conv.extra["holes"].added
    assert len(conv.labels) == len(conv.mesh.faces) == len(added) and added.sum() > 0


def test_triangle_soup_left_open():
    # An STL whose corners were never welded (or jittered apart) is a soup: every triangle a piece whose whole rim is
    # a loop. A hole is small against its own piece, so none is covered (covering each made one closed pillow per
    # triangle, and the decomposition one part with no boundary: exit 3 where recon gave a result before).
    s = _sphere()
    tri = np.asarray(s.vertices)[np.asarray(s.faces)]
    corners = tri.reshape(-1, 3) + np.random.default_rng(0).normal(scale=1e-3, size=(len(tri) * 3, 3))
    mesh = clean_mesh(corners, np.arange(len(corners)).reshape(-1, 3))
    assert len(boundary_loops(mesh)) == len(mesh.faces)  # a soup: a loop per triangle
    closed, report = close_holes(mesh)
    assert closed is mesh and report.closed == 0


def test_a_crack_left_by_a_dropped_cap_is_zipped_not_filled():
    """An exporter's cap triangle (a corner on its opposite edge: zero area) is dropped in cleaning, leaving a loop of
    its three corners that encloses nothing (export seeds 31, 66, 137 crashed filling it). Zipping splits the
    neighbour across the long edge at the middle corner: the cube closes with its exact volume and area, no triangle
    added off the input's, and every edge has two triangles running opposite ways."""
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    V, F = np.asarray(box.vertices, dtype=float), np.asarray(box.faces)
    t = 0
    a, c, x = F[t]
    mid = len(V)
    V = np.vstack([V, 0.5 * (V[a] + V[c])])
    # triangle t split at the midpoint of its edge (a, c) only on its own side; the cap (c, mid, a) closes it as read
    F = np.vstack([np.delete(F, t, axis=0), [[a, mid, x], [mid, c, x], [c, mid, a]]])
    mesh = clean_mesh(V, F)
    assert mesh.report.degenerate_faces == 1 and len(boundary_loops(mesh)) == 1
    out, report = close_holes(mesh)
    assert (report.loops, report.closed, report.area_added) == (1, 1, 0.0)
    assert out.report.boundary_edges == 0 and len(out.faces) == 14
    assert abs(out.area - 6.0) < 1e-12 and abs(trimesh.Trimesh(out.vertices, out.faces).volume - 1.0) < 1e-12
    directed = {(int(p), int(q)) for row in out.faces for p, q in zip(row, np.roll(row, -1))}
    assert len(directed) == 3 * len(out.faces) and all((q, p) in directed for p, q in directed)
