"""The segment stage's context (mesh, tolerance, noise, fit memo) and the fits of faces it makes once each."""

from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .._array import row_norms, unique_inverse
from ..fit import MISFIT_SCALE, SurfaceFit, fit_plane, fit_surface, residual_scale
from .._tolerance import SIGMAS_PER_TOLERANCE
from ..mesh import Mesh, stable_argsort
from ._labels import vertices_of

__all__ = ["SegmentContext", "exact_vertices", "fit_members", "fit_parts", "fit_triangles", "misfits",
           "vertex_normals", "ANALYTIC", "CURVED", "MIN_PART_VERTICES", "MIN_CORNER_VERTICES", "MIN_FLAT_VERTICES",
           "GROW_ANGLE_DEG"]

log = logging.getLogger(__name__)

#: Surface types a merge may keep (a B-spline fits anything: merging on it would erase edges).
ANALYTIC = ("plane", "sphere", "cylinder", "cone", "torus")
CURVED = ANALYTIC[1:]

#: A part needs this many distinct vertices to carry a surface of its own (``fit_surface`` needs 16).
MIN_PART_VERTICES = 16
#: A smaller piece may still be a planar face of its own (a chamfer's corner triangle): it needs this many
#: vertices, the fewest a triangle subdivided once has (3 corners, 3 mid-edge points) — three points are
#: any plane, the other three are the evidence.
MIN_CORNER_VERTICES = 6
#: On a noise-free mesh the vertices are exact and a CAD export draws a rectangular face with 2 triangles: 4
#: vertices, 3 for the plane and 1 as evidence (a single triangle is any plane), when its triangles are large
#: beside the mesh's (:data:`recon.segment._labels.DRAWN_AREA_RATIO`).
MIN_FLAT_VERTICES = 4
#: On a noise-free mesh an analytic surface misfits its face when its robust residual is above this share of the
#: tolerance (:func:`recon.segment.grow_faces`); a surface of the face's own type fits it to round-off.
EXACT_MISFIT = 0.05
#: ... when its vertices are exact: the median robust residual of its analytic faces is under this share of the
#: tolerance (round-off is many orders below it; a remeshed model's vertices lie a share of the tolerance off).
EXACT_RESIDUAL = 0.001
#: A triangle lies on a face's surface when its vertices are within tolerance of it and its normal within this
#: angle of the surface's (the angle :func:`recon.decompose.split_by_fitting` grows regions with): well
#: above the normals' scatter under a noise of a quarter of the tolerance, well below a chamfer's 45° turn.
GROW_ANGLE_DEG = 30.0
#: A noise-free part's own normal replaces the mesh's vertex normal where the two differ by more than this: the
#: vertex lies on a sharp edge (30°, the crease a noise-free seed disc does not grow across, `SEED_CREASE_COS`).
OWN_NORMAL_COS = float(np.cos(np.deg2rad(30.0)))


@dataclass(frozen=True)
class SegmentContext:
    """What every pass of the segment stage reads besides the labels and fits: the mesh, the tolerance, the noise,
    and the memo of the fits made so far.

    Attributes
    ----------
    mesh : Mesh
    tolerance : float
        Model units (:func:`recon.convert`'s).
    noise : float or None
        The noise σ a tolerance stands for on a noisy mesh (tolerance / ``SIGMAS_PER_TOLERANCE``); None on a
        noise-free mesh (the decomposition measured σ = 0: a CAD export, whose vertices lie on their surfaces),
        where the residuals are the tessellation's and no surface misfits by the noise.
    memo : dict
        Fits by (tolerance, type bound, triangle set), closed-form probes and regions grown inside faces. The stage
        fits the same part several times over (to dissolve sharp features, after merging, for a small piece's
        neighbours), and a fit depends on nothing but its triangles: each is made once.
    """

    mesh: Mesh
    tolerance: float
    noise: float | None
    memo: dict = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def of(cls, mesh: Mesh, tolerance: float, *, sigma: float) -> "SegmentContext":
        """The context :func:`recon.convert` runs the stage in, for a mesh whose measured noise is ``sigma``: on a
        noisy mesh the tolerance is the noise's 4σ; on a noise-free one (σ = 0) it is a floor."""
        return cls(mesh, float(tolerance), tolerance / SIGMAS_PER_TOLERANCE if sigma > 0 else None)

    @property
    def noise_free(self) -> bool:
        """Whether the mesh is noise-free (the decomposition measured σ = 0): its vertices are exact up to the
        tessellation."""
        return self.noise is None

    @cached_property
    def pairs(self) -> np.ndarray:
        """(e, 2) int: the triangles that share an edge."""
        return np.asarray(self.mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)

    @cached_property
    def vertex_normals(self) -> np.ndarray:
        """(n, 3) area-weighted unit vertex normals of the mesh."""
        m = self.mesh
        return vertex_normals(m.vertices, m.faces, m.face_normals, m.face_areas)

    def vertices(self, tris) -> np.ndarray:
        """The sorted vertex ids of the triangles ``tris``."""
        return vertices_of(self.mesh.faces, tris, len(self.mesh.vertices))


