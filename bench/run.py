"""The project benchmark: the numbers users and we decide by, measured in one command.

``python -m bench.run [--cases fixtures,meshes,scaling,freecad] [--out DIR] [--quick]`` writes
``DIR/bench.json`` (every row, every figure) and ``DIR/bench.md`` (the tables; ``bench/RESULTS.md`` is a committed
copy of one full run and the README shows its headline rows).

Case groups
-----------
fixtures
    Every committed ground-truth fixture (7 parts × clean/noisy05/noisy20/coarse/open): faces and surface types
    against the truth, face recovery, type agreement, deviation of our B-rep *and of the true STEP* from the mesh.
meshes
    The real meshes in ``../shared/meshes`` (skipped where absent). The ABC model has a true STEP: its triangles
    get the true face nearest their centroid, so it is scored like a fixture.
freecad
    The route FreeCAD users take today (mesh → shape → refine → solid → STEP, :func:`recon._freecad.freecad_route`)
    on the same meshes (``--quick``: only meshes up to :data:`QUICK_FREECAD_TRIANGLES` triangles), so the speed
    ratio is measured; always also on the 100k scaling part, where issue 5 sets its target (FreeCAD takes tens of
    minutes there: a run killed at ``--timeout`` still bounds the ratio from below). Skipped where FreeCAD is not
    installed.
scaling
    ``box_fillet`` remeshed like the fixtures and subdivided with projection onto the true faces to 10k, 100k, 1M
    and 2M triangles (cached in ``fixtures/large/scaling``): time and peak memory per stage, and the log-log slope.

Every case runs in its own subprocess with a time limit; an exception, a crash, a timeout or an invalid solid is a
row of the table, never the end of the run. Peak memory is the subprocess's ``ru_maxrss``, or more when the
decomposition's forked worker (``decompose(jobs=2)``) adds pages of its own; per stage it is the peak reached while
the stage ran (a sampling thread: the process's RSS plus its children's private memory, corrected by
``ru_maxrss`` when the stage set a new peak).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import logging
import os
import platform
import resource
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from recon._io import atomic_path, write_json
from recon.errors import InputError

__all__ = [
    "COLUMNS",
    "GROUPS",
    "Case",
    "BenchResult",
    "fixture_cases",
    "mesh_cases",
    "freecad_cases",
    "scaling_cases",
    "run_case",
    "run_benchmark",
    "type_agreement",
    "loglog_slope",
    "render_markdown",
    "main",
]

log = logging.getLogger(__name__)

GROUPS = ("fixtures", "meshes", "freecad", "scaling")
REPO = Path(__file__).resolve().parent.parent
#: the real meshes nobody on the project made (not in the repository)
MESH_DIR = REPO / ".." / "shared" / "meshes"
SCALING_DIR = REPO / "fixtures" / "large" / "scaling"
DEFAULT_OUT = REPO / "bench" / "out"
#: ``--quick`` runs FreeCAD only on meshes up to this many triangles (it takes ~70–550 s on 40k–112k)
QUICK_FREECAD_TRIANGLES = 25_000
#: The scaling part FreeCAD also runs on, with or without ``--quick``: issue 5's "≥ 100× faster at 100k triangles".
FREECAD_PART_TRIANGLES = 100_000
SCALING_SIZES = (10_000, 100_000, 1_000_000, 2_000_000)
SCALING_PART = "box_fillet"
#: seconds per case, by group
TIMEOUTS = {"fixtures": 900, "meshes": 1800, "freecad": 1800, "scaling": 7200}
#: resident memory (MiB) above which a case's subprocess is killed (it shares the machine), by group
MEMORY_LIMITS = {"fixtures": 8192, "meshes": 8192, "freecad": 8192, "scaling": 12288}
#: the stages timed per case (``recon.pipeline.STAGES`` plus writing the STEP file)
STAGES = ("load", "decompose", "fit", "brep", "deviation", "export")

#: Every row of ``bench.json`` has these keys (``None`` where not applicable or not measured).
COLUMNS = {
    "case": "unique case name",
    "group": "fixtures | meshes | freecad | scaling",
    "kind": "fixture | mesh | freecad | scaling",
    "source": "the mesh file measured",
    "status": "ok | invalid (not a valid closed solid) | error (exception) | timeout | crashed",
    "error": "one line: what failed, where",
    "triangles": "triangles after cleaning (input triangles for FreeCAD)",
    "faces_true": "faces of the true B-rep",
    "faces_ours": "faces of the result (recon, or FreeCAD for freecad rows)",
    "types_true": "true faces by surface type",
    "types_ours": "our faces by surface type",
    "type_agreement": "area share of true faces whose best-overlapping face of ours has the same surface type",
    "recovered": "share of true faces matched by one of our faces with area IoU >= 0.5",
    "mean_iou": "mean over true faces of the best area IoU with our faces",
    "dec_recovered": "as recovered, for the raw decomposition (before sharp strips dissolve into faces)",
    "dec_mean_iou": "as mean_iou, for the raw decomposition",
    "m2s_max": "mesh -> our shape: max |distance|, % of the mesh's bounding-box diagonal",
    "m2s_p95": "mesh -> our shape: 95th percentile, % of diagonal",
    "m2s_rms": "mesh -> our shape: RMS, % of diagonal",
    "s2m_max": "our shape -> mesh: max, % of diagonal",
    "s2m_p95": "our shape -> mesh: 95th percentile, % of diagonal",
    "s2m_rms": "our shape -> mesh: RMS, % of diagonal",
    "true_m2s_max": "mesh -> true STEP: max, % of diagonal",
    "true_m2s_p95": "mesh -> true STEP: 95th percentile, % of diagonal",
    "true_m2s_rms": "mesh -> true STEP: RMS, % of diagonal",
    "true_s2m_max": "true STEP -> mesh: max, % of diagonal",
    "true_s2m_p95": "true STEP -> mesh: 95th percentile, % of diagonal",
    "true_s2m_rms": "true STEP -> mesh: RMS, % of diagonal",
    "ours_true_max": "our shape -> true STEP (points exactly on ours, recon.deviation.model_deviation): max, % of diagonal",
    "ours_true_p95": "our shape -> true STEP: 95th percentile, % of diagonal",
    "ours_true_rms": "our shape -> true STEP: RMS, % of diagonal",
    "true_ours_max": "true STEP -> our shape (points exactly on the true faces): max, % of diagonal",
    "true_ours_p95": "true STEP -> our shape: 95th percentile, % of diagonal",
    "true_ours_rms": "true STEP -> our shape: RMS, % of diagonal",
    "expected": "solid (the mesh is closed) | shell (an open scan)",
    "valid": "the expected result: a valid closed solid with volume > 0 from a closed mesh, a valid shell from an "
    "open one (OpenCascade's check; FreeCAD's isValid and a solid for freecad rows)",
    "shape_type": "solid | shell | compound ...",
    "failed_faces": "parts that got no face of their own",
    "face_fits": "per face: [name, surface type, status, fit max % diag, fit RMS % diag, fit max / tolerance]",
    "seconds": "seconds per stage: load, decompose, fit, brep, deviation, export (FreeCAD: its own stages)",
    "convert_seconds": "load + decompose + fit + brep + export: mesh file to STEP file (what FreeCAD is timed on)",
    "wall_seconds": "whole subprocess, with interpreter start and imports",
    "peak_mb": "peak resident memory of the case's subprocess (FreeCAD: of freecadcmd), MiB",
    "stage_peak_mb": "peak resident memory while each stage ran, MiB",
    "step_bytes": "size of the STEP file written",
}


@dataclass(frozen=True)
class Case:
    """One benchmark case: what to measure, run in a subprocess by :func:`run_case`.

    Attributes
    ----------
    name : str
    group : str
        One of :data:`GROUPS`.
    kind : str
        ``fixture`` (``spec["part"]``, ``spec["variant"]``), ``mesh`` (``spec["path"]``, optional
        ``spec["true_step"]``), ``freecad`` (``spec["path"]``) or ``scaling`` (``spec["triangles"]``).
    spec : dict
        Plain JSON for the worker.
    timeout : float
        Seconds before the subprocess is killed.
    max_memory_mb : float, optional
        Resident memory (MiB) at which it is killed; default :data:`MEMORY_LIMITS` of its group.
    """

    name: str
    group: str
    kind: str
    spec: dict = field(default_factory=dict)
    timeout: float = 900.0
    max_memory_mb: float | None = None


@dataclass(frozen=True)
class BenchResult:
    """Result of :func:`run_benchmark`: the rows (dicts with :data:`COLUMNS`) and the files written."""

    rows: tuple
    json_path: Path
    md_path: Path


# ----------------------------------------------------------------------------------------------------------------
# Cases


def fixture_cases(*, root=None, timeout: float | None = None) -> list[Case]:
    """One case per committed fixture (part × variant)."""
    from recon.fixtures import list_fixtures

    t = TIMEOUTS["fixtures"] if timeout is None else timeout
    spec_root = None if root is None else str(root)
    return [
        Case(f"{p}/{v}", "fixtures", "fixture", {"part": p, "variant": v, "root": spec_root}, t)
        for p, v in list_fixtures(root=root)
    ]


def _real_meshes(mesh_dir: Path) -> list[Path]:
    if not mesh_dir.is_dir():
        return []
    return sorted(p for p in mesh_dir.iterdir() if p.suffix.lower() in (".off", ".stl", ".obj", ".ply"))


def mesh_cases(*, mesh_dir=None, timeout: float | None = None) -> list[Case]:
    """One case per real mesh in ``mesh_dir`` (default :data:`MESH_DIR`); none where the folder is absent."""
    mesh_dir = Path(MESH_DIR if mesh_dir is None else mesh_dir)
    t = TIMEOUTS["meshes"] if timeout is None else timeout
    cases = []
    for p in _real_meshes(mesh_dir):
        gt = p.with_name(p.stem + ".gt.step")
        spec = {"path": str(p.resolve())}
        if gt.exists():
            spec["true_step"] = str(gt.resolve())
        cases.append(Case(f"mesh/{p.stem}", "meshes", "mesh", spec, t))
    if not cases:
        log.warning("no real meshes in %s: the meshes group is empty", mesh_dir)
    return cases


def _triangle_count(path: Path) -> int:
    """Triangles in a mesh file, read cheaply (OFF header, binary STL header; otherwise a full read)."""
    suffix = path.suffix.lower()
    with open(path, "rb") as fh:
        if suffix == ".off":
            words = []
            for line in fh:
                line = line.split(b"#")[0].strip()
                if line:
                    words += line.split()
                if len(words) >= 3 and words[0].upper().endswith(b"OFF"):
                    if len(words) >= 4:
                        return int(words[2])
                elif len(words) >= 3:
                    return int(words[1])
        if suffix == ".stl":
            head = fh.read(84)
            n = int.from_bytes(head[80:84], "little")
            if 84 + 50 * n == path.stat().st_size:
                return n
    from recon.mesh import read_triangles

    return int(len(read_triangles(path)[1]))


def freecad_cases(*, quick: bool = False, mesh_dir=None, fixture_root=None, timeout: float | None = None) -> list[Case]:
    """The FreeCAD route on the clean fixtures and the real meshes (``quick``: only the small ones).

    Empty where FreeCAD is not installed.
    """
    from recon._freecad import freecadcmd
    from recon.fixtures import FIXTURE_DIR, list_fixtures

    if freecadcmd() is None:
        log.warning("FreeCAD is not installed: no freecad cases")
        return []
    t = TIMEOUTS["freecad"] if timeout is None else timeout
    root = Path(FIXTURE_DIR if fixture_root is None else fixture_root)
    paths = [(f"{p}/{v}", root / f"{p}_{v}.stl") for p, v in list_fixtures(root=root) if v == "clean"]
    paths += [(f"mesh/{p.stem}", p) for p in _real_meshes(Path(MESH_DIR if mesh_dir is None else mesh_dir))]
    cases = []
    for name, path in paths:
        n = _triangle_count(path)
        if quick and n > QUICK_FREECAD_TRIANGLES:
            log.info("--quick: FreeCAD skips %s (%d triangles)", name, n)
            continue
        cases.append(Case(f"freecad:{name}", "freecad", "freecad", {"path": str(path.resolve()), "of": name}, t))
    # The part issue 5 states the speed target on (≥ 100× at 100k triangles): run even with --quick. The mesh is
    # the scaling group's, made on first use (in the case's subprocess, outside FreeCAD's timing).
    n = FREECAD_PART_TRIANGLES
    cases.append(Case(f"freecad:scaling/{_size_name(n)}", "freecad", "freecad",
                      {"path": str(_scaling_mesh_path(n).resolve()), "of": f"scaling/{_size_name(n)}", "triangles": n},
                      t))
    return cases


def scaling_cases(*, sizes=SCALING_SIZES, timeout: float | None = None) -> list[Case]:
    """``box_fillet`` at each size in ``sizes`` (triangles); the meshes are made on first use."""
    t = TIMEOUTS["scaling"] if timeout is None else timeout
    return [Case(f"scaling/{_size_name(n)}", "scaling", "scaling", {"triangles": int(n)}, t) for n in sizes]


def _size_name(n: int) -> str:
    return f"{n // 1_000_000}M" if n % 1_000_000 == 0 else f"{n // 1000}k" if n % 1000 == 0 else str(n)


# ----------------------------------------------------------------------------------------------------------------
# Measures (pure numpy; tested directly)


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


def loglog_slope(x, y) -> float:
    """Least-squares slope of log y against log x: the exponent k of y ∝ x^k (NaN with fewer than 2 points)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


