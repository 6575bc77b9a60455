"""Plane atoms that hold a curved face's quad and a tangent fillet's triangle in one plane are split between the two
faces (recon/segment/_exact_split.py).

A cylinder whose top rim is filleted has 4 faces: the cylinder, the torus, two planes. Exported with OpenCascade at the
corpus's settings, a fillet triangle next to the rim can lie in the plane of the cylinder quad beside it to round-off;
that atom, no curved surface holding it whole, cut the cylinder's strip there: 2-4 cylinders and 3-6 planes for 4 faces
(export seeds 86 and 136 on the corpus). The expected faces are the part's own, triangle for triangle.
"""

from __future__ import annotations

from collections import Counter

import build123d as bd
import numpy as np
import pytest

from recon.mesh import clean_mesh
from recon.segment._exact import exact_faces, plane_atoms, roundoff

#: the run's tolerance as recon picks it for a noise-free mesh: 1e-4 of the diagonal
TOL_SHARE = 1e-4


def _export(solid, chord: float, angle: float):
    """``solid`` tessellated as the corpus's ``export`` regime does, with the true face of every triangle."""
    from bench.corpus.regimes import make_fixtures

    bb = solid.bounding_box()
    diag = (bb.max - bb.min).length
    v, t, labels = make_fixtures().occ_mesh(solid, deflection=chord * diag, angular=angle)[:3]
    mesh = clean_mesh(np.asarray(v, float), np.asarray(t))
    assert len(mesh.faces) == len(labels)  # the cleaner keeps an exported mesh's triangles in order
    return mesh, np.asarray(labels)


@pytest.mark.parametrize("radius, fillet, height, chord, angle",
                         [(10, 0.5, 20, 1e-3, 0.5), (19, 4, 10, 1.5e-3, 0.3), (27.7, 2, 20, 1.5e-3, 0.5)])
def test_rim_fillet_triangle_coplanar_with_a_cylinder_quad_splits_its_atom(radius, fillet, height, chord, angle):
    solid = bd.fillet(bd.Cylinder(radius, height).edges().group_by(bd.Axis.Z)[-1], fillet)
    mesh, true = _export(solid, chord, angle)
    atoms = plane_atoms(mesh, roundoff(mesh.vertices))
    # the case itself: some plane atom holds triangles of two true faces
    assert any(len(np.unique(true[atoms == a])) > 1 for a in np.unique(atoms))
    found = exact_faces(mesh, TOL_SHARE * float(mesh.diagonal), atoms)
    assert found is not None
    assert dict(Counter(f.type for f in found.fits.values())) == {"cylinder": 1, "torus": 1, "plane": 2}
    # the same partition of the triangles as the part's faces
    pairs = set(zip(found.labels.tolist(), true.tolist()))
    assert len(pairs) == 4
