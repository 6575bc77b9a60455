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

from bench.corpus import regimes
from bench.corpus.parts import part

ROOT = Path(__file__).resolve().parents[1]
#: quick seeds covering the families: swept, sphere, prismatic (shell, holes, variable fillet), lofted, a pyramid with
#: every edge blended (four fillets at the apex), revolved (a tangent chain of tori)
SEEDS = (4, 10, 12, 21, 26, 27, 29, 30)


def _signature(seed):
    solid, meta = part(seed)
    return meta["faces"], round(meta["volume"], 6), round(meta["area"], 6), meta["occ_types"]


@pytest.fixture(scope="module")
def parts():
    return {s: part(s) for s in SEEDS}


def test_same_seed_same_part_in_this_process_and_another():
    quick = (10, 21, 29)
    here = [_signature(s) for s in quick]
    assert here == [_signature(s) for s in quick]
    code = ("import json, sys; from tests.test_corpus import _signature; "
            f"print(json.dumps([_signature(s) for s in {list(quick)}]))")
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
        # STEP writes reals to 15+ digits: only round-off may change (seed 1, not here, loses 3e-4 of its volume in
        # the round trip: the corpus takes the STEP as the truth and records that in meta["step_volume_error"])
        assert back.volume == pytest.approx(meta["volume"], rel=1e-9)
        assert 1 <= meta["faces"] <= 150


def test_bad_seed_is_refused():
    for bad in (-1, 1.5, "3", True):
        with pytest.raises(ValueError):
            part(bad)


def test_export_vertices_lie_on_their_true_faces(parts):
    """Every welded vertex is a node of its face's OpenCascade triangulation, and an inner node is the face's surface
    at the node's (u, v) to round-off; a node on the face's boundary lies on the edge curve, which OpenCascade keeps
    within the edge's tolerance of the surface. (Not measured by projecting: OpenCascade's point projections miss
    seed 4's swept B-spline by up to 1.2e-5 of the diagonal where S(u, v) is exact to 2e-15.)"""
    from OCP.BRep import BRep_Tool
    from OCP.TopLoc import TopLoc_Location
    from scipy.spatial import cKDTree

    for seed, (solid, meta) in parts.items():
        v, t, lab = regimes.tessellate(solid, "export", seed)  # leaves the triangulations on the solid's faces
        assert len(lab) == len(t) and lab.min() >= 0
        assert set(lab.tolist()) == set(range(meta["faces"]))  # every true face has triangles, every triangle a face
        assert regimes.is_watertight(t)
        diag = meta["diagonal"]
        for fi, face in enumerate(solid.faces()):
            loc = TopLoc_Location()
            tri = BRep_Tool.Triangulation_s(face.wrapped, loc)
            surf = BRep_Tool.Surface_s(face.wrapped)  # located: in the same frame as the transformed nodes
            trsf = loc.Transformation()
            pts = [tri.Node(i).Transformed(trsf) for i in range(1, tri.NbNodes() + 1)]
            nodes = np.array([[p.X(), p.Y(), p.Z()] for p in pts])
            on_surface = np.array([p.Distance(surf.Value(tri.UVNode(i).X(), tri.UVNode(i).Y()))
                                   for i, p in enumerate(pts, start=1)])
            edge_tol = max(BRep_Tool.Tolerance_s(e.wrapped) for e in face.edges())
            own = np.unique(t[lab == fi])
            dist, idx = cKDTree(nodes).query(v[own])
            assert dist.max() <= 1e-12 * diag, (seed, fi, dist.max() / diag)
            inner = on_surface <= 1e-9 * diag
            assert (on_surface[~inner] <= edge_tol).all(), (seed, fi, on_surface.max() / diag, edge_tol / diag)
            assert inner.sum() >= len(nodes) - len(np.unique(np.concatenate(
                [np.array([BRep_Tool.PolygonOnTriangulation_s(e.wrapped, tri, loc).Node(k)
                           for k in range(1, BRep_Tool.PolygonOnTriangulation_s(e.wrapped, tri, loc).NbNodes() + 1)])
                 for e in face.edges()]))), (seed, fi)  # only boundary nodes may be off the surface


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
    pytest.param(8, id="seed8-plate-holes-rib"),  # exit 1 today: it may exit 0 only once it is right
    pytest.param(10, id="seed10-sphere"),  # exit 0 with the sphere within tolerance
    # Before the acceptance rules (issue 20) these exited 0 far outside tolerance: seed 2 (a shelled cylinder, 5 true
    # faces, 188 triangles) with 4 faces 12.4 % of the diagonal off the true part, seed 11 (a hexagonal plate, 8 faces,
    # 20 triangles) with 2 faces 24 % off, against a stated tolerance of 0.05 %.
    pytest.param(2, id="seed2-shelled-cylinder"),
    pytest.param(11, id="seed11-hexagon-plate"),
]


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """One corpus cache for the module: a part or mesh made by one test is read by the next."""
    return tmp_path_factory.mktemp("corpus_cache")


