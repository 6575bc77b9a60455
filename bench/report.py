"""The benchmark's report: ``bench.md`` from the rows of ``bench.json`` (headline, per-case tables, FreeCAD side by
side, scaling, failures)."""

from __future__ import annotations

import numpy as np

from .cases import COLUMNS, FREECAD_PART_TRIANGLES, SCALING_PART, STAGES, size_name

__all__ = ["render_markdown", "headline_rows", "part_speed_line", "loglog_slope"]


#: Variants whose faces the per-face fit table lists (all of them would be 500 rows).
FACE_TABLE_VARIANTS = ("clean", "noisy20")


def loglog_slope(x, y) -> float:
    """Least-squares slope of log y against log x: the exponent k of y ∝ x^k (NaN with fewer than 2 points)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


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
    name = f"scaling/{size_name(FREECAD_PART_TRIANGLES)}"
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
    pairs = _speed_pairs(rows)
    L = _head(rows, meta, pairs)
    L += _fixture_tables(rows)
    L += _mesh_table(rows)
    L += _freecad_table(rows, pairs)
    L += _scaling_table(rows)
    bad = [r for r in rows if r.get("status") not in ("ok", None)]
    if bad:
        L += ["## Failures and invalid results", ""]
        L += [f"- `{r['case']}` — {r.get('status')}: {r.get('error') or ''}" for r in bad]
        L.append("")
    L += ["## Columns", "", "Every row of `bench.json` has these keys:", ""]
    L += [f"- `{k}`: {v}" for k, v in COLUMNS.items()]
    L.append("")
    return "\n".join(L)


def _head(rows, meta: dict, pairs) -> list[str]:
    """Title, the run's facts, the headline table and the speed figures against FreeCAD."""
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
    return L


def _fixture_tables(rows) -> list[str]:
    """The fixtures against their truth, both-way deviations (fixtures and real meshes) and per-face fits."""
    L = []
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
    return L


def _mesh_table(rows) -> list[str]:
    L = []
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
    return L


def _freecad_table(rows, pairs) -> list[str]:
    L = []
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
    return L


def _scaling_table(rows) -> list[str]:
    L = []
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
    return L


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
