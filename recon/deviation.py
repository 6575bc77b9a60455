"""Deviation analysis: how far a mesh lies from a B-rep, and the B-rep from the mesh, per face.

This is the check users trust a reconstruction by (as in Geomagic or PolyWorks): distances in both
directions, summarised as max, 95th percentile, RMS and mean, in model units and as a percentage of
the mesh's bounding-box diagonal, and per B-rep face.

* mesh → shape: every mesh vertex, exact signed distance to the B-rep's faces (positive outside
  the solid), see :class:`recon.brep._distance.BrepDistance`;
* shape → mesh: points exactly on the B-rep faces (tessellation nodes plus area-uniform samples),
  unsigned distance to the mesh triangles (``trimesh.proximity.closest_point``, exact to them).
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError

__all__ = ["DeviationStats", "FaceDeviation", "DeviationReport", "deviation", "plot_deviation"]

log = logging.getLogger(__name__)

#: Default number of area-uniform samples on the B-rep for the shape → mesh direction.
DEFAULT_SAMPLES = 20_000
#: Above this many triangles the preview splats points into a z-buffer instead of drawing polygons.
_POLY_LIMIT = 100_000


@dataclass(frozen=True)
class DeviationStats:
    """Summary of one direction's distances (absolute values) in model units."""

    max: float
    p95: float
    rms: float
    mean: float
    count: int
    diagonal: float
    signed_min: float | None = None  # most negative signed distance (inside), mesh → shape only
    signed_max: float | None = None  # most positive signed distance (outside), mesh → shape only

    @classmethod
    def of(cls, values, diagonal: float, *, signed: bool) -> DeviationStats:
        """Statistics of ``values`` ((n,) float, n ≥ 1); ``signed`` adds the signed extremes."""
        v = np.asarray(values, dtype=float)
        a = np.abs(v)
        return cls(
            max=float(a.max()),
            p95=float(np.percentile(a, 95)),
            rms=float(np.sqrt(np.mean(a * a))),
            mean=float(a.mean()),
            count=int(a.size),
            diagonal=float(diagonal),
            signed_min=float(v.min()) if signed else None,
            signed_max=float(v.max()) if signed else None,
        )

    def pct(self, value: float) -> float:
        """``value`` as a percentage of the bounding-box diagonal."""
        return 100.0 * value / self.diagonal if self.diagonal > 0 else float("nan")

    def to_json(self) -> dict:
        out = {k: getattr(self, k) for k in ("max", "p95", "rms", "mean")}
        out.update({f"{k}_pct": self.pct(getattr(self, k)) for k in ("max", "p95", "rms", "mean")})
        out["count"] = self.count
        if self.signed_min is not None:
            out["signed_min"] = self.signed_min
            out["signed_max"] = self.signed_max
        return out


@dataclass(frozen=True)
class FaceDeviation:
    """One B-rep face: the mesh points whose nearest face it is, and the face's own samples.

    ``max``/``rms``/signed extremes are ``None`` when no mesh point is nearest to the face.
    """

    name: str
    type: str
    count: int
    max: float | None
    rms: float | None
    signed_min: float | None
    signed_max: float | None
    shape_to_mesh_max: float | None

    def to_json(self) -> dict:
        return {
            "name": self.name,
            "type": self.type,
            "max": self.max,
            "rms": self.rms,
            "count": self.count,
            "signed_min": self.signed_min,
            "signed_max": self.signed_max,
            "shape_to_mesh_max": self.shape_to_mesh_max,
        }


