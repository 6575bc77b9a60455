"""``python -m bench.corpus --regime export --count 200 --out DIR``: run recon on the corpus, write the figures.

Each part runs in a worker process (``--jobs``), and recon in a subprocess of it with ``--timeout`` and
``--memory``; a finished case is written to ``DIR/rows/`` at once (a rerun skips it unless ``--force``). At the end
``DIR/corpus.json`` holds every row of the regimes run into DIR and ``DIR/CORPUS.md`` the summary and pictures.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import logging
import multiprocessing
import sys
import time
from pathlib import Path

from .measure import run_job
from .real import real_seeds
from .regimes import REGIMES
from .truth import DEFAULT_CACHE

log = logging.getLogger("bench.corpus")


def parse_seeds(text: str) -> list[int]:
    """``"0-9,20,30-31"`` → [0..9, 20, 30, 31]."""
    seeds = []
    for piece in text.split(","):
        lo, _, hi = piece.strip().partition("-")
        seeds.extend(range(int(lo), int(hi or lo) + 1))
    if any(s < 0 for s in seeds):
        raise ValueError("seeds are non-negative integers")
    return seeds


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.corpus", description=__doc__.splitlines()[0])
    p.add_argument("--regime", action="append", choices=REGIMES, help="regime (repeatable; default export)")
    p.add_argument("--count", type=int, default=20, help="parts: seeds 0..COUNT-1 (default 20)")
    p.add_argument("--seeds", help="seeds instead of --count, e.g. 0-199 or 3,5,40-49")
    p.add_argument("--real", action="store_true",
                   help="the real CAD parts of ../shared/parts instead of generated ones (all of them, or those "
                        "--seeds numbers in name order)")
    p.add_argument("--jobs", type=int, default=1, help="parts at a time (default 1)")
    p.add_argument("--timeout", type=float, default=600.0, help="seconds recon may take per part (default 600)")
    p.add_argument("--memory", type=int, default=4096, help="MiB of address space recon may take (default 4096)")
    p.add_argument("--out", type=Path, help="folder for rows/, corpus.json, CORPUS.md, pictures (required unless "
                   "--generate-only)")
    p.add_argument("--cache", type=Path, default=DEFAULT_CACHE, help="folder of the generated parts and meshes")
    p.add_argument("--force", action="store_true", help="redo cases whose row exists")
    p.add_argument("--freecad", action="store_true",
                   help="also time FreeCAD's mesh → shape → refine route on each mesh (added to rows run before)")
    p.add_argument("--no-recon", action="store_true",
                   help="with --freecad: only FreeCAD's route (rows a later run without it completes with recon)")
    p.add_argument("--generate-only", action="store_true",
                   help="only make the parts and meshes into --cache (no recon); times in CACHE/generation.json")
    p.add_argument("--worst", type=int, default=5, help="worst cases pictured per regime (default 5)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("build123d").setLevel(logging.WARNING)
    try:
        seeds = parse_seeds(args.seeds) if args.seeds else list(range(args.count))
        if args.real:
            seeds = real_seeds(parse_seeds(args.seeds) if args.seeds else None)
    except ValueError as err:
        print(f"--seeds: {err}", file=sys.stderr)
        return 2
    if args.jobs < 1 or args.timeout <= 0 or args.count < 0:
        print("--jobs, --timeout and --count must be positive", file=sys.stderr)
        return 2
    regimes = args.regime or ["export"]
    if args.generate_only:
        return _generate_only(seeds, regimes, args)
    if args.out is None:
        print("--out is required (unless --generate-only)", file=sys.stderr)
        return 2
    rows_dir = args.out / "rows"
    rows_dir.mkdir(parents=True, exist_ok=True)
    if args.no_recon and not args.freecad:
        print("--no-recon runs only FreeCAD's route: give --freecad too", file=sys.stderr)
        return 2
    kw = {"cache": args.cache, "keep": args.out / "steps", "timeout": args.timeout, "memory_mb": args.memory,
          "freecad": args.freecad, "recon": not args.no_recon}
    todo = []
    for r in regimes:
        for s in seeds:
            path = rows_dir / f"{r}_seed_{s:05d}.json"
            old = None if args.force or not path.exists() else json.loads(path.read_text())
            need_recon = old is None or (not args.no_recon and old.get("status") == "no-recon")
            need_fc = args.freecad and (old is None or "fc_status" not in old)
            if need_recon or need_fc:
                # an earlier row keeps what this run does not redo: recon's figures, or FreeCAD's
                todo.append((s, r, dict(kw, recon=need_recon and not args.no_recon, freecad=need_fc, old=old)))
    log.info("%d cases to run (%d already done)", len(todo), len(seeds) * len(regimes) - len(todo))
    t0 = time.perf_counter()
    with cf.ProcessPoolExecutor(args.jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = {pool.submit(run_job, job): job for job in todo}
        for fut in cf.as_completed(futures):
            seed, regime, _ = futures[fut]
            try:
                row = fut.result()
            except Exception as err:  # the worker process died (a crash outside recon's own subprocess)
                row = {"seed": seed, "regime": regime, "status": "worker", "message": f"{type(err).__name__}: {err}"}
            (rows_dir / f"{regime}_seed_{seed:05d}.json").write_text(json.dumps(row, indent=1))
            log.info("%s seed %d: %s, faces %s/%s, types %s, ours→true p95 %s %%, %s s%s", regime, seed,
                     row.get("status"), row.get("faces_ours"), row.get("faces_true"),
                     _g(row.get("type_agreement")), _g(row.get("ours_true_p95")), row.get("seconds"),
                     f"; FreeCAD {row['fc_status']}, {row.get('fc_faces')} faces, {row.get('fc_seconds')} s"
                     if row.get("fc_status") else "")
    log.info("ran %d cases in %.0f s", len(todo), time.perf_counter() - t0)
    from .report import write_report

    write_report(args.out, cache=args.cache, worst=args.worst)
    return 0


def _generate_only(seeds, regimes, args) -> int:
    from .generate import generate, timing_summary

    t0 = time.perf_counter()
    rows = generate(seeds, regimes, cache=args.cache, jobs=args.jobs, memory_mb=args.memory)
    log.info("generated %d cases in %.0f s", len(rows), time.perf_counter() - t0)
    for regime, s in timing_summary(rows).items():
        log.info("%s: %d cases, failed %s; (median, worst decile, max): %s", regime, s["n"], s["failed"] or "none",
                 ", ".join(f"{k} {tuple(round(x, 2) for x in s[k])}" for k in s if k not in ("n", "failed")))
    return 1 if any(r["status"] != "ok" for r in rows) else 0


def _g(x):
    return "–" if x is None else f"{x:.3g}"


if __name__ == "__main__":
    sys.exit(main())
