"""``python -m bench.corpus --generate-only``: fill the cache with parts and meshes, no recon run.

Each case is generated in a worker process limited to ``--memory`` MiB of address space (the limit recon gets), so a
part or mesh that needs more is a failed case, not a stalled machine; a worker that dies is replaced and the case
recorded. Per case: the seconds to make the part (0 when cached) and the mesh, and the worker's peak resident memory
while making them. ``CACHE/generation.json`` keeps the latest record of every (regime, seed) made or checked.
"""

from __future__ import annotations

import concurrent.futures as cf
import json
import logging
import multiprocessing
import resource
import time
from pathlib import Path

import numpy as np

from .truth import materialise

log = logging.getLogger("bench.corpus")


def _init_worker(memory_mb: int | None) -> None:
    logging.getLogger("build123d").setLevel(logging.WARNING)
    if memory_mb:
        resource.setrlimit(resource.RLIMIT_AS, (memory_mb << 20, memory_mb << 20))


def _peak_mb(reset: bool = False) -> float | None:
    """This process's peak resident memory (VmHWM) in MiB; ``reset`` starts a new peak (Linux clear_refs 5)."""
    try:
        if reset:
            Path("/proc/self/clear_refs").write_text("5")
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


def generate_job(job) -> dict:
    """Make (or read from the cache) the part and mesh of a ``(seed, regime, cache)`` job; never raises."""
    seed, regime, cache = job
    row = {"seed": int(seed), "regime": regime}
    _peak_mb(reset=True)
    t0 = time.perf_counter()
    try:
        truth = materialise(seed, regime, Path(cache))
    except MemoryError:
        row.update(status="memory", message="MemoryError")
    except Exception as err:  # a generator failure is a bug of the corpus: recorded with its reason
        row.update(status="generator", message=f"{type(err).__name__}: {err}"[:300])
    else:
        row.update(status="ok", family=truth.meta["family"], faces_true=truth.meta["faces"],
                   triangles=truth.info["triangles"], watertight=truth.info["watertight"],
                   part_seconds=truth.meta.get("generate_seconds"), mesh_seconds=truth.info.get("generate_seconds"))
    row["seconds"] = round(time.perf_counter() - t0, 2)
    row["peak_mb"] = _peak_mb()
    return row


def generate(seeds, regimes, *, cache: Path, jobs: int = 1, memory_mb: int | None = 4096) -> list[dict]:
    """Generate every (regime, seed) into ``cache``; returns the rows (also merged into ``cache/generation.json``).

    At most ``jobs`` cases are in flight, so when a worker dies the case that killed it is among them: alone it is
    charged; with others they are all run again one at a time."""
    # seed by seed (every regime of a seed, then the next): a run stopped early has whole seeds
    todo = [(s, r, str(cache)) for s in seeds for r in regimes]
    todo.reverse()  # popped from the end
    rows = []
    ctx = multiprocessing.get_context("spawn")
    while todo:
        with cf.ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_init_worker, initargs=(memory_mb,)) as pool:
            running = {}
            while todo or running:
                while todo and len(running) < jobs:
                    job = todo.pop()
                    running[pool.submit(generate_job, job)] = job
                done, _ = cf.wait(running, return_when=cf.FIRST_COMPLETED)
                try:
                    for fut in done:
                        rows.append(_logged(fut.result()))
                        del running[fut]
                except cf.process.BrokenProcessPool as err:
                    if len(running) == 1:
                        job = running.popitem()[1]
                        rows.append(_logged({"seed": job[0], "regime": job[1], "status": "worker",
                                             "message": f"the worker died: {err}"[:200]}))
                    else:
                        todo.extend(reversed(list(running.values())))
                        jobs = 1
                    break
    _merge(Path(cache) / "generation.json", rows)
    return rows


def _logged(row: dict) -> dict:
    log.info("generate %s seed %d: %s, %s triangles, %s s, peak %s MiB%s", row["regime"], row["seed"], row["status"],
             row.get("triangles"), row.get("seconds"), _r(row.get("peak_mb")),
             f" ({row['message']})" if row.get("message") else "")
    return row


def _r(x):
    return "–" if x is None else f"{x:.0f}"


def _merge(path: Path, rows: list[dict]) -> None:
    old = json.loads(path.read_text()) if path.exists() else []
    key = {(r["regime"], r["seed"]): r for r in old}
    key.update({(r["regime"], r["seed"]): r for r in rows})
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(sorted(key.values(), key=lambda r: (r["regime"], r["seed"])), indent=1))


def timing_summary(rows: list[dict]) -> dict:
    """Per regime: cases, failures, median and worst decile (90th percentile) of seconds and peak MiB."""
    out = {}
    for regime in sorted({r["regime"] for r in rows}):
        rs = [r for r in rows if r["regime"] == regime]
        s = {"n": len(rs), "failed": [r["seed"] for r in rs if r["status"] != "ok"]}
        for key in ("seconds", "part_seconds", "mesh_seconds", "peak_mb", "triangles"):
            v = np.array([r[key] for r in rs if r.get(key) is not None], float)
            if v.size:
                s[key] = (float(np.median(v)), float(np.percentile(v, 90, method="higher")), float(v.max()))
        out[regime] = s
    return out
