"""The FreeCAD addon (freecad/, package.xml) run headless in freecadcmd, installed the way the Addon Manager installs
it: the repository in FreeCAD's Mod folder (here a fresh user folder, FREECAD_USER_HOME, so the user's own FreeCAD
settings are never read or written). Skips where FreeCAD is absent, fails there where RECON_REQUIRE_FREECAD=1."""

import json
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from recon._freecad import freecadcmd
from recon.brep import KIND_COLOURS

REPO = Path(__file__).resolve().parents[1]
BOX = REPO / "fixtures" / "data" / "box_fillet_clean.stl"

# Runs inside freecadcmd: the command's core on a Mesh object (as the GUI command on the selection) and on a file
# path (as the command with a file chosen), with recon's python set through the addon's setting.
DRIVER = r"""
import json, os
import FreeCAD, Mesh
import recon_addon

recon_addon.params().SetString("ReconPython", os.environ["RECON_FC_PYTHON"])
doc = FreeCAD.newDocument("addon")
Mesh.insert(os.environ["RECON_FC_MESH"], doc.Name)
mesh = doc.Objects[-1]
logged = []
res = recon_addon.mesh_to_cad(doc, mesh, log=logged.append)
shape = res.feature.Shape
sheet = res.sheet
rows = []
for i in range(1, len(shape.Faces) + 2):
    rows.append([sheet.getContents(c + str(i)) for c in "ABCD"])
by_file = recon_addon.mesh_to_cad(doc, os.environ["RECON_FC_MESH"])  # prints its summary on stdout
errors = {}
recon_addon.params().SetString("ReconPython", "/nonexistent/python")
try:
    recon_addon.recon_command()
except recon_addon.ReconAddonError as exc:
    errors["setting"] = str(exc)
recon_addon.params().SetString("ReconPython", os.environ["RECON_FC_PYTHON"])
with open("empty.stl", "w") as fh:
    fh.write("solid empty\nendsolid empty\n")
before = len(doc.Objects)
try:
    recon_addon.mesh_to_cad(doc, "empty.stl")
except recon_addon.ReconAddonError as exc:
    errors["bad_mesh"] = str(exc)
errors["objects_added"] = len(doc.Objects) - before
out = {
    "module": recon_addon.__file__,
    "command": recon_addon.recon_command(),
    "mesh_type": mesh.TypeId,
    "type": shape.ShapeType, "valid": shape.isValid(), "solids": len(shape.Solids), "volume": shape.Volume,
    "closed": all(s.isClosed() for s in shape.Shells),
    "surfaces": [f.Surface.__class__.__name__ for f in shape.Faces],
    "face_names": list(res.feature.FaceNames), "face_kinds": list(res.feature.FaceKinds),
    "face_colors": [list(c)[:3] for c in res.feature.FaceColors],
    "names_checked": res.names_checked, "exit_code": res.run.exit_code, "report": res.run.report,
    "sheet_label": sheet.Label, "sheet_type": sheet.TypeId, "rows": rows, "logged": logged,
    "feature_label": res.feature.Label, "within": res.feature.WithinTolerance,
    "file_faces": len(by_file.feature.Shape.Faces), "file_valid": by_file.feature.Shape.isValid(),
    "file_label": by_file.feature.Label, "errors": errors,
}
with open(os.environ["RECON_FC_OUT"], "w") as fh:
    json.dump(out, fh)
"""


@pytest.fixture(scope="module")
def addon_run(tmp_path_factory):
    exe = freecadcmd()
    assert exe is not None  # the freecad marker skipped (or failed) the test otherwise
    tmp = tmp_path_factory.mktemp("fc_addon")
    user = tmp / "freecad-user"
    (user / "Mod").mkdir(parents=True)
    (user / "Mod" / "recon").symlink_to(REPO, target_is_directory=True)  # what the Addon Manager's clone gives
    (tmp / "driver.py").write_text(DRIVER)
    env = dict(os.environ, FREECAD_USER_HOME=str(user), RECON_FC_PYTHON=sys.executable, RECON_FC_MESH=str(BOX),
               RECON_FC_OUT=str(tmp / "out.json"))
    proc = subprocess.run([exe, str(tmp / "driver.py")], env=env, cwd=tmp, capture_output=True, text=True,
                          timeout=120)
    out = tmp / "out.json"
    assert out.exists(), "freecadcmd ran no addon: " + " | ".join((proc.stderr or proc.stdout).splitlines()[-5:])
    return json.loads(out.read_text()), proc.stdout


