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
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from recon._io import atomic_path, write_json

from .cases import (
    COLUMNS,
    DEFAULT_OUT,
    FREECAD_PART_TRIANGLES,
    GROUPS,
    MEMORY_LIMITS,
    QUICK_FREECAD_TRIANGLES,
    REPO,
    Case,
    child_env,
    fixture_cases,
    freecad_cases,
    mesh_cases,
    scaling_cases,
    scaling_mesh,
    size_name,
)
from .measure import one_line, pid_rss_mb, plain, worker
from .report import render_markdown

__all__ = ["BenchResult", "run_case", "run_benchmark", "main"]


@dataclass(frozen=True)
class BenchResult:
    """Result of :func:`run_benchmark`: the rows (dicts with :data:`COLUMNS`) and the files written."""

    rows: tuple
    json_path: Path
    md_path: Path


# ----------------------------------------------------------------------------------------------------------------
# Running a case in a subprocess


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
                env=child_env(),
            )
            while True:
                pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
                if pid:
                    break
                if time.perf_counter() - t0 > limit:
                    killed_for = f"no result within {limit:g} s: killed"
                elif pid_rss_mb(proc.pid) > mem_limit:
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
            row.update(status="crashed", error=one_line(f"{where}subprocess {how}; last log line: {last}"))
        if row["status"] in ("timeout", "crashed", "error"):
            row["stderr_tail"] = [one_line(s) for s in stderr_tail]
        row["wall_seconds"] = round(wall, 3)
        if row.get("peak_mb") is None:
            row["peak_mb"] = round(usage.ru_maxrss / 1024.0, 1)
    return row


# ----------------------------------------------------------------------------------------------------------------
# The run


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
        rows.append(plain(row))
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
    if "scaling" not in groups and f"freecad:scaling/{size_name(FREECAD_PART_TRIANGLES)}" in names:
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
        print(scaling_mesh(args.make_scaling))
        return 0
    if args.worker:
        logging.basicConfig(level=logging.WARNING, format="%(name)s: %(message)s")
        return worker(*args.worker)
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