# ----------------------------------------------------------------------------------------------------------------
# Running a case in a subprocess


def _child_env() -> dict:
    """The environment of a subprocess of the benchmark: this checkout first on the path, so that it finds ``bench``
    (it runs in a temporary folder) and measures the same ``recon`` as the process that started it."""
    path = os.environ.get("PYTHONPATH")
    return {**os.environ, "PYTHONPATH": str(REPO) + (os.pathsep + path if path else "")}


def _one_line(text: str, limit: int = 300) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _empty_row(case: Case) -> dict:
    row = {k: None for k in COLUMNS}
    row.update(case=case.name, group=case.group, kind=case.kind, source=case.spec.get("path"))
    return row


def run_case(case: Case, *, timeout: float | None = None, cwd=None) -> dict:
    """Measure one case in a fresh subprocess; never raises for a failing case.

    Parameters
    ----------
    case : Case
    timeout : float, optional
        Seconds; default ``case.timeout``. The subprocess (and anything it started) is killed then.
    cwd : path, optional
        Working directory of the subprocess (default: a temporary folder).

    Returns
    -------
    dict
        A row with the keys of :data:`COLUMNS` (plus ``stderr_tail`` when the case failed).
    """
    limit = case.timeout if timeout is None else float(timeout)
    row = _empty_row(case)
    with tempfile.TemporaryDirectory(prefix="recon-bench-") as tmp:
        tmp = Path(tmp)
        spec_path, result_path, err_path = tmp / "case.json", tmp / "result.json", tmp / "stderr.txt"
        stage_path = tmp / "stage.txt"
        spec_path.write_text(json.dumps({"name": case.name, "group": case.group, "kind": case.kind,
                                         "stage_file": str(stage_path), **case.spec}))
        mem_limit = case.max_memory_mb or MEMORY_LIMITS.get(case.group, 8192)
        killed_for = None
        t0 = time.perf_counter()
        with open(err_path, "wb") as err:
            proc = subprocess.Popen(
                [sys.executable, "-m", "bench.run", "--worker", str(spec_path), str(result_path)],
                stdin=subprocess.DEVNULL, stdout=err, stderr=err, cwd=str(cwd or tmp), start_new_session=True,
                env=_child_env(),
            )
            while True:
                pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
                if pid:
                    break
                if time.perf_counter() - t0 > limit:
                    killed_for = f"no result within {limit:g} s: killed"
                elif _pid_rss_mb(proc.pid) > mem_limit:
                    killed_for = f"resident memory over {mem_limit:g} MiB: killed"
                if killed_for:
                    os.killpg(proc.pid, signal.SIGKILL)  # the session we started: the worker and its children
                    pid, status, usage = os.wait4(proc.pid, 0)
                    break
                time.sleep(0.05)
            proc.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - t0
        stderr_tail = err_path.read_text(errors="replace").strip().splitlines()[-5:]
        stage = stage_path.read_text().strip() if stage_path.exists() else ""
        where = f"in {stage}: " if stage else ""
        if result_path.exists() and not killed_for:
            row.update(json.loads(result_path.read_text()))
        elif killed_for:
            row.update(status="timeout" if "memory" not in killed_for else "crashed", error=where + killed_for)
        else:
            code = proc.returncode
            how = f"killed by signal {-code}" if code < 0 else f"exit code {code}"
            if code == -signal.SIGKILL:
                how += f" (peak {usage.ru_maxrss / 1024:.0f} MiB: out of memory?)"
            last = stderr_tail[-1] if stderr_tail else "no output"
            row.update(status="crashed", error=_one_line(f"{where}subprocess {how}; last log line: {last}"))
        if row["status"] in ("timeout", "crashed", "error"):
            row["stderr_tail"] = [_one_line(s) for s in stderr_tail]
        row["wall_seconds"] = round(wall, 3)
        if row.get("peak_mb") is None:
            row["peak_mb"] = round(usage.ru_maxrss / 1024.0, 1)
    return row


# ----------------------------------------------------------------------------------------------------------------
# The worker (runs inside the subprocess)


def _pid_rss_mb(pid: int) -> float:
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


#: Variants whose faces the per-face fit table lists (all of them would be 500 rows).
FACE_TABLE_VARIANTS = ("clean", "noisy20")


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
    from recon.deviation import deviation, model_deviation
    from recon.pipeline import convert

    true_labels_input = true_types = true_step = None
    if spec["kind"] == "fixture":
        from recon.fixtures import load_fixture

        fx = load_fixture(spec["part"], spec["variant"], root=spec.get("root"))
        path, true_labels_input, true_types, true_step = fx.stl_path, fx.labels, fx.face_types, fx.step_path
        row["faces_true"] = len(fx.true_faces)
        row["types_true"] = _types_text(Counter(true_types))
    elif spec["kind"] == "scaling":
        path = _scaling_mesh_path(int(spec["triangles"]))
        if not path.exists():
            _make_scaling_mesh(int(spec["triangles"]))
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
        row.update(status="error", error=_one_line(f"{current['stage']}: {type(err).__name__}: {err}"))
        row["stage_peak_mb"] = memory.peaks
        row["seconds"] = partial  # the stages that finished
        return row
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
    seconds = dict(rep["seconds"])
    if "deviation" in rep:
        row.update(_stats_pct(rep["deviation"]["mesh_to_shape"], "m2s"))
        row.update(_stats_pct(rep["deviation"]["shape_to_mesh"], "s2m"))
    lost = sum(1 for r in conv.brep.faces if r.status == "failed" or r.face is None)
    row["status"] = "ok" if row["valid"] and not lost else "invalid"
    if row["status"] == "invalid":
        bad = [] if row["valid"] else [f"{val['shape_type']}, valid={val['valid']}, closed={val['closed']}"]
        if lost:
            bad.append(f"{lost} parts without a face")
        row["error"] = _one_line(f"not a valid {row['expected']}: " + "; ".join(bad))
    notes = []

    from recon.brep import write_shape

    memory.begin("export")
    t = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            out = write_shape(Path(tmp) / "out.step", conv.brep)
            row["step_bytes"] = out.stat().st_size
    except Exception as err:
        notes.append(_one_line(f"export: {type(err).__name__}: {err}"))
    seconds["export"] = round(time.perf_counter() - t, 4)
    memory.end("export")
    memory.stop()
    row["seconds"] = seconds
    row["convert_seconds"] = round(sum(seconds.get(s, 0.0) for s in STAGES if s != "deviation"), 3)
    row["stage_peak_mb"] = memory.peaks

    # Truth: everything below is measurement, not part of the conversion.
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
            notes.append(_one_line(f"truth from STEP: {type(err).__name__}: {err}"))
    elif true_labels_input is not None:
        true_labels = np.asarray(true_labels_input)[conv.mesh.source_face]
    else:
        true_labels = None
    if true_labels is not None:
        from recon.decompose import face_recovery

        areas = conv.mesh.face_areas
        rec = face_recovery(conv.labels, true_labels, areas)
        row["recovered"], row["mean_iou"] = rec.recovered, rec.mean_iou
        drec = face_recovery(np.asarray(conv.decomposition.labels), true_labels, areas)
        row["dec_recovered"], row["dec_mean_iou"] = drec.recovered, drec.mean_iou
        row["type_agreement"] = type_agreement(conv.labels, true_labels, areas, _our_face_types(conv), true_types)
    if true_step is not None:
        try:
            dev = deviation(factor * conv.mesh.vertices, conv.mesh.faces, true_step)
            row.update(_stats_pct(dev.mesh_to_shape.to_json(), "true_m2s"))
            row.update(_stats_pct(dev.shape_to_mesh.to_json(), "true_s2m"))
        except Exception as err:
            notes.append(_one_line(f"deviation to the true STEP: {type(err).__name__}: {err}"))
        try:
            # the model against the model: no mesh noise in it (the mesh's own deviation from the truth is the
            # floor of m2s; this is what a designer would see comparing the two parts)
            md = model_deviation(conv.brep.occ, true_step, diagonal=factor * diag, shape_scale=factor)
            row.update(_stats_pct(md.to_reference.to_json(), "ours_true"))
            row.update(_stats_pct(md.from_reference.to_json(), "true_ours"))
        except Exception as err:
            notes.append(_one_line(f"deviation between our shape and the true STEP: {type(err).__name__}: {err}"))
    if notes:
        row["notes"] = notes
    row["peak_mb"] = round(max(_maxrss_mb(), memory.peak), 1)  # with the decomposition's worker's own pages
    return row


def _measure_freecad(spec: dict, row: dict) -> dict:
    from recon._freecad import freecad_route

    path = Path(spec["path"])
    if not path.exists() and spec.get("triangles"):
        _make_scaling_mesh(int(spec["triangles"]))
    row["triangles"] = _triangle_count(path)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            res = freecad_route(path, Path(tmp) / "freecad.step", timeout=float(spec.get("timeout", 3600)))
        except subprocess.TimeoutExpired:
            row.update(status="timeout", error="freecadcmd did not finish in time")
            return row
        except Exception as err:
            row.update(status="error", error=_one_line(f"{type(err).__name__}: {err}"))
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


def _load_make_fixtures():
    import importlib.util

    script = REPO / "fixtures" / "make_fixtures.py"
    if not script.exists():
        raise InputError(f"scaling: needs {script} to make the meshes, not found")
    spec = importlib.util.spec_from_file_location("_recon_make_fixtures", script)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _make_scaling_mesh(triangles: int) -> None:
    """Make (and cache) a scaling mesh in a child process, so its memory and time stay out of the case's figures."""
    subprocess.run([sys.executable, "-m", "bench.run", "--make-scaling", str(triangles)],
                   check=True, stdin=subprocess.DEVNULL, capture_output=True, env=_child_env())


def _scaling_mesh_path(triangles: int, *, folder: Path = SCALING_DIR) -> Path:
    return folder / f"{SCALING_PART}_{_size_name(triangles)}.stl"