pytestmark = pytest.mark.freecad


def test_the_addon_loads_from_the_mod_folder_and_runs_recon_in_its_own_python(addon_run):
    res, _ = addon_run
    # FreeCAD found the workbench's folder through package.xml's <subdirectory>, as after an Addon Manager install.
    assert Path(res["module"]).parent.name == "freecad" and "/Mod/recon/" in res["module"]
    assert res["command"] == [sys.executable, "-m", "recon"]  # the ReconPython setting
    assert res["mesh_type"] == "Mesh::Feature"


def test_one_valid_solid_with_the_reports_faces(addon_run):
    res, _ = addon_run
    report = res["report"]
    assert res["exit_code"] == 0 and res["within"] is True
    assert res["type"] == "Solid" and res["valid"] and res["solids"] == 1 and res["closed"]
    # recon's verdict measured the same STEP file read back by OpenCascade: equal to round-off.
    (solid,) = [r for r in report["verdict"]["rules"] if r["rule"] == "solid"]
    assert res["volume"] == pytest.approx(solid["value"]["volume"], rel=1e-9)
    # The box with 3 mm fillets: 6 planes, 12 fillet cylinders, 8 corner spheres (its true faces).
    assert report["faces_by_type"] == {"plane": 6, "cylinder": 12, "sphere": 8} and report["n_faces"] == 26
    fc_types = Counter(s.lower() for s in res["surfaces"])
    assert fc_types == Counter(report["faces_by_type"])  # FreeCAD's own reading of the surfaces agrees
    assert res["file_faces"] == 26 and res["file_valid"]  # the command on a mesh file gives the same solid
    assert res["feature_label"] == "box_fillet_clean (recon)"
    assert res["file_label"].startswith(res["feature_label"])  # FreeCAD numbers a second label: "...(recon)001"


def test_the_spreadsheet_names_every_face_as_the_report(addon_run):
    res, _ = addon_run
    report = res["report"]
    header, *rows = res["rows"]
    assert res["sheet_type"] == "Spreadsheet::Sheet" and header == ["Face", "Name", "Kind", "Surface"]
    assert [r[0] for r in rows] == [f"Face{i}" for i in range(1, 27)]
    names = [r[1] for r in rows]
    assert sorted(names) == sorted(f["name"] for f in report["faces"]) and names == res["face_names"]
    surface = {f["name"]: f["surface"] for f in report["faces"]}
    assert [r[3] for r in rows] == [surface[n] for n in names]
    # The name on FaceN is that face's: the report's surface type for the name is FreeCAD's type of FaceN.
    assert [surface[n] for n in names] == [s.lower() for s in res["surfaces"]]
    assert res["names_checked"]  # and its area share is the report's (recon_addon.names_match_report)
    assert Counter(r[2] for r in rows) == Counter({k: n for k, n in report["decomposition"].items() if n})


def test_faces_coloured_by_kind_as_recons_step(addon_run):
    res, _ = addon_run
    assert len(res["face_colors"]) == 26
    for kind, colour in zip(res["face_kinds"], res["face_colors"]):
        # Read from the STEP (sRGB there) back to recon's own values; FreeCAD stores colours as 8-bit.
        assert colour == pytest.approx(KIND_COLOURS[kind], abs=1 / 255)


def test_headless_the_report_is_printed(addon_run):
    res, stdout = addon_run
    assert res["logged"][0].startswith("result: within tolerance")
    assert "faces: 26 (12 cylinder, 8 sphere, 6 plane)" in res["logged"]
    assert any(s.startswith("deviation mesh→shape: max") for s in res["logged"])
    assert "result: within tolerance" in stdout and "faces: 26 (12 cylinder, 8 sphere, 6 plane)" in stdout


def test_errors_are_one_line_and_add_nothing(addon_run):
    res, _ = addon_run
    errors = res["errors"]
    assert "ReconPython" in errors["setting"] and "/nonexistent/python" in errors["setting"]
    # recon's exit 2 (bad input: a mesh without triangles) reaches the user with recon's own line, and no object.
    assert errors["bad_mesh"].startswith("recon convert failed (exit 2): ") and "\n" not in errors["bad_mesh"]
    assert errors["objects_added"] == 0
