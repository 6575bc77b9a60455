"""The benchmark harness: its measures on analytic inputs, and one real run where failures become rows."""

import json

import numpy as np
import pytest

from bench.cases import COLUMNS, STAGES, Case, fixture_cases
from bench.measure import type_agreement
from bench.report import loglog_slope, part_speed_line, render_markdown
from bench.run import run_benchmark
from recon.fixtures import load_fixture


def test_type_agreement_is_area_weighted_over_true_faces():
    # Four unit triangles: true face 0 (plane) has three, true face 1 (cylinder) one.
    true = np.array([0, 0, 0, 1])
    areas = np.ones(4)
    same = np.array([5, 5, 5, 7])
    assert type_agreement(same, true, areas, {5: "plane", 7: "cylinder"}, ("plane", "cylinder")) == 1.0
    # our face 7 was fitted as a plane: the cylinder's area (1 of 4) disagrees
    assert type_agreement(same, true, areas, {5: "plane", 7: "plane"}, ("plane", "cylinder")) == 0.75
    # one face of ours over everything: it is the best overlap of both true faces, a plane
    assert type_agreement(np.zeros(4, int), true, areas, {0: "plane"}, ("plane", "cylinder")) == 0.75
    # weights are areas, not triangle counts; unknown truth (-1) is ignored
    w = np.array([1.0, 1.0, 1.0, 9.0])
    assert type_agreement(same, true, w, {5: "plane", 7: "plane"}, ("plane", "cylinder")) == pytest.approx(0.25)
    assert type_agreement(same, np.array([0, 0, 0, -1]), areas, {5: "plane"}, ("plane", "cylinder")) == 1.0
    assert np.isnan(type_agreement(same, -np.ones(4, int), areas, {5: "plane"}, ("plane",)))


def test_loglog_slope_recovers_power_law_exponent():
    n = np.array([1e4, 1e5, 1e6, 2e6])
    assert loglog_slope(n, 3.0 * n**1.5) == pytest.approx(1.5)
    assert loglog_slope(n, 0.2 * n) == pytest.approx(1.0)
    # a case that failed (None/NaN) drops out; one point left gives no slope
    assert loglog_slope(n, [1.0, 10.0, np.nan, None]) == pytest.approx(1.0)
    assert np.isnan(loglog_slope(n[:1], [1.0]))


def test_run_writes_both_files_and_failures_become_rows(tmp_path):
    (case,) = [c for c in fixture_cases() if c.name == "box_fillet/coarse"]
    bad = tmp_path / "bad.off"
    bad.write_text("this is not a mesh\n")
    broken = Case("mesh/bad", "meshes", "mesh", {"path": str(bad)}, timeout=300)
    slow = Case("mesh/too-slow", "meshes", "mesh", {"path": str(bad)}, timeout=0.01)
    greedy = Case("mesh/too-big", "meshes", "mesh", {"path": str(bad)}, timeout=300, max_memory_mb=1)
    res = run_benchmark([case, broken, slow, greedy], out=tmp_path / "out")

    data = json.loads(res.json_path.read_text())
    rows = {r["case"]: r for r in data["rows"]}
    assert set(rows) == {"box_fillet/coarse", "mesh/bad", "mesh/too-slow", "mesh/too-big"}
    for r in rows.values():
        assert set(COLUMNS) <= set(r)

    fx = load_fixture("box_fillet", "coarse")
    good = rows["box_fillet/coarse"]
    assert good["status"] in ("ok", "invalid"), good["error"]
    assert good["triangles"] == len(fx.faces)  # the fixture is clean: nothing dropped
    assert good["faces_true"] == 26
    assert good["types_true"] == "12 cylinder, 8 sphere, 6 plane"
    assert set(good["seconds"]) == set(STAGES)
    assert 0.0 <= good["type_agreement"] <= 1.0 and 0.0 <= good["recovered"] <= 1.0
    # the fixture's vertices were projected onto the true surfaces (stored as float32): mesh → true STEP ≈ 0
    assert good["true_m2s_max"] < 1e-3
    assert good["peak_mb"] > 0 and good["step_bytes"] > 0
    # one fit record per face; a fit accepted as "ok" is within 2 tolerances at its max (the acceptance rule)
    assert len(good["face_fits"]) >= good["faces_ours"] > 0
    ok_fits = [f for f in good["face_fits"] if f[2] == "ok"]
    assert ok_fits and all(f[5] <= 2.0 + 1e-9 and 0.0 <= f[4] <= f[3] for f in ok_fits)

    assert rows["mesh/bad"]["status"] == "error"
    assert rows["mesh/bad"]["error"].startswith("load:")
    assert rows["mesh/too-slow"]["status"] == "timeout"
    assert rows["mesh/too-big"]["status"] == "crashed"  # a Python interpreter alone holds more than 1 MiB
    assert "memory over 1 MiB" in rows["mesh/too-big"]["error"]

    md = res.md_path.read_text()
    assert "## Fixtures (ground truth)" in md and "| box_fillet/coarse |" in md
    assert "`mesh/bad` — error: load:" in md
    for key in COLUMNS:
        assert f"- `{key}`:" in md


def test_unit_factor_takes_a_mesh_into_its_step_units():
    from bench.measure import unit_factor

    # abc_00000050: STL in metres (diagonal 0.135), STEP in millimetres (135).
    assert unit_factor(0.1349, 134.9) == 1000.0
    assert unit_factor(10.0, 254.0) == 25.4  # inches → mm
    assert unit_factor(254.0, 10.0) == pytest.approx(1 / 25.4)
    assert unit_factor(1.0, 1.01) == 1.0 and unit_factor(1.0, 1.5) == 1.0  # same units, or no unit step


def test_part_speed_line_gives_the_ratio_or_a_lower_bound_on_a_timeout():
    ours = {"case": "scaling/100k", "group": "scaling", "triangles": 103_296, "convert_seconds": 5.0, "faces_ours": 26}
    done = {"case": "freecad:scaling/100k", "group": "freecad", "status": "ok", "convert_seconds": 900.0,
            "faces_ours": 30_000}
    line = part_speed_line([ours, done])
    assert "FreeCAD 900 s" in line and "recon 5.0 s" in line and "**180×**" in line
    killed = {"case": "freecad:scaling/100k", "group": "freecad", "status": "timeout", "wall_seconds": 400.0}
    assert "**more than 80×**" in part_speed_line([ours, killed])
    assert part_speed_line([ours]) is None  # no FreeCAD row: no claim
    assert part_speed_line([done]) is None
    # the pair also enters the side-by-side table, whose ratio is the same
    md = render_markdown([ours, done])
    assert "| scaling/100k |" in md and "180.00×" in md
