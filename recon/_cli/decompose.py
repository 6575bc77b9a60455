"""``recon decompose``: smooth patches and the junction/linear/terminal parts of a mesh (§4)."""

from __future__ import annotations

import logging

log = logging.getLogger(__name__)


def add_parser(sub):
    p = sub.add_parser("decompose", help="decompose a mesh into smooth patches and feature parts (§4)")
    p.add_argument("mesh", help="triangle mesh (STL/OBJ/PLY/OFF/3MF/GLB)")
    p.add_argument("--json", required=True, metavar="D.json",
                   help="output JSON: a part id per input triangle, parts, skeleton")
    p.add_argument("--preview", metavar="P.png", help="output PNG preview")
    p.add_argument("--scale", type=float, metavar="S",
                   help="feature scale in mesh units, > 0 (default: from sampling and noise)")
    p.add_argument("--omega-min", type=float, metavar="W",
                   help="skeleton pruning threshold (arc length, mesh units, > 0)")
    p.add_argument("--jobs", type=int, metavar="N", help="processes to use (default: the cores available)")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    from .._io import write_json
    from ..decompose import decompose
    from ..mesh import input_labels, load_mesh
    from ._checks import at_least, check_outputs, positive_length

    positive_length("--scale", args.scale)
    positive_length("--omega-min", args.omega_min)
    at_least("--jobs", args.jobs, 1)
    check_outputs([("input mesh", args.mesh)], [("--json", args.json), ("--preview", args.preview)])
    mesh = load_mesh(args.mesh)
    dec = decompose(mesh, scale=args.scale, omega_min=args.omega_min, jobs=args.jobs)
    write_json(args.json, dec.to_json(triangle_labels=input_labels(mesh, dec.labels)))
    if args.preview:
        from ..preview import render_parts

        render_parts(
            args.preview,
            mesh.vertices,
            mesh.faces,
            dec.labels,
            [p.kind for p in dec.parts],
            skeleton_vertices=dec.skeleton.vertices,
            skeleton_edges=dec.skeleton.edges,
            skeleton_faces=dec.skeleton.faces,
            title=", ".join(f"{v} {k}" for k, v in dec.counts().items()),
        )
    return 0
