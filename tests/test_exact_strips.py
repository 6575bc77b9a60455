"""Runs of plane strips the exact path's seeds left as planes become their curved face (recon/segment/_exact_strips.py),
narrow true planes next to curved faces stay planes, and a strip's quad sharing its plane with a fillet's triangle
goes to its cylinder (recon/segment/_exact_split.py).

Expected numbers are the parts' own: a cylinder with one filleted rim has 4 faces (a cylinder, a torus, two planes); a
bar whose two top edges are filleted down to a 0.4-wide flat and one bottom edge chamfered has 9 (two cylinders, seven
planes).
"""

from __future__ import annotations

from collections import Counter

import build123d as bd
import numpy as np
import pytest

from recon.mesh import clean_mesh
from recon.segment import _exact as E
from recon.segment._exact_strips import strip_faces

#: the run's tolerance as recon picks it for a noise-free mesh: 1e-4 of the diagonal
TOL_SHARE = 1e-4


def _export(solid, chord: float, angle: float):
    """``solid`` tessellated as the corpus's ``export`` regime does (OCC, chord ``chord`` of the diagonal), with the
    true face of every triangle."""
    from bench.corpus.regimes import make_fixtures

    bb = solid.bounding_box()
    diag = (bb.max - bb.min).length
    v, t, labels = make_fixtures().occ_mesh(solid, deflection=chord * diag, angular=angle)[:3]
    mesh = clean_mesh(np.asarray(v, float), np.asarray(t))
    assert len(mesh.faces) == len(labels)  # the cleaner keeps an exported mesh's triangles in order
    return mesh, np.asarray(labels)


def _rimmed_cylinder():
    """Export seed 15's first step: a cylinder of r 19 whose top rim is a fillet of r 4.1 (4 faces)."""
    return bd.fillet(bd.Cylinder(19, 15.5).edges().group_by(bd.Axis.Z)[-1], 4.1)


def test_a_cylinder_left_as_strips_is_found_whole_and_nothing_else_moves():
    """Export seed 15: a cylinder one quad tall between the bottom plane and a fillet torus came out as 70 planes (every
    seed's ring crossed into the torus). Given the curved faces without the cylinder, its strips are one run that a
    surface holds whole: one new face, exactly the cylinder's triangles, a cylinder by its rulings."""
    solid = _rimmed_cylinder()
    kinds = [f.geom_type.name for f in solid.faces()]
    mesh, true = _export(solid, 1e-3, 0.3)
    cyl = kinds.index("CYLINDER")
    V, F = mesh.vertices, mesh.faces
    eps, sag = E.roundoff(V), E.SAG_SHARE * float(mesh.diagonal)
    at = E._Atoms.of(mesh, E.plane_atoms(mesh, eps))
    regions = E.reclaim(at, E.grow_curved(at, eps, sag), eps, sag)
    # the seeds' result as on seed 15: the torus found, the cylinder's strips left as planes
    others = [(r, f) for r, f in regions if not (true[np.concatenate([at.tris[a] for a in r])] == cyl).any()]
    assert len(others) == len(regions) - 1
    out = strip_faces(at, others, eps, lambda ids, tris: next(iter(E._candidates(V, F, ids, tris, eps, sag)), None))
    assert out[:len(others)] == others
    assert len(out) == len(others) + 1
    region, fit = out[-1]
    tris = np.concatenate([at.tris[a] for a in region])
    assert sorted(tris.tolist()) == np.flatnonzero(true == cyl).tolist()
    assert E._best_type(at, region, fit, eps, sag)[0].type == "cylinder"


@pytest.mark.parametrize("chord, angle", [(1e-3, 0.3), (1e-3, 0.5)])
def test_rimmed_cylinder_true_faces(chord, angle):
    found = E.exact_faces(*_faces_args(_rimmed_cylinder(), chord, angle))
    assert found is not None
    assert dict(Counter(f.type for f in found.fits.values())) == {"cylinder": 1, "torus": 1, "plane": 2}


def _faces_args(solid, chord, angle):
    mesh, _ = _export(solid, chord, angle)
    return mesh, TOL_SHARE * float(mesh.diagonal), E.plane_atoms(mesh, E.roundoff(mesh.vertices))


@pytest.mark.parametrize("chord, angle", [(1e-3, 0.3), (2e-3, 0.5)])
def test_a_narrow_flat_between_fillets_and_a_chamfer_stay_planes(chord, angle):
    """A 0.4-wide flat between two fillets of r 2 (tangent to both: a smooth run of strips with them) and a 45° chamfer
    (below the crease angle: smooth with its two planes) are planes: no cylinder holds them with their neighbours."""
    bar = bd.Box(30, 4.4, 10)
    bar = bd.fillet(bar.edges().filter_by(bd.Axis.X).group_by(bd.Axis.Z)[-1], 2)
    bar = bd.chamfer(bar.edges().filter_by(bd.Axis.X).group_by(bd.Axis.Z)[0].sort_by(bd.Axis.Y)[0], 1)
    true = Counter(f.geom_type.name.lower() for f in bar.faces())
    assert true == {"plane": 7, "cylinder": 2}
    found = E.exact_faces(*_faces_args(bar, chord, angle))
    assert found is not None
    assert dict(Counter(f.type for f in found.fits.values())) == dict(true)


@pytest.mark.parametrize("radius, fillet, height, chord, angle",
                         [(10, 0.5, 20, 1e-3, 0.5), (19, 4, 10, 1.5e-3, 0.3), (27.7, 2, 20, 1.5e-3, 0.5)])
def test_a_rim_fillet_triangle_in_a_cylinder_quads_plane_splits_its_atom(radius, fillet, height, chord, angle):
    """A fillet triangle next to the rim can lie in the plane of the cylinder quad beside it to round-off: that plane
    atom, held whole by no curved surface, cut the cylinder's strip (recon/segment/_exact_split.py; export seeds 86 and
    136). Before: 5, 7 and 11 faces for these 4; now the part's faces, triangle for triangle."""
    solid = bd.fillet(bd.Cylinder(radius, height).edges().group_by(bd.Axis.Z)[-1], fillet)
    mesh, true = _export(solid, chord, angle)
    atoms = E.plane_atoms(mesh, E.roundoff(mesh.vertices))
    assert any(len(np.unique(true[atoms == a])) > 1 for a in np.unique(atoms))  # the case: an atom of two true faces
    found = E.exact_faces(mesh, TOL_SHARE * float(mesh.diagonal), atoms)
    assert found is not None
    assert dict(Counter(f.type for f in found.fits.values())) == {"cylinder": 1, "torus": 1, "plane": 2}
    assert len(set(zip(found.labels.tolist(), true.tolist()))) == 4  # the same partition as the part's faces
