"""``DIR/corpus.json`` and ``DIR/CORPUS.md`` from the rows of a corpus run: per regime the median and the worst decile of
each figure beside the issues' targets, and the worst cases by seed with a picture (true part | recon's result)."""

from __future__ import annotations

import json
import math
import platform
import subprocess
from pathlib import Path

import numpy as np

#: (key, title, better, unit): ``better`` is "high" or "low"; a case without the figure (no result) counts as the
#: worst value there is (0 for "high", ∞ for "low"), so failures pull the median instead of leaving it
FIGURES = (
    ("type_agreement", "types right (area)", "high", ""),
    ("ours_true_p95", "ours→true p95 % diag", "low", ""),
    ("true_ours_p95", "true→ours p95 % diag", "low", ""),
    ("floor_ratio", "mesh→ours / mesh→true p95", "low", ""),
    ("face_error", "face count error ∣ours − true∣ / true", "low", ""),
    ("seconds", "recon convert s (wall)", "low", ""),
    ("convert_seconds", "recon's stages without its deviation check, s", "low", ""),
)
#: FreeCAD's route on the same meshes (``--freecad``), beside recon's figures where the run has it
FC_FIGURES = (
    ("fc_seconds", "FreeCAD mesh → shape → refine → solid → STEP s (its stages)", "low", ""),
    ("fc_wall_seconds", "FreeCAD route s (wall, freecadcmd start-up included)", "low", ""),
    ("fc_faces", "FreeCAD faces", "low", ""),
    ("fc_face_ratio", "FreeCAD faces / true faces", "low", ""),
)

#: the issues' targets per regime (issue 22 for export/fine, issue 23 for the scans), as written there
TARGETS = {
    "export": {"valid": "100 %", "exact faces": "≥ 95 %", "faces ±10 %": "100 %",
               "type_agreement": "≥ 0.99 (worst decile ≥ 0.95)",
               "ours_true_p95": "≤ 0.01 median", "seconds": "≤ 2 s median (≤ 10k triangles)"},
    "fine": {"valid": "≥ 98 %", "faces ±10 %": "≥ 90 %", "type_agreement": "≥ 0.97 median"},
    "scan05": {"valid": "≥ 98 %", "faces ±15 %": "≥ 90 %", "type_agreement": "≥ 0.95", "ours_true_p95": "≤ 0.1",
               "floor_ratio": "≤ 1.1"},
    "scan10": {"valid": "≥ 98 %", "faces ±15 %": "≥ 90 %", "type_agreement": "≥ 0.95", "ours_true_p95": "≤ 0.1",
               "floor_ratio": "≤ 1.1", "seconds": "≤ 20 s median at 150k triangles"},
    "scan20": {"valid": "≥ 95 %", "faces ±15 %": "≥ 80 %", "type_agreement": "≥ 0.90", "ours_true_p95": "≤ 0.15"},
    "scan50": {"valid": "≥ 90 %"}, "scan10-holes": {"valid": "≥ 90 %"}, "scan10-outliers": {"valid": "≥ 90 %"},
}
TARGETS["export-obj"] = TARGETS["export"]


def load_rows(out: Path) -> list[dict]:
    rows = [json.loads(p.read_text()) for p in sorted((out / "rows").glob("*.json"))]
    for r in rows:
        if r.get("mesh_true_p95") and r.get("mesh_ours_p95") is not None:
            r["floor_ratio"] = r["mesh_ours_p95"] / r["mesh_true_p95"]
        if r.get("faces_ours") is not None and r.get("faces_true"):
            r["face_error"] = abs(r["faces_ours"] - r["faces_true"]) / r["faces_true"]
        if r.get("recon_seconds"):  # recon's own stages; the deviation check is its verdict, not the conversion
            r["convert_seconds"] = sum(v for k, v in r["recon_seconds"].items() if k != "deviation")
        unified = r.get("faces_true_unified") or r.get("faces_true")
        if r.get("faces_ours") is not None and unified:
            r["face_error_unified"] = abs(r["faces_ours"] - unified) / unified
        if r.get("fc_faces") is not None and r.get("faces_true"):
            r["fc_face_ratio"] = r["fc_faces"] / r["faces_true"]
    return sorted(rows, key=lambda r: (r["regime"], r["seed"]))


