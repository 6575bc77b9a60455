"""``convert_many``: many meshes to B-reps on a Dask cluster, a summary row per mesh."""

from __future__ import annotations

import contextlib
import logging
import math
import os
import posixpath
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

from ..errors import InputError
from ._inputs import OUTPUT_FORMATS, Part, find_parts, finished_reports, fs_of, is_local, name_parts, run_key
from ._summary import BatchRow, SummaryWriter, write_html

if TYPE_CHECKING:  # (both load on use: the batch extra, and pandas where installed)
    import distributed
    import pandas

__all__ = ["convert_many", "BatchProgress"]

log = logging.getLogger(__name__)

#: Seconds to wait for a scheduler given by address before calling it unreachable.
CONNECT_TIMEOUT = 20


@dataclass(frozen=True)
class BatchProgress:
    """What :func:`convert_many` tells its ``progress`` callback: once before the first part (``row`` None, with the
    dashboard's link when one runs), then after every part."""

    done: int
    failed: int
    total: int
    row: BatchRow | None = None
    dashboard: str | None = None


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _memory_bytes(memory_limit: int | str | None) -> int | None:
    """``memory_limit`` in bytes: an int, or a size Dask reads ("4GB", "500MiB")."""
    if memory_limit is None:
        return None
    if isinstance(memory_limit, str):
        from dask.utils import parse_bytes

        try:
            memory_limit = parse_bytes(memory_limit)
        except ValueError:
            raise InputError(f"memory limit must be a size such as 4GB or 500MiB, got {memory_limit!r}") from None
    if not (isinstance(memory_limit, int) and memory_limit > 0):
        raise InputError(f"memory limit must be a positive number of bytes, got {memory_limit}")
    return memory_limit


def _check_options(fmt: str, tolerance, timeout, workers) -> None:
    if fmt not in OUTPUT_FORMATS:
        raise InputError(f"format must be one of {', '.join(OUTPUT_FORMATS)}, got {fmt!r}")
    if tolerance is not None and not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance)
                                      and tolerance > 0):
        raise InputError(f"tolerance must be a positive finite length, got {tolerance}")
    if timeout is not None and not (isinstance(timeout, (int, float)) and timeout > 0):
        raise InputError(f"timeout must be a positive number of seconds, got {timeout}")
    if workers is not None and not (isinstance(workers, int) and workers >= 1):
        raise InputError(f"workers must be at least 1, got {workers}")


def _prepare_out(out: str, parts: list[Part], suffix: str) -> str:
    """Make the output folder; refuse one that is a file, or outputs that would land on an input."""
    fs, root = fs_of(out)
    if fs.isfile(root):
        raise InputError(f"--out {out}: is a file, not a folder")
    local = is_local(fs)
    same = os.path.realpath if local else (lambda path: path)
    inputs = {same(fs_of(p.url)[1]) for p in parts if type(fs_of(p.url)[0]) is type(fs)}
    for p in parts:
        if same(posixpath.join(root, p.name + suffix)) in inputs:
            raise InputError(f"{p.url}: its output {p.name + suffix} would overwrite an input; choose another --out "
                             "or --format")
    fs.makedirs(root, exist_ok=True)
    return root if local else fs.unstrip_protocol(root)


def _client(client, scheduler: str | None, workers: int | None, memory_limit: int | None):
    """The client to use and what to close afterwards (nothing when the caller brought the client). A local
    cluster's workers get ``memory_limit`` as Dask's own worker memory limit (default: the machine's memory shared
    out among them)."""
    if client is not None:
        return client, []
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return (c := Client(scheduler, timeout=CONNECT_TIMEOUT)), [c]
        except (OSError, TimeoutError, ValueError) as err:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler}: {err}") from None
    # One thread per worker process: a conversion holds a core, and processes keep parts apart.
    cluster = LocalCluster(n_workers=workers or _cores(), threads_per_worker=1, processes=True, host="127.0.0.1",
                           memory_limit=memory_limit or "auto")
    c = Client(cluster)
    return c, [c, cluster]


def _dashboard(client, local: bool) -> str | None:
    import importlib.util

    # Without bokeh the scheduler still serves a "dashboard" that only says bokeh is missing: no link then.
    if local and importlib.util.find_spec("bokeh") is None:
        return None
    try:
        return client.dashboard_link if "dashboard" in client.scheduler_info().get("services", {}) else None
    except Exception:  # noqa: BLE001 — a link is a courtesy; no dashboard is no failure
        return None


def _failed(row: BatchRow) -> bool:
    return row.status in ("error", "invalid")


def convert_many(
    inputs: list[str | os.PathLike] | str | os.PathLike,
    out: str | os.PathLike,
    *,
    client: distributed.Client | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    tolerance: float | None = None,
    format: str = "step",
    timeout: float | None = None,
    force: bool = False,
    preview: bool = True,
    deviation: bool = True,
    memory_limit: int | str | None = None,
    progress: Callable[[BatchProgress], None] | None = None,
) -> pandas.DataFrame | list[BatchRow]:
    """Convert many meshes on a Dask cluster; each one as ``recon.convert`` would, in its own process.

    Parameters
    ----------
    inputs : path, URL, folder or glob pattern, or a list of them
        Folders are searched recursively for the mesh formats recon reads (STL, OBJ, PLY, OFF, 3MF, GLB). Any
        fsspec URL works where the workers can reach it.
    out : path or URL
        Output folder (made if missing): ``NAME.step`` (or ``.brep``/``.stl``), ``NAME.report.json``,
        ``NAME.preview.png`` per input, ``summary.csv`` and ``summary.html``.
    client : distributed.Client, optional
        An existing client (a notebook's). Default: a local cluster of ``workers`` processes, or ``scheduler``.
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:port``).
    workers : int, optional
        Worker processes of the local cluster (default: the cores available).
    tolerance : float, optional
        As :func:`recon.convert`'s.
    format : {"step", "iges", "brep", "stl"}
    timeout : float, optional
        Seconds one part may take; past it the part is an ``error`` row (default: no limit).
    force : bool
        Convert again parts an earlier run finished (default: skip them).
    preview : bool
        Write a preview picture per part (for ``summary.html``).
    deviation : bool
        Measure each result's deviation from its mesh (``recon convert --no-deviation`` when False: faster, and the
        row's message says the result is NOT verified).
    memory_limit : int or str, optional
        Bytes (or a size such as ``"4GB"``). For the local cluster this function starts it is Dask's worker memory
        limit; for every cluster, the most one part's process may use: past it the process is killed and the part is
        an ``error`` row that says so (default: the worker's own memory limit).
    progress : callable(BatchProgress), optional

    Returns
    -------
    pandas.DataFrame or list of BatchRow
        One row per input, in the order they finished; a DataFrame where pandas is installed.
    """
    from .. import __version__

    specs = [str(s) for s in ([inputs] if isinstance(inputs, (str, os.PathLike)) else list(inputs))]
    _check_options(format, tolerance, timeout, workers)
    memory_limit = _memory_bytes(memory_limit)
    if client is not None and (scheduler is not None or workers is not None):
        raise InputError("give either a client, a scheduler address or a number of workers")
    if scheduler is not None and workers is not None:
        raise InputError("give either a scheduler address or a number of workers, not both")
    out = str(out)
    suffix = OUTPUT_FORMATS[format]
    parts = name_parts(find_parts(specs, exclude=out))
    out = _prepare_out(out, parts, suffix)

    jobs: list = []
    rows: list = []
    owned: list = []
    keys = [run_key(part, version=__version__, tolerance=tolerance, fmt=format, deviation=deviation) for part in parts]
    earlier = [None] * len(parts) if force else finished_reports(out, parts, keys)
    writer = SummaryWriter(out)
    try:
        for part, key, report in zip(parts, keys, earlier):
            if report is not None:
                dev = (report.get("deviation") or {}).get("mesh_to_shape") or {}
                rows.append(BatchRow(part.url, posixpath.join(out, part.name + suffix), "skipped", report["n_faces"],
                                     bool(report["validity"]["ok"]), dev.get("p95_pct"), 0.0, part.note))
                writer.add(rows[-1])
            else:
                jobs.append({"url": part.url, "name": part.name, "note": part.note, "out": out, "suffix": suffix,
                             "tolerance": tolerance, "preview": preview, "deviation": deviation,
                             "timeout": timeout, "key": key,
                             # A local cluster started here has it as its workers' Dask limit, which the task reads.
                             "memory_limit": None if client is None and scheduler is None else memory_limit,
                             "size": part.size})
        rows += _run_jobs(jobs, rows, writer, owned, client=client, scheduler=scheduler, workers=workers,
                          memory_limit=memory_limit, progress=progress)
    finally:
        # The summaries first: after Ctrl-C the command has ~2 s to end, and a local cluster takes longer to close.
        try:
            writer.close()
            write_html(out, rows, title=f"recon batch: {out}", previews=preview)
        finally:
            for thing in owned:
                thing.close()
    try:
        import pandas as pd
    except ImportError:
        return rows
    from dataclasses import asdict

    frame = pd.DataFrame([asdict(r) for r in rows], columns=list(BatchRow.__dataclass_fields__))
    return frame.astype({"faces": "Int64"})  # a count, empty where nothing was written (not a float NaN)


