"""One corpus case: make the mesh, run ``recon convert`` on it in a limited subprocess, measure against the truth.

Every figure is measured on recon's written STEP file, re-read (what a user gets), against the true STEP:

- ``valid``: the re-read file is one solid, ``BRepCheck_Analyzer`` valid, every edge shared by exactly two faces;
- ``faces_ours`` against ``faces_true``;
- ``type_agreement``: area-uniform points on the true part; each takes the type of the nearest face of ours; the
  share whose type is the true face's. recon's report has no face per input triangle, and sampling the true surface
  weights every true face by its area whatever the mesh did (a face with no triangle left still counts);
- ``ours_true_p95`` / ``true_ours_p95``: as :func:`recon.deviation.model_deviation` (area-uniform points on each
  B-rep, exact distance to the other; the true side's points also give the types), % of the true diagonal;
- ``mesh_ours_p95`` / ``mesh_true_p95``: the mesh's vertices (at most :data:`MAX_VERTICES`, a seeded subset) to
  our B-rep and to the true one; the second is the floor the mesh's noise sets;
- ``tolerance_pct``: the tolerance recon's report states; ``issue20_ok`` is False when recon exited 0 with an
  ours→true p95 above it (issue 20: exit 0 must mean within tolerance).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .truth import DEFAULT_CACHE, materialise_apart

#: vertices measured per mesh for mesh→ours / mesh→true (a p95 of 10,000 points: ±0.5 percentile points at 2σ)
MAX_VERTICES = 10_000
#: area-uniform points on each B-rep for the types and ours→true / true→ours (a p95 of 5,000: ±0.6 points at 2σ)
SAMPLES = 5_000
#: free-form OCC types (recon writes every free-form face as a B-spline)
_FREEFORM = {"other", "bezier", "bspline"}


def _limit(memory_mb):
    def apply():
        if memory_mb:
            resource.setrlimit(resource.RLIMIT_AS, (memory_mb << 20, memory_mb << 20))
    return apply


def run_recon(mesh: Path, out: Path, report: Path, *, timeout: float, memory_mb: int | None) -> dict:
    """``recon convert`` in a subprocess with a time and address-space limit; a crash or a timeout is a result."""
    cmd = [sys.executable, "-m", "recon", "convert", str(mesh), str(out), "--report", str(report), "--jobs", "1"]
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env,
                              preexec_fn=_limit(memory_mb), cwd=str(out.parent))
    except subprocess.TimeoutExpired:
        return {"exit": None, "status": "timeout", "seconds": round(time.perf_counter() - t0, 2),
                "message": f"no result in {timeout:g} s"}
    seconds = round(time.perf_counter() - t0, 2)
    # the reason: recon's verdict ("result: …", on stdout) where it printed one, else its last line on stderr
    lines = [x for x in proc.stdout.splitlines() if x.startswith("result: ")][:1]
    lines = lines or [x for x in proc.stderr.strip().splitlines() if x.strip() and not x.startswith("recon: ")]
    status = {0: "ok", 1: "exit1", 2: "exit2", 3: "exit3"}.get(proc.returncode, "crash")  # 3: no result (a BrepError)
    return {"exit": proc.returncode, "status": status, "seconds": seconds, "message": lines[-1][:300] if lines else ""}


def _types(bd) -> list:
    return ["bspline" if t in _FREEFORM else t for t in bd.types]


def check_solid(shape) -> dict:
    """One solid, valid, every edge between two faces (a seam counts twice on its one face; a degenerated edge, a
    cone's apex or a sphere's pole, has one face by construction)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SOLID
    from OCP.TopExp import TopExp, TopExp_Explorer
    from OCP.TopoDS import TopoDS
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape

    solids, exp = 0, TopExp_Explorer(shape, TopAbs_SOLID)
    while exp.More():
        solids += 1
        exp.Next()
    emap = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, emap)
    free = sum(1 for i in range(1, emap.Extent() + 1)
               if emap.FindFromIndex(i).Extent() < 2 and not BRep_Tool.Degenerated_s(TopoDS.Edge_s(emap.FindKey(i))))
    valid = bool(BRepCheck_Analyzer(shape).IsValid())
    return {"solids": solids, "free_edges": free, "brep_valid": valid, "valid": solids == 1 and valid and free == 0}


