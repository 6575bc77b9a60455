"""Do recon's solids survive the edits users make next, as often as the true CAD solids do? (issue 25)

Each solid gets the same edit plan, chosen from its own geometry by one rule, so a true solid and recon's solid of the
same part get comparable edits:

- **fillet**: up to five sharp edges (faces meeting at more than 6°) shared by two distinct faces and at least 4 r long, spread evenly over the edges sorted
  by length, each filleted alone with r = 0.5 % of the bounding-box diagonal (the size issue 25 tried in FreeCAD);
- **drill**: a through hole of radius 1 % of the diagonal, normal to each of the two largest planar faces, at the
  centroid of the face's mesh triangle nearest the face's centre of mass (inside the face by construction).

An edit passes when OpenCascade reports it done, the result is a valid solid (``BRepCheck_Analyzer``), and its volume
is plausible: a hole removes material but less than its cylinder through the whole box, a fillet changes the volume
by less than 5 % (r = 0.5 % of the diagonal cannot do more). Every edit runs in a worker process with a time limit;
an edit that exceeds it is a ``hang`` (issue 25 saw a fillet hang FreeCAD for over 300 s).

Sources: the fixtures (true ``fixtures/data/<part>.step`` against recon's conversion of ``<part>_<variant>.stl``),
the export corpus (true ``parts/seed_N.step`` from a ``bench.corpus`` cache against the STEP files of a corpus run)
and the real meshes (recon's solid only: no true solid exists).

Usage: ``python -m bench.editability [--fixtures clean,coarse] [--corpus-run DIR --corpus-cache DIR] [--meshes]
[--limit 60] --out DIR``; writes ``editability.json`` and ``editability.md`` there.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import select
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
FIXTURES = REPO / "fixtures" / "data"
MESHES = REPO.parent / "shared" / "meshes"
PARTS = ("box_chamfer", "box_fillet", "lofted", "plate_holes", "pocket", "prism", "revolved")
FILLET_FRACTION = 0.005  # r as a fraction of the diagonal: the fillet issue 25 tried in FreeCAD
HOLE_FRACTION = 0.01  # hole radius as a fraction of the diagonal: a hole a user drills through a face
N_FILLETS = 5  # fillet edits per solid (issue 25: 30 tries over four parts ≈ 7 per part, fillets and holes)
N_HOLES = 2  # planar faces drilled per solid
SMOOTH_ANGLE = 0.1  # rad: faces meeting within 6° look smooth there; users fillet the edges that look sharp
FILLET_DV = 0.05  # a fillet of r = 0.5 % of the diagonal changes the volume by far less than 5 %


# --------------------------------------------------------------------------------------------------- worker side
def _load(path: str):
    from recon.brep._step_read import read_step

    shape, _ = read_step(path)
    return shape


def _diag(shape) -> float:
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box)
    x0, y0, z0, x1, y1, z1 = box.Get()
    return math.dist((x0, y0, z0), (x1, y1, z1))


def _volume(shape) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return float(props.Mass())


def _crease_angle(edge, f1, f2) -> float:
    """The largest angle between the two faces' normals at a quarter, half and three quarters of the edge.

    Measured, not read from ``BRep_Tool.Continuity``: ``BRepLib::EncodeRegularity`` leaves tangent edges of a recon
    solid C0 where their normals agree to 1e-6.
    """
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Surface
    from OCP.BRepLProp import BRepLProp_SLProps
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf

    curve = BRepAdaptor_Curve(edge)
    t0, t1 = curve.FirstParameter(), curve.LastParameter()
    worst = 0.0
    for w in (0.25, 0.5, 0.75):
        p = curve.Value(t0 + w * (t1 - t0))
        normals = []
        for face in (f1, f2):
            proj = GeomAPI_ProjectPointOnSurf(p, BRep_Tool.Surface_s(face))
            if proj.NbPoints() == 0:
                return math.pi  # no normal to compare: treat as sharp, the edit will tell
            u, v = proj.LowerDistanceParameters()
            props = BRepLProp_SLProps(BRepAdaptor_Surface(face), u, v, 1, 1e-9)
            if not props.IsNormalDefined():
                return math.pi
            n = props.Normal()
            normals.append((n.X(), n.Y(), n.Z()))
        dot = abs(sum(a * b for a, b in zip(*normals)))
        worst = max(worst, math.acos(min(1.0, dot)))
    return worst


def _fillet_edges(shape, r: float) -> list:
    """Sharp edges between two distinct faces, at least 4 r long, spread over the length order."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape

    emap = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndUniqueAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, emap)
    found = []
    for i in range(1, emap.Extent() + 1):
        edge = TopoDS.Edge_s(emap.FindKey(i))
        faces = emap.FindFromIndex(i)
        if BRep_Tool.Degenerated_s(edge) or faces.Extent() != 2:
            continue
        f1, f2 = (TopoDS.Face_s(f) for f in faces)
        if _crease_angle(edge, f1, f2) < SMOOTH_ANGLE:
            continue
        props = GProp_GProps()
        BRepGProp.LinearProperties_s(edge, props)
        length = float(props.Mass())
        if length < 4 * r:
            continue
        c = props.CentreOfMass()
        found.append((-round(length, 9), round(c.X(), 6), round(c.Y(), 6), round(c.Z(), 6), i, edge))
    found.sort(key=lambda t: t[:5])
    if len(found) <= N_FILLETS:
        return [t[-1] for t in found]
    picks = sorted({round(k * (len(found) - 1) / (N_FILLETS - 1)) for k in range(N_FILLETS)})
    return [found[k][-1] for k in picks]


