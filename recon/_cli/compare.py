"""``recon compare MESH SHAPE.step --json R.json [--preview P.png]``: deviation mesh ↔ B-rep."""

from __future__ import annotations

import logging
from pathlib import Path

log = logging.getLogger(__name__)


def add_parser(sub):
    p = sub.add_parser(
        "compare",
        help="distances from a mesh to a B-rep (STEP) and back, per face",
        description="Deviation analysis: exact signed distances from the mesh vertices to the B-rep "
        "faces (positive outside) and from samples of the B-rep to the mesh; max, p95, RMS, mean in "
        "model units and %% of the mesh's bounding-box diagonal, overall and per face.",
    )
    p.add_argument("mesh", help="triangle mesh (STL, OBJ, PLY, OFF, 3MF, GLB)")
    p.add_argument("shape", help="B-rep as a STEP file")
    p.add_argument("--json", required=True, metavar="R.json", help="write the report here")
    p.add_argument("--preview", metavar="P.png", help="write a colour map of the signed distance here")
    p.add_argument("--samples", type=int, default=None, help="area-uniform samples on the B-rep (default 20000)")
    p.set_defaults(func=run)
    return p


def _load_mesh(path: str):
    import numpy as np
    import trimesh

    from ..errors import InputError

    path = Path(path)
    if not path.is_file():
        raise InputError(f"mesh file {path} does not exist")
    try:
        mesh = trimesh.load(str(path), force="mesh")
    except Exception as err:  # trimesh raises many types on bad files
        raise InputError(f"mesh file {path} could not be read: {err}".splitlines()[0]) from err
    faces = np.asarray(getattr(mesh, "faces", np.empty((0, 3))))
    if len(faces) == 0:
        raise InputError(f"mesh file {path} holds no triangles")
    return np.asarray(mesh.vertices, dtype=float), faces.astype(np.int64)


def run(args) -> int:
    from .._io import write_json
    from ..deviation import deviation, plot_deviation

    vertices, faces = _load_mesh(args.mesh)
    report = deviation(vertices, faces, args.shape, samples=args.samples)
    write_json(args.json, report.to_json())
    if args.preview:
        plot_deviation(vertices, faces, report.signed, args.preview, title=Path(args.mesh).name)
    m = report.mesh_to_shape
    log.info("mesh → shape: max %.4g (%.3f%%), rms %.4g", m.max, m.pct(m.max), m.rms)
    return 0
