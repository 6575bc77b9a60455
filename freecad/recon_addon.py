"""recon inside FreeCAD, without its GUI: run recon on a mesh, bring the B-rep back as a Part feature with recon's face
names, kinds and colours, and a spreadsheet of the faces.

Importable in ``freecadcmd`` (no FreeCADGui). recon itself never runs in FreeCAD's Python: it needs numpy, OCP and
build123d in versions FreeCAD's interpreter does not have, so it runs in its own environment as a subprocess
(``recon convert MESH OUT.step --report R.json``), found through the setting ``ReconPython`` (see
:func:`recon_command`). Face names and colours are read from the STEP file recon writes (the ``ADVANCED_FACE`` names
and ``STYLED_ITEM`` colours) in the order FreeCAD numbers the faces, and checked against the report's face areas.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import FreeCAD

#: FreeCAD parameter group of the addon's settings (Tools > Edit parameters, or the addon's preferences).
PARAM_PATH = "User parameter:BaseApp/Preferences/Mod/Recon"

#: recon's colours by face kind (recon.brep.KIND_COLOURS, the paper's Figure 4): the fallback for a face the STEP file
#: gives no colour.
KIND_COLOURS = {
    "patch": (0.75, 0.75, 0.75),
    "linear": (0.58, 0.29, 0.78),
    "junction": (0.95, 0.85, 0.15),
    "terminal": (0.30, 0.70, 0.30),
}

#: what the spreadsheet lists per face, in its columns A, B, ...
SHEET_COLUMNS = ("Face", "Name", "Kind", "Surface", "Status", "Area", "MeshToShapeMax", "ShapeToMeshMax")
#: columns written as text with 3 significant digits: a sheet shows numbers to 2 decimals, so 9e-07 mm would read 0.00
_SMALL_COLUMNS = ("MeshToShapeMax", "ShapeToMeshMax")

# recon's exit codes (README): 0 good, 1 written but not good; anything else wrote nothing.
_WRITTEN = (0, 1)

Colour = Tuple[float, float, float]


class ReconAddonError(RuntimeError):
    """recon could not be run or gave no result; the message says why in one line."""


@dataclass
class ReconRun:
    """One finished ``recon convert``: where its files are, its exit code, its report and its output."""

    step: str
    report_path: str
    exit_code: int
    report: dict
    stdout: str
    stderr: str
    seconds: float


@dataclass
class StepFace:
    """A face of recon's STEP file as FreeCAD numbers it (``Face{index}``), with the name and colour recon gave it."""

    index: int
    name: str
    colour: Optional[Colour]


@dataclass
class ReconResult:
    """What :func:`mesh_to_cad` put in the document."""

    feature: object
    sheet: object
    run: ReconRun
    faces: List[StepFace] = field(default_factory=list)
    colours: List[Colour] = field(default_factory=list)
    names_checked: bool = False


# --- settings -------------------------------------------------------------------------------------------------------


def params():
    """The addon's parameter group."""
    return FreeCAD.ParamGet(PARAM_PATH)


def recon_command() -> List[str]:
    """The command that starts recon: ``[ReconPython, "-m", "recon"]`` where the setting ``ReconPython`` names the
    Python of recon's environment (e.g. ``/home/me/recon/.venv/bin/python``), else ``recon`` found on PATH."""
    python = params().GetString("ReconPython", "").strip()
    if python:
        if not (os.path.isfile(python) and os.access(python, os.X_OK)):
            raise ReconAddonError(
                f"the setting ReconPython ({PARAM_PATH}) is {python!r}, which is not an executable file: "
                "set it to the python of the environment where recon is installed"
            )
        return [python, "-m", "recon"]
    found = shutil.which("recon")
    if found is None:
        raise ReconAddonError(
            "recon is not on PATH: install it (pip install recon) or set ReconPython in " + PARAM_PATH
            + " to the python of its environment"
        )
    return [found]


def _child_env() -> Dict[str, str]:
    """The environment recon runs in: FreeCAD's own, less what points a Python at FreeCAD's interpreter.

    PYTHONHOME always belongs to FreeCAD's Python; an AppImage (APPDIR set) also sets PYTHONPATH and LD_LIBRARY_PATH
    for its bundled libraries, which would load the wrong numpy/OpenCascade into recon's Python."""
    env = dict(os.environ)
    env.pop("PYTHONHOME", None)
    if "APPDIR" in env:
        for key in ("PYTHONPATH", "LD_LIBRARY_PATH"):
            env.pop(key, None)
    return env