def _scaling_mesh(triangles: int, *, folder: Path = SCALING_DIR) -> Path:
    """``box_fillet`` with about ``triangles`` triangles: the fixtures' remesher at n / 4^k, then k subdivisions
    with projection onto the true faces (k the least with n / 4^k ≤ 8000). Cached in ``folder``."""
    path = _scaling_mesh_path(triangles, folder=folder)
    if path.exists() and path.with_suffix(".labels.npy").exists():
        return path
    mf = _load_make_fixtures()
    folder.mkdir(parents=True, exist_ok=True)
    solid = mf.build_part(SCALING_PART)
    table = mf.face_table(solid)
    area = sum(e["area"] for e in table)
    k = 0
    while triangles / 4**k > 8000:
        k += 1
    V, T, L, kind, owner, feature, face_proj, edge_proj = mf.scanlike_mesh(solid, table, mf.h_for(area, triangles / 4**k))
    mesh = (V, T, L, kind, owner, feature)
    for _ in range(k):
        mesh = mf.subdivide(*mesh, face_proj, edge_proj)
    mf._write_mesh(path, mesh[0], mesh[1], mesh[2])
    log.info("scaling mesh %s: %d triangles", path.name, len(mesh[1]))
    return path


def _worker(spec_path: str, result_path: str) -> int:
    spec = json.loads(Path(spec_path).read_text())
    row = {"status": None}
    t = time.perf_counter()
    try:
        if spec["kind"] == "freecad":
            row = _measure_freecad(spec, row)
        else:
            row = _measure_convert(spec, row)
    except Exception as err:  # anything the measures themselves did not expect
        row.update(status="error", error=_one_line(f"{type(err).__name__}: {err}"))
    row.setdefault("status", "error")
    row["worker_seconds"] = round(time.perf_counter() - t, 3)
    write_json(result_path, _plain(row))
    return 0


def _plain(obj):
    """JSON-ready: numpy scalars to Python, NaN to None."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


# ----------------------------------------------------------------------------------------------------------------
# The run and its report


def _machine() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True,
                                timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "commit": commit,
            "date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")}


def run_benchmark(cases, *, out=DEFAULT_OUT, merge: bool = False, timeout: float | None = None,
                  progress=None, meta: dict | None = None) -> BenchResult:
    """Run ``cases`` one after the other and write ``out/bench.json`` and ``out/bench.md`` after each.

    Parameters
    ----------
    cases : sequence of Case
    out : path
        Output folder (created).
    merge : bool
        Keep the rows of ``out/bench.json`` whose case is not run now (e.g. add scaling to a previous run).
    timeout : float, optional
        Seconds per case, overriding each case's own limit.
    progress : callable(index, total, row), optional
        Called after each case.
    meta : dict, optional
        Extra facts for the report's header (e.g. the command line).

    Returns
    -------
    BenchResult
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    json_path, md_path = out / "bench.json", out / "bench.md"
    kept = []
    if merge and json_path.exists():
        names = {c.name for c in cases}
        kept = [r for r in json.loads(json_path.read_text()).get("rows", []) if r.get("case") not in names]
    meta = {**_machine(), **(meta or {})}
    rows = list(kept)
    order = {g: i for i, g in enumerate(GROUPS)}
    for i, case in enumerate(cases):
        row = run_case(case, timeout=timeout)
        rows.append(_plain(row))
        rows.sort(key=lambda r: order.get(r.get("group"), 99))
        _write(rows, meta, json_path, md_path)
        if progress is not None:
            progress(i, len(cases), row)
    _write(rows, meta, json_path, md_path)
    return BenchResult(tuple(rows), json_path, md_path)


def _write(rows, meta, json_path, md_path):
    write_json(json_path, {"meta": meta, "columns": COLUMNS, "rows": rows})
    with atomic_path(md_path) as tmp:
        tmp.write_text(render_markdown(rows, meta))


def _f(v, fmt="{:.3g}", none="–"):
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return none
    return fmt.format(v)


def _pct(v):
    return _f(v, "{:.3g}")


def _median(values):
    vals = [v for v in values if v is not None and np.isfinite(v)]
    return float(np.median(vals)) if vals else None


def _table(header, rows) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return lines


def _status(r) -> str:
    s = r.get("status") or "?"
    return "**" + s + "**" if s != "ok" else "ok"


def _speed_pairs(rows) -> list[tuple]:
    """(recon row, freecad row) pairs on the same mesh, both finished."""
    ours = {r["case"]: r for r in rows if r.get("group") in ("fixtures", "meshes", "scaling")}
    pairs = []
    for fc in rows:
        if fc.get("group") != "freecad":
            continue
        name = fc["case"].split(":", 1)[1]
        if name in ours:
            pairs.append((ours[name], fc))
    return pairs


