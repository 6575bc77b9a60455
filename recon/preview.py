"""Headless PNG preview of a labelled mesh: painter's algorithm on a 2D PolyCollection (Agg backend).

Projecting and depth-sorting the triangles ourselves and drawing them as one 2D ``PolyCollection`` is
much faster than ``Poly3DCollection`` (which re-projects and re-sorts on every draw): 100k triangles
render in a couple of seconds.
"""

from __future__ import annotations

import logging
import os

import numpy as np

from ._io import atomic_path
from .errors import ExportError, InputError

__all__ = ["render_parts", "render_result", "KIND_COLOURS"]

log = logging.getLogger(__name__)

#: Part colours by kind, after the paper's figures (junctions yellow, linear purple, terminals green).
KIND_COLOURS = {
    "junction": (0.98, 0.85, 0.15),
    "linear": (0.60, 0.40, 0.80),
    "terminal": (0.35, 0.75, 0.35),
}
_PASTELS = np.array(
    [
        (0.80, 0.80, 0.80),
        (0.70, 0.78, 0.88),
        (0.88, 0.76, 0.70),
        (0.74, 0.86, 0.78),
        (0.86, 0.80, 0.88),
        (0.90, 0.88, 0.74),
        (0.72, 0.84, 0.86),
        (0.62, 0.62, 0.66),
    ]
)


def _view(vertices, elev=25.0, azim=-55.0):
    """Rotation taking world coordinates to a view (x right, y up, z towards the viewer)."""
    a, e = np.radians(azim), np.radians(elev)
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(e - np.pi / 2), -np.sin(e - np.pi / 2)], [0, np.sin(e - np.pi / 2), np.cos(e - np.pi / 2)]])
    return rx @ rz


def render_parts(
    path: str | os.PathLike,
    vertices: np.ndarray,
    faces: np.ndarray,
    labels: np.ndarray,
    kinds: list[str] | tuple[str, ...],
    *,
    skeleton_vertices: np.ndarray | None = None,
    skeleton_edges: np.ndarray | None = None,
    skeleton_faces: np.ndarray | None = None,
    elev: float = 25.0,
    azim: float = -55.0,
    size: int = 900,
    title: str | None = None,
) -> None:
    """Write a shaded PNG of a mesh coloured by part (patches in pastels, features by kind).

    Parameters
    ----------
    path : path-like
        Output PNG.
    vertices : (n, 3) float
    faces : (m, 3) int
    labels : (m,) int
        Part id per triangle.
    kinds : sequence of str
        Kind of each part id.
    skeleton_vertices : (k, 3) float, optional
    skeleton_edges : (e, 2) int, optional
        Drawn in black where they face the viewer.
    skeleton_faces : (k,) int, optional
        Mesh triangle of each skeleton vertex: edges on back-facing triangles are hidden.
    elev, azim : float
        View direction in degrees.
    size : int
        Image size in pixels.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection

    V = np.asarray(vertices, float)
    F = np.asarray(faces, np.int64)
    labels = np.asarray(labels)
    if labels.shape != (len(F),):
        raise InputError(f"`labels` must be ({len(F)},), got {labels.shape}")
    R = _view(V, elev, azim)
    P = (V - V.mean(axis=0)) @ R.T
    tri = P[F]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    front = cross[:, 2] > 0
    nz = np.where(norm > 0, cross[:, 2] / np.maximum(norm, 1e-300), 0.0)
    light = np.array([-0.3, 0.4, 0.87])
    light /= np.linalg.norm(light)
    lam = np.abs(cross @ light) / np.maximum(norm, 1e-300)
    shade = 0.35 + 0.65 * lam
    base = np.empty((len(kinds), 3))
    for i, k in enumerate(kinds):
        base[i] = KIND_COLOURS[k] if k in KIND_COLOURS else _PASTELS[i % len(_PASTELS)]
    colour = np.clip(base[labels] * shade[:, None], 0, 1)
    keep = front & (np.abs(nz) >= 0)
    order = np.argsort(tri[keep, :, 2].mean(axis=1))
    polys = tri[keep][order][:, :, :2]
    fig = plt.figure(figsize=(size / 100, size / 100), dpi=100)
    ax = fig.add_axes([0, 0, 1, 1])
    ax.add_collection(PolyCollection(polys, facecolors=colour[keep][order], edgecolors="none", antialiaseds=False))
    if skeleton_vertices is not None and skeleton_edges is not None and len(skeleton_edges):
        S = (np.asarray(skeleton_vertices) - V.mean(axis=0)) @ R.T
        E = np.asarray(skeleton_edges)
        # crude visibility: keep edges not hidden behind the front surface at their endpoints
        seg = S[E]
        zfront = _depth_at(P, F[front], seg.mean(axis=1)[:, :2])
        vis = seg[:, :, 2].mean(axis=1) >= zfront - 0.02 * np.ptp(P[:, 2])
        if skeleton_faces is not None:
            vis &= front[np.asarray(skeleton_faces)[E]].all(axis=1)
        ax.add_collection(LineCollection(seg[vis][:, :, :2], colors="black", linewidths=1.0))
    lo, hi = P[:, :2].min(axis=0), P[:, :2].max(axis=0)
    pad = 0.05 * float((hi - lo).max())
    c = 0.5 * (lo + hi)
    r = 0.5 * float((hi - lo).max()) + pad
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_aspect("equal")
    ax.axis("off")
    if title:
        ax.text(0.02, 0.98, title, transform=ax.transAxes, va="top", fontsize=10)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png")
    except OSError as err:
        raise ExportError(f"cannot write preview {path}: {err}") from None
    finally:
        plt.close(fig)


def render_result(path: str | os.PathLike, result, *, title: str) -> None:
    """Draw a conversion's B-rep (``recon.convert``'s result) to a PNG, faces coloured by kind: the picture of
    ``recon convert --preview`` and of ``recon batch``."""
    from .brep import result_tessellation

    # 2e-3 of the diagonal: finer than a pixel of the picture on any part, coarse enough to draw in a second.
    deflection = result.report["mesh"]["diagonal"] * 2e-3
    v, f, lab, kinds = result_tessellation(result.brep, deflection=deflection)
    render_parts(path, v, f, lab, kinds, title=title)


def _depth_at(P, F, xy, cells=256):
    """Largest front-facing depth per query point, on a coarse grid of triangle centroids (approximate)."""
    cen = P[F].mean(axis=1)
    lo = P[:, :2].min(axis=0)
    span = max(float(np.ptp(P[:, :2], axis=0).max()), 1e-300)
    ij = np.clip(((cen[:, :2] - lo) / span * (cells - 1)).astype(int), 0, cells - 1)
    grid = np.full((cells, cells), -np.inf)
    np.maximum.at(grid, (ij[:, 0], ij[:, 1]), cen[:, 2])
    q = np.clip(((xy - lo) / span * (cells - 1)).astype(int), 0, cells - 1)
    z = grid[q[:, 0], q[:, 1]]
    return np.where(np.isfinite(z), z, -np.inf)
