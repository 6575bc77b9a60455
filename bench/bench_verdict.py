"""How many benchmark cases each acceptance rule of :mod:`recon.verdict` flags, with the figures.

Every fixture variant and every real mesh runs ``python -m recon convert MESH OUT.step --report R.json`` in its own
subprocess, one after the other (the verdict is in the report, judged on the STEP file read back). The table gives,
per case, the exit code and every rule's value against its limit; the summary counts the cases each rule flags.

Usage: ``python bench/bench_verdict.py [--only SUBSTR ...] [--timeout 900] [--out bench/out_verdict]``; writes
``verdict.json`` and ``verdict_table.md`` in the output folder (bench/verdict.md quotes them).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
FIXTURES = REPO / "fixtures" / "data"
MESHES = REPO.parent / "shared" / "meshes"  # ../shared beside the checkout, as CI lays it out
PARTS = ("box_chamfer", "box_fillet", "lofted", "plate_holes", "pocket", "prism", "revolved")
VARIANTS = ("clean", "noisy05", "noisy20", "coarse", "open")
RULES = ("solid", "coverage", "overlap", "mesh_to_shape_p95", "mesh_to_shape_max", "shape_to_mesh_p95",
         "shape_to_mesh_max", "volume")


def cases() -> list[tuple[str, Path]]:
    out = [(f"{p}/{v}", FIXTURES / f"{p}_{v}.stl") for p in PARTS for v in VARIANTS]
    out += [(f"mesh/{p.stem}", p) for p in sorted(MESHES.iterdir())
            if p.suffix.lower() in (".off", ".stl", ".obj", ".ply")] if MESHES.is_dir() else []
    return out


def run(name: str, path: Path, out: Path, timeout: float) -> dict:
    work = out / name.replace("/", "__")
    work.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "recon", "convert", str(path), str(work / "out.step"),
                               "--report", str(work / "report.json")], capture_output=True, text=True,
                              timeout=timeout, cwd=REPO)
    except subprocess.TimeoutExpired:
        return {"case": name, "rc": None, "error": f"timeout {timeout:g} s"}
    row = {"case": name, "rc": proc.returncode, "seconds": round(time.perf_counter() - t, 1),
           "line": next((ln for ln in proc.stdout.splitlines() if ln.startswith("result:")), proc.stderr[-300:])}
    rep = work / "report.json"
    if rep.exists():
        report = json.loads(rep.read_text())
        row["tolerance"] = report["tolerance"]
        row["diagonal"] = report["mesh"]["diagonal"]
        row["faces"] = report["n_faces"]
        row["verdict_seconds"] = report["verdict"]["seconds"]
        row["rules"] = {r["rule"]: {k: r[k] for k in ("ok", "value", "limit", "faces")} for r in
                        report["verdict"]["rules"]}
    return row


def _cell(rule: dict | None) -> str:
    if rule is None:
        return ""
    mark = {True: "ok", False: "**FAIL**", None: "—"}[rule["ok"]]
    v, lim = rule["value"], rule["limit"]
    if isinstance(v, (int, float)) and isinstance(lim, (int, float)):
        return f"{mark} {v:.3g}/{lim:.3g}"
    return mark


def table(rows: list[dict]) -> str:
    head = ["case", "exit", "T", *RULES]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        rules = r.get("rules", {})
        lines.append("| " + " | ".join([r["case"], str(r["rc"]), f"{r.get('tolerance', float('nan')):.3g}",
                                         *(_cell(rules.get(k)) for k in RULES)]) + " |")
    flagged = {k: [r["case"] for r in rows if r.get("rules", {}).get(k, {}).get("ok") is False] for k in RULES}
    lines += ["", "| rule | cases flagged | which |", "|---|---|---|"]
    lines += [f"| {k} | {len(v)} | {', '.join(v)} |" for k, v in flagged.items()]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "out_verdict")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    todo = [(n, p) for n, p in cases() if not args.only or any(s in n for s in args.only)]
    for i, (name, path) in enumerate(todo, 1):
        row = run(name, path, args.out, args.timeout)
        rows.append(row)
        print(f"[{i}/{len(todo)}] {name}: exit {row['rc']} {row.get('seconds', '')} s  {row.get('line', '')[:160]}",
              flush=True)
        (args.out / "verdict.json").write_text(json.dumps(rows, indent=1, allow_nan=False))
    (args.out / "verdict_table.md").write_text(table(rows) + "\n")


if __name__ == "__main__":
    main()
