"""The decomposition drawn like the paper's Figure 2(b): parts coloured by kind, bridges and separators dashed."""

from __future__ import annotations

import logging
import os
from typing import TYPE_CHECKING

import numpy as np

from .._io import atomic_path
from ..errors import ExportError, InputError
from ._types import SkeletonResult

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["plot_decomposition", "KIND_COLORS"]

log = logging.getLogger(__name__)

#: Fill colour of each part kind, as in the paper's Figure 2(b) and Figure 4.
KIND_COLORS = {"junction": "#f2c80f", "terminal": "#3aa655", "linear": "#8e5cb5"}
_SHAPE_COLOR = "#d9d9d9"
_BOUNDARY_COLOR = "#404040"


def plot_decomposition(result: SkeletonResult, *, ax: Axes | None = None, path: str | os.PathLike | None = None,
                       dpi: int = 150) -> Axes:
    """Draw the shape, its parts, the segment graph's bridges and separators, and the skeleton on top.

    Junctions are yellow, terminals green, linear parts purple; bridges are dashed black, separator
    edges dashed white (§3, Figure 2(b)). Equal aspect, no axes.

    Parameters
    ----------
    result : SkeletonResult
    ax : matplotlib.axes.Axes, optional
        Where to draw. If omitted, a new figure is made (with the Agg canvas: no display needed).
    path : path-like, optional
        Write the figure as PNG here (atomically: a failed write leaves no file).
    dpi : int
        Resolution of the PNG.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn on.
    """
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MplPath

    if not isinstance(result, SkeletonResult):
        raise InputError(f"result must be a SkeletonResult, got {type(result).__name__}")
    pts = np.asarray(result.points, dtype=np.float64)
    if ax is None:
        extent = np.ptp(pts, axis=0) if len(pts) else np.ones(2)
        height = float(np.clip(6.0 * extent[1] / max(extent[0], 1e-12), 2.0, 9.0))
        fig = Figure(figsize=(6, height), layout="constrained")
        ax = fig.add_subplot()

    # The sampled shape underneath, one compound path; rings oriented by nesting depth so that holes stay
    # empty whatever fill rule the backend uses.
    rings = [pts[result.curve == c] for c in np.unique(result.curve)]
    if rings:
        depth = _nesting_depth(rings, MplPath)
        oriented = [_oriented(r, ccw=d % 2 == 0) for r, d in zip(rings, depth)]
        ax.add_patch(PathPatch(_compound_path(oriented, MplPath), facecolor=_SHAPE_COLOR, edgecolor="none", zorder=1))

    for part in result.parts:
        color = KIND_COLORS.get(part.kind, "#999999")
        outer = _oriented(part.polygon, ccw=True)
        holes = [_oriented(h, ccw=False) for h in part.holes]
        ax.add_patch(
            PathPatch(
                _compound_path([outer, *holes], MplPath),
                facecolor=color,
                edgecolor=color,
                linewidth=0.4,
                zorder=2,
                label=part.kind,
            )
        )

    for ring in rings:
        closed = np.vstack([ring, ring[:1]])
        ax.plot(closed[:, 0], closed[:, 1], color=_BOUNDARY_COLOR, linewidth=0.8, zorder=3)

    sg = result.segment_graph
    if len(sg.separators):
        ax.add_collection(
            LineCollection(pts[np.asarray(sg.separators)], colors="white", linewidths=1.2, linestyles="--", zorder=4)
        )

    sk = result.skeleton
    edges = np.asarray(sk.edges, dtype=np.int64).reshape(-1, 2)
    is_bridge = np.zeros(len(edges), dtype=bool)
    if len(sg.bridges):
        is_bridge[np.asarray(sg.bridges, dtype=np.int64)] = True
    segs = np.asarray(sk.vertices, dtype=np.float64)[edges] if len(edges) else np.zeros((0, 2, 2))
    if (~is_bridge).any():
        ax.add_collection(LineCollection(list(segs[~is_bridge]), colors="black", linewidths=1.0, zorder=5))
    if is_bridge.any():
        ax.add_collection(LineCollection(list(segs[is_bridge]), colors="black", linewidths=1.4, linestyles="--", zorder=5))

    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.03 * float(np.max(hi - lo))
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_axis_off()

    if path is not None:
        try:
            with atomic_path(path) as tmp:
                # the root figure: an axes given on a subfigure has no savefig of its own
                ax.figure.figure.savefig(tmp, format="png", dpi=dpi)
        except OSError as err:
            raise ExportError(f"cannot write plot {path}: {err}") from None
        log.info("wrote %s", path)
    return ax


def _oriented(ring: np.ndarray, *, ccw: bool) -> np.ndarray:
    ring = np.asarray(ring, dtype=np.float64)
    x, y = ring[:, 0], ring[:, 1]
    area2 = float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    return ring if (area2 > 0) == ccw else ring[::-1]


def _nesting_depth(rings, MplPath) -> list[int]:
    paths = [MplPath(r) for r in rings]
    return [sum(paths[j].contains_point(r[0]) for j in range(len(rings)) if j != i) for i, r in enumerate(rings)]


def _compound_path(rings, MplPath):
    verts, codes = [], []
    for ring in rings:
        if len(ring) < 3:
            continue
        verts.append(np.vstack([ring, ring[:1]]))
        c = np.full(len(ring) + 1, MplPath.LINETO, dtype=np.uint8)
        c[0], c[-1] = MplPath.MOVETO, MplPath.CLOSEPOLY
        codes.append(c)
    if not verts:
        return MplPath(np.zeros((0, 2)))
    return MplPath(np.concatenate(verts), np.concatenate(codes))