def part_speed_line(rows) -> str | None:
    """Issue 5's speed figure: the FreeCAD route against recon on the 100k-triangle scaling part, mesh file → STEP.

    A FreeCAD run killed at its time limit still bounds the ratio from below (it had not finished after that
    long); a recon run that did not finish gives no figure.
    """
    name = f"scaling/{_size_name(FREECAD_PART_TRIANGLES)}"
    fc = next((r for r in rows if r.get("case") == f"freecad:{name}"), None)
    ours = next((r for r in rows if r.get("case") == name), None)
    if fc is None or ours is None or not ours.get("convert_seconds"):
        return None
    t_ours = float(ours["convert_seconds"])
    head = f"The {ours.get('triangles') or FREECAD_PART_TRIANGLES:,}-triangle part (`{name}`), mesh file → STEP file: "
    if fc.get("status") in ("ok", "invalid") and fc.get("convert_seconds"):
        t_fc = float(fc["convert_seconds"])
        return (f"{head}FreeCAD {t_fc:.0f} s ({fc.get('faces_ours')} faces), recon {t_ours:.1f} s "
                f"({ours.get('faces_ours')} faces): **{t_fc / t_ours:.0f}×** faster (issue 5: ≥ 100×).")
    if fc.get("status") == "timeout" and fc.get("wall_seconds"):
        t_fc = float(fc["wall_seconds"])
        return (f"{head}FreeCAD had not finished after {t_fc:.0f} s (killed), recon {t_ours:.1f} s: "
                f"**more than {t_fc / t_ours:.0f}×** faster (issue 5: ≥ 100×).")
    return f"{head}FreeCAD {fc.get('status')}: {fc.get('error') or 'no time'}; recon {t_ours:.1f} s."


def headline_rows(rows) -> list[list[str]]:
    """The README's headline table: one row per fixture variant, real meshes, and the FreeCAD comparison."""
    out = []
    groups = []
    for v in ("clean", "noisy05", "noisy20", "coarse", "open"):
        groups.append((f"fixtures, {v}", [r for r in rows if r.get("kind") == "fixture" and r["case"].endswith("/" + v)]))
    groups.append(("real meshes", [r for r in rows if r.get("group") == "meshes"]))
    for label, rs in groups:
        if not rs:
            continue
        n = len(rs)
        valid = sum(1 for r in rs if r.get("valid"))
        failed = sum(1 for r in rs if r.get("status") in ("error", "timeout", "crashed"))
        ft = sum(r.get("faces_true") or 0 for r in rs if r.get("faces_true") and r.get("faces_ours") is not None)
        fo = sum(r.get("faces_ours") or 0 for r in rs if r.get("faces_true") and r.get("faces_ours") is not None)
        out.append([
            label, str(n), f"{valid}/{n}" + (f" ({failed} failed)" if failed else ""),
            f"{fo} / {ft}" if ft else "–",
            _f(_median([r.get("type_agreement") for r in rs]), "{:.0%}"),
            _f(_median([r.get("recovered") for r in rs]), "{:.0%}"),
            _pct(_median([r.get("m2s_p95") for r in rs])),
            _pct(_median([r.get("s2m_p95") for r in rs])),
            _pct(_median([r.get("true_m2s_p95") for r in rs])),
            _pct(_median([r.get("ours_true_p95") for r in rs])),
            _f(_median([r.get("convert_seconds") for r in rs]), "{:.1f}"),
            _f(max([r.get("peak_mb") or 0 for r in rs]), "{:.0f}"),
        ])
    return out


HEADLINE_HEADER = [
    "cases", "n", "valid results (solid; shell if open)", "faces ours / true", "type agreement (median)", "faces recovered IoU≥0.5 "
    "(median)", "mesh→shape p95 % diag (median)", "shape→mesh p95 % diag (median)", "mesh→true STEP p95 % (median)",
    "ours→true STEP p95 % (median)", "mesh→STEP s (median)", "peak MiB (max)",
]