def _run_jobs(jobs, done_rows, writer, owned, *, client, scheduler, workers, memory_limit,
              progress) -> list[BatchRow]:
    """Submit the jobs, collect their rows as they finish. On Ctrl-C the futures are cancelled and what finished
    stays in the summary (the caller writes it). A client or cluster made here is put in ``owned`` for the
    caller to close."""
    total, told = len(done_rows) + len(jobs), [0, 0]  # parts told to `progress`, and failed among them

    def tell(row=None, dashboard=None):
        if row is not None:
            told[0] += 1
            told[1] += _failed(row)
        if progress is not None:
            progress(BatchProgress(told[0], told[1], total, row, dashboard))

    new: list[BatchRow] = []
    if not jobs:
        tell()
        for row in done_rows:
            tell(row)
        return new
    from distributed import as_completed

    from ._task import run_part

    client, made = _client(client, scheduler, workers, memory_limit)
    owned.extend(made)
    futures = []
    try:
        tell(dashboard=_dashboard(client, local=len(made) == 2))
        for row in done_rows:
            tell(row)
        # The largest parts first (Dask runs higher priority first): the batch's tail is then small parts.
        futures = [client.submit(run_part, job, key=f"recon-part-{job['name']}-{os.urandom(4).hex()}",
                                 priority=job["size"], pure=False) for job in jobs]
        by_key = {f.key: job for f, job in zip(futures, jobs)}
        for future in as_completed(futures):
            job = by_key[future.key]
            try:
                row = BatchRow(**future.result())
            except Exception as err:  # noqa: BLE001 — the worker died (KilledWorker), or cannot run recon at all
                row = BatchRow(job["url"], "", "error", None, None, None, 0.0, task_failure(client, err))
            new.append(row)
            writer.add(row)
            tell(row)
        return new
    except BaseException:
        with contextlib.suppress(Exception):  # one request for all: each future's own cancel is a round trip
            client.cancel(futures)
        done_rows.extend(new)  # the caller's summary keeps what finished before the interruption
        new.clear()
        raise


def task_failure(client, err: BaseException) -> str:
    """One line on a part whose task raised: its workers died (when Dask's nanny restarted the last one for
    passing its memory limit, that), or the task could not run recon at all."""
    if type(err).__name__ != "KilledWorker":
        return " ".join(f"the task failed on its worker: {type(err).__name__}: {err}".split())[:300]
    tries = getattr(err, "allowed_failures", 0) + 1
    tried = f"tried on {tries} worker{'s' if tries > 1 else ''}"
    last = getattr(getattr(err, "last_worker", None), "address", None)
    try:
        events = client.get_events("worker-restart-memory")
    except Exception:  # noqa: BLE001 — the events only sharpen the message
        events = ()
    for _, event in events:
        if event.get("worker") == last:
            return (f"killed by the memory limit: its worker's memory ({event.get('rss', 0) / 2**20:,.0f} MiB) "
                    f"passed Dask's limit and its nanny restarted it ({tried}; last {last})")
    return f"its worker died running it ({tried}; last {last}): a crash, or the machine or its scheduler ended it"
