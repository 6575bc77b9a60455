"""recon batch on this machine: throughput on 1 and 2 workers, scaling efficiency, per-part overhead, isolation.

    python bench/bench_batch.py overhead             # Dask no-op round trip, runner protocol round trip
    python bench/bench_batch.py isolation            # a crashing part: in the worker vs in a runner process
    python bench/bench_batch.py throughput [--corpus DIR] [--workers 1 2] [--timeout S] [--memory-limit 4GB]
    python bench/bench_batch.py alone [--corpus DIR] [--timeout S]   # recon convert per part, for comparison

Prints Markdown rows for bench/batch.md. Run it alone: it measures wall time on every core.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "fixtures" / "data"
MESH_DIR = ROOT.parent / "shared" / "meshes"  # ../shared beside the checkout, as CI lays it out
SCANS = ["block", "casting", "fandisk", "fandisk-b", "fandisk-b_noisy0.1", "joint", "rocker-arm", "rocker-arm2500"]


def _noop(x):
    return x


def overhead(n: int = 2000) -> None:
    """The scheduling cost of one part: a no-op task's round trip, one at a time (latency) and n at once
    (throughput of the scheduler and the comms); then the runner's protocol round trip for a part that fails at
    once (staging, the JSON lines, no conversion)."""
    from distributed import Client, LocalCluster

    from recon.batch._task import run_part

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1") as cluster, \
            Client(cluster) as client:
        client.submit(_noop, 0, pure=False).result()
        t = time.perf_counter()
        for i in range(50):
            client.submit(_noop, i, pure=False).result()
        serial = (time.perf_counter() - t) / 50
        t = time.perf_counter()
        client.gather(client.map(_noop, range(n), pure=False))
        batch = (time.perf_counter() - t) / n
        print(f"| Dask no-op task, one at a time (submit → result) | {serial * 1e3:.1f} ms |")
        print(f"| Dask no-op task, {n} at once on 2 workers (wall / n) | {batch * 1e3:.2f} ms |")
        out = tempfile.mkdtemp()
        job = {"url": str(Path(out) / "missing.stl"), "name": "missing", "note": "", "out": out, "suffix": ".step",
               "tolerance": None, "preview": False, "timeout": None, "key": {}, "size": 0}
        t = time.perf_counter()
        client.submit(run_part, job, pure=False).result()  # starts the runner (imports recon and OCP)
        start = time.perf_counter() - t
        times = []
        for _ in range(20):
            t = time.perf_counter()
            row = client.submit(run_part, dict(job), pure=False).result()
            times.append(time.perf_counter() - t)
        assert row["status"] == "error"
        print(f"| runner start (import recon + OpenCascade), once per worker and after a crash | {start:.2f} s |")
        print(f"| part round trip through Dask and the runner, no conversion (median of 20) | "
              f"{statistics.median(times) * 1e3:.1f} ms |")
        shutil.rmtree(out)


def _abort_in_worker(x):
    os.abort()


def _set_env(name, value):
    if value is None:
        os.environ.pop(name, None)
    else:
        os.environ[name] = value


def _sleep(x):
    time.sleep(x)
    return x


def isolation() -> None:
    """What a crashing part costs when the worker runs it itself (nanny restart, allowed-failures retries) and when
    the worker's runner process runs it."""
    from distributed import Client, LocalCluster

    from recon.batch._task import run_part

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1") as cluster, \
            Client(cluster) as client:
        good = client.submit(_sleep, 2.0, pure=False)
        t = time.perf_counter()
        bad = client.submit(_abort_in_worker, 0, pure=False)
        try:
            bad.result()
            outcome = "returned"
        except Exception as err:  # noqa: BLE001 — KilledWorker expected
            outcome = type(err).__name__
        crash = time.perf_counter() - t
        good_ok = good.result() == 2.0
        client.wait_for_workers(2, timeout=120)
        back = time.perf_counter() - t
        print(f"| in the worker: os.abort() in a task | {outcome} after {crash:.1f} s (the task retried on "
              f"restarted workers until allowed-failures); both workers back after {back:.1f} s; a task beside it "
              f"{'finished' if good_ok else 'was lost'} |")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1") as cluster, \
            Client(cluster) as client:
        out = tempfile.mkdtemp()
        shutil.copy(DATA / "prism_coarse.stl", Path(out) / "boom.stl")
        job = {"url": str(Path(out) / "boom.stl"), "name": "boom", "note": "", "out": out + "/o", "suffix": ".step",
               "tolerance": None, "preview": False, "timeout": None, "key": {}, "size": 0}
        os.makedirs(out + "/o")
        client.run(_set_env, "RECON_TEST_ABORT", "boom.stl")  # before the runners start: they inherit it
        for w in client.scheduler_info()["workers"]:  # every worker's runner started: the crash is timed alone
            client.submit(run_part, dict(job, url="/nonexistent.stl"), workers=[w], pure=False).result()
        t = time.perf_counter()
        row = client.submit(run_part, job, pure=False).result()
        crash = time.perf_counter() - t
        print(f"| in the runner: os.abort() in the conversion | `{row['status']}` row after {crash:.2f} s "
              f"({row['message']}); the worker lives; the next part starts a new runner |")
        client.run(_set_env, "RECON_TEST_ABORT", None)
        shutil.rmtree(out)


def _triangles(stl: Path) -> int | None:
    """The triangle count the corpus records beside its mesh (``seed_N.json``), if it does."""
    info = stl.with_suffix(".json")
    if not info.exists():
        return None
    import json

    return json.loads(info.read_text()).get("triangles")


def _inputs(corpus: str | None, count: int, *, max_triangles: int | None = None,
            scans: list[str] = SCANS) -> list[str]:
    """The export parts (the first ``count`` STL files of ``corpus`` by name with at most ``max_triangles``, else
    the fixtures) and the real scans named."""
    found = sorted(Path(corpus).resolve().glob("*.stl") if corpus else DATA.glob("*.stl"))
    if max_triangles:
        found = [p for p in found if (_triangles(p) or 0) <= max_triangles]
    parts = [str(p) for p in found][:count] if corpus else [str(p) for p in found]
    scans = [str(MESH_DIR / f"{s}.off") for s in scans if (MESH_DIR / f"{s}.off").exists()]
    print(f"parts: {len(parts)} from {corpus or 'fixtures/data'}, scans: {len(scans)}", file=sys.stderr)
    return parts + scans


def throughput(inputs: list[str], workers: list[int], *, timeout: float | None, memory_limit: str | None,
               save: Path) -> None:
    """Every input on a fresh local cluster of n workers (its start timed apart); the rows kept in ``save``."""
    from distributed import Client, LocalCluster

    from recon.batch import convert_many

    base = {}
    save.mkdir(parents=True, exist_ok=True)
    for n in workers:
        out = tempfile.mkdtemp(prefix=f"bench-batch-{n}-")
        t = time.perf_counter()
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                          memory_limit=memory_limit or "auto") as cluster, Client(cluster) as client:
            start = time.perf_counter() - t
            t = time.perf_counter()
            rows = convert_many(inputs, out, client=client, preview=False, force=True, timeout=timeout,
                                memory_limit=memory_limit)
            wall = time.perf_counter() - t
        rows.to_csv(save / f"workers{n}.csv", index=False)
        busy = float(rows["seconds"].sum())
        counts = rows["status"].value_counts().to_dict()
        base.setdefault("wall", wall * n)
        print(f"| {n} | {len(rows)} | {start:.1f} | {wall:.1f} | {60 * len(rows) / wall:.2f} | {busy:.1f} | "
              f"{busy / (n * wall):.2f} | {base['wall'] / (n * wall):.2f} | "
              f"{', '.join(f'{v} {k}' for k, v in counts.items())} |", flush=True)
        shutil.rmtree(out)


def alone(inputs: list[str], *, timeout: float | None, save: Path) -> None:
    """Each input through ``python -m recon convert`` (one process per part, as a shell loop does), its wall
    time beside the part's time inside ``recon batch`` (``save/workers1.csv``)."""
    import csv
    import subprocess

    batch = {}
    if (save / "workers1.csv").exists():
        with open(save / "workers1.csv", newline="") as fh:
            batch = {r["input"]: r for r in csv.DictReader(fh)}
    out = Path(tempfile.mkdtemp(prefix="bench-alone-"))
    rows = []
    for mesh in inputs:
        cmd = [sys.executable, "-m", "recon", "convert", mesh, str(out / "part.step"), "--jobs", "1", "-q"]
        t = time.perf_counter()
        try:
            code = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=timeout).returncode
        except subprocess.TimeoutExpired:
            code = "timeout"
        wall = time.perf_counter() - t
        b = batch.get(mesh, {})
        rows.append((mesh, code, wall, b.get("status"), float(b["seconds"]) if b else None))
        print(f"{Path(mesh).name}: convert exit {code} {wall:.1f} s; in batch {b.get('status')} "
              f"{b.get('seconds')} s", file=sys.stderr, flush=True)
        with open(save / "alone.csv", "w", newline="") as fh:
            csv.writer(fh).writerows([("input", "exit", "wall", "batch_status", "batch_seconds"), *rows])
    both = [(w, s) for _, c, w, st, s in rows if c in (0, 1) and st in ("ok", "invalid")]
    total_alone, total_batch = sum(w for w, _ in both), sum(s for _, s in both)
    print(f"| {len(both)} parts converted both ways | recon convert, one process each: {total_alone:.1f} s | "
          f"inside recon batch (the part's own time): {total_batch:.1f} s | "
          f"difference per part: {(total_alone - total_batch) / max(len(both), 1):.2f} s |")
    shutil.rmtree(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=["overhead", "isolation", "throughput", "alone"])
    ap.add_argument("--corpus", help="folder of export-corpus STL files (default: the fixtures)")
    ap.add_argument("--count", type=int, default=40, help="corpus parts taken, first by name (default 40)")
    ap.add_argument("--max-triangles", type=int, help="only corpus parts of at most this many triangles")
    ap.add_argument("--scans", nargs="*", default=SCANS, help="real meshes of ../shared/meshes taken (names)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--timeout", type=float, help="seconds per part (swept corpus parts can run for many minutes)")
    ap.add_argument("--memory-limit", help="Dask's memory limit per worker, and per part (e.g. 4GB)")
    ap.add_argument("--save", type=Path, default=Path(tempfile.gettempdir()) / "bench-batch",
                    help="folder for the rows of each run (CSV)")
    args = ap.parse_args()
    if args.what == "overhead":
        overhead()
    elif args.what == "isolation":
        isolation()
    elif args.what == "throughput":
        inputs = _inputs(args.corpus, args.count, max_triangles=args.max_triangles, scans=args.scans)
        throughput(inputs, args.workers, timeout=args.timeout, memory_limit=args.memory_limit, save=args.save)
    else:
        alone(_inputs(args.corpus, args.count, max_triangles=args.max_triangles, scans=args.scans),
              timeout=args.timeout, save=args.save)


if __name__ == "__main__":
    main()