# --- running recon --------------------------------------------------------------------------------------------------


def export_mesh(mesh_obj, path: str) -> str:
    """Write a Mesh feature's mesh as STL, in document coordinates (``Mesh`` carries the feature's placement)."""
    mesh_obj.Mesh.write(path)
    return path


def convert(
    mesh_path: str,
    workdir: str,
    *,
    tolerance: Optional[float] = None,
    command: Optional[Sequence[str]] = None,
    timeout: Optional[float] = None,
    poll: Optional[Callable[[], bool]] = None,
) -> ReconRun:
    """Run ``recon convert`` on ``mesh_path``; the STEP and the report go to ``workdir``.

    ``poll`` is called about ten times a second while recon runs (a GUI keeps its window alive there); returning
    False stops recon. Raises :class:`ReconAddonError` when recon wrote nothing (bad input, a crash, stopped)."""
    base = os.path.splitext(os.path.basename(mesh_path))[0] or "mesh"
    step = os.path.join(workdir, base + ".step")
    report_path = os.path.join(workdir, base + ".report.json")
    argv = list(command or recon_command()) + ["convert", mesh_path, step, "--report", report_path]
    if tolerance:
        argv += ["--tolerance", repr(float(tolerance))]
    t0 = time.monotonic()
    out_path, err_path = os.path.join(workdir, "stdout.txt"), os.path.join(workdir, "stderr.txt")
    # Files, not pipes: recon's output is not read until it ends, and a full pipe would stall it.
    with open(out_path, "w") as out, open(err_path, "w") as err:
        proc = subprocess.Popen(argv, stdout=out, stderr=err, stdin=subprocess.DEVNULL, env=_child_env(), cwd=workdir)
        code = _wait(proc, t0, timeout, poll)
    with open(out_path, errors="replace") as fh:
        stdout = fh.read()
    with open(err_path, errors="replace") as fh:
        stderr = fh.read()
    if code not in _WRITTEN or not (os.path.exists(step) and os.path.exists(report_path)):
        tail = " | ".join((stderr or stdout).strip().splitlines()[-3:]) or "no output"
        raise ReconAddonError(f"recon convert failed (exit {code}): {tail}")
    with open(report_path) as fh:
        report = json.load(fh)
    return ReconRun(step, report_path, code, report, stdout, stderr, time.monotonic() - t0)


def _wait(proc: subprocess.Popen, t0: float, timeout: Optional[float], poll: Optional[Callable[[], bool]]) -> int:
    while True:
        try:
            return proc.wait(timeout=0.1)  # 10 polls a second keep a GUI responsive
        except subprocess.TimeoutExpired:
            pass
        stop = poll is not None and poll() is False
        late = timeout is not None and time.monotonic() - t0 > timeout
        if stop or late:
            proc.terminate()  # recon removes its half-written files on SIGTERM (README: exit 143)
            try:
                proc.wait(timeout=10)  # recon stops within ~2 s of SIGTERM (README); then it is hung
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            raise ReconAddonError("recon was stopped" if stop else f"recon took longer than {timeout:g} s: stopped")


# --- reading recon's STEP file --------------------------------------------------------------------------------------

_STRING = re.compile(r"'(?:[^']|'')*'")
_RECORD = re.compile(r"#(\d+)\s*=\s*([A-Z0-9_]+)\s*\((.*)\)\s*$", re.S)


def _entities(text: str) -> Dict[int, Tuple[str, str]]:
    """The DATA section's simple entities: ``{id: (TYPE, arguments)}`` (complex ``( A() B() )`` ones are skipped)."""
    start = text.find("DATA;")
    data = text[start + 5:] if start >= 0 else text
    out: Dict[int, Tuple[str, str]] = {}
    record: List[str] = []
    pos = 0
    # Records end at a ';' outside a string (names may hold ';').
    for m in re.finditer(r"'(?:[^']|'')*'|;", data):
        if m.group() != ";":
            continue
        record.append(data[pos:m.start()])
        pos = m.end()
        hit = _RECORD.match("".join(record).strip())
        record = []
        if hit:
            out[int(hit.group(1))] = (hit.group(2), hit.group(3))
    return out


def _refs(args: str) -> List[int]:
    return [int(r) for r in re.findall(r"#(\d+)", _STRING.sub("''", args))]


