"""One case measured, inside the subprocess :func:`bench.run.run_case` starts (``python -m bench.run --worker``).

recon's conversion of the mesh with its time and peak memory per stage, then everything the truth allows (faces
recovered, type agreement, deviations of our B-rep and of the true STEP); or the FreeCAD route on the same mesh.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np

from recon._io import write_json

from .cases import SCALING_PART, STAGES, make_scaling_mesh, scaling_mesh_path, triangle_count

__all__ = ["type_agreement", "unit_factor", "worker"]


def type_agreement(labels, true_labels, areas, our_types, true_types) -> float:
    """Area-weighted share of the true faces whose best-overlapping face of ours has the same surface type.

    Parameters
    ----------
    labels : (m,) int
        Our face per triangle.
    true_labels : (m,) int
        True face per triangle; negative = unknown (ignored).
    areas : (m,) float
        Triangle areas.
    our_types : mapping int → str
        Surface type of each of our faces (a label missing from it never agrees).
    true_types : sequence of str
        Surface type of each true face, indexed by true label.

    Returns
    -------
    float
        In [0, 1]; NaN when no triangle has a known true face.
    """
    from recon.decompose import face_recovery

    rec = face_recovery(labels, true_labels, areas)
    if len(rec.true_ids) == 0:
        return float("nan")
    t = np.asarray(true_labels)
    a = np.asarray(areas, dtype=float)
    ok = t >= 0
    weight = np.bincount(t[ok], weights=a[ok])[rec.true_ids]
    same = np.array([our_types.get(int(p)) == true_types[int(i)] for i, p in zip(rec.true_ids, rec.best_part)])
    return float(weight[same].sum() / weight.sum()) if weight.sum() > 0 else float("nan")


def one_line(text: str, limit: int = 300) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def pid_rss_mb(pid: int) -> float:
    try:
        with open(f"/proc/{pid}/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return 0.0


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def _maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _children_private_mb() -> float:
    """Memory only this process's children hold (their private pages, MiB): a forked worker shares the parent's
    pages until either writes them, so its RSS would count them twice."""
    total = 0.0
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return 0.0
    for tid in tasks:
        try:
            with open(f"/proc/self/task/{tid}/children") as fh:
                kids = fh.read().split()
        except OSError:
            continue
        for pid in kids:
            try:
                with open(f"/proc/{pid}/smaps_rollup") as fh:
                    for line in fh:
                        if line.startswith(("Private_Clean:", "Private_Dirty:")):
                            total += int(line.split()[1]) / 1024.0
            except (OSError, ValueError, IndexError):
                continue
    return total


#: The children's private memory is read at every this many samples: ``smaps_rollup`` walks a process's page
#: tables (3.5 ms for a 0.5 GB worker), and read at every 10 ms sample it took a third of a core from the
#: decomposition it measures (the 100k box's decomposition 2.5 → 3.6 s in the bench).
CHILD_SAMPLE_EVERY = 25


class _StageMemory:
    """Peak RSS per stage: a sampling thread, and ``ru_maxrss`` for the stage that set the process's peak.

    A sample is the process's RSS plus its children's private memory (the decomposition's forked worker);
    ``peak`` is the largest of them all, or ``ru_maxrss`` when that is larger (a peak between two samples).
    """

    def __init__(self, interval: float = 0.01):
        self.peaks: dict[str, float] = {}
        self._stage = None
        self._start_max = 0.0
        self._cur = 0.0
        self.peak = 0.0
        self._interval = interval
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()

    def _sample(self):
        kids, tick = 0.0, 0
        while not self._stop.wait(self._interval):
            try:
                if tick % CHILD_SAMPLE_EVERY == 0:
                    kids = _children_private_mb()
                tick += 1
                now = _rss_mb() + kids
            except OSError:
                return
            self._cur = max(self._cur, now)
            self.peak = max(self.peak, now)

    def __call__(self, stage: str, fraction: float):
        """A :func:`recon.pipeline.convert` progress callback."""
        if fraction == 0.0:
            self.begin(stage)
        elif fraction >= 1.0:
            self.end(stage)

    def begin(self, stage: str):
        self._stage = stage
        self._start_max = _maxrss_mb()
        self._cur = _rss_mb()

    def end(self, stage: str):
        now_max = _maxrss_mb()
        peak = max(self._cur, _rss_mb())
        if now_max > self._start_max:  # the process's peak was set during this stage
            peak = max(peak, now_max)
        self.peaks[stage] = round(peak, 1)
        self._stage = None

    def stop(self):
        self._stop.set()


def _stats_pct(stats: dict, prefix: str) -> dict:
    return {f"{prefix}_{k}": float(stats[f"{k}_pct"]) for k in ("max", "p95", "rms")}


def _pct_of(value, diagonal: float):
    return None if value is None or not np.isfinite(value) else 100.0 * float(value) / diagonal


def _ratio(value, tolerance: float):
    return None if value is None or not np.isfinite(value) else float(value) / tolerance


def _types_text(counter) -> str:
    return ", ".join(f"{n} {t}" for t, n in sorted(dict(counter).items(), key=lambda kv: (-kv[1], kv[0])))


def _our_face_types(conversion) -> dict:
    """Surface type of each face label: the B-rep face made for it (largest if several), else its fit."""
    out, best = {}, {}
    for r in conversion.brep.faces:
        if r.face is None or r.status == "failed":
            continue
        if r.area > best.get(r.part, -1.0):
            best[r.part], out[int(r.part)] = r.area, r.surface_type
    for p, fit in conversion.fits.items():
        out.setdefault(int(p), fit.type if fit.params else None)
    return out


#: Unit factors by which a mesh file and its true STEP may differ (m, cm, inch against mm).
UNIT_FACTORS = (10.0, 100.0, 1000.0, 25.4)


def unit_factor(mesh_diagonal: float, step_diagonal: float) -> float:
    """The factor that takes a mesh into its true STEP's units: a unit factor (or its inverse) that the ratio of
    the two bounding-box diagonals matches within 2 %, else 1. (abc_00000050: the STL is in metres, the STEP
    in millimetres; compared as they were, every triangle sat 13,000 % of the diagonal from the truth.)"""
    ratio = step_diagonal / mesh_diagonal
    for f in UNIT_FACTORS:
        for c in (f, 1.0 / f):
            if abs(ratio / c - 1.0) < 0.02:
                return c
    return 1.0


def _truth_from_step(vertices, faces, step_path) -> tuple:
    """True face per triangle for a mesh with a true STEP but no labels: the face nearest the centroid, with
    the mesh taken into the STEP's units first. Returns the labels, the true face types and that factor."""
    from recon.brep._distance import BrepDistance
    from recon.brep._step_read import read_step

    shape, _ = read_step(step_path)
    bd = BrepDistance(getattr(shape, "wrapped", shape))
    vertices = np.asarray(vertices, dtype=np.float64)
    factor = unit_factor(float(np.linalg.norm(np.ptp(vertices, axis=0))), bd.diagonal)
    centroids = factor * vertices[np.asarray(faces)].mean(axis=1)
    _, nearest, _ = bd.signed_distance(centroids)
    return np.asarray(nearest, dtype=np.int64), tuple(bd.types), factor


def _measure_convert(spec: dict, row: dict) -> dict:
    """recon's conversion of the case's mesh, timed per stage, then scored against whatever truth the case has."""
    from recon.pipeline import convert

    path, truth = _case_input(spec, row)

    # What convert() imports on first use (OpenCascade through recon.brep, trimesh for reading the file) is
    # imported before the clock starts: start-up, as the FreeCAD route imports Mesh and Part before its own
    # (recon/_freecad/fc_route.py). Counted, it was 1.2 s of the 100k part's 2.9 s (OCP 0.9 s, trimesh 0.3 s).
    import trimesh  # noqa: F401

    import recon.brep  # noqa: F401

    memory = _StageMemory()
    current = {"stage": "load"}
    started: dict[str, float] = {}
    partial: dict[str, float] = {}

    def progress(stage, fraction):
        current["stage"] = stage
        memory(stage, fraction)
        if fraction == 0.0 and spec.get("stage_file"):  # so that a crash can be placed
            Path(spec["stage_file"]).write_text(stage)
        if fraction == 0.0:
            started[stage] = time.perf_counter()
        elif fraction >= 1.0 and stage in started:
            partial[stage] = round(time.perf_counter() - started[stage], 4)

    try:
        conv = convert(path, progress=progress)
    except Exception as err:  # a failing stage is a result
        memory.stop()
        row.update(status="error", error=one_line(f"{current['stage']}: {type(err).__name__}: {err}"))
        row["stage_peak_mb"] = memory.peaks
        row["seconds"] = partial  # the stages that finished
        return row
    _conversion_row(conv, row)
    seconds = dict(conv.report["seconds"])
    notes = []
    _export(conv, row, memory, seconds, notes)
    memory.stop()
    row["seconds"] = seconds
    row["convert_seconds"] = round(sum(seconds.get(s, 0.0) for s in STAGES if s != "deviation"), 3)
    row["stage_peak_mb"] = memory.peaks

    # Truth: everything below is measurement, not part of the conversion.
    _against_truth(conv, row, *truth, notes)
    if notes:
        row["notes"] = notes
    row["peak_mb"] = round(max(_maxrss_mb(), memory.peak), 1)  # with the decomposition's worker's own pages
    return row


def _case_input(spec: dict, row: dict) -> tuple:
    """The mesh file of a case and its truth: ``(path, (true labels per input triangle, true face types, true
    STEP))``, each None where the case has none; the true face counts go into ``row``."""
    true_labels_input = true_types = true_step = None
    if spec["kind"] == "fixture":
        from recon.fixtures import load_fixture

        fx = load_fixture(spec["part"], spec["variant"], root=spec.get("root"))
        path, true_labels_input, true_types, true_step = fx.stl_path, fx.labels, fx.face_types, fx.step_path
        row["faces_true"] = len(fx.true_faces)
        row["types_true"] = _types_text(Counter(true_types))
    elif spec["kind"] == "scaling":
        path = scaling_mesh_path(int(spec["triangles"]))
        if not path.exists():
            make_scaling_mesh(int(spec["triangles"]))
        true_labels_input = np.load(path.with_suffix(".labels.npy")).astype(np.int64)
        from recon.fixtures import FIXTURE_DIR

        fx_meta = json.loads((Path(FIXTURE_DIR) / f"{SCALING_PART}.json").read_text())
        true_types = tuple(f["type"] for f in fx_meta["faces"])  # the scaling meshes are labelled like it
        row["faces_true"] = len(true_types)
        row["types_true"] = _types_text(Counter(true_types))
    else:
        path = Path(spec["path"])
        if spec.get("true_step"):
            true_step = Path(spec["true_step"])
    row["source"] = str(path)
    return path, (true_labels_input, true_types, true_step)


def _conversion_row(conv, row: dict) -> None:
    """What the conversion's own report says: triangles, faces and their types, validity, each face's fit, the
    mesh↔shape deviation, and the case's status."""
    rep = conv.report
    row["triangles"] = rep["mesh"]["triangles"]
    row["faces_ours"] = rep["n_faces"]
    row["types_ours"] = _types_text(rep["faces_by_type"])
    val = rep["validity"]
    row["expected"] = "solid" if conv.mesh.report.closed else "shell"
    if row["expected"] == "solid":
        row["valid"] = bool(val["ok"])
    else:  # an open scan: a valid shell is the right answer
        row["valid"] = bool(val["valid"]) and val["shape_type"] == "shell"
    row["shape_type"] = val["shape_type"]
    row["failed_faces"] = sum(1 for f in rep["faces"] if f["status"] == "failed")
    # each face's fit against its own mesh points, in % of the diagonal and in tolerances (issue 4's table)
    diag, tol = rep["mesh"]["diagonal"], rep["tolerance"]
    row["face_fits"] = [[f["name"], f["surface"], f["status"], _pct_of(f.get("fit_max"), diag),
                         _pct_of(f.get("fit_rms"), diag), _ratio(f.get("fit_max"), tol)] for f in rep["faces"]]
    if "deviation" in rep:
        row.update(_stats_pct(rep["deviation"]["mesh_to_shape"], "m2s"))
        row.update(_stats_pct(rep["deviation"]["shape_to_mesh"], "s2m"))
    lost = sum(1 for r in conv.brep.faces if r.status == "failed" or r.face is None)
    row["status"] = "ok" if row["valid"] and not lost else "invalid"
    if row["status"] == "invalid":
        bad = [] if row["valid"] else [f"{val['shape_type']}, valid={val['valid']}, closed={val['closed']}"]
        if lost:
            bad.append(f"{lost} parts without a face")
        row["error"] = one_line(f"not a valid {row['expected']}: " + "; ".join(bad))


def _export(conv, row: dict, memory: _StageMemory, seconds: dict, notes: list) -> None:
    """Write the STEP file (the last stage of mesh file → STEP file), timed into ``seconds``."""
    from recon.brep import write_shape

    memory.begin("export")
    t = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            out = write_shape(Path(tmp) / "out.step", conv.brep)
            row["step_bytes"] = out.stat().st_size
    except Exception as err:
        notes.append(one_line(f"export: {type(err).__name__}: {err}"))
    seconds["export"] = round(time.perf_counter() - t, 4)
    memory.end("export")


def _against_truth(conv, row: dict, true_labels_input, true_types, true_step, notes: list) -> None:
    """The result scored against the truth: faces recovered and type agreement (true labels, given or from the true
    STEP), deviations of the mesh and of our B-rep from the true STEP."""
    from recon.deviation import deviation, model_deviation

    diag = conv.report["mesh"]["diagonal"]
    factor = 1.0
    if true_labels_input is None and true_step is not None:
        try:
            true_labels, true_types, factor = _truth_from_step(conv.mesh.vertices, conv.mesh.faces, true_step)
            row["faces_true"] = len(true_types)
            row["types_true"] = _types_text(Counter(true_types))
            if factor != 1.0:
                notes.append(f"the true STEP is in other units: the mesh was scaled by {factor:g} to compare")
        except Exception as err:
            true_labels = None
            notes.append(one_line(f"truth from STEP: {type(err).__name__}: {err}"))
    elif true_labels_input is not None:
        true_labels = np.asarray(true_labels_input)[conv.mesh.source_face]
    else:
        true_labels = None
    if true_labels is not None:
        from recon.decompose import face_recovery

        # on the input's triangles: those recon added to close a hole (source_face -1) have no true label
        mine = conv.mesh.source_face >= 0
        areas, labels, true_labels = conv.mesh.face_areas[mine], conv.labels[mine], true_labels[mine]
        rec = face_recovery(labels, true_labels, areas)
        row["recovered"], row["mean_iou"] = rec.recovered, rec.mean_iou
        dec_labels = np.asarray(conv.decomposition.labels)
        drec = face_recovery(dec_labels[mine] if len(dec_labels) == len(mine) else dec_labels, true_labels, areas)
        row["dec_recovered"], row["dec_mean_iou"] = drec.recovered, drec.mean_iou
        row["type_agreement"] = type_agreement(labels, true_labels, areas, _our_face_types(conv), true_types)
    if true_step is not None:
        try:
            holes = conv.extra.get("holes")  # the input's vertices only: not those added to close a hole
            dev = deviation(factor * conv.mesh.vertices, conv.mesh.faces, true_step, measured=None if holes is None
                            else np.arange(len(conv.mesh.vertices)) < holes.input_vertices)
            row.update(_stats_pct(dev.mesh_to_shape.to_json(), "true_m2s"))
            row.update(_stats_pct(dev.shape_to_mesh.to_json(), "true_s2m"))
        except Exception as err:
            notes.append(one_line(f"deviation to the true STEP: {type(err).__name__}: {err}"))
        try:
            # the model against the model: no mesh noise in it (the mesh's own deviation from the truth is the
            # floor of m2s; this is what a designer would see comparing the two parts)
            md = model_deviation(conv.brep.occ, true_step, diagonal=factor * diag, shape_scale=factor)
            row.update(_stats_pct(md.to_reference.to_json(), "ours_true"))
            row.update(_stats_pct(md.from_reference.to_json(), "true_ours"))
        except Exception as err:
            notes.append(one_line(f"deviation between our shape and the true STEP: {type(err).__name__}: {err}"))


def _measure_freecad(spec: dict, row: dict) -> dict:
    from recon._freecad import freecad_route

    path = Path(spec["path"])
    if not path.exists() and spec.get("triangles"):
        make_scaling_mesh(int(spec["triangles"]))
    row["triangles"] = triangle_count(path)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            res = freecad_route(path, Path(tmp) / "freecad.step", timeout=float(spec.get("timeout", 3600)))
        except subprocess.TimeoutExpired:
            row.update(status="timeout", error="freecadcmd did not finish in time")
            return row
        except Exception as err:
            row.update(status="error", error=one_line(f"{type(err).__name__}: {err}"))
            return row
    row["faces_ours"] = res.get("faces")
    row["valid"] = bool(res.get("valid"))
    row["shape_type"] = str(res.get("type", "")).lower() or None
    row["seconds"] = {k: round(v, 4) for k, v in res.get("stages", {}).items()}
    row["convert_seconds"] = round(float(res.get("seconds", float("nan"))), 3)
    row["step_bytes"] = res.get("step_bytes")
    row["peak_mb"] = round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0, 1)
    row["status"] = "ok" if row["valid"] and row["shape_type"] == "solid" else "invalid"
    if row["status"] == "invalid":
        row["error"] = f"FreeCAD result: {row['shape_type']}, isValid={row['valid']}"
    return row


def worker(spec_path: str, result_path: str) -> int:
    spec = json.loads(Path(spec_path).read_text())
    row = {"status": None}
    t = time.perf_counter()
    try:
        if spec["kind"] == "freecad":
            row = _measure_freecad(spec, row)
        else:
            row = _measure_convert(spec, row)
    except Exception as err:  # anything the measures themselves did not expect
        row.update(status="error", error=one_line(f"{type(err).__name__}: {err}"))
    row.setdefault("status", "error")
    row["worker_seconds"] = round(time.perf_counter() - t, 3)
    write_json(result_path, plain(row))
    return 0


def plain(obj):
    """JSON-ready: numpy scalars to Python, NaN to None."""
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj
