"""``recon convert``: the main job — a triangle mesh in, a B-rep solid (STEP, BREP or STL) out."""

from __future__ import annotations

import gc
import logging
import sys
import time
from pathlib import Path

from ._checks import MAX_DIAGONAL, MIN_DIAGONAL
from ._format import UNIT_LABELS, deviation_line, length, number

OUTPUT_SUFFIXES = (".step", ".stp", ".igs", ".iges", ".brep", ".stl")


def add_parser(sub):
    p = sub.add_parser(
        "convert",
        help="reconstruct a B-rep solid from a triangle mesh (the main job)",
        description="Reconstruct an editable B-rep from a triangle mesh: decompose it into smooth patches, fillets and "
        "corners, fit one surface per part, and assemble a solid on a shared curve network.",
    )
    p.add_argument("mesh", help="input triangle mesh: STL, OBJ, PLY, OFF, 3MF or GLB; the part's bounding-box "
                   f"diagonal must lie between {MIN_DIAGONAL:g} and {MAX_DIAGONAL:.2g} units (OpenCascade's fixed "
                   "precision)")
    p.add_argument("out", help="output B-rep; the format follows the extension: .step/.stp (AP242 or AP214, with face "
                   "names and colours), .igs/.iges (IGES 5.3, B-rep solids), .brep (OpenCascade) or .stl (tessellated)")
    p.add_argument("--units", choices=tuple(UNIT_LABELS), default="mm", help="the unit of the mesh's numbers, which "
                   "the STEP or IGES file declares so that a CAD program shows the part at its true size; lengths in "
                   "the summary and the report are in it (default: mm; .brep and .stl files carry no unit)")
    p.add_argument("--schema", choices=("AP242", "AP214"), default=None, help="STEP application protocol: AP242 "
                   "(current CAD) or AP214 (older readers); STEP output only (default: AP242)")
    p.add_argument("--report", metavar="R.json", help="write the report (faces by type, deviation, validity, time per "
                   "stage, per-face figures) as JSON")
    p.add_argument("--preview", metavar="P.png", help="write a PNG of the result, faces coloured by kind (patches in "
                   "pastels, fillets purple, corners yellow)")
    p.add_argument("--tolerance", type=float, metavar="T", help="fit tolerance in mesh units, at least 1e-7 "
                   "(OpenCascade's precision) and at most 5%% of the part's bounding-box diagonal (default: max(4σ, "
                   "1e-4 × diagonal), σ the estimated mesh noise)")
    p.add_argument("--scale", type=float, metavar="S", help="feature scale of the decomposition in mesh units "
                   "(default: from the sampling and the noise)")
    p.add_argument("--no-deviation", action="store_true", help="skip measuring the deviation (faster)")
    p.add_argument("--jobs", type=int, metavar="N", help="processes to use (default: the cores available)")
    p.set_defaults(func=run)
    return p


class _Progress:
    """The run's progress on stderr (:class:`recon._progress.StageProgress`: a live line per stage on a terminal,
    a plain line every few seconds elsewhere; ``stream`` None: none). At every call it stops a run whose interrupt
    some library swallowed (see ``recon._cli._signals``)."""

    def __init__(self, stream):
        from .._progress import StageProgress, interval_from_env

        self.shown = None if stream is None else StageProgress(stream, tty=stream.isatty(),
                                                                 interval=interval_from_env())
        self.done = set()  # the CLI loads the mesh itself: convert()'s own "load" stage is not shown again

    def __call__(self, stage, frac):
        from .._io import commits_stopped

        if commits_stopped():
            raise KeyboardInterrupt(commits_stopped())
        if self.shown is None or stage in self.done:
            return
        self.shown(stage, frac)
        if frac >= 1.0:
            self.done.add(stage)

    def filter(self, record) -> bool:
        """A log filter that erases a half-drawn progress line before the message is printed."""
        if self.shown is not None:
            self.shown.clear()
        return True