@pytest.mark.parametrize("seed", _REGRESSION)
def test_recon_never_exits_0_outside_its_tolerance(seed, tmp_path, cache):
    from bench.corpus.measure import run_recon
    from bench.corpus.truth import materialise
    from recon.deviation import model_deviation

    truth = materialise(seed, "export", cache)
    out, report = tmp_path / "ours.step", tmp_path / "report.json"
    res = run_recon(truth.mesh, out, report, timeout=300, memory_mb=4096)
    assert res["status"] in ("ok", "exit1"), res
    if res["exit"] != 0:
        return
    tol = json.loads(report.read_text())["tolerance"]
    md = model_deviation(out, truth.step, samples=5000)
    assert md.to_reference.p95 <= tol, (md.to_reference.p95, tol)


def test_dense_sizing_lands_in_the_regime_range_whatever_the_remesher_made():
    """The subdivisions are chosen on the count the remesher made (each multiplies it by exactly 4): inside the
    range for any remeshed count up to its top, and the nearest in ratio to the target among those inside.
    (fine seed 6 was remeshed to 462 triangles for a target of 282 and subdivided 5 times: 473,088 > 300k.)"""
    for lo, hi in (regimes.FINE_RANGE, regimes.SCAN_RANGE):
        for target in np.geomspace(lo, hi, 13).astype(int):
            for n in np.unique(np.geomspace(1, hi, 400).astype(int)):
                k = regimes.subdivisions(int(n), int(target), (lo, hi))
                count = n * 4**k
                inside = [n * 4**j for j in range(12) if lo <= n * 4**j <= hi]
                assert lo <= count <= hi, (target, n, k)
                assert abs(np.log(count / target)) == min(abs(np.log(c / target)) for c in inside)
    assert regimes.subdivisions(462, 289_326, regimes.FINE_RANGE) == 4  # 118,272, not 473,088
    with pytest.raises(ValueError):
        regimes.subdivisions(100, 1000, (1000, 2000))  # no factor 4 between the bounds: a range not always reachable


def test_generate_only_records_a_case_the_generator_cannot_make(cache):
    """--generate-only's job never raises: a mesh the generator cannot make is a row with its reason (here a regime
    that does not exist, after the part itself was made and cached). Seed 11 shares the module's cache with the
    regression runs above, so nothing is made twice."""
    from bench.corpus.generate import generate_job

    row = generate_job((11, "no-such-regime", str(cache)))
    assert row["status"] == "generator" and "no-such-regime" in row["message"], row
    assert (cache / "parts" / "seed_00011.step").exists()
    ok = generate_job((11, "export", str(cache)))
    assert ok["status"] == "ok" and ok["watertight"], ok
    assert len(np.load(cache / "export" / "seed_00011.labels.npy")) == ok["triangles"]  # a true face per triangle


def test_real_parts_are_cases_read_where_they_lie(tmp_path, shared):
    """The shared real parts are corpus cases keyed after every generated seed, in name order. Their truth is the shared
    file itself (no copy in the cache), and their metadata is the part's: the io1 flange of the shared README has 17
    faces (11 cylinders, 5 planes, 1 cone); its export mesh is closed and gives every true face triangles. The count
    to judge recon by joins neighbouring faces on one surface (77 → 47 on the axle, whose every full cylinder or cone
    is two halves)."""
    from bench.corpus.real import REAL_BASE, real_files, real_seeds
    from bench.corpus.truth import materialise

    folder = shared("parts")
    files = real_files(folder)
    assert len(files) >= 12 and files == sorted(files)
    keys = real_seeds(None, folder)
    assert keys == [REAL_BASE + i for i in range(len(files))]
    with pytest.raises(ValueError):
        real_seeds([len(files)], folder)
    key = keys[[f.name for f in files].index("pythonocc_io1_flange.step")]
    truth = materialise(key, "export", tmp_path)
    assert truth.step == folder / "pythonocc_io1_flange.step"
    assert not (tmp_path / "parts" / f"seed_{key:05d}.step").exists()
    types = truth.meta["face_types"]
    assert (len(types), types.count("cylinder"), types.count("plane"), types.count("cone")) == (17, 11, 5, 1)
    assert truth.meta["family"] == "real:pythonocc_io1_flange"
    lab = np.load(truth.mesh.with_suffix(".labels.npy"))
    assert set(lab.tolist()) == set(range(17)) and truth.info["watertight"]
    # no two of its faces share a surface; the SolidWorks axle drew each full cylinder and cone as two halves
    assert truth.meta["faces_unified"] == 17
    from bench.corpus.truth import true_part

    axle = keys[[f.name for f in files].index("elmer_vaporizer_axle.step")]
    meta = true_part(axle, tmp_path)[1]
    assert (meta["faces"], meta["faces_unified"]) == (77, 47)