def _measured(truth, ours_step: Path, seed: int, timeout: float) -> dict:
    """:func:`measure` in a forked child killed after ``timeout`` s: one OCC face classification can loop for hours
    (export seed 13's STEP), and no signal reaches Python inside it. The child sends the solid check as soon as it
    has it, so a timeout keeps that much."""
    import multiprocessing

    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)

    def child():
        try:
            send.send(measure(truth, ours_step, seed, checked=send.send))
        except Exception as err:
            send.send({"measure_error": f"{type(err).__name__}: {err}"[:300]})
        send.send(None)  # done

    proc = ctx.Process(target=child, daemon=True)
    proc.start()
    send.close()  # the child's end only: a child that dies unheard gives EOF here, not a wait
    row: dict = {}
    deadline = time.monotonic() + timeout
    try:
        while recv.poll(max(0.0, deadline - time.monotonic())):
            part = recv.recv()
            if part is None:
                break
            row.update(part)
        else:
            row["measure_error"] = f"TimeoutError: measuring took over {timeout:g} s"
    except EOFError:
        row["measure_error"] = f"the measuring process died (exit {proc.exitcode})"
    proc.kill()
    proc.join()
    return row


def measure(truth, ours_step: Path, seed: int, checked=None) -> dict:
    """The figures of our STEP against the true one (see the module docstring); % of the true diagonal.
    ``checked``: called with the solid check's figures as soon as they are known."""
    import trimesh

    from recon.brep._distance import BrepDistance
    from recon.brep._step_read import read_step
    rng = np.random.default_rng(seed)
    ours, _ = read_step(ours_step)
    true, _ = read_step(truth.step)
    row = check_solid(ours)
    if checked is not None:
        checked(dict(row))
    a, b = BrepDistance(ours, rng=rng), BrepDistance(true, rng=rng)
    diag = truth.meta["diagonal"]
    row["faces_ours"] = len(a.types)
    # model_deviation's two directions, done here so that the true samples' nearest faces of ours give the types
    pa, _ = a.surface_samples(SAMPLES, rng=rng, nodes=False)
    pb, tface = b.surface_samples(SAMPLES, rng=rng, nodes=False)
    to_true = np.abs(b.signed_distance(pa)[0])
    from_true, oface, _ = a.signed_distance(pb)
    ta, tb = _types(a), _types(b)
    row["type_agreement"] = float(np.mean([ta[o] == tb[t] for o, t in zip(oface, tface)]))
    row["ours_true_p95"] = 100 * _p95(to_true) / diag
    row["true_ours_p95"] = 100 * _p95(np.abs(from_true)) / diag
    mesh = trimesh.load(truth.mesh, process=False, force="mesh")
    v = np.asarray(mesh.vertices)
    if len(v) > MAX_VERTICES:
        v = v[np.sort(rng.choice(len(v), MAX_VERTICES, replace=False))]
    row["mesh_ours_p95"] = 100 * _p95(np.abs(a.signed_distance(v)[0])) / diag
    row["mesh_true_p95"] = 100 * _p95(np.abs(b.signed_distance(v)[0])) / diag
    return row


def _p95(values) -> float:
    """95th percentile of the finite values (a point whose nearest face could not be measured is NaN: left out)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return float(np.percentile(v, 95)) if v.size else float("nan")


def run_freecad(mesh: Path, *, timeout: float) -> dict:
    """FreeCAD's route on the same mesh (mesh → shape → refine → solid → STEP, :func:`recon._freecad.freecad_route`):
    ``fc_seconds`` its stages inside freecadcmd, ``fc_wall_seconds`` with freecadcmd's start-up, faces, validity."""
    from recon._freecad import freecad_route, freecadcmd

    if freecadcmd() is None:
        return {"fc_status": "absent"}
    with tempfile.TemporaryDirectory(prefix="corpus_fc_") as tmp:
        try:
            res = freecad_route(mesh, Path(tmp) / "freecad.step", timeout=timeout)
        except subprocess.TimeoutExpired:
            return {"fc_status": "timeout"}
        except Exception as err:  # FreeCAD failing is its row, not the end of the run
            return {"fc_status": "error", "fc_message": f"{type(err).__name__}: {err}"[:200]}
    ok = bool(res.get("valid")) and str(res.get("type", "")).lower() == "solid"
    return {"fc_status": "ok" if ok else "invalid", "fc_faces": res.get("faces"), "fc_valid": ok,
            "fc_seconds": round(float(res["seconds"]), 3), "fc_wall_seconds": round(float(res["wall_seconds"]), 2)}