def summary(report: dict, *, unit: str = "mm") -> str:
    """The end-of-run summary: the verdict first (within tolerance or not, and why), then faces by type, validity,
    deviation, time and warnings. Lengths are in the mesh's units, ``unit`` (what the output file declares)."""
    v = report["validity"]
    kinds = ", ".join(f"{n} {t}" for t, n in sorted(report["faces_by_type"].items(), key=lambda kv: -kv[1]))
    lines = [verdict_line(report, unit=unit)] if "verdict" in report else []
    solid = next((r for r in report.get("verdict", {}).get("rules", []) if r["rule"] == "solid"), None)
    if solid is not None:  # what the written file holds, read back (the verdict's own figures)
        v = {**v, **solid["value"], "ok": solid["ok"]}
    vol = "n/a" if v["volume"] is None else f"{number(v['volume'], 6)} {unit}³"
    lines += [
        f"faces: {report['n_faces']} ({kinds})",
        f"solid: {'valid closed solid' if v['ok'] else 'NOT a valid closed solid'} "
        f"({v['shape_type']}, valid={v['valid']}, closed={v['closed']}, free edges={v['free_edges']}, volume={vol})",
    ]
    dev = report.get("deviation")
    if dev:
        for way, key in (("mesh→shape", "mesh_to_shape"), ("shape→mesh", "shape_to_mesh")):
            line = deviation_line(way, dev[key], dev["diagonal"], unit)
            if key == "shape_to_mesh":
                # Where the shape leaves the mesh: a face that reaches far out shows here only (mesh→shape
                # measures from the mesh's points, which all lie near some face).
                far = max((f for f in dev.get("faces", []) if f.get("shape_to_mesh_max") is not None),
                          key=lambda f: f["shape_to_mesh_max"], default=None)
                if far is not None:
                    line += f"; farthest: {far['name']}"
            lines.append(line)
    secs = report["seconds"]
    lines.append("time: " + ", ".join(f"{k} {v:.2f} s" for k, v in secs.items()) + f"; total {sum(secs.values()):.2f} s")
    warnings = report.get("warnings", [])
    for w in warnings[:SUMMARY_WARNINGS]:
        lines.append(f"warning: {w}")
    if len(warnings) > SUMMARY_WARNINGS:
        lines.append(f"… and {len(warnings) - SUMMARY_WARNINGS} more warnings (all of them in --report's \"warnings\")")
    return "\n".join(lines)


#: Rules named in the verdict line; the report has all of them.
VERDICT_RULES = 3


def verdict_line(report: dict, *, unit: str = "mm") -> str:
    """One line a CAD user reads at a glance: "within tolerance", "NOT within tolerance (rule …: value vs limit, faces
    …)", or for a run that measured no deviation "deviation NOT verified"."""
    verdict = report["verdict"]
    tol = f"tolerance {length(report['tolerance'], unit)}"
    failed = [r for r in verdict["rules"] if r["ok"] is False]
    if failed:
        # (a wrong solid is not within tolerance of the part either, whichever rule shows it)
        words = "NOT within tolerance"
        why = "; ".join(_rule_words(r, unit) for r in failed[:VERDICT_RULES])
        more = f"; and {len(failed) - VERDICT_RULES} more rules" if len(failed) > VERDICT_RULES else ""
        return f"result: {words} ({tol}; {why}{more}); see --report's \"verdict\""
    if verdict["within_tolerance"] is None:
        return (f"result: deviation NOT verified (not measured): a valid result with a face for every part and its "
                f"volume within the limit, but how far it lies from the mesh is unknown ({tol})")
    solid = "a valid shell (the mesh is open)" if report["mesh"].get("open") else "a valid closed solid"
    return (f"result: within tolerance ({tol}{_between_vertices(report, unit)}): {solid} as written, a face for every "
            f"part, deviation both ways and volume within their limits")


def _between_vertices(report: dict, unit: str) -> str:
    """What the tolerance holds between the mesh's vertices, where a coarse mesh's chord sag exceeds T: the faces are
    pinned there only to T + sag (the shape→mesh p95 limit), which is all a user may read of the true part."""
    rule = next((r for r in report["verdict"]["rules"] if r["rule"] == "shape_to_mesh_p95"), None)
    T = float(report["tolerance"])
    if rule is None or not isinstance(rule["limit"], (int, float)) or not rule["limit"] - T > T:
        return ""  # (as the verdict's own detail: only a sag above T changes what T means)
    return (f" at the mesh's vertices, {length(rule['limit'], unit)} between them: the mesh's chord sag "
            f"{length(rule['limit'] - T, unit)} is all it tells of the surface there")


