"""Benchmark the B-rep stage on the fixture parts: TRUE labels, surfaces from recon.fit, and TRUE surfaces.

For each part: curve network from the true labels, one ``recon.fit.fit_surface`` per part on its mesh
points, ``build_solid``; reports validity, closedness, face count against the true count, volume error
against the CAD original, face statuses, and time. The same with the TRUE surfaces as a control.

Run ``python bench/bench_brep.py [--parts box_fillet,plate_holes] [--variant clean] [--repeat 2]``.
Uses ``recon.fixtures.load_fixture`` when it exists, else builds the parts with the fixture script's
builders and tessellates them face by face (``recon.brep.labelled_tessellation``).
"""

from __future__ import annotations

import argparse
import importlib.util
import logging
import sys
import time
from pathlib import Path

import numpy as np

from recon.brep import build_solid, labelled_tessellation
from recon.curves import curve_network

ROOT = Path(__file__).resolve().parents[1]
PARTS = ("box_fillet", "box_chamfer", "plate_holes", "revolved", "lofted", "prism", "pocket")


def _builders():
    spec = importlib.util.spec_from_file_location("make_fixtures", ROOT / "fixtures" / "make_fixtures.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def load_part(name: str, variant: str, deflection: float):
    """vertices, faces, true labels, true surfaces (list by label), CAD volume."""
    mod = _builders()
    shape = getattr(mod, f"_{name}")()
    v, f, lab, surfaces = labelled_tessellation(shape, deflection=deflection)
    try:
        from recon.fixtures import load_fixture  # noqa: F401  (the fixtures' meshes, once they land)

        fx = load_fixture(name, variant)
        v, f, lab = np.asarray(fx[0]), np.asarray(fx[1]), np.asarray(fx[2])
    except Exception as err:  # fixtures not available: keep the direct tessellation
        logging.getLogger(__name__).debug("load_fixture(%s): %s", name, err)
    return v, f, lab, surfaces, shape.volume, len(shape.faces())


def part_normals(v, f):
    tri = v[f]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    vn = np.zeros_like(v)
    for k in range(3):
        np.add.at(vn, f[:, k], fn)
    n = np.linalg.norm(vn, axis=1)
    return vn / np.where(n > 0, n, 1)[:, None]


def fitted_surfaces(v, f, lab, *, tolerance):
    from recon.fit import fit_surface

    fits = {}
    for p in np.unique(lab).tolist():
        tris = f[lab == p]
        ids, local = np.unique(tris, return_inverse=True)
        local = local.reshape(-1, 3)
        pts = v[ids]
        while len(pts) < 16:  # a plane tessellated as two triangles: subdivide (exact on planes)
            import trimesh.remesh

            pts, local = trimesh.remesh.subdivide(pts, local)
        nrm = part_normals(pts, local)
        fits[p] = fit_surface(pts, nrm, tolerance=tolerance, faces=local)
    return fits


def run(name, variant, *, deflection, tolerance, repeat):
    v, f, lab, true_surfaces, volume, n_true = load_part(name, variant, deflection)
    net = curve_network(v, f, lab)
    rows = []
    for label, surfaces_fn in (("true", lambda: dict(enumerate(true_surfaces))),
                               ("fitted", lambda: fitted_surfaces(v, f, lab, tolerance=tolerance))):
        t0 = time.perf_counter()
        surfaces = surfaces_fn()
        t_fit = time.perf_counter() - t0
        times = []
        res = None
        for _ in range(repeat):
            t0 = time.perf_counter()
            try:
                res = build_solid(net, surfaces, tolerance=tolerance)
            except Exception as err:  # a crash is a result here
                res = err
            times.append(time.perf_counter() - t0)
        if isinstance(res, Exception):
            rows.append((name, label, f"ERROR {type(res).__name__}: {res}"[:120]))
            continue
        val = res.validity
        statuses = {}
        for r in res.faces:
            statuses[r.status] = statuses.get(r.status, 0) + 1
        types = {}
        for r in res.faces:
            types[r.surface_type] = types.get(r.surface_type, 0) + 1
        rows.append((name, label,
                     f"ok={res.ok!s:5s} {val.shape_type:8s} valid={val.valid!s:5s} closed={val.closed!s:5s} free={val.free_edges:3d} "
                     f"faces={val.n_faces:3d}/{n_true:<3d} dV={val.volume / volume - 1:+.2e} "
                     f"status={statuses} types={types} build={min(times):.2f}s fit={t_fit:.2f}s "
                     f"warn={len(res.warnings)}"))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default=",".join(PARTS))
    ap.add_argument("--variant", default="clean")
    ap.add_argument("--deflection", type=float, default=0.1)
    ap.add_argument("--tolerance", type=float, default=0.05)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.ERROR)
    print(f"# B-rep stage, variant={args.variant}, tolerance={args.tolerance}, true labels")
    for name in args.parts.split(","):
        for row in run(name, args.variant, deflection=args.deflection, tolerance=args.tolerance, repeat=args.repeat):
            print(f"{row[0]:12s} {row[1]:6s} {row[2]}")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
