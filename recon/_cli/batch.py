"""``recon batch``: many meshes to B-reps on a Dask cluster, with a summary (``recon.convert_many``)."""

from __future__ import annotations

import logging
import os
import sys
import time


def add_parser(sub):
    p = sub.add_parser(
        "batch",
        help="convert many meshes on a Dask cluster (this machine's cores, or a cluster), with a summary",
        description="Convert every mesh named (files, folders searched for STL/OBJ/PLY/OFF/3MF/GLB, glob patterns; "
        "local paths or fsspec URLs) as `recon convert` would, each in its own process: DIR/NAME.step, "
        "DIR/NAME.report.json, DIR/NAME.preview.png, DIR/summary.csv (written as parts finish) and DIR/summary.html. "
        "A rerun skips parts already converted good with the same recon and options. Exit 0 when every part is "
        "good, 1 when some are invalid or failed, 2 for bad arguments.",
    )
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="mesh file, folder or glob pattern (path or URL)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (path or URL; made if missing)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, metavar="N", help="worker processes of a local cluster, one part each "
                       "at a time (default: the cores available)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="use a running Dask cluster (tcp://HOST:PORT)")
    p.add_argument("--tolerance", type=float, metavar="T", help="fit tolerance in mesh units, for every part "
                   "(default: each part's own, as recon convert)")
    p.add_argument("--format", choices=["step", "iges", "brep", "stl"], default="step",
                   help="output format (default: step; iges for importers that read no STEP)")
    p.add_argument("--timeout", type=float, metavar="S", help="seconds one part may take before it is stopped and "
                   "counted as failed (default: no limit)")
    p.add_argument("--memory-limit", metavar="SIZE", help="memory per worker of the local cluster (Dask's worker "
                   "memory limit, e.g. 4GB) and per part on any cluster: a part past it is stopped and counted as "
                   "failed (default: the machine's memory shared among the workers, or the cluster workers' own)")
    p.add_argument("--force", action="store_true", help="convert again the parts an earlier run finished")
    p.add_argument("--no-deviation", action="store_true", help="skip measuring each result's deviation (faster; "
                   "results are then NOT verified, as with recon convert --no-deviation)")
    p.add_argument("--no-preview", action="store_true", help="write no preview pictures (faster)")
    p.set_defaults(func=run)
    return p


def _message(row) -> str:
    # recon's messages about a file start with its path, which the line already shows.
    return row.message.removeprefix(f"{row.input}: ")


class _Bar:
    """A tqdm bar on a terminal: parts done, failed, rate and time left."""

    def __init__(self, stream):
        self.stream, self.bar = stream, None

    def __call__(self, p) -> None:
        if p.row is None:
            from tqdm import tqdm

            if p.dashboard:
                print(f"Dask dashboard: {p.dashboard}", file=self.stream)
            self.bar = tqdm(total=p.total, unit="part", file=self.stream, dynamic_ncols=True)
            return
        if p.row.status in ("error", "invalid"):
            self.bar.write(f"{p.row.status} {p.row.input}: {_message(p.row)}", file=self.stream)
        self.bar.set_postfix(failed=p.failed, refresh=False)
        self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


class _Lines:
    """One line per finished part (logs, pipes)."""

    def __init__(self, stream):
        self.stream, self.t0 = stream, time.monotonic()

    def __call__(self, p) -> None:
        if p.row is None:
            if p.dashboard:
                print(f"Dask dashboard: {p.dashboard}", file=self.stream, flush=True)
            return
        r = p.row
        what = f"{r.faces} faces, {r.seconds:.1f} s" if r.faces is not None else _message(r)
        if r.faces is not None and r.message:
            what += f"; {r.message}"
        print(f"[{p.done}/{p.total}] {r.status} {r.input}: {what}", file=self.stream, flush=True)

    def close(self) -> None:
        pass


def run(args) -> int:
    from ..batch import convert_many

    if not args.verbose:
        # Dask's own notices (ports taken, tasks cancelled on Ctrl-C, workers closing) are not the user's business
        # unless asked with -v. The variable reaches the local cluster's worker processes too.
        os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "error")
        import distributed  # noqa: F401  (its import sets its loggers' levels: quieten them after it)

        for name in ("distributed", "tornado"):
            logging.getLogger(name).setLevel(logging.ERROR)
    show = _Bar(sys.stderr) if sys.stderr.isatty() else _Lines(sys.stderr)
    t0 = time.monotonic()
    try:
        rows = convert_many(args.inputs, args.out, scheduler=args.scheduler, workers=args.workers,
                            tolerance=args.tolerance, format=args.format, timeout=args.timeout, force=args.force,
                            preview=not args.no_preview, deviation=not args.no_deviation,
                            memory_limit=args.memory_limit, progress=show)
    finally:
        show.close()
    statuses = list(rows["status"]) if hasattr(rows, "columns") else [r.status for r in rows]
    counts = ", ".join(f"{statuses.count(s)} {s}" for s in ("ok", "skipped", "invalid", "error") if statuses.count(s))
    if not args.quiet:  # the result on stdout; the per-part lines above are progress, on stderr
        print(f"{len(statuses)} parts in {time.monotonic() - t0:.1f} s: {counts}; summary in {args.out}/summary.csv "
              "and summary.html")
    return 1 if any(s in ("invalid", "error") for s in statuses) else 0