def _hole_sites(shape, diag: float) -> list[tuple[tuple[float, float, float], tuple[float, float, float]]]:
    """(point, outward normal) on the largest planar faces, at a mesh triangle's centroid inside the face."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepGProp import BRepGProp
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.GeomAbs import GeomAbs_Plane
    from OCP.GProp import GProp_GProps
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    BRepMesh_IncrementalMesh(shape, 0.01 * diag, False, 0.5, False)
    planes = []
    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        face = TopoDS.Face_s(exp.Current())
        exp.Next()
        ad = BRepAdaptor_Surface(face)
        if ad.GetType() != GeomAbs_Plane:
            continue
        props = GProp_GProps()
        BRepGProp.SurfaceProperties_s(face, props)
        c = props.CentreOfMass()
        planes.append((-round(float(props.Mass()), 9), (c.X(), c.Y(), c.Z()), face, ad))
    planes.sort(key=lambda t: (t[0], t[1]))
    sites = []
    for _, centre, face, ad in planes[:N_HOLES]:
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None or tri.NbTriangles() == 0:
            continue  # a face OpenCascade cannot mesh has no site; the plan is shorter, as a user would find
        best = None
        for k in range(1, tri.NbTriangles() + 1):
            a, b, cc = tri.Triangle(k).Get()
            p = [tri.Node(j).Transformed(loc.Transformation()) for j in (a, b, cc)]
            g = tuple(sum(q.Coord(m) for q in p) / 3 for m in (1, 2, 3))
            d = math.dist(g, centre)
            if best is None or d < best[0]:
                best = (d, g)
        ax = ad.Plane().Axis().Direction()
        n = (ax.X(), ax.Y(), ax.Z())
        if face.Orientation() == TopAbs_REVERSED:
            n = (-n[0], -n[1], -n[2])
        sites.append((best[1], n))
    return sites


def _check(result, v0: float, kind: str, diag: float, r: float) -> str:
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer

    if result is None or result.IsNull():
        return "no shape"
    if not TopExp_Explorer(result, TopAbs_SOLID).More():
        return "no solid"
    if not BRepCheck_Analyzer(result).IsValid():
        return "invalid"
    v = _volume(result)
    if kind == "drill" and not (0 < v0 - v <= math.pi * r * r * 2 * diag):
        return f"volume {v:.6g} from {v0:.6g}"
    if kind == "fillet" and not abs(v - v0) <= FILLET_DV * abs(v0):
        return f"volume {v:.6g} from {v0:.6g}"
    return "ok"


def _edit(shape, v0: float, diag: float, plan_item) -> str:
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepFilletAPI import BRepFilletAPI_MakeFillet
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    kind, what = plan_item
    try:
        if kind == "fillet":
            r = FILLET_FRACTION * diag
            op = BRepFilletAPI_MakeFillet(shape)
            op.Add(r, what)
            op.Build()
        else:
            r = HOLE_FRACTION * diag
            (px, py, pz), (nx, ny, nz) = what
            start = gp_Pnt(px - nx * diag, py - ny * diag, pz - nz * diag)
            tool = BRepPrimAPI_MakeCylinder(gp_Ax2(start, gp_Dir(nx, ny, nz)), r, 2 * diag).Shape()
            op = BRepAlgoAPI_Cut(shape, tool)
        if not op.IsDone():
            return "not done"
        return _check(op.Shape(), v0, kind, diag, r)
    except Exception as exc:  # OCC raises Standard_Failure subclasses (StdFail_NotDone, …) for a failed edit
        return f"not done: {type(exc).__name__}"


def worker(path: str, start: int) -> None:
    """Print one JSON line per edit from ``start`` on; the parent kills a worker that hangs."""
    shape = _load(path)
    diag = _diag(shape)
    v0 = _volume(shape)
    plan = [("fillet", e) for e in _fillet_edges(shape, FILLET_FRACTION * diag)]
    plan += [("drill", s) for s in _hole_sites(shape, diag)]
    from recon.brep._result import count_shapes
    from OCP.TopAbs import TopAbs_FACE

    print(json.dumps({"plan": [k for k, _ in plan], "faces": count_shapes(shape, TopAbs_FACE)}), flush=True)
    for i in range(start, len(plan)):
        t = time.perf_counter()
        outcome = _edit(shape, v0, diag, plan[i])
        print(json.dumps({"i": i, "kind": plan[i][0], "outcome": outcome,
                          "seconds": round(time.perf_counter() - t, 3)}), flush=True)


# --------------------------------------------------------------------------------------------------- parent side
def _read_line(proc: subprocess.Popen, limit: float) -> str | None:
    ready, _, _ = select.select([proc.stdout], [], [], limit)
    return proc.stdout.readline() if ready else None


def edit_solid(path: Path, limit: float) -> dict:
    """Run the edit plan on one STEP solid; an edit over ``limit`` seconds is a hang and the worker restarts after it."""
    edits: list[dict] = []
    plan: list[str] | None = None
    faces = None
    start = 0
    while plan is None or start < len(plan):
        proc = subprocess.Popen([sys.executable, "-m", "bench.editability", "--worker", str(path), str(start)],
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, cwd=REPO)
        try:
            head = _read_line(proc, 10 * limit)  # reading and meshing the solid: bounded like ten edits
            if not head:
                return {"error": "could not read or plan", "edits": edits}
            head_row = json.loads(head)
            plan, faces = head_row["plan"], head_row["faces"]
            while start < len(plan):
                line = _read_line(proc, limit)
                if not line:
                    edits.append({"i": start, "kind": plan[start], "outcome": "hang", "seconds": limit})
                    start += 1
                    break
                edits.append(json.loads(line))
                start += 1
        finally:
            proc.kill()
            proc.wait()
    return {"plan": plan, "faces": faces, "edits": edits}


def _rate(rows: list[dict], side: str, kind: str | None = None) -> tuple[int, int]:
    ok = n = 0
    for row in rows:
        for e in row.get(side, {}).get("edits", []):
            if kind is None or e["kind"] == kind:
                n += 1
                ok += e["outcome"] == "ok"
    return ok, n


def _convert(mesh: Path, out: Path) -> tuple[Path | None, int | None]:
    step = out / (mesh.stem + ".step")
    if not step.exists():
        rc = subprocess.run([sys.executable, "-m", "recon", "convert", str(mesh), str(step), "-q", "--no-deviation"],
                            cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode
        (out / (mesh.stem + ".rc")).write_text(str(rc))
    rc_file = out / (mesh.stem + ".rc")
    rc = int(rc_file.read_text()) if rc_file.exists() else None
    return (step if step.exists() else None), rc


def _pairs(args) -> list[tuple[str, Path | None, Path | None, dict]]:
    work = Path(args.out) / "converted"
    work.mkdir(parents=True, exist_ok=True)
    pairs = []
    for variant in filter(None, args.fixtures.split(",")):
        for part in PARTS:
            step, rc = _convert(FIXTURES / f"{part}_{variant}.stl", work)
            pairs.append((f"{part}/{variant}", FIXTURES / f"{part}.step", step, {"exit": rc}))
    if args.corpus_run:
        rows = json.loads((Path(args.corpus_run) / "corpus.json").read_text())["rows"]
        for r in rows:
            name = f"{r['regime']}_seed_{r['seed']:05d}"
            step = Path(args.corpus_run) / "steps" / f"{name}.step"
            truth = Path(args.corpus_cache) / "parts" / f"seed_{r['seed']:05d}.step"
            pairs.append((name, truth, step if step.exists() else None,
                          {"exit": r.get("exit"), "exact_faces": r.get("faces_ours") == r.get("faces_true")}))
    if args.meshes and MESHES.is_dir():
        for mesh in sorted(p for p in MESHES.iterdir() if p.suffix in (".off", ".stl")):
            step, rc = _convert(mesh, work)
            pairs.append((f"mesh/{mesh.stem}", None, step, {"exit": rc}))
    return pairs


def _summary(rows: list[dict]) -> list[str]:
    lines = ["| set | edits | true solids valid | recon's solids valid | ratio | hangs (recon) |", "|---|---|---|---|---|---|"]
    subsets = {"all recon results": rows,
               "recon exit 0": [r for r in rows if r.get("exit") == 0],
               "recon's face count exact": [r for r in rows if r.get("exact_faces")]}
    for label, sub in subsets.items():
        for kind in ("fillet", "drill", None):
            paired = [r for r in sub if "true" in r and "recon" in r]
            tk, tn = _rate(paired, "true", kind)
            rk, rn = _rate(paired, "recon", kind)
            hangs = sum(e["outcome"] == "hang" for r in paired for e in r["recon"].get("edits", [])
                        if kind is None or e["kind"] == kind)
            ratio = (rk / rn) / (tk / tn) if rn and tn and tk else float("nan")
            lines.append(f"| {label}, {kind or 'both'} ({len(paired)} parts) | {rn} / {tn} | {tk}/{tn} "
                         f"({100 * tk / max(tn, 1):.0f} %) | {rk}/{rn} ({100 * rk / max(rn, 1):.0f} %) | "
                         f"{ratio:.2f} | {hangs} |")
    alone = [r for r in rows if "true" not in r and "recon" in r]
    if alone:
        rk, rn = _rate(alone, "recon")
        lines.append(f"\nReal meshes (no true solid): {rk}/{rn} edits valid on recon's solids.")
    return lines


def _failures(rows: list[dict]) -> list[str]:
    out = ["", "| case | side | edit | outcome | seconds |", "|---|---|---|---|---|"]
    for r in rows:
        for side in ("true", "recon"):
            for e in r.get(side, {}).get("edits", []):
                if e["outcome"] != "ok":
                    out.append(f"| {r['case']} | {side} | {e['kind']} {e['i']} | {e['outcome']} | {e['seconds']} |")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", nargs=2, metavar=("STEP", "START"), help=argparse.SUPPRESS)
    ap.add_argument("--fixtures", default="clean", help="fixture variants, comma-separated (default: clean)")
    ap.add_argument("--corpus-run", help="output folder of a bench.corpus run (corpus.json, steps/)")
    ap.add_argument("--corpus-cache", help="the bench.corpus cache of that run (parts/seed_N.step)")
    ap.add_argument("--meshes", action="store_true", help="also the real meshes in ../shared/meshes")
    ap.add_argument("--limit", type=float, default=60.0, help="seconds one edit may take before it is a hang")
    ap.add_argument("--out", default="bench/out_editability")
    args = ap.parse_args(argv)
    if args.worker:
        worker(args.worker[0], int(args.worker[1]))
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name, truth, ours, extra in _pairs(args):
        row = {"case": name, **extra}
        if truth is not None and truth.exists():
            row["true"] = edit_solid(truth, args.limit)
        if ours is not None:
            row["recon"] = edit_solid(ours, args.limit)
        if "exact_faces" not in row and "true" in row and "recon" in row:
            row["exact_faces"] = row["true"].get("faces") == row["recon"].get("faces")
        rows.append(row)
        tk, tn = _rate([row], "true")
        rk, rn = _rate([row], "recon")
        print(f"{name}: true {tk}/{tn}, recon {rk}/{rn}", file=sys.stderr, flush=True)
    (out / "editability.json").write_text(json.dumps(rows, indent=1))
    md = ["# Editability: fillet and drill edits on true and recon solids", ""] + _summary(rows) + _failures(rows)
    (out / "editability.md").write_text("\n".join(md) + "\n")
    print("\n".join(_summary(rows)))
    return 0


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
