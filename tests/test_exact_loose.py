"""The exact path where a STEP edge is tolerant (recon/segment/_exact_loose.py): the vertices on the edge lie on one
of its two faces to round-off and off the other by up to the edge's tolerance (gmsh exports of real parts: up to
18 round-offs on the clamp, bench/exact.md s35-strip). Built here from an OCC export of a cylinder (quads from cap to
cap: every vertex on a cap's rim) whose top rim has every other vertex pushed outward within its cap plane by k
round-offs: exact on the plane, off the cylinder by k round-offs (not onto another cylinder or cone: a uniform push
would be one)."""

from __future__ import annotations

from collections import Counter

import build123d as bd
import numpy as np
import pytest

from recon.mesh import Mesh, clean_mesh
from recon.segment._exact import exact_faces, plane_atoms, roundoff
from recon.segment._exact_loose import chain, long_edge_neighbours

#: the run's tolerance as recon picks it for a noise-free mesh: 1e-4 of the diagonal
TOL_SHARE = 1e-4


def _cylinder() -> Mesh:
    from bench.corpus.regimes import make_fixtures

    solid = bd.Cylinder(27, 20)
    bb = solid.bounding_box()
    v, t = make_fixtures().occ_mesh(solid, deflection=1e-3 * (bb.max - bb.min).length, angular=0.5)[:2]
    return clean_mesh(np.asarray(v, float), np.asarray(t))


def _rim_pushed(mesh: Mesh, k: float) -> Mesh:
    """The mesh with every other vertex of its top rim moved outward in the cap plane by ``k`` round-offs."""
    V = mesh.vertices.copy()
    r = np.hypot(V[:, 0], V[:, 1])
    rim = np.flatnonzero((np.abs(V[:, 2] - V[:, 2].max()) < 1e-9) & (r > 27 - 1e-6))
    rim = rim[np.argsort(np.arctan2(V[rim, 1], V[rim, 0]))][::2]
    V[rim, :2] *= (1 + k * roundoff(V) / r[rim])[:, None]
    return clean_mesh(V, mesh.faces)


def _types(mesh: Mesh):
    found = exact_faces(mesh, TOL_SHARE * float(mesh.diagonal), plane_atoms(mesh, roundoff(mesh.vertices)))
    return None if found is None else dict(Counter(f.type for f in found.fits.values()))


@pytest.mark.xfail(strict=True, reason="open (bench/exact.md s36-loose, s37-loose): the first pass finds 14 cones of 5 "
                   "quads holding their pushed vertices to round-off; a vertex between two found faces is not loose, so "
                   "no union of the pieces holds them: 9 faces at k=8 (6 cylinders, a cone), main's 2 planes and a "
                   "B-spline at k=18. Loose there too gives the 3 faces but mixed faces on export seeds 48 and 90")
@pytest.mark.parametrize("k", [8.0, 18.0])
def test_a_rim_off_by_a_tolerant_edge_is_still_the_cylinder(k):
    """k round-offs off the cylinder, exact on the cap (18: the clamp's largest; both within the run's tolerance, 50
    round-offs here): the true 3 faces, as with an exact rim. Without the second pass every quad missed round-off at
    a pushed vertex and stayed a plane."""
    mesh = _cylinder()
    assert _types(mesh) == {"cylinder": 1, "plane": 2}
    assert _types(_rim_pushed(mesh, k)) == {"cylinder": 1, "plane": 2}


def test_a_rim_off_by_more_than_the_tolerance_is_not_taken():
    """Pushed by twice the run's tolerance, the rim is on no cylinder within it: no cylinder is found."""
    mesh = _cylinder()
    k = 2 * TOL_SHARE * float(mesh.diagonal) / roundoff(mesh.vertices)
    assert "cylinder" not in (_types(_rim_pushed(mesh, k)) or {})


def test_a_chain_walks_a_zig_zag_strip_along_its_long_edges():
    """A cylinder drawn as one strip (each triangle from one end circle to the other): the chain from a triangle
    reaches 3 steps each way along the strip, 7 triangles, and never crosses a rim (the short edges)."""
    n, r, h = 24, 2.0, 30.0
    a = np.linspace(0, np.pi / 2, n + 1)
    V = np.r_[np.c_[r * np.cos(a), r * np.sin(a), np.zeros(n + 1)], np.c_[r * np.cos(a), r * np.sin(a), np.full(n + 1, h)]]
    F = np.array([t for i in range(n) for t in ((i, i + 1, n + 1 + i), (i + 1, n + 2 + i, n + 1 + i))])
    mesh = clean_mesh(V, F)

    class At:  # one atom per triangle, all smooth
        labels = np.arange(len(F))
        tris = [np.array([t]) for t in range(len(F))]

        @staticmethod
        def smooth(x, y):
            return True

    nbr = long_edge_neighbours(mesh)
    c = chain(At, 20, np.ones(len(F), bool), nbr)
    assert c == list(range(17, 24))