def _rule_words(rule: dict, unit: str) -> str:
    faces = rule["faces"]
    at = f", faces {', '.join(faces[:4])}{' …' if len(faces) > 4 else ''}" if faces else ""
    if isinstance(rule["value"], (int, float)) and isinstance(rule["limit"], (int, float)) \
            and rule["rule"] not in ("coverage", "overlap", "face_count"):
        unit = f"{unit}³" if rule["rule"] == "volume" else unit
        return f"rule {rule['rule']}: {length(rule['value'], unit)} vs limit {length(rule['limit'], unit)}{at}"
    return f"rule {rule['rule']}: {rule['detail']}{at}"


#: Warnings the summary lists; the report has all of them.
SUMMARY_WARNINGS = 5


class _RepeatedInSummary:
    """Log filter: drops ``build_solid``'s warnings, which the summary (and the report) repeat. On a terminal they
    also broke the progress line of the B-rep stage."""

    def filter(self, record) -> bool:
        return not (record.name == "recon.brep._build" and record.levelno == logging.WARNING
                    and str(record.msg).startswith("build_solid: "))


def run(args) -> int:
    from ..errors import InputError
    from ._checks import at_least, check_outputs, positive_length

    out = Path(args.out)
    if out.suffix.lower() not in OUTPUT_SUFFIXES:
        raise InputError(f"output {out}: unknown extension {out.suffix!r}; use one of {', '.join(OUTPUT_SUFFIXES)}")
    if args.schema is not None and out.suffix.lower() not in (".step", ".stp"):
        raise InputError(f"--schema {args.schema}: a STEP option, and the output {out} is not .step/.stp")
    positive_length("--tolerance", args.tolerance)
    positive_length("--scale", args.scale)
    at_least("--jobs", args.jobs, 1)
    check_outputs([("input mesh", args.mesh)],
                  [("output", args.out), ("--report", args.report), ("--preview", args.preview)])

    # Progress on stderr: a live line on a terminal; elsewhere a line every few seconds, none in a short run.
    progress = _Progress(None if args.quiet else sys.stderr)
    filters = [progress] if args.verbose else [_RepeatedInSummary(), progress]
    handlers = list(logging.getLogger().handlers)
    for handler in handlers:
        for f in filters:
            handler.addFilter(f)
    collecting = gc.isenabled()
    gc.disable()  # (the CAD kernel's import makes ~200k binding objects: full collections that find nothing)
    from ..brep._messages import occ_messages

    # They live until exit: out of the collector's sight, neither its full collections nor the one at exit walk them
    # (0.3 s at exit alone, measured: bench/speed.md s37-speed).
    gc.freeze()
    if collecting:
        gc.enable()
    try:
        with occ_messages():  # OpenCascade's own messages to the log: not into the summary nor the progress line
            return _convert(args, out, progress)
    finally:  # (main() may run again in this process: a test, a notebook)
        for handler in handlers:
            for f in filters:
                handler.removeFilter(f)


def _convert(args, out: Path, progress: _Progress) -> int:
    from .._io import write_json
    from ._checks import check_size, check_tolerance
    from ..mesh import load_mesh
    from ..pipeline import convert
    from ..verdict import write_checked

    if progress.shown is not None and progress.shown.tty:
        print(f"recon convert {args.mesh}", file=sys.stderr)
    # Loaded here, so that the part's size and the tolerance are checked before the work starts.
    t_load = time.perf_counter()
    progress("load", 0.0)
    mesh = load_mesh(args.mesh)
    progress("load", 1.0)
    t_load = time.perf_counter() - t_load
    check_size(mesh.diagonal)
    check_tolerance(args.tolerance, mesh.diagonal)
    result = convert(
        mesh,
        tolerance=args.tolerance,
        scale=args.scale,
        deviation=not args.no_deviation,
        progress=progress,
        jobs=args.jobs,
    )
    result.report["seconds"]["load"] = result.report["seconds"].get("load", 0.0) + t_load
    # judged on the file as written, read back from disk
    verdict = write_checked(result, out, name=out.stem, units=args.units, schema=args.schema or "AP242")
    if args.report:
        write_json(args.report, result.report)
    if args.preview:
        from ..preview import render_result

        render_result(args.preview, result, title=f"{result.report['n_faces']} faces")
    if not args.quiet:  # the result on stdout (`> summary.txt` keeps it); progress and warnings went to stderr
        print(summary(result.report, unit=UNIT_LABELS[args.units]))
        print(f"wrote {out}", flush=True)
    return 0 if verdict.ok else 1