def vertex_normals(vertices: np.ndarray, faces: np.ndarray, face_normals: np.ndarray, areas: np.ndarray):
    """(n, 3) unit normals at the vertices: the area-weighted sum of their triangles' normals."""
    w = face_normals * areas[:, None]
    # np.add.at once per corner, into zeros: bincount adds in input order (corner 0 of every face, then 1, then 2),
    # the same sums at a tenth of the cost
    idx = faces.T.ravel()
    vn = np.stack([np.bincount(idx, weights=np.tile(w[:, j], 3), minlength=len(vertices)) for j in range(3)], axis=1)
    n = row_norms(vn)  # np.linalg.norm(axis=1), bit for bit
    return vn / np.where(n > 0, n, 1.0)[:, None]


def misfits(fit: SurfaceFit, pts: np.ndarray, ctx: SegmentContext) -> bool:
    """Whether ``fit`` is a compromise on the points ``pts``: their robust residual scale is above
    :data:`recon.fit._select.MISFIT_SCALE` × the noise (never on a noise-free mesh, where the residuals are the
    tessellation's)."""
    return ctx.noise is not None and residual_scale(fit, pts) > MISFIT_SCALE * ctx.noise


def exact_vertices(labels: np.ndarray, fits: dict, ctx: SegmentContext) -> bool:
    """Whether the mesh's vertices lie on their surfaces to round-off, as a CAD export's do: the median robust
    residual of its analytic faces is under :data:`EXACT_RESIDUAL` tolerances (:func:`recon.segment.grow_faces`'
    test). Never on a noisy mesh."""
    if not ctx.noise_free:
        return False
    V = ctx.mesh.vertices
    scales = [residual_scale(f, V[ctx.vertices(labels == r)]) for r, f in fits.items() if f.ok and f.type in ANALYTIC]
    return bool(scales) and float(np.median(scales)) <= EXACT_RESIDUAL * ctx.tolerance


def fit_parts(labels: np.ndarray, ctx: SegmentContext, *, only=None, upto: str | None = None,
              progress=None) -> dict[int, SurfaceFit]:
    """One surface per label (or per label in ``only``), fitted to the label's vertices with their normals.

    ``upto``: try only the analytic types up to this one (in :func:`recon.fit.fit_surface`'s order) and no
    B-spline — the same answer whenever the full fit would give one of those types, at a fraction of the cost.
    ``progress(done, total, "parts fitted")``, optional, is told each part fitted.
    """
    if only is not None and len(only) * 8 < labels.max() + 1:  # a few faces: no sort of all the labels
        return {p: fit_members(np.flatnonzero(labels == p), p, upto, ctx) for p in only}
    order = stable_argsort(labels, labels.max() + 1)
    bounds = np.searchsorted(labels[order], np.arange(labels.max() + 2))
    parts = range(labels.max() + 1) if only is None else only
    fits = {}
    for k, p in enumerate(parts, 1):
        fits[p] = fit_members(order[bounds[p] : bounds[p + 1]], p, upto, ctx)
        if progress is not None:
            progress(k, len(parts), "parts fitted")
    return fits