def _values(rows, key, better):
    worst = 0.0 if better == "high" else math.inf
    return np.array([r[key] if r.get(key) is not None and np.isfinite(r[key]) else worst for r in rows], float)


def summary(rows) -> dict:
    """Per-regime shares and (median, worst decile) of every figure."""
    out = {}
    for regime in sorted({r["regime"] for r in rows}):
        cases = [r for r in rows if r["regime"] == regime]
        rs = [r for r in cases if r.get("status") != "no-recon"]  # recon's figures: the cases recon ran on
        n = len(rs)
        share = lambda f: sum(1 for r in rs if f(r)) / n  # noqa: E731
        s = {"n": n}
        if rs:
            s.update({
                "valid": share(lambda r: r.get("valid") is True),
                "exit0": share(lambda r: r.get("exit") == 0),
                "exact faces": share(lambda r: r.get("face_error") == 0),
                "exact faces, same-surface faces joined": share(lambda r: r.get("face_error_unified") == 0),
                "faces ±10 %": share(lambda r: r.get("face_error") is not None and r["face_error"] <= 0.10),
                "faces ±15 %": share(lambda r: r.get("face_error") is not None and r["face_error"] <= 0.15),
                "exit 0 outside what recon states (issue 20)": sum(1 for r in rs if r.get("issue20_ok") is False),
                "exit 0 but not a valid solid": sum(1 for r in rs if r.get("exit") == 0 and r.get("valid") is not True),
                "exit 0 with a wrong face count (joined)": sum(1 for r in rs if r.get("exit") == 0
                                                                and r.get("face_error_unified") != 0),
                "triangles median": float(np.median([r.get("triangles", 0) for r in rs])),
            })
        fc = [r for r in cases if r.get("fc_status")]  # the cases FreeCAD's route ran on (a timeout counts as ∞)
        if fc:
            s["FreeCAD cases"] = len(fc)
            s["FreeCAD triangles median"] = float(np.median([r.get("triangles", 0) for r in fc]))
            s["FreeCAD valid solid"] = sum(1 for r in fc if r.get("fc_valid")) / len(fc)
        for group, figures in ((rs, FIGURES if rs else ()), (fc, FC_FIGURES if fc else ())):
            for key, _, better, _ in figures:
                v = _values(group, key, better)
                q = 10 if better == "high" else 90
                s[key] = (float(np.median(v)),
                          float(np.percentile(v, q, method="lower" if better == "high" else "higher")))
        out[regime] = s
    return out


def _ran(rows, regime) -> list[dict]:
    """The rows of ``regime`` recon ran on."""
    return [r for r in rows if r["regime"] == regime and r.get("status") != "no-recon"]


def badness(r) -> tuple:
    """Sort key, worst first: no valid result, then low type agreement, then deviation."""
    return (r.get("valid") is True, r.get("type_agreement") or 0.0, -(r.get("ours_true_p95") or math.inf))


def _fmt(x):
    if x is None:
        return "–"
    if isinstance(x, float):
        if math.isinf(x):
            return "∞"
        return f"{x:.3g}"
    return str(x)