def render_markdown(rows, meta: dict | None = None) -> str:
    """The benchmark report as Markdown: headline, per-case tables, FreeCAD side by side, scaling, failures."""
    meta = meta or {}
    L = ["# recon benchmark", ""]
    L.append(
        f"Run {meta.get('date', '?')} on commit `{meta.get('commit', '?')}`, {meta.get('cpu', '?')} "
        f"({meta.get('cores', '?')} cores, shared: timings are noisy), Python {meta.get('python', '?')}. "
        f"Command: `{meta.get('command', 'python -m bench.run')}`. Every case ran in its own subprocess "
        "with a time limit. Deviations are % of the mesh's bounding-box diagonal."
    )
    L.append("")
    head = headline_rows(rows)
    if head:
        L += ["## Headline", ""] + _table(HEADLINE_HEADER, head) + [""]
    pairs = _speed_pairs(rows)
    done = [(o, fc) for o, fc in pairs if o.get("convert_seconds") and fc.get("convert_seconds")
            and fc.get("status") in ("ok", "invalid")]
    if done:
        ratios = [fc["convert_seconds"] / o["convert_seconds"] for o, fc in done]
        L.append(
            f"FreeCAD route vs recon, mesh file → STEP file on the same {len(done)} meshes: median time ratio "
            f"{np.median(ratios):.2f}× (FreeCAD / recon; range {min(ratios):.2f}–{max(ratios):.2f}×); "
            f"median faces FreeCAD {np.median([fc['faces_ours'] or 0 for _, fc in done]):.0f} vs recon "
            f"{np.median([o['faces_ours'] or 0 for o, _ in done]):.0f}; valid solids FreeCAD "
            f"{sum(1 for _, fc in done if fc.get('status') == 'ok')}/{len(done)}, recon "
            f"{sum(1 for o, _ in done if o.get('valid'))}/{len(done)}."
        )
        L.append("")
    part = part_speed_line(rows)
    if part:
        L += [part, ""]

    fx = [r for r in rows if r.get("group") == "fixtures"]
    if fx:
        L += ["## Fixtures (ground truth)", ""]
        L += _table(
            ["case", "status", "triangles", "faces true / ours", "types true", "types ours", "type agr.",
             "IoU≥0.5 faces / dec.", "mean IoU faces / dec.", "valid", "s (load/dec/fit/brep/dev/export)",
             "peak MiB"],
            [[r["case"], _status(r), _f(r.get("triangles"), "{:,}"), f"{_f(r.get('faces_true'), '{}')} / "
              f"{_f(r.get('faces_ours'), '{}')}", r.get("types_true") or "–", r.get("types_ours") or "–",
              _f(r.get("type_agreement"), "{:.0%}"),
              f"{_f(r.get('recovered'), '{:.0%}')} / {_f(r.get('dec_recovered'), '{:.0%}')}",
              f"{_f(r.get('mean_iou'), '{:.2f}')} / {_f(r.get('dec_mean_iou'), '{:.2f}')}",
              _valid(r), _stage_times(r), _f(r.get("peak_mb"), "{:.0f}")] for r in fx],
        )
        L.append("")
    scored = [r for r in rows if r.get("group") in ("fixtures", "meshes")]
    if scored:
        L += ["## Deviation, both ways (% of diagonal: max / p95 / RMS)", "",
              "Ours = the B-rep recon made; true = the true STEP (fixtures, ABC): mesh→true is the floor set by the "
              "mesh itself (its noise), ours↔true compares the two models on points exactly on each (no noise in it).",
              ""]
        L += _table(
            ["case", "mesh→ours", "ours→mesh", "mesh→true", "true→mesh", "ours→true", "true→ours"],
            [[r["case"], _dev(r, "m2s"), _dev(r, "s2m"), _dev(r, "true_m2s"), _dev(r, "true_s2m"),
              _dev(r, "ours_true"), _dev(r, "true_ours")] for r in scored],
        )
        L.append("")
    faced = [r for r in fx if r.get("face_fits") and r["case"].rsplit("/", 1)[-1] in FACE_TABLE_VARIANTS]
    if faced:
        L += ["## Per-face fit deviation (fixtures, " + ", ".join(FACE_TABLE_VARIANTS) + ")", "",
              "Each face's surface against the mesh points it was fitted to: max and RMS distance in % of the "
              "diagonal, and the max in tolerances (a fit is accepted at p99 ≤ 1 and max ≤ 2 tolerances; "
              "\"poor\" faces kept a surface outside that, \"filled\" ones got a filling B-spline).", ""]
        L += _table(["case", "face", "type", "status", "fit max % diag", "fit RMS % diag", "max / tolerance"],
                    [[r["case"], name, kind, status, _f(mx, "{:.3g}"), _f(rms, "{:.3g}"), _f(ratio, "{:.2f}")]
                     for r in faced for name, kind, status, mx, rms, ratio in r["face_fits"]])
        L.append("")
    ms = [r for r in rows if r.get("group") == "meshes"]
    if ms:
        L += ["## Real meshes", "", "Only `abc_00000050` has a true B-rep; its triangles take the true face nearest "
              "their centroid.", ""]
        L += _table(
            ["mesh", "status", "triangles", "faces ours", "types ours", "faces true", "type agr.", "IoU≥0.5",
             "valid", "s (load/dec/fit/brep/dev/export)", "STEP kB", "peak MiB", "error"],
            [[r["case"], _status(r), _f(r.get("triangles"), "{:,}"), _f(r.get("faces_ours"), "{}"),
              r.get("types_ours") or "–", _f(r.get("faces_true"), "{}"), _f(r.get("type_agreement"), "{:.0%}"),
              _f(r.get("recovered"), "{:.0%}"), _valid(r), _stage_times(r),
              _f((r.get("step_bytes") or 0) / 1000 if r.get("step_bytes") else None, "{:.0f}"),
              _f(r.get("peak_mb"), "{:.0f}"), r.get("error") or ""] for r in ms],
        )
        L.append("")
    fc_rows = [r for r in rows if r.get("group") == "freecad"]
    if fc_rows:
        ours = {o["case"]: o for o, _ in pairs}
        L += ["## FreeCAD route side by side", "",
              "FreeCAD: `Part.Shape.makeShapeFromMesh` → `removeSplitter` → solid → STEP, in `freecadcmd`; its "
              "in-process stage times (no start-up). recon: load + decompose + fit + B-rep + STEP export "
              "(deviation excluded; no start-up).", ""]
        body = []
        for fc in fc_rows:
            name = fc["case"].split(":", 1)[1]
            o = ours.get(name, {})
            ratio = (fc["convert_seconds"] / o["convert_seconds"]
                     if fc.get("convert_seconds") and o.get("convert_seconds") else None)
            body.append([
                name, _f(fc.get("triangles"), "{:,}"), _status(fc),
                f"{_f(fc.get('faces_ours'), '{}')} / {_f(o.get('faces_ours'), '{}')}",
                f"{_valid(fc)} / {_valid(o) if o else '–'}",
                f"{_f((fc.get('step_bytes') or 0) / 1000 if fc.get('step_bytes') else None, '{:,.0f}')} / "
                f"{_f((o.get('step_bytes') or 0) / 1000 if o.get('step_bytes') else None, '{:,.0f}')}",
                f"{_f(fc.get('convert_seconds'), '{:.1f}')} / {_f(o.get('convert_seconds'), '{:.1f}')}",
                _f(ratio, "{:.2f}×"),
                f"{_f(fc.get('peak_mb'), '{:.0f}')} / {_f(o.get('peak_mb'), '{:.0f}')}",
            ])
        L += _table(["mesh", "triangles", "FreeCAD status", "faces FreeCAD / recon", "valid FreeCAD / recon",
                     "STEP kB FreeCAD / recon", "s FreeCAD / recon", "time ratio", "peak MiB FreeCAD / recon"], body)
        L.append("")
    sc = sorted((r for r in rows if r.get("group") == "scaling"), key=lambda r: r.get("triangles") or 0)
    if sc:
        L += ["## Scaling", "", f"`{SCALING_PART}` remeshed like the fixtures and subdivided with projection onto the "
              "true faces. Seconds and peak MiB per stage; the last row is the log-log slope k of time ∝ n^k "
              "over the finished sizes.", ""]
        stages = [s for s in STAGES]
        body = []
        for r in sc:
            sec = r.get("seconds") or {}
            mem = r.get("stage_peak_mb") or {}
            body.append([r["case"], _status(r), _f(r.get("triangles"), "{:,}")]
                        + [f"{_f(sec.get(s), '{:.2f}')} / {_f(mem.get(s), '{:.0f}')}" for s in stages]
                        + [_f(r.get("convert_seconds"), "{:.1f}"), _f(r.get("peak_mb"), "{:.0f}"), _valid(r)])
        ok = [r for r in sc if r.get("seconds") and r.get("triangles")]
        if len(ok) >= 2:
            n = [r["triangles"] for r in ok]
            slope_row = ["slope k", "", ""]
            for s in stages:
                kt = loglog_slope(n, [r["seconds"].get(s) for r in ok])
                km = loglog_slope(n, [(r.get("stage_peak_mb") or {}).get(s) for r in ok])
                slope_row.append(f"{_f(kt, '{:.2f}')} / {_f(km, '{:.2f}')}")
            slope_row += [_f(loglog_slope(n, [r["convert_seconds"] for r in ok]), "{:.2f}"),
                          _f(loglog_slope(n, [r.get("peak_mb") for r in ok]), "{:.2f}"), ""]
            body.append(slope_row)
        L += _table(["case", "status", "triangles"] + [f"{s} s / MiB" for s in stages]
                    + ["mesh→STEP s", "peak MiB", "valid"], body)
        L.append("")
    bad = [r for r in rows if r.get("status") not in ("ok", None)]
    if bad:
        L += ["## Failures and invalid results", ""]
        L += [f"- `{r['case']}` — {r.get('status')}: {r.get('error') or ''}" for r in bad]
        L.append("")
    L += ["## Columns", "", "Every row of `bench.json` has these keys:", ""]
    L += [f"- `{k}`: {v}" for k, v in COLUMNS.items()]
    L.append("")
    return "\n".join(L)


