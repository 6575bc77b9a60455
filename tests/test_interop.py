"""recon's result keeps being modelled in CadQuery (the ``cadquery`` extra, which the ``test`` extra installs)."""

import math
from pathlib import Path

import build123d as bd
import cadquery as cq
import pytest

import recon

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "data"


@pytest.fixture(scope="module")
def box_fillet():
    """The bundled filleted box (60 × 40 × 30, fillets r = 5), converted: 26 faces."""
    return recon.convert(FIXTURES / "box_fillet_clean.stl", deviation=False)


def test_to_cadquery_is_the_same_solid(box_fillet):
    solid = recon.to_cadquery(box_fillet)
    assert isinstance(solid, cq.Solid) and solid.isValid()
    assert solid.wrapped.IsSame(box_fillet.shape.wrapped)  # the same OpenCascade shape, not a copy
    assert len(solid.Faces()) == len(box_fillet.shape.faces())
    assert solid.Volume() == pytest.approx(box_fillet.shape.volume, rel=1e-12)


def test_a_hole_drilled_in_cadquery_removes_its_cylinder(box_fillet):
    # CadQuery's own idiom on recon's solid: a through hole of r = 5 in the top face's centre, 15 from any fillet.
    # The top and bottom are planes, so the solid loses exactly pi r^2 times its height there.
    body = cq.Workplane(obj=recon.to_cadquery(box_fillet))
    top, bottom = body.faces(">Z").val(), body.faces("<Z").val()
    assert top.geomType() == bottom.geomType() == "PLANE"
    height = top.Center().z - bottom.Center().z
    assert height == pytest.approx(30.0, abs=0.01 * 30)  # the fixture's height, within the fit's tolerance
    result = body.faces(">Z").workplane().hole(10.0).val()
    (drilled,) = result.Solids()  # (CadQuery returns a cut as a compound: of one solid here)
    assert drilled.isValid() and result.isValid()
    assert len(drilled.Faces()) == len(box_fillet.shape.faces()) + 1  # the hole's wall
    removed = box_fillet.shape.volume - drilled.Volume()
    assert removed == pytest.approx(math.pi * 5.0**2 * height, rel=1e-6)


def test_to_cadquery_takes_a_build123d_shape_and_refuses_anything_else():
    box = bd.Box(3, 2, 1)
    assert recon.to_cadquery(box).Volume() == pytest.approx(6.0, rel=1e-12)
    with pytest.raises(TypeError, match="not str"):
        recon.to_cadquery("box.step")
