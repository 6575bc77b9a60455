"""The editability benchmark's edits and checks on a cube, where each edit's volume change is analytic."""

import math

import pytest
from build123d import Box

from bench.editability import (FILLET_FRACTION, HOLE_FRACTION, N_FILLETS, _check, _diag, _edit, _fillet_edges,
                               _hole_sites, _volume)

A = 10.0  # cube side


@pytest.fixture(scope="module")
def cube():
    return Box(A, A, A).wrapped


def test_plan_takes_sharp_edges_and_the_largest_planes(cube):
    diag = _diag(cube)
    assert diag == pytest.approx(A * math.sqrt(3), rel=1e-6)
    assert len(_fillet_edges(cube, FILLET_FRACTION * diag)) == N_FILLETS  # 12 sharp edges, five spread over them
    sites = _hole_sites(cube, diag)
    assert len(sites) == 2
    for point, normal in sites:  # on a face, along its outward normal
        axis = max(range(3), key=lambda k: abs(normal[k]))
        assert abs(normal[axis]) == pytest.approx(1.0)
        assert point[axis] == pytest.approx(math.copysign(A / 2, normal[axis]))


def test_fillet_and_drill_change_the_volume_as_analytic(cube):
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepFilletAPI import BRepFilletAPI_MakeFillet
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    diag, v0 = _diag(cube), _volume(cube)
    edge = _fillet_edges(cube, FILLET_FRACTION * diag)[0]
    assert _edit(cube, v0, diag, ("fillet", edge)) == "ok"
    r = FILLET_FRACTION * diag
    op = BRepFilletAPI_MakeFillet(cube)
    op.Add(r, edge)
    assert v0 - _volume(op.Shape()) == pytest.approx(A * r * r * (1 - math.pi / 4), rel=1e-4)
    site = _hole_sites(cube, diag)[0]
    assert _edit(cube, v0, diag, ("drill", site)) == "ok"
    rh = HOLE_FRACTION * diag
    (px, py, pz), n = site
    tool = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(px - n[0] * diag, py - n[1] * diag, pz - n[2] * diag),
                                           gp_Dir(*n)), rh, 2 * diag).Shape()
    drilled = BRepAlgoAPI_Cut(cube, tool).Shape()
    assert v0 - _volume(drilled) == pytest.approx(math.pi * rh * rh * A, rel=1e-6)


def test_check_refuses_a_drill_that_adds_material_and_a_fillet_that_eats_the_part(cube):
    diag, v0 = _diag(cube), _volume(cube)
    bigger = Box(A, A, 2 * A).wrapped
    assert _check(bigger, v0, "drill", diag, HOLE_FRACTION * diag).startswith("volume")
    assert _check(Box(A, A, A / 2).wrapped, v0, "fillet", diag, FILLET_FRACTION * diag).startswith("volume")
    assert _check(cube, v0, "fillet", diag, FILLET_FRACTION * diag) == "ok"