def test_a_hanging_measurement_is_cut_at_the_limit_and_keeps_its_solid_check(monkeypatch):
    """Export seed 13's STEP held a face where one OCC classification looped for over 37 min, in C++, where no signal
    reaches Python: the measurement runs in a child that is killed at the limit; what it sent before stays."""
    import time

    from bench.corpus import measure as M

    def hangs(truth, step, seed, checked=None):
        checked({"valid": True, "solids": 1})
        time.sleep(600)

    monkeypatch.setattr(M, "measure", hangs)
    t0 = time.monotonic()
    row = M._measured(None, None, 0, timeout=2.0)
    assert time.monotonic() - t0 < 30
    assert row["valid"] is True and row["solids"] == 1
    assert row["measure_error"].startswith("TimeoutError")
    monkeypatch.setattr(M, "measure", lambda truth, step, seed, checked=None: {"valid": False, "faces_ours": 3})
    assert M._measured(None, None, 0, timeout=30.0) == {"valid": False, "faces_ours": 3}


def test_a_cone_split_in_halves_on_one_surface_counts_once_in_the_joined_truth(tmp_path):
    """Export seed 45's countersink is two half-cones on one surface (26 faces): joined, 25 — the count a mesh can
    prove. The report scores recon's count against both and calls an exit 0 wrong only against the joined one."""
    from bench.corpus.real import unified_faces
    from bench.corpus.report import load_rows, summary

    solid, meta = part(45)
    assert (meta["faces"], unified_faces(solid)) == (26, 25)
    (tmp_path / "rows").mkdir()
    for seed, ours in ((45, 25), (46, 24)):
        row = {"seed": seed, "regime": "export", "status": "ok", "exit": 0, "valid": True, "faces_ours": ours,
               "faces_true": 26, "faces_true_unified": 25}
        (tmp_path / "rows" / f"{seed}.json").write_text(json.dumps(row))
    s = summary(load_rows(tmp_path))["export"]
    assert (s["exact faces"], s["exact faces, same-surface faces joined"]) == (0.0, 0.5)
    assert s["exit 0 with a wrong face count (joined)"] == 1


def test_what_recon_states_between_the_vertices_is_t_plus_the_chord_sag_where_larger():
    """Export seed 42 (a loft drawn by 866 triangles) exits 0 with its B-spline 0.024 % of the diagonal off the true
    surface against T = 0.010 %: but the mesh's own triangles lie 0.35 mm (0.32 %) off it there, and recon states
    T + the chord sag between the vertices. The corpus judges exit 0 against that statement."""
    from bench.corpus.measure import _stated

    def report(limit):
        return {"tolerance": 0.01, "verdict": {"rules": [{"rule": "shape_to_mesh_p95", "limit": limit}]}}

    assert _stated(report(0.26)) == 0.26
    assert _stated(report(0.01)) == 0.01
    assert _stated(report(None)) == 0.01  # not measured: the tolerance alone
    assert _stated({"tolerance": 0.01}) == 0.01


def test_off_part_is_the_distance_to_the_trimmed_faces():
    """A plate with a through hole of radius 2: points on its faces are on the part; a point on the top face's plane
    at the hole's centre (where a membrane over the hole would put it) is the radius away, at the hole's wall."""
    from build123d import Box, Cylinder

    plate = Box(20, 20, 5) - Cylinder(2, 5)
    on = np.array([[5.0, 5.0, 2.5], [-7.0, 3.0, -2.5], [10.0, 0.0, 1.0], [2.0, 0.0, 0.0], [0.0, -2.0, 1.5]])
    assert regimes.off_part(plate, on) == pytest.approx(0.0, abs=1e-7)
    assert regimes.off_part(plate, np.array([[0.0, 0.0, 2.5]])) == pytest.approx(2.0, abs=1e-7)
    assert regimes.off_part(plate, np.array([[1.0, 0.0, 2.5], [0.0, 0.0, 0.0]])) == pytest.approx(2.0, abs=1e-7)


def test_a_mesh_off_its_part_is_not_a_case(monkeypatch):
    """A remeshed mesh with a vertex farther than OFF_PART_EDGES of its edges from the part is refused (scan10 seed 0:
    a membrane over five bolt holes, bench/scan.md "s39-rim"); within it, the mesh is made."""
    from build123d import Box

    box = Box(10, 10, 10)
    v, t, _, _, h, _ = regimes._dense(box, 2000, (1000, 8000))
    assert regimes.off_part(box, v) <= regimes.OFF_PART_EDGES * h  # every vertex projected onto its face
    monkeypatch.setattr(regimes, "off_part", lambda solid, vertices: 1.01 * regimes.OFF_PART_EDGES * h)
    with pytest.raises(regimes.MeshNotPart):
        regimes._dense(box, 2000, (1000, 8000))