def render(rows, summ, pictures, machine) -> str:
    lines = ["# recon on the random-part corpus", "", f"Machine: {machine}.", "",
             "Medians and worst deciles over every case of the regime; a case without a result counts as the worst "
             "value (types 0, deviations ∞). Deviations in % of the true part's bounding-box diagonal. See "
             "bench/corpus/README.md for what each figure means.", ""]
    for regime, s in summ.items():
        t = TARGETS.get(regime, {})
        head = [f"recon on {s['n']} parts (median {s['triangles median']:.0f} triangles)"] if s["n"] else []
        if "FreeCAD cases" in s:
            head.append(f"FreeCAD's route on {s['FreeCAD cases']} (median {s['FreeCAD triangles median']:.0f} "
                        "triangles)")
        lines += [f"## {regime}: {', '.join(head)}", "", "| figure | measured | target |", "|---|---|---|"]
        if s["n"]:
            for key in ("valid", "exit0", "exact faces", "exact faces, same-surface faces joined", "faces ±10 %",
                        "faces ±15 %"):
                lines.append(f"| {key} | {100 * s[key]:.0f} % | {t.get(key, '')} |")
            for key in ("exit 0 outside what recon states (issue 20)", "exit 0 but not a valid solid",
                        "exit 0 with a wrong face count (joined)"):
                lines.append(f"| {key} | {s[key]} | 0 |")
        if "FreeCAD valid solid" in s:
            lines.append(f"| FreeCAD valid solid | {100 * s['FreeCAD valid solid']:.0f} % | |")
        for key, title, better, _ in FIGURES + FC_FIGURES:
            if key in s:
                med, dec = s[key]
                lines.append(f"| {title}: median / worst decile | {_fmt(med)} / {_fmt(dec)} | {t.get(key, '')} |")
        worst = sorted(_ran(rows, regime), key=badness)[:10]
        if worst:
            lines += ["", "Worst cases:", "", "| seed | family | true faces | triangles | status | exit | valid | "
                      "faces | types | ours→true p95 | s | message |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in worst:
            lines.append("| " + " | ".join(_fmt(r.get(k)) for k in ("seed", "family", "faces_true", "triangles", "status",
                         "exit", "valid", "faces_ours", "type_agreement", "ours_true_p95", "seconds"))
                         + f" | {str(r.get('message') or r.get('measure_error') or '')[:80].replace('|', '/')} |")
        for seed, png in pictures.get(regime, []):
            lines += ["", f"seed {seed} (left: the true part, one colour a face; right: recon's result):", "",
                      f"![{regime} seed {seed}]({png})"]
        lines.append("")
    return "\n".join(lines)


def _labelled_mesh(shape_path):
    """Vertices, triangles and face per triangle of a STEP file's tessellation (for the pictures)."""
    from build123d import import_step

    from .regimes import make_fixtures

    shape = import_step(str(shape_path))
    bb = shape.bounding_box()
    diag = math.dist((bb.min.X, bb.min.Y, bb.min.Z), (bb.max.X, bb.max.Y, bb.max.Z))
    return make_fixtures().occ_mesh(shape, deflection=2e-3 * diag, angular=0.3)[:3]


def picture(true_step, ours_step, path, title) -> None:
    """Side by side: the true part and ours, one pastel colour per face (recon.preview.render_parts)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from recon.preview import render_parts

    halves = []
    for name, step in (("true", true_step), ("ours", ours_step)):
        png = path.with_name(f"{path.stem}_{name}.png")
        if step is not None and Path(step).exists():
            v, t, lab = _labelled_mesh(step)
            render_parts(png, v, t, lab, ["patch"] * (int(lab.max()) + 1), size=500,
                         title=f"{name}: {int(lab.max()) + 1} faces")
            halves.append(plt.imread(png))
            png.unlink()
    fig, axes = plt.subplots(1, len(halves), figsize=(5 * len(halves), 5))
    for ax, img in zip(np.atleast_1d(axes), halves):
        ax.imshow(img)
        ax.axis("off")
    fig.suptitle(title)
    fig.savefig(path, dpi=80, bbox_inches="tight")
    plt.close(fig)


def machine() -> str:
    cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")), platform.processor())
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    except OSError:
        commit = "?"
    import os

    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, commit {commit}"


def write_report(out: Path, *, cache: Path, worst: int = 5) -> dict:
    from .truth import true_part

    rows = load_rows(out)
    summ = summary(rows)
    pictures = {}
    for regime in summ:
        pics = []
        for r in sorted(_ran(rows, regime), key=badness)[:worst]:
            png = out / "pictures" / f"{regime}_seed_{r['seed']:05d}.png"
            png.parent.mkdir(parents=True, exist_ok=True)
            ours = out / "steps" / f"{regime}_seed_{r['seed']:05d}.step"
            try:
                picture(true_part(r["seed"], cache)[0], ours if ours.exists() else None, png,
                        f"{regime} seed {r['seed']}: {r.get('status')}, faces {r.get('faces_ours')}/{r.get('faces_true')}")
                pics.append((r["seed"], png.relative_to(out).as_posix()))
            except Exception as err:  # a picture that cannot be drawn is left out, the row stays
                r.setdefault("notes", []).append(f"picture: {type(err).__name__}: {err}"[:200])
        pictures[regime] = pics
    info = machine()
    (out / "corpus.json").write_text(json.dumps({"machine": info, "summary": summ, "rows": rows}, indent=1))
    (out / "CORPUS.md").write_text(render(rows, summ, pictures, info))
    return summ