def _first_string(args: str) -> str:
    m = _STRING.search(args)
    return m.group()[1:-1].replace("''", "'") if m else ""


def _colour_of(ents: Dict[int, Tuple[str, str]], style: int, depth: int = 0) -> Optional[Colour]:
    """The first COLOUR_RGB reached from a style entity (presentation style → fill area → colour)."""
    kind, args = ents.get(style, ("", ""))
    if kind == "COLOUR_RGB":
        rgb = [float(x) for x in re.findall(r"[-+]?\d*\.?\d+(?:[eE][-+]?\d+)?", _STRING.sub("", args))[:3]]
        return (rgb[0], rgb[1], rgb[2]) if len(rgb) == 3 else None  # recon writes display (sRGB) values
    if depth > 8:  # a style reaches its colour in 7 steps (STYLED_ITEM … FILL_AREA_STYLE_COLOUR → COLOUR_RGB)
        return None
    for ref in _refs(args):
        found = _colour_of(ents, ref, depth + 1)
        if found is not None:
            return found
    return None


def step_faces(path: str) -> List[StepFace]:
    """The faces of recon's STEP file in FreeCAD's order (the shells' face lists, solid by solid, as OpenCascade's
    reader builds them), each with its name and colour."""
    with open(path, errors="replace") as fh:
        ents = _entities(fh.read())
    colours: Dict[int, Colour] = {}
    for kind, args in ents.values():
        if kind in ("STYLED_ITEM", "OVER_RIDING_STYLED_ITEM"):
            refs = _refs(args)
            styles, item = refs[:-1], refs[-1] if refs else -1
            colour = next((c for c in (_colour_of(ents, s) for s in styles) if c is not None), None)
            if colour is not None and ents.get(item, ("",))[0] == "ADVANCED_FACE":
                colours[item] = colour
    faces: List[StepFace] = []
    seen = set()
    for eid in sorted(ents):
        kind, args = ents[eid]
        if kind not in ("CLOSED_SHELL", "OPEN_SHELL"):
            continue
        for ref in _refs(args):
            if ents.get(ref, ("",))[0] == "ADVANCED_FACE" and ref not in seen:
                seen.add(ref)
                faces.append(StepFace(len(faces) + 1, _first_string(ents[ref][1]), colours.get(ref)))
    return faces


def kind_of(name: str) -> str:
    """recon's kind of a face from its name (``patch_3`` → ``patch``)."""
    return name.rsplit("_", 1)[0] if "_" in name else name


def face_colours(faces: Sequence[StepFace]) -> List[Colour]:
    """Per face: the colour recon's STEP gives it, else recon's colour for its kind."""
    return [f.colour or KIND_COLOURS.get(kind_of(f.name), KIND_COLOURS["patch"]) for f in faces]


def names_match_report(shape, faces: Sequence[StepFace], report: dict) -> bool:
    """True when every named face's share of the total area is the share the report gives that name (to 1e-6): the
    names sit on the right FreeCAD faces. Shares, so a STEP written in other units still compares."""
    by_name = {f["name"]: f.get("area") for f in report.get("faces", [])}
    if len(faces) != len(shape.Faces) or any(by_name.get(f.name) is None for f in faces):
        return False
    total_fc = sum(f.Area for f in shape.Faces)
    total_rep = sum(by_name[f.name] for f in faces)
    if total_fc <= 0 or total_rep <= 0:
        return False
    # Both areas come from OpenCascade on the same surfaces, so they agree to round-off. Faces of equal area (a box's
    # 8 corners) cannot be told apart this way: there the order rests on the reader keeping the shells' face order.
    return all(abs(sf.Area / total_fc - by_name[f.name] / total_rep) <= 1e-6 for sf, f in zip(shape.Faces, faces))


# --- the report -----------------------------------------------------------------------------------------------------


def _mm(x: Optional[float]) -> str:
    return "n/a" if x is None else f"{x:.4g} mm"


