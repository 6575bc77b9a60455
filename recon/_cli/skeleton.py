"""``recon skeleton``: the paper's 2D skeleton and decomposition of a shape (§2–3)."""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path


log = logging.getLogger(__name__)


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not value > 0 or value == float("inf"):  # (NaN fails the first test)
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return value


def add_parser(sub):
    p = sub.add_parser(
        "skeleton",
        help="2D skeleton and decomposition of a shape (§2–3)",
        description="Voronoi skeleton of a 2D shape, pruned by boundary arc length (§2), and its decomposition "
        "into junction, terminal and linear parts (§3). Lengths are in shape units: the JSON file's units, "
        "pixels for images, SVG user units for SVG (with y pointing up).",
    )
    p.add_argument(
        "shape",
        metavar="SHAPE",
        help='shape file: .json {"curves": [[[x, y], ...], ...]}, .svg (closed paths), or a silhouette image '
        "(.png, .bmp, .tif, ...: non-zero pixels are the shape)",
    )
    p.add_argument(
        "--json", required=True, metavar="OUT.json", help="write skeleton, parts and segment graph here (shape units)"
    )
    p.add_argument("--plot", metavar="OUT.png", help="also draw the decomposition as a PNG (default: no plot)")
    p.add_argument(
        "--omega-min",
        type=_positive,
        metavar="W",
        help="pruning threshold ω_min (§2, condition 3): a Voronoi edge is kept only if its two boundary sites are "
        "more than W apart along the boundary; shape units (default: 5 %% of the shape's bounding-box diagonal, "
        "at least 4 spacings)",
    )
    p.add_argument(
        "--spacing",
        type=_positive,
        metavar="S",
        help="boundary resampling step; shape units (default: total boundary length / 2000, at least 16 "
        "samples per curve)",
    )
    p.add_argument(
        "--invert",
        action="store_true",
        help="images only: zero pixels are the shape (default: off, non-zero pixels are the shape)",
    )
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    from ..skeleton2d import load_shape, plot_decomposition, skeletonize
    from .._io import atomic_path

    from ._checks import check_outputs

    out_json = Path(args.json)
    out_png = Path(args.plot) if args.plot else None
    check_outputs([("input shape", args.shape)], [("--json", args.json), ("--plot", args.plot)])

    t0 = time.perf_counter()
    shape = load_shape(args.shape, invert=args.invert)
    result = skeletonize(shape, omega_min=args.omega_min, spacing=args.spacing)
    elapsed = time.perf_counter() - t0

    doc = {"shape": str(args.shape), **result.to_json()}
    # Both outputs appear together or not at all.
    with atomic_path(out_json) as tmp_json:
        with open(tmp_json, "w") as fh:
            json.dump(doc, fh)
        if out_png is not None:
            with atomic_path(out_png) as tmp_png:
                plot_decomposition(result, path=tmp_png)

    kinds = {k: sum(p.kind == k for p in result.parts) for k in ("junction", "terminal", "linear")}
    sk = result.skeleton
    if args.quiet:
        return 0
    print(  # the result on stdout, like convert's summary
        f"recon skeleton: {args.shape}: {len(sk.vertices)} skeleton vertices, {len(sk.edges)} edges; "
        f"{len(result.parts)} parts ({kinds['junction']} junction, {kinds['terminal']} terminal, "
        f"{kinds['linear']} linear); omega_min {result.omega_min:.4g}, spacing {result.spacing:.4g}; "
        f"{elapsed:.2f} s",
    )
    return 0
