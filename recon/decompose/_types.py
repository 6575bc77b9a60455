"""Result of the surface decomposition (Wekel & Hellwich §4): parts, their boundaries and the skeleton."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

__all__ = ["PART_KINDS", "Part", "PartKind", "BoundaryCurves", "SurfaceSkeleton", "Decomposition"]

class PartKind(StrEnum):
    """A part's kind: a smooth patch, or one of the three base types of §3 in the critical region (a value equals
    its name in reports, ``PartKind.PATCH == "patch"``)."""

    PATCH = "patch"
    JUNCTION = "junction"
    LINEAR = "linear"
    TERMINAL = "terminal"


#: Smooth patches, then the three base types of §3 in the critical region.
PART_KINDS = tuple(PartKind)


@dataclass(frozen=True)
class Part:
    """One part of the decomposition.

    Attributes
    ----------
    id : int
        The label its triangles carry in ``Decomposition.labels``.
    kind : PartKind
        ``"patch"`` (a smooth region one face covers), ``"junction"`` (three or more feature lines
        meet), ``"linear"`` (a feature between two patches) or ``"terminal"`` (a feature that fades out).
    sharp : bool
        For linear parts and junctions: the part is no wider than the feature scale, i.e. a sharp
        edge/corner seen through the smoothing window rather than a blend with a width of its own.
    neighbours : tuple of int
        Ids of the parts sharing a mesh edge with this one, ascending.
    n_triangles : int
    area : float
    """

    id: int
    kind: PartKind
    sharp: bool
    neighbours: tuple[int, ...]
    n_triangles: int
    area: float


@dataclass(frozen=True)
class BoundaryCurves:
    """Polylines between neighbouring parts, packed like shapely: ``coords[offsets[i]:offsets[i+1]]``.

    Attributes
    ----------
    coords : (p, 3) float
    vertex_ids : (p,) int
        Mesh vertex index of each coordinate.
    offsets : (b + 1,) int
    parts : (b, 2) int
        The two part ids each curve separates, smaller first.
    closed : (b,) bool
        The curve is a loop (its first point is not repeated at the end).
    """

    coords: np.ndarray
    vertex_ids: np.ndarray
    offsets: np.ndarray
    parts: np.ndarray
    closed: np.ndarray

    def __len__(self) -> int:
        return len(self.parts)

    def curve(self, i: int) -> np.ndarray:
        """(q, 3) float: the points of curve ``i``."""
        return self.coords[self.offsets[i] : self.offsets[i + 1]]


@dataclass(frozen=True)
class SurfaceSkeleton:
    """The pruned skeleton of the critical region (§2 carried to the surface).

    Nodes are critical triangles the skeleton passes through (placed at their centroids); an edge joins
    two triangles across a mesh edge whose end vertices have generating boundary points with
    ``ω > ω_min`` (§2, condition 3; ``ω = ∞`` between different boundary curves).

    Attributes
    ----------
    vertices : (k, 3) float
    edges : (e, 2) int
    faces : (k,) int
        The mesh triangle of each skeleton vertex.
    """

    vertices: np.ndarray
    edges: np.ndarray
    faces: np.ndarray

    @property
    def degree(self) -> np.ndarray:
        """(k,) int: number of skeleton edges at each vertex (1 terminal, 2 linear, ≥3 junction)."""
        return np.bincount(self.edges.ravel(), minlength=len(self.vertices))


@dataclass(frozen=True)
class Decomposition:
    """Smooth patches and the segment graph of the critical region, one label per triangle.

    Attributes
    ----------
    labels : (m,) int
        Part id of every triangle of the mesh that was decomposed.
    parts : tuple of Part
        Indexed by id.
    curves : BoundaryCurves
    skeleton : SurfaceSkeleton
    scale : float
        Feature scale used (standard deviation of the smoothing window, mesh units).
    omega_min : float
        Pruning threshold used (arc length, mesh units).
    threshold : float
        Feature-measure threshold between smooth and critical.
    noise : float
        Estimated vertex noise (mesh units).
    critical : (m,) bool
        Triangles of the critical region.
    tolerance : float
        Distance within which a triangle counted as lying on a patch's fitted surface (mesh units): the
        fit-based tolerance ``max(4 σ, 5e-4 · diagonal)`` with σ measured on the fitted smooth faces, or the
        ``tolerance`` given to :func:`decompose`.
    extra : dict
        ``"fits"``: {part id: SurfaceFit} — the analytic surface each patch was grown on, and, for a linear
        part or junction that one blend surface covers (≥ 80 % of its area), that blend's surface. Free-form
        patches (no analytic surface fits) have no entry; the fits are of the regions before orphans were
        absorbed, so a caller that relabels triangles should refit.
    """

    labels: np.ndarray
    parts: tuple[Part, ...]
    curves: BoundaryCurves
    skeleton: SurfaceSkeleton
    scale: float
    omega_min: float
    threshold: float
    noise: float
    critical: np.ndarray
    tolerance: float = float("nan")
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def count(self, kind: str) -> int:
        """Number of parts of one kind."""
        return sum(p.kind == kind for p in self.parts)

    def counts(self) -> dict[str, int]:
        """Number of parts of each kind, e.g. ``{"patch": 6, "junction": 8, "linear": 12, "terminal": 0}``."""
        return {k: self.count(k) for k in PART_KINDS}

    def to_json(self, *, triangle_labels: np.ndarray | None = None) -> dict:
        """The JSON document of ``recon decompose --json``.

        Parameters
        ----------
        triangle_labels : (m0,) int, optional
            Labels mapped to the input file's triangles (−1 where cleaning dropped one); default ``labels``.
        """
        labels = self.labels if triangle_labels is None else triangle_labels
        counts = np.bincount(self.labels, minlength=len(self.parts))
        return {
            "triangle_labels": np.asarray(labels).tolist(),
            "parts": [
                {
                    "id": p.id,
                    "kind": p.kind,
                    "sharp": p.sharp,
                    "neighbours": list(p.neighbours),
                    "triangles": int(counts[p.id]),
                    "area": p.area,
                }
                for p in self.parts
            ],
            "skeleton": {"vertices": self.skeleton.vertices.tolist(), "edges": self.skeleton.edges.tolist()},
            "scale": self.scale,
            "omega_min": self.omega_min,
            "threshold": self.threshold,
            "noise": self.noise,
            "tolerance": self.tolerance,
        }
