"""``recon compare MESH SHAPE.step --json R.json [--preview P.png]``: deviation mesh ↔ B-rep."""

from __future__ import annotations

from pathlib import Path

from ._checks import MIN_SAMPLES
from ._format import UNIT_LABELS, deviation_line


def add_parser(sub):
    p = sub.add_parser(
        "compare",
        help="distances from a mesh to a B-rep (STEP) and back, per face",
        description="Deviation analysis: exact signed distances from the mesh vertices to the B-rep "
        "faces (positive outside) and from samples of the B-rep to the mesh; max, p95, RMS, mean in "
        "model units and % of the mesh's bounding-box diagonal, overall and per face.",
    )
    p.add_argument("mesh", help="triangle mesh (STL, OBJ, PLY, OFF, 3MF, GLB)")
    p.add_argument("shape", help="B-rep as a STEP file")
    p.add_argument("--json", required=True, metavar="R.json", help="write the report here")
    p.add_argument("--preview", metavar="P.png", help="write a colour map of the signed distance here")
    p.add_argument("--units", choices=tuple(UNIT_LABELS), default="mm", help="the unit of the mesh's numbers: the "
                   "STEP file is read in it, whatever unit it declares (default: mm, as recon convert's --units)")
    p.add_argument("--samples", type=int, default=None, metavar="N",
                   help=f"area-uniform samples on the B-rep, at least {MIN_SAMPLES} (default 20000)")
    p.set_defaults(func=run)
    return p


def _load_mesh(path: str):
    from ..mesh import load_mesh

    mesh = load_mesh(path)  # the same checks and messages as convert's
    return mesh.vertices, mesh.faces


def _check_step(path: str) -> None:
    """A STEP file begins with ``ISO-10303-21``; anything else is refused before OpenCascade's parser prints to
    the terminal about it."""
    from ..errors import InputError

    try:
        with open(path, "rb") as fh:
            head = fh.read(256).lstrip(b"\xef\xbb\xbf \t\r\n")
    except FileNotFoundError:
        raise InputError(f"STEP file {path} does not exist") from None
    except IsADirectoryError:
        raise InputError(f"STEP file {path} is a folder") from None
    if not head.upper().startswith(b"ISO-10303-21"):
        raise InputError(f"{path} is not a STEP file (it does not begin with ISO-10303-21)")


def run(args) -> int:
    from .._io import write_json
    from ..deviation import deviation, plot_deviation
    from ._checks import at_least, check_outputs

    at_least("--samples", args.samples, MIN_SAMPLES, " (the p95 must rest on 5 samples or more)")
    check_outputs([("input mesh", args.mesh), ("input shape", args.shape)],
                  [("--json", args.json), ("--preview", args.preview)])
    _check_step(args.shape)
    vertices, faces = _load_mesh(args.mesh)
    from ..brep._export import model_units
    from ..brep._messages import occ_messages

    # OpenCascade's reader warnings to the log, not into the summary on stdout; the shape in the mesh's unit
    with occ_messages(), model_units(args.units):
        report = deviation(vertices, faces, args.shape, samples=args.samples)
    write_json(args.json, report.to_json())
    if args.preview:
        plot_deviation(vertices, faces, report.signed, args.preview, title=Path(args.mesh).name)
    if not args.quiet:  # the result on stdout, like convert's summary
        print(summary(report, unit=UNIT_LABELS[args.units]))
        print(f"wrote {args.json}", flush=True)
    return 0


def summary(report, unit: str = "mm") -> str:
    """The deviation both ways, one line each (lengths in ``unit``, the mesh's)."""
    data = report.to_json()
    return "\n".join(deviation_line(way, data[key], data["diagonal"], unit)
                     for way, key in (("mesh→shape", "mesh_to_shape"), ("shape→mesh", "shape_to_mesh")))