def summary_lines(report: dict) -> List[str]:
    """The report in a few lines: the verdict, faces by type, the solid, the deviation both ways."""
    verdict = report.get("verdict") or {}
    failed = [r for r in verdict.get("rules", []) if not r.get("ok")]
    within = verdict.get("within_tolerance")
    tol = _mm(report.get("tolerance"))
    if within:
        head = f"result: within tolerance (tolerance {tol})"
    elif within is None and not failed:
        head = f"result: deviation NOT verified (tolerance {tol})"
    else:
        head = f"result: NOT within tolerance (tolerance {tol}): " + "; ".join(
            f"{r['rule']} ({', '.join(r.get('faces') or [])})" if r.get("faces") else r["rule"] for r in failed
        )
    types = sorted((report.get("faces_by_type") or {}).items(), key=lambda kv: (-kv[1], kv[0]))
    v = report.get("validity") or {}
    vol = v.get("volume")
    lines = [
        head,
        f"faces: {report.get('n_faces')} (" + ", ".join(f"{n} {t}" for t, n in types) + ")",
        "solid: " + ("valid closed solid" if v.get("ok") else "NOT a valid closed solid")
        + (f", volume {vol:.6g} mm³" if vol is not None else ""),
    ]
    dev = report.get("deviation") or {}
    for key, label in (("mesh_to_shape", "mesh→shape"), ("shape_to_mesh", "shape→mesh")):
        d = dev.get(key)
        if d:
            lines.append(f"deviation {label}: max {_mm(d.get('max'))}, p95 {_mm(d.get('p95'))}, "
                         f"rms {_mm(d.get('rms'))}")
    return lines


def face_rows(faces: Sequence[StepFace], report: dict) -> List[List[object]]:
    """One row per FreeCAD face, in SHEET_COLUMNS' order."""
    rep = {f["name"]: f for f in report.get("faces", [])}
    dev = {f["name"]: f for f in (report.get("deviation") or {}).get("faces", [])}
    rows: List[List[object]] = []
    for f in faces:
        r, d = rep.get(f.name, {}), dev.get(f.name, {})
        rows.append([f"Face{f.index}", f.name, kind_of(f.name), r.get("surface", ""), r.get("status", ""),
                     r.get("area"), d.get("max"), d.get("shape_to_mesh_max")])
    return rows


def deviation_colours(faces: Sequence[StepFace], report: dict) -> List[Colour]:
    """The deviation map on the faces: each face by how far the mesh's points lie from it (the report's per-face
    mesh→shape max) over 2T, the limit of recon's mesh_to_shape_max rule (README): blue at 0, white at half the
    limit, red at the limit and beyond; grey where the report has no figure."""
    tol = report.get("tolerance") or 0.0
    dev = {f["name"]: f.get("max") for f in (report.get("deviation") or {}).get("faces", [])}
    out: List[Colour] = []
    for f in faces:
        x = dev.get(f.name)
        if x is None or not tol or not math.isfinite(x):
            out.append((0.5, 0.5, 0.5))
            continue
        out.append(_blue_white_red(min(max(x / (2.0 * tol), 0.0), 1.0)))
    return out


def _blue_white_red(t: float) -> Colour:
    if t <= 0.5:
        s = t / 0.5
        return (s, s, 1.0)
    s = (t - 0.5) / 0.5
    return (1.0, 1.0 - s, 1.0 - s)


# --- into the document ----------------------------------------------------------------------------------------------


def _text(value: object) -> str:
    """A spreadsheet cell's content: numbers as they are, text quoted (so ``1e-3`` or ``=x`` stay text)."""
    if value is None:
        return ""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return repr(float(value))
    return "'" + str(value)


def add_face_sheet(doc, label: str, rows: Sequence[Sequence[object]]):
    """A Spreadsheet listing each face (Face1..FaceN) with recon's name, kind, surface type, build status, area (mm²)
    and deviations (mm): FreeCAD 0.20 shows no names of sub-shapes, so the names live here and in ``FaceNames``."""
    sheet = doc.addObject("Spreadsheet::Sheet", "ReconFaces")
    sheet.Label = label
    cols = [chr(ord("A") + i) for i in range(len(SHEET_COLUMNS))]
    for col, title in zip(cols, SHEET_COLUMNS):
        sheet.set(f"{col}1", "'" + title)
    for i, row in enumerate(rows, start=2):
        for col, title, value in zip(cols, SHEET_COLUMNS, row):
            if isinstance(value, float) and title in _SMALL_COLUMNS:
                value = f"{value:.3g}"
            if value is not None and value != "":
                sheet.set(f"{col}{i}", _text(value))
    return sheet


