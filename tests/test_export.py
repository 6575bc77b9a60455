"""Writing the B-rep (recon.brep._export) and OpenCascade's own messages (recon.brep._messages)."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
from OCP.BRepFill import BRepFill_Filling
from OCP.GeomAbs import GeomAbs_C0
from OCP.gp import gp_Pnt

from recon.brep import write_shape
from recon.brep._export import model_units, read_iges
from recon.brep._messages import occ_messages
from recon.brep._result import shape_validity
from recon.brep._step_read import faces_of, read_step

WIRE_WARNING = "WireFromList: can't find the next edge"


def _filling_of_a_broken_wire() -> bool:
    """A filling whose boundary has a stray edge: OCCT 7.9 sends "Warning: WireFromList: ..." to its messenger."""
    filling = BRepFill_Filling()
    for a, b in [((0, 0, 0), (1, 0, 0)), ((1, 0, 0), (1, 1, 0)), ((1, 1, 0), (0, 1, 0)), ((5, 5, 0), (6, 5, 0))]:
        filling.Add(BRepBuilderAPI_MakeEdge(gp_Pnt(*a), gp_Pnt(*b)).Edge(), GeomAbs_C0, True)
    filling.Build()
    return filling.IsDone()


@pytest.fixture()
def occ_prints_warnings():
    """The default messenger's printers at OCCT's default level (Info) for the test: build123d's export_step leaves
    them at Fail for the rest of the process, which hides warnings whether recon routes them or not."""
    from OCP.Message import Message, Message_Gravity

    printers = Message.DefaultMessenger_s().Printers()
    printers = [printers.Value(i) for i in range(1, printers.Length() + 1)]
    old = [p.GetTraceLevel() for p in printers]
    for p in printers:
        p.SetTraceLevel(Message_Gravity.Message_Info)
    yield
    for p, level in zip(printers, old):
        p.SetTraceLevel(level)


def test_occ_warnings_go_to_the_debug_log_not_to_the_terminal(capfd, caplog, tmp_path, monkeypatch,
                                                               occ_prints_warnings):
    """Outside occ_messages the warning reaches the process's stdout in ANSI colours (the trigger is real); inside,
    neither stdout nor stderr gets it, the log has it at debug level, plain, and no file is left in TMPDIR."""
    _filling_of_a_broken_wire()
    out = capfd.readouterr().out
    assert WIRE_WARNING in out and "\x1b[" in out
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    with caplog.at_level(logging.DEBUG, logger="recon.brep.occ"):
        with occ_messages():
            with occ_messages():  # re-entrant: the inner end keeps the outer's routing
                pass
            _filling_of_a_broken_wire()
    captured = capfd.readouterr()
    assert WIRE_WARNING not in captured.out + captured.err, captured
    logged = [r for r in caplog.records if r.name == "recon.brep.occ"]
    assert [r.levelno for r in logged] == [logging.DEBUG]
    assert logged[0].getMessage() == ("Warning: WireFromList: can't find the next edge. The wire is not complete, "
                                      "some edges are lost.")
    assert list(tmp_path.iterdir()) == []
    _filling_of_a_broken_wire()  # the messenger's own printer is back
    assert WIRE_WARNING in capfd.readouterr().out


# --------------------------------------------------------------------------------------------------
# Units, schema, IGES: written, read back by OpenCascade
# --------------------------------------------------------------------------------------------------

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "data"


@pytest.fixture(scope="module")
def prism():
    """The clean prism fixture's B-rep (exact planes) and its volume in memory, in the mesh's units."""
    from recon import convert

    result = convert(FIXTURES / "prism_clean.stl", deviation=False)
    assert result.brep.validity.ok
    return result.brep, float(result.brep.validity.volume)


@pytest.mark.parametrize("units, mm_per_unit, declared", [("mm", 1.0, "SI_UNIT(.MILLI.,.METRE.)"),
                                                           ("inch", 25.4, "CONVERSION_BASED_UNIT('INCH'"),
                                                           ("m", 1000.0, "SI_UNIT($,.METRE.)")])
def test_step_declares_the_mesh_unit_and_keeps_its_numbers(tmp_path, prism, units, mm_per_unit, declared):
    """The file states the unit and keeps the numbers: OpenCascade reading it in mm gets the part mm_per_unit times
    larger (volume by its cube: 25.4³ = 16387.064 for inches); read in the same unit, the volume in memory."""
    brep, volume = prism
    path = write_shape(tmp_path / "p.step", brep, units=units)
    assert declared in path.read_text()
    shape, _ = read_step(path)
    assert shape_validity(shape).volume == pytest.approx(volume * mm_per_unit ** 3, rel=1e-9)
    with model_units(units):
        shape, _ = read_step(path)
    assert shape_validity(shape).volume == pytest.approx(volume, rel=1e-9)
    shape, _ = read_step(path)  # the reader's unit is mm again after the context
    assert shape_validity(shape).volume == pytest.approx(volume * mm_per_unit ** 3, rel=1e-9)


@pytest.mark.parametrize("schema, words", [("AP242", "AP242_MANAGED_MODEL_BASED_3D_ENGINEERING"),
                                           ("AP214", "AUTOMOTIVE_DESIGN")])
def test_step_schema(tmp_path, prism, schema, words):
    brep, volume = prism
    path = write_shape(tmp_path / "p.step", brep, schema=schema)
    header = path.read_text()[:2000]
    assert "FILE_SCHEMA" in header and words in header, header
    shape, names = read_step(path)
    assert shape_validity(shape).volume == pytest.approx(volume, rel=1e-9)
    assert sorted(names) == sorted(r.name for r in brep.faces)  # face names survive in both protocols


@pytest.mark.parametrize("suffix, units, mm_per_unit", [(".igs", "mm", 1.0), (".iges", "inch", 25.4)])
def test_iges_round_trip(tmp_path, prism, suffix, units, mm_per_unit):
    """IGES in B-rep mode: one valid solid with the same faces, the volume to IGES's printed precision, and the
    declared unit honoured like STEP's."""
    brep, volume = prism
    path = write_shape(tmp_path / f"p{suffix}", brep, units=units)
    with model_units(units):
        shape = read_iges(path)
    val = shape_validity(shape)
    assert val.ok and val.n_solids == 1 and val.shape_type == "solid"
    assert len(faces_of(shape)) == len(faces_of(brep.occ)) == val.n_faces
    assert val.volume == pytest.approx(volume, rel=1e-9)
    assert shape_validity(read_iges(path)).volume == pytest.approx(volume * mm_per_unit ** 3, rel=1e-9)


def test_bad_units_and_schema_are_refused(tmp_path, prism):
    from recon.errors import InputError

    with pytest.raises(InputError, match="`units` must be one of mm, inch, m"):
        write_shape(tmp_path / "p.step", prism[0], units="ft")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="`schema` must be one of AP214, AP242"):
        write_shape(tmp_path / "p.step", prism[0], schema="AP203")  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []
