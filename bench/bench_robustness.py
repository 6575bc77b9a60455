"""Robustness sweep of ``recon convert``: every fixture variant and every real mesh, one subprocess each.

Each case runs ``python -m recon convert MESH OUT.step --report R.json`` with an address-space limit
(``RLIMIT_AS``) and a wall-clock timeout, and the table records exit code / signal / last error line /
time / peak resident memory (the child's own ``ru_maxrss`` from ``os.wait4``).

Usage: ``python bench/bench_robustness.py [--jobs 2] [--mem-gb 6] [--timeout 300] [--only SUBSTR ...]
[--out bench/out_robustness]``; writes ``robustness.md`` and ``robustness.json`` in the output folder.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
FIXTURES = REPO / "fixtures" / "data"
MESHES = REPO.parent / "shared" / "meshes"  # ../shared beside the checkout, as CI lays it out
PARTS = ("box_chamfer", "box_fillet", "lofted", "plate_holes", "pocket", "prism", "revolved")
VARIANTS = ("clean", "noisy05", "noisy20", "coarse", "open")


def cases():
    out = [(f"{p}/{v}", FIXTURES / f"{p}_{v}.stl") for p in PARTS for v in VARIANTS]
    for m in sorted(MESHES.glob("*")):
        if m.suffix in (".stl", ".off", ".obj", ".ply"):
            out.append((f"mesh/{m.stem}", m))
    return out


def run_case(name, path, outdir: Path, mem_gb: float, timeout: float):
    stem = name.replace("/", "_")
    step = outdir / f"{stem}.step"
    report = outdir / f"{stem}.json"
    limit = int(mem_gb * 2**30)

    def limits():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        os.setsid()

    t0 = time.perf_counter()
    with open(outdir / f"{stem}.log", "wb") as log:
        proc = subprocess.Popen([sys.executable, "-m", "recon", "convert", str(path), str(step), "--report",
                                 str(report)], stdout=log, stderr=subprocess.STDOUT, preexec_fn=limits, cwd=REPO)
        deadline = t0 + timeout
        timed_out = False
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                os.killpg(proc.pid, signal.SIGKILL)
                timed_out = True
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.2)
    secs = time.perf_counter() - t0
    text = (outdir / f"{stem}.log").read_text(errors="replace")
    lines = [ln for ln in text.splitlines() if ln.strip()]
    traceback = "Traceback (most recent call last)" in text
    err = next((ln for ln in reversed(lines) if "Error" in ln or "error" in ln), lines[-1] if lines else "")
    row = {"case": name, "seconds": round(secs, 1), "peak_mb": round(usage.ru_maxrss / 1024),
           "rc": os.WEXITSTATUS(status) if os.WIFEXITED(status) else None,
           "signal": os.WTERMSIG(status) if os.WIFSIGNALED(status) else None,
           "timeout": timed_out, "traceback": traceback, "error": err[:200] if (traceback or
                                                                             not os.WIFEXITED(status) or
                                                                             os.WEXITSTATUS(status) == 2) else ""}
    if report.exists():
        r = json.loads(report.read_text())
        row.update(faces=r["n_faces"], valid=r["validity"]["ok"], shape=r["validity"]["shape_type"],
                   dev_p95_pct=(r.get("deviation") or {}).get("mesh_to_shape", {}).get("p95_pct"),
                   dev_seconds=r["seconds"].get("deviation"))
    return row


def status(row):
    if row["timeout"]:
        return "TIMEOUT"
    if row["signal"]:
        return f"SIGNAL {row['signal']}"
    if row["traceback"]:
        return "TRACEBACK"
    if row["rc"] == 2:
        return "error"
    return "ok" if row["rc"] == 0 else "invalid"


def table(rows):
    out = ["| case | status | rc | s | peak MiB | faces | shape | dev s | mesh→shape p95 % | error |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        p95 = r.get("dev_p95_pct")
        out.append(f"| {r['case']} | {status(r)} | {r['rc']} | {r['seconds']} | {r['peak_mb']} | {r.get('faces', '–')} "
                   f"| {r.get('shape', '–')} | {r.get('dev_seconds', '–')} | "
                   f"{'–' if p95 is None else f'{p95:.3g}'} | {r['error'].replace('|', '/')} |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--mem-gb", type=float, default=6.0)
    ap.add_argument("--timeout", type=float, default=300.0)
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--out", default=str(REPO / "bench" / "out_robustness"))
    a = ap.parse_args()
    outdir = Path(a.out)
    outdir.mkdir(parents=True, exist_ok=True)
    todo = [c for c in cases() if not a.only or any(s in c[0] for s in a.only)]
    with ThreadPoolExecutor(a.jobs) as ex:
        futs = [ex.submit(run_case, n, p, outdir, a.mem_gb, a.timeout) for n, p in todo]
        rows = []
        for f in futs:
            rows.append(f.result())
            r = rows[-1]
            print(f"{r['case']:<28} {status(r):<10} {r['seconds']:>6} s {r['peak_mb']:>6} MiB {r['error'][:100]}",
                  flush=True)
    (outdir / "robustness.json").write_text(json.dumps(rows, indent=1))
    (outdir / "robustness.md").write_text(table(rows) + "\n")
    print(table(rows))


if __name__ == "__main__":
    main()
