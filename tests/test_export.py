"""Writing the B-rep (recon.brep._export) and OpenCascade's own messages (recon.brep._messages)."""

from __future__ import annotations

import logging

from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
from OCP.BRepFill import BRepFill_Filling
from OCP.GeomAbs import GeomAbs_C0
from OCP.gp import gp_Pnt

from recon.brep._messages import occ_messages

WIRE_WARNING = "WireFromList: can't find the next edge"


def _filling_of_a_broken_wire() -> bool:
    """A filling whose boundary has a stray edge: OCCT 7.9 sends "Warning: WireFromList: ..." to its messenger."""
    filling = BRepFill_Filling()
    for a, b in [((0, 0, 0), (1, 0, 0)), ((1, 0, 0), (1, 1, 0)), ((1, 1, 0), (0, 1, 0)), ((5, 5, 0), (6, 5, 0))]:
        filling.Add(BRepBuilderAPI_MakeEdge(gp_Pnt(*a), gp_Pnt(*b)).Edge(), GeomAbs_C0, True)
    filling.Build()
    return filling.IsDone()


def test_occ_warnings_go_to_the_debug_log_not_to_the_terminal(capfd, caplog, tmp_path, monkeypatch):
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