def _add_properties(obj, faces: Sequence[StepFace], colours: Sequence[Colour], run: ReconRun) -> None:
    report = run.report
    verdict = report.get("verdict") or {}
    props = (
        ("App::PropertyStringList", "FaceNames", "recon's name of each face, in the order Face1..FaceN",
         [f.name for f in faces]),
        ("App::PropertyStringList", "FaceKinds", "recon's kind of each face (patch, linear, junction, terminal)",
         [kind_of(f.name) for f in faces]),
        ("App::PropertyColorList", "FaceColors", "recon's colour of each face (by kind), as in its STEP file",
         [tuple(c) for c in colours]),
        ("App::PropertyString", "ReconVerdict", "recon's verdict on the result", summary_lines(report)[0]),
        ("App::PropertyBool", "WithinTolerance", "recon's verdict: every acceptance rule holds",
         bool(verdict.get("within_tolerance"))),
        ("App::PropertyFloat", "Tolerance", "recon's tolerance of the run, in mm", float(report.get("tolerance") or 0)),
        ("App::PropertyString", "ReconReport", "recon's report (JSON)", json.dumps(report)),
    )
    for kind, name, doc_, value in props:
        obj.addProperty(kind, name, "Recon", doc_)
        setattr(obj, name, value)
    for name in ("FaceNames", "FaceKinds", "FaceColors", "ReconVerdict", "WithinTolerance", "Tolerance",
                 "ReconReport"):
        obj.setEditorMode(name, 1)  # read-only: they describe recon's run, editing them changes nothing


def insert_result(doc, run: ReconRun, label: str) -> ReconResult:
    """Add recon's solid as a Part feature named after the mesh, with its face names, kinds and colours, and the
    spreadsheet of its faces. Colours go on the view where there is a GUI (and always in ``FaceColors``)."""
    import Part

    shape = Part.read(run.step)
    if shape.ShapeType == "Compound" and len(shape.Solids) == 1 and len(shape.Faces) == len(shape.Solids[0].Faces):
        shape = shape.Solids[0]
    faces = step_faces(run.step)
    if len(faces) != len(shape.Faces):  # not a file recon named: number the faces, colour them as patches
        faces = [StepFace(i + 1, f"face_{i + 1}", None) for i in range(len(shape.Faces))]
    colours = face_colours(faces)
    feature = doc.addObject("Part::Feature", "Recon")
    feature.Label = label
    feature.Shape = shape
    _add_properties(feature, faces, colours, run)
    sheet = add_face_sheet(doc, label + " faces", face_rows(faces, run.report))
    doc.recompute()
    apply_colours(feature, colours)
    return ReconResult(feature, sheet, run, faces, colours, names_match_report(shape, faces, run.report))


def apply_colours(feature, colours: Sequence[Colour]) -> bool:
    """Colour the faces on the feature's view (GUI only); returns whether there was a view to colour."""
    view = getattr(feature, "ViewObject", None)
    if view is None or len(colours) != len(feature.Shape.Faces):
        return False
    view.DiffuseColor = [(r, g, b, 0.0) for r, g, b in colours]
    return True


def mesh_to_cad(doc, source, *, tolerance: Optional[float] = None, command: Optional[Sequence[str]] = None,
                timeout: Optional[float] = None, poll: Optional[Callable[[], bool]] = None,
                log: Optional[Callable[[str], None]] = None) -> ReconResult:
    """The command's work: ``source`` is a Mesh feature (exported to a temporary STL) or a mesh file's path; recon
    converts it in its own environment; the solid, its names and colours and the face spreadsheet go into ``doc``.
    The summary is printed (FreeCAD's report view, or stdout in freecadcmd) unless ``log`` takes it."""
    tolerance = tolerance if tolerance is not None else (params().GetFloat("Tolerance", 0.0) or None)
    with tempfile.TemporaryDirectory(prefix="recon-freecad-") as tmp:
        if isinstance(source, str):
            mesh_path, label = os.path.abspath(source), os.path.splitext(os.path.basename(source))[0]
        else:
            label = source.Label
            mesh_path = export_mesh(source, os.path.join(tmp, _safe(source.Name) + ".stl"))
        run = convert(mesh_path, tmp, tolerance=tolerance, command=command, timeout=timeout, poll=poll)
        result = insert_result(doc, run, label + " (recon)")
    say = log or (lambda s: FreeCAD.Console.PrintMessage(s + "\n"))
    for line in summary_lines(run.report):
        say(line)
    if not result.names_checked:
        say("warning: recon's face names could not be matched to FreeCAD's faces by area; check the spreadsheet")
    return result


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name) or "mesh"