def _unified(truth) -> int | None:
    """The true face count with neighbouring faces on one surface joined, from the part's metadata (recorded where the
    part is made); from its STEP for a part cached before it was recorded. (The builder splits some cones and
    cylinders in two halves that meet on one surface, which no mesh can tell apart: export seed 45's countersink.)"""
    if "faces_unified" in truth.meta:
        return truth.meta["faces_unified"]
    from .real import unified_faces
    from .truth import read_part

    return unified_faces(read_part(truth.step))


def run_case(seed: int, regime: str, *, cache: Path = DEFAULT_CACHE, keep: Path | None = None,
             timeout: float = 600.0, memory_mb: int | None = 4096, freecad: bool = False, recon: bool = True) -> dict:
    """The row of one (seed, regime): generation, recon (unless ``recon`` is False: status ``no-recon``), measurement,
    FreeCAD's route where ``freecad``; any failure is recorded, never raised."""
    row = {"seed": int(seed), "regime": regime}
    t0 = time.perf_counter()
    try:
        truth = materialise_apart(seed, regime, cache)
    except Exception as err:  # the generator failing is a row too (and a bug of the corpus to fix)
        row.update(status="generator", message=f"{type(err).__name__}: {err}"[:300])
        return row
    row["generate_seconds"] = round(time.perf_counter() - t0, 2)
    meta = truth.meta
    row["faces_true_unified"] = _unified(truth)
    row.update(family=meta["family"], traits=meta["traits"], faces_true=meta["faces"],
               triangles=truth.info["triangles"], mesh_watertight=truth.info["watertight"])
    if recon:
        row.update(_recon_row(truth, seed, regime, keep=keep, timeout=timeout, memory_mb=memory_mb))
    else:
        row["status"] = "no-recon"
    if freecad:
        row.update(run_freecad(truth.mesh, timeout=timeout))
    row["total_seconds"] = round(time.perf_counter() - t0, 2)
    return row


def _recon_row(truth, seed: int, regime: str, *, keep: Path | None, timeout: float, memory_mb: int | None) -> dict:
    """recon convert on the case's mesh and the figures of its STEP file."""
    row = {}
    with tempfile.TemporaryDirectory(prefix="corpus_") as tmp:
        out, report = Path(tmp) / "ours.step", Path(tmp) / "report.json"
        row.update(run_recon(truth.mesh, out, report, timeout=timeout, memory_mb=memory_mb))
        if report.exists():
            try:
                rep = json.loads(report.read_text())
                row["tolerance_pct"] = 100 * rep["tolerance"] / truth.meta["diagonal"]
                row["recon_seconds"] = {k: v for k, v in rep.get("seconds", {}).items()}
                row["recon_says_valid"] = bool(rep["validity"]["ok"])
            except (ValueError, KeyError) as err:
                row["report_error"] = f"{type(err).__name__}: {err}"[:200]
        if out.exists():
            try:
                row.update(_measured(truth, out, seed, timeout))  # the same limit as recon's
            except Exception as err:  # a measurement failing is recorded beside recon's own outcome
                row["measure_error"] = f"{type(err).__name__}: {err}"[:300]
            if keep is not None:
                keep.mkdir(parents=True, exist_ok=True)
                (keep / f"{regime}_seed_{seed:05d}.step").write_bytes(out.read_bytes())
    if row.get("ours_true_p95") is not None and row.get("tolerance_pct") is not None:
        row["issue20_ok"] = not (row["exit"] == 0 and row["ours_true_p95"] > row["tolerance_pct"])
    return row


def run_job(job) -> dict:
    """:func:`run_case` of a ``(seed, regime, keywords)`` job, for a process pool's worker. ``keywords["old"]``: the
    case's row from an earlier run, whose FreeCAD figures (or recon's) the new row keeps where it has none."""
    import logging

    logging.getLogger("build123d").setLevel(logging.WARNING)  # a spawned worker has its own loggers
    seed, regime, kw = job
    kw = dict(kw)
    old = kw.pop("old", None) or {}
    row = run_case(seed, regime, **kw)
    fc = lambda r: {k: v for k, v in r.items() if k.startswith("fc_")}  # noqa: E731
    if old and not kw.get("recon", True):
        return {**old, **fc(row)}  # only FreeCAD's route was run: the earlier row with its figures added
    return {**fc(old), **row}