def _valid(r) -> str:
    v = r.get("valid")
    if v is None:
        return "–"
    return "yes" if v else f"no ({r.get('shape_type') or '?'})"


def _dev(r, prefix) -> str:
    vals = [r.get(f"{prefix}_{k}") for k in ("max", "p95", "rms")]
    return "–" if all(v is None for v in vals) else " / ".join(_pct(v) for v in vals)


def _stage_times(r) -> str:
    sec = r.get("seconds") or {}
    return "/".join(_f(sec.get(s), "{:.1f}") for s in STAGES) if sec else "–"


# ----------------------------------------------------------------------------------------------------------------
# Command line


def _cases_for(groups, *, quick: bool) -> list[Case]:
    cases = []
    for g in groups:
        if g == "fixtures":
            cases += fixture_cases()
        elif g == "meshes":
            cases += mesh_cases()
        elif g == "freecad":
            cases += freecad_cases(quick=quick)
        elif g == "scaling":
            cases += scaling_cases()
    # FreeCAD's 100k part needs recon's run on it for the ratio (the scaling group has it; otherwise add it).
    names = {c.name for c in cases}
    if "scaling" not in groups and f"freecad:scaling/{_size_name(FREECAD_PART_TRIANGLES)}" in names:
        cases += scaling_cases(sizes=(FREECAD_PART_TRIANGLES,))
    return cases


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.run", description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="fixtures,meshes,freecad",
                        help=f"comma-separated groups among {','.join(GROUPS)} (default: fixtures,meshes,freecad; "
                        "scaling takes long)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default bench/out)")
    parser.add_argument("--quick", action="store_true",
                        help=f"FreeCAD only on meshes up to {QUICK_FREECAD_TRIANGLES:,} triangles")
    parser.add_argument("--only", default=None, help="run only cases whose name contains this text")
    parser.add_argument("--timeout", type=float, default=None, help="seconds per case (default: per group)")
    parser.add_argument("--merge", action="store_true", help="keep rows of other cases from OUT/bench.json")
    parser.add_argument("--worker", nargs=2, metavar=("SPEC", "RESULT"), help=argparse.SUPPRESS)
    parser.add_argument("--make-scaling", type=int, metavar="TRIANGLES",
                        help="only make (and cache) the scaling mesh of about this many triangles")
    args = parser.parse_args(argv)
    if args.make_scaling:
        logging.basicConfig(level=logging.INFO, format="%(message)s")
        print(_scaling_mesh(args.make_scaling))
        return 0
    if args.worker:
        logging.basicConfig(level=logging.WARNING, format="%(name)s: %(message)s")
        return _worker(*args.worker)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    groups = [g.strip() for g in args.cases.split(",") if g.strip()]
    unknown = [g for g in groups if g not in GROUPS]
    if unknown:
        parser.error(f"--cases: unknown group(s) {', '.join(unknown)}; expected some of {', '.join(GROUPS)}")
    cases = _cases_for(groups, quick=args.quick)
    if args.only:
        cases = [c for c in cases if args.only in c.name]
    command = "python -m bench.run " + " ".join(argv if argv is not None else sys.argv[1:])

    def progress(i, n, row):
        print(f"[{i + 1}/{n}] {row['case']}: {row['status']}"
              + (f" ({row['error']})" if row.get("error") else "")
              + f", {row.get('wall_seconds', 0):.0f} s", file=sys.stderr, flush=True)

    res = run_benchmark(cases, out=args.out, merge=args.merge, timeout=args.timeout, progress=progress,
                        meta={"command": command.strip(), "quick": args.quick})
    print(f"wrote {res.md_path} and {res.json_path} ({len(res.rows)} rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