def fit_members(members: np.ndarray, p: int, upto: str | None, ctx: SegmentContext) -> SurfaceFit:
    """The surface of the triangles ``members`` (ascending ids), made once per context (``ctx.memo``); ``p`` names
    the part in the log."""
    memo, tolerance = ctx.memo, ctx.tolerance
    digest = hashlib.sha1(np.asarray(members, dtype=np.int64).tobytes()).digest()
    key = (float(tolerance), upto, digest)
    if key not in memo:
        # The full fit and the fit of every analytic type (upto the last) try the same analytic types in the same
        # way, and differ only where none fits (then the full fit goes on to a B-spline): one's analytic fit
        # within tolerance is the other's.
        other = memo.get((float(tolerance), ANALYTIC[-1] if upto is None else None, digest)) \
            if upto in (None, ANALYTIC[-1]) else None
        if other is not None and other.ok and other.type in ANALYTIC:
            memo[key] = other
        else:
            memo[key] = fit_triangles(ctx.mesh.vertices, ctx.mesh.faces[members], ctx.vertex_normals, tolerance, p,
                                      upto, noise=ctx.noise)
    return memo[key]


def fit_triangles(V, tris, vn, tolerance: float, p: int, upto: str | None = None, *, noise: float | None
                  ) -> SurfaceFit:
    """The surface of one part: its triangles ``tris`` (k, 3) (vertex ids into ``V``, normals ``vn``); ``p`` names
    it in the log. ``noise``: as :attr:`SegmentContext.noise` (None: a noise-free mesh)."""
    ids, local = unique_inverse(tris.ravel(), len(V))  # np.unique(tris, return_inverse=True)
    if (MIN_FLAT_VERTICES if noise is None else MIN_CORNER_VERTICES) <= len(ids) < MIN_PART_VERTICES:  # small faces
        plane = fit_plane(V[ids], tolerance=tolerance)
        if plane.ok:
            return plane
    if len(ids) < MIN_PART_VERTICES:
        return SurfaceFit("plane", {}, {"max": np.nan, "rms": np.nan, "p99": np.nan}, len(ids), False,
                          f"{len(ids)} vertices: too few for a surface")
    local = local.reshape(-1, 3)
    nrm = vn[ids]
    if noise is None:  # where the part's own triangles turn the normal by more than a crease's angle, theirs
        own = own_normals(V, tris, local, len(ids))
        crease = np.einsum("ij,ij->i", own, nrm) < OWN_NORMAL_COS
        nrm = np.where(crease[:, None], own, nrm)
    if upto is not None:
        return fit_surface(V[ids], nrm, tolerance=tolerance, types=ANALYTIC[: ANALYTIC.index(upto) + 1],
                           allow_bspline=False, faces=local, sigma=noise)
    fit = fit_surface(V[ids], nrm, tolerance=tolerance, faces=local, sigma=noise, bspline_normals=vn[ids])
    if not fit.params:  # nothing at all could be fitted: the B-spline must carry it
        log.warning("part %d: no surface fits (%s)", p, fit.reason)
    return fit


def own_normals(V: np.ndarray, tris: np.ndarray, local: np.ndarray, k: int) -> np.ndarray:
    """(k, 3) unit normals at a part's k vertices from its own triangles ``tris`` alone (area-weighted);
    ``local`` numbers their corners 0 … k − 1.

    For a noise-free mesh. Its vertices lie on the true surfaces, and on a CAD tessellation nearly all of them
    on a sharp edge (a hole's strips run from one end circle to the other), where the mesh's vertex normals
    average in the faces beyond the edge: from them a hole's cylinder axis comes out tilted, from the part's own
    triangles it fits to round-off. (The decomposition's region fits use the same rule,
    :func:`recon.decompose._regionfit._region_normals`.) Only the analytic fitters get them: a B-spline over a part
    that is several faces parametrises better over the mesh's normals.
    """
    fn = np.cross(V[tris[:, 1]] - V[tris[:, 0]], V[tris[:, 2]] - V[tris[:, 0]])  # length: twice the area
    out = np.stack([np.bincount(local.ravel(), weights=np.repeat(fn[:, j], 3), minlength=k) for j in range(3)],
                   axis=1)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)
