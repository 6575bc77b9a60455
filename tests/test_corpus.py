"""The random-part corpus (bench/corpus): a deterministic generator, exact ground truth, and recon's regression cases.

Everything asserted is ground truth: a seed builds the same solid in any process; the export tessellation's vertices
lie on their true faces (measured with OpenCascade's exact BRepExtrema); the mesh is closed; the OBJ's polygons have
the triangles' area; exit 0 never comes with a result farther from the true part than the tolerance recon states.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("build123d")

from bench.corpus import regimes  # noqa: E402
from bench.corpus.parts import part  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: quick seeds covering the families: prismatic (holes, shell), blended (variable fillet), lofted, swept, revolved
SEEDS = (1, 6, 10, 12, 21, 29, 30)


def _signature(seed):
    solid, meta = part(seed)
    return meta["faces"], round(meta["volume"], 6), round(meta["area"], 6), meta["occ_types"]


@pytest.fixture(scope="module")
def parts():
    return {s: part(s) for s in SEEDS}


def test_same_seed_same_part_in_this_process_and_another():
    here = [_signature(s) for s in SEEDS[:4]]
    assert here == [_signature(s) for s in SEEDS[:4]]
    code = ("import json, sys; from tests.test_corpus import _signature; "
            f"print(json.dumps([_signature(s) for s in {list(SEEDS[:4])}]))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True,
                         env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert json.loads(out.stdout.strip().splitlines()[-1]) == [list(x[:3]) + [x[3]] for x in here]


def test_step_round_trip_is_the_part(parts, tmp_path):
    from build123d import export_step, import_step

    for seed, (solid, meta) in parts.items():
        assert solid.is_valid and len(solid.solids()) == 1
        path = tmp_path / f"{seed}.step"
        export_step(solid, str(path))
        back = import_step(str(path))
        assert len(back.faces()) == meta["faces"] == len(meta["face_types"])
        assert back.volume == pytest.approx(meta["volume"], rel=1e-9)
        assert 1 <= meta["faces"] <= 150


def test_bad_seed_is_refused():
    for bad in (-1, 1.5, "3", True):
        with pytest.raises(ValueError):
            part(bad)


def test_export_vertices_lie_on_their_true_faces(parts):
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.gp import gp_Pnt

    for seed, (solid, meta) in parts.items():
        v, t, lab = regimes.tessellate(solid, "export", seed)
        assert len(lab) == len(t) and lab.min() >= 0
        assert set(lab.tolist()) == set(range(meta["faces"]))  # every true face has triangles, every triangle a face
        assert regimes.is_watertight(t)
        faces = solid.faces()
        rng = np.random.default_rng(seed)
        worst = 0.0
        for ti in rng.choice(len(t), min(60, len(t)), replace=False):
            for vi in t[ti]:
                dss = BRepExtrema_DistShapeShape(BRepBuilderAPI_MakeVertex(gp_Pnt(*v[vi])).Vertex(),
                                                 faces[lab[ti]].wrapped)
                worst = max(worst, dss.Value())
        assert worst < 1e-9 * meta["diagonal"], (seed, worst / meta["diagonal"])


def test_export_settings_are_in_the_issue_range():
    for seed in range(50):
        chord, angle = regimes.export_settings(seed)
        assert 1e-4 <= chord <= 1e-2 and 0.1 <= angle <= 0.8


def test_quad_obj_has_the_triangles_area(parts, tmp_path):
    import trimesh

    merged = 0
    for seed, (solid, meta) in parts.items():
        v, t, lab = regimes.tessellate(solid, "export", seed)
        polys, plab = regimes.planar_polygons(v, t, lab, [k == "plane" for k in meta["face_types"]])
        merged += len(t) - len(polys)
        path = tmp_path / f"{seed}.obj"
        regimes.write_obj(path, v, polys)
        back = trimesh.load(path, process=False, force="mesh")
        assert back.area == pytest.approx(trimesh.Trimesh(v, t, process=False).area, rel=1e-12)
        assert len(back.faces) == len(t)  # a convex n-gon fans into n − 2 triangles: as many as were merged
    assert merged > 0


# recon on a fixed handful: the rule of issue 20 (exit 0 means within the stated tolerance), as measured today.
_REGRESSION = [
    pytest.param(0, id="seed0"),
    pytest.param(2, id="seed2", marks=pytest.mark.xfail(strict=True, reason=(
        "issue 20: export seed 2 (a shelled cylinder, 5 faces, 188 triangles): exit 0 with 4 faces whose "
        "ours→true p95 is 205 % of the diagonal against a stated tolerance of 0.05 %"))),
]


@pytest.mark.parametrize("seed", _REGRESSION)
def test_recon_never_exits_0_outside_its_tolerance(seed, tmp_path):
    from bench.corpus.measure import run_recon
    from bench.corpus.truth import materialise
    from recon.deviation import model_deviation

    truth = materialise(seed, "export", tmp_path / "cache")
    out, report = tmp_path / "ours.step", tmp_path / "report.json"
    res = run_recon(truth.mesh, out, report, timeout=300, memory_mb=4096)
    assert res["status"] in ("ok", "exit1"), res
    if res["exit"] != 0:
        return
    tol = json.loads(report.read_text())["tolerance"]
    md = model_deviation(out, truth.step, samples=5000)
    assert md.to_reference.p95 <= tol, (md.to_reference.p95, tol)