@dataclass(frozen=True)
class DeviationReport:
    """Result of :func:`deviation`.

    Attributes
    ----------
    diagonal : float
        Bounding-box diagonal of the mesh (the base of the ``*_pct`` values).
    mesh_to_shape, shape_to_mesh : DeviationStats
    faces : tuple of FaceDeviation
        One per B-rep face, in the B-rep's face order.
    signed : (n,) float
        Signed distance of each mesh vertex to the B-rep (positive outside).
    nearest_face : (n,) int64
        Index into ``faces`` of each vertex's nearest face.
    """

    diagonal: float
    mesh_to_shape: DeviationStats
    shape_to_mesh: DeviationStats
    faces: tuple[FaceDeviation, ...]
    signed: np.ndarray = field(repr=False)
    nearest_face: np.ndarray = field(repr=False)

    def to_json(self) -> dict:
        """The report as JSON-ready data: ``{"diagonal", "mesh_to_shape", "shape_to_mesh", "faces"}``."""
        return {
            "diagonal": self.diagonal,
            "mesh_to_shape": self.mesh_to_shape.to_json(),
            "shape_to_mesh": self.shape_to_mesh.to_json(),
            "faces": [f.to_json() for f in self.faces],
        }


def _check_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vertices, dtype=float)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise InputError(f"mesh_vertices: expected a non-empty (n, 3) float array, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise InputError("mesh_vertices: expected finite coordinates, found NaN or inf")
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or not np.issubdtype(f.dtype, np.integer):
        raise InputError(f"mesh_faces: expected a non-empty (m, 3) integer array, got shape {f.shape}")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(f"mesh_faces: indices must lie in [0, {len(v)}), found {f.min()}..{f.max()}")
    return v, f.astype(np.int64)


def deviation(mesh_vertices, mesh_faces, shape_or_step_path, *, samples: int | None = None, rng=None) -> DeviationReport:
    """Distances from a mesh to a B-rep and back, overall and per face.

    Parameters
    ----------
    mesh_vertices : (n, 3) float
        The mesh points measured to the B-rep.
    mesh_faces : (m, 3) int
        Triangles, for the B-rep → mesh direction.
    shape_or_step_path : TopoDS_Shape, build123d/CadQuery shape, str or path-like
        The B-rep, or a STEP file (face names are read from it).
    samples : int, optional
        Area-uniform samples on the B-rep for shape → mesh, besides its tessellation nodes;
        default :data:`DEFAULT_SAMPLES`.
    rng : numpy.random.Generator, optional
        For the samples; default ``np.random.default_rng(0)`` (reproducible reports).

    Returns
    -------
    DeviationReport

    Raises
    ------
    InputError
        Bad mesh arrays, a missing/unreadable STEP file, or a shape without faces.
    """
    import trimesh

    from .brep._distance import BrepDistance
    from .brep._step_read import read_step

    v, f = _check_mesh(mesh_vertices, mesh_faces)
    if samples is not None and (int(samples) != samples or samples < 0):
        raise InputError(f"samples: expected a non-negative integer, got {samples!r}")
    rng = np.random.default_rng(0) if rng is None else rng

    if isinstance(shape_or_step_path, (str, os.PathLike)):
        shape, names = read_step(shape_or_step_path)
    else:
        shape, names = getattr(shape_or_step_path, "wrapped", shape_or_step_path), None
    brep = BrepDistance(shape, rng=rng)
    if names is None:
        names = tuple(f"face_{i}" for i in range(len(brep.faces)))

    diagonal = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    signed, nearest, _ = brep.signed_distance(v)
    log.info("mesh → shape: %d points, max |d| %.4g", len(v), np.nanmax(np.abs(signed)))

    pts, pts_face = brep.surface_samples(DEFAULT_SAMPLES if samples is None else int(samples), rng=rng)
    mesh = trimesh.Trimesh(v, f, process=False)
    _, back, _ = trimesh.proximity.closest_point(mesh, pts)
    log.info("shape → mesh: %d samples, max %.4g", len(pts), back.max())

    faces = []
    for i, (name, kind) in enumerate(zip(names, brep.types)):
        mine = signed[nearest == i]
        theirs = back[pts_face == i]
        faces.append(
            FaceDeviation(
                name=name,
                type=kind,
                count=int(mine.size),
                max=float(np.abs(mine).max()) if mine.size else None,
                rms=float(np.sqrt(np.mean(mine * mine))) if mine.size else None,
                signed_min=float(mine.min()) if mine.size else None,
                signed_max=float(mine.max()) if mine.size else None,
                shape_to_mesh_max=float(theirs.max()) if theirs.size else None,
            )
        )
    return DeviationReport(
        diagonal=diagonal,
        mesh_to_shape=DeviationStats.of(signed, diagonal, signed=True),
        shape_to_mesh=DeviationStats.of(back, diagonal, signed=False),
        faces=tuple(faces),
        signed=signed,
        nearest_face=nearest,
    )


def plot_deviation(mesh_vertices, mesh_faces, signed, path, *, limit: float | None = None,
                   title: str | None = None) -> None:
    """Write a PNG of the mesh coloured by signed distance, with a colour bar in model units.

    Parameters
    ----------
    mesh_vertices : (n, 3) float
    mesh_faces : (m, 3) int
    signed : (n,) float
        Per-vertex signed distance (e.g. ``DeviationReport.signed``).
    path : str or path-like
        Output PNG, written atomically.
    limit : float, optional
        Colour range ±limit; default the largest absolute distance.
    title : str, optional
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib import cm, colors

    from ._io import atomic_path

    v, f = _check_mesh(mesh_vertices, mesh_faces)
    s = np.asarray(signed, dtype=float)
    if s.shape != (len(v),):
        raise InputError(f"signed: expected shape ({len(v)},), got {s.shape}")
    lim = float(np.nanmax(np.abs(s))) if limit is None else float(limit)
    lim = lim if lim > 0 else 1.0
    norm = colors.Normalize(-lim, lim)
    cmap = matplotlib.colormaps["coolwarm"]

    # An isometric-like view from (+x, -y, +z): elevation 30°, azimuth -60° (matplotlib's default).
    elev, azim = np.radians(30.0), np.radians(-60.0)
    right = np.array([-np.sin(azim), np.cos(azim), 0.0])
    towards = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
    up = np.cross(towards, right)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    x, y, depth = (v - centre) @ right, (v - centre) @ up, (v - centre) @ towards

    fig, ax = plt.subplots(figsize=(7, 6), dpi=120)
    if len(f) <= _POLY_LIMIT:
        from matplotlib.collections import PolyCollection

        order = np.argsort(depth[f].mean(axis=1))  # painter's algorithm: far triangles first
        tri2d = np.stack([x[f], y[f]], axis=-1)[order]
        face_val = np.nanmean(s[f], axis=1)[order]
        # Light the colour a little by the facing of each triangle so the shape reads.
        a, b, c = (v[f[order, k]] for k in range(3))
        nrm = np.cross(b - a, c - a)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
        shade = 0.55 + 0.45 * np.abs(nrm @ towards)
        rgba = cmap(norm(face_val))
        rgba[:, :3] *= shade[:, None]
        ax.add_collection(PolyCollection(tri2d, facecolors=rgba, edgecolors="none", antialiaseds=False))
    else:
        # z-buffer splat of the vertices: nearest point per pixel wins.
        res = 900
        span = max(np.ptp(x), np.ptp(y), 1e-300)
        px = np.clip(((x - x.min()) / span * (res - 1)).astype(int), 0, res - 1)
        py = np.clip(((y - y.min()) / span * (res - 1)).astype(int), 0, res - 1)
        pix = py * res + px
        order = np.lexsort((-depth, pix))  # per pixel, the nearest to the viewer first
        first = np.ones(len(order), dtype=bool)
        first[1:] = pix[order][1:] != pix[order][:-1]
        keep = order[first]
        img = np.full((res, res, 4), 1.0)
        img[py[keep], px[keep]] = cmap(norm(s[keep]))
        ax.imshow(img, origin="lower", extent=(x.min(), x.min() + span, y.min(), y.min() + span))
    ax.set_xlim(x.min(), x.max())
    ax.set_ylim(y.min(), y.max())
    ax.set_aspect("equal")
    ax.set_axis_off()
    bar = fig.colorbar(cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.8)
    bar.set_label("signed distance mesh → B-rep (model units, + outside)")
    if title:
        ax.set_title(title)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png")
    finally:
        plt.close(fig)
