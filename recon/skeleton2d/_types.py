"""Data of the 2D method (Wekel & Hellwich §2–3): shapes in, skeleton and parts out.

Bulk data are numpy arrays; results are frozen dataclasses (see shared/STYLE.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Shape2D", "Skeleton2D", "Part2D", "SegmentGraph", "SkeletonResult", "PART_KINDS"]

#: The three base types of §3, in the order the JSON and the plot use.
PART_KINDS = ("junction", "terminal", "linear")


@dataclass(frozen=True)
class Shape2D:
    """A 2D shape given by closed, non-intersecting boundary curves (outer boundaries and holes, any orientation).

    Attributes
    ----------
    curves : tuple of (k_i, 2) float
        Each curve's points in order; the first point is not repeated at the end.
    """

    curves: tuple[np.ndarray, ...]

    @property
    def bounds(self) -> np.ndarray:
        """(2, 2) float: ``[[xmin, ymin], [xmax, ymax]]``."""
        pts = np.concatenate(self.curves)
        return np.array([pts.min(axis=0), pts.max(axis=0)])

    @property
    def diagonal(self) -> float:
        """Length of the bounding-box diagonal."""
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))


@dataclass(frozen=True)
class Skeleton2D:
    """The pruned Voronoi skeleton (§2).

    Attributes
    ----------
    vertices : (n, 2) float
    radius : (n,) float
        Distance of each vertex to its generating boundary points (the radius of its empty circle).
    edges : (e, 2) int
        Vertex index pairs.
    """

    vertices: np.ndarray
    radius: np.ndarray
    edges: np.ndarray

    @property
    def degree(self) -> np.ndarray:
        """(n,) int: number of skeleton edges at each vertex."""
        return np.bincount(self.edges.ravel(), minlength=len(self.vertices))


@dataclass(frozen=True)
class Part2D:
    """One part of the decomposition (§3).

    Attributes
    ----------
    kind : str
        ``"junction"``, ``"terminal"`` or ``"linear"``.
    polygon : (p, 2) float
        Outer boundary, counter-clockwise, first point not repeated.
    holes : tuple of (q, 2) float
        Inner boundaries (a closed linear chain around a hole is one part with a hole).
    skeleton_vertices : (a,) int
        Indices into ``Skeleton2D.vertices`` of the vertices inside this part.
    skeleton_edges : (b,) int
        Indices into ``Skeleton2D.edges`` of the edges this part owns (bridges are owned by the segment graph).
    boundary_segments : (c, 2) int
        Pairs of indices into ``SkeletonResult.points``: the sampled boundary edges on this part's border.
    """

    kind: str
    polygon: np.ndarray
    holes: tuple[np.ndarray, ...]
    skeleton_vertices: np.ndarray
    skeleton_edges: np.ndarray
    boundary_segments: np.ndarray

    @property
    def area(self) -> float:
        """Area of the polygon less its holes."""
        return _ring_area(self.polygon) - sum(_ring_area(h) for h in self.holes)


@dataclass(frozen=True)
class SegmentGraph:
    """The segment graph G of §3: parts are nodes, bridges with their separator edges are edges.

    Attributes
    ----------
    edges : (g, 2) int
        Pairs of part indices.
    bridges : (g,) int
        Index into ``Skeleton2D.edges`` of the bridge behind each graph edge.
    separators : (g, 2) int
        The separator edge of each bridge: its dual Delaunay edge, as two indices into ``SkeletonResult.points``.
    """

    edges: np.ndarray
    bridges: np.ndarray
    separators: np.ndarray


@dataclass(frozen=True)
class SkeletonResult:
    """Skeleton and decomposition of one shape, with the sampling they were computed on.

    Attributes
    ----------
    points : (N, 2) float
        The resampled boundary points (the Voronoi sites).
    curve : (N,) int
        Index of the boundary curve each point lies on.
    potential : (N,) float
        Curve potential φ: arc length from the curve's reference point (§2).
    curve_length : (C,) float
        Length of each boundary curve.
    skeleton : Skeleton2D
    parts : tuple of Part2D
    segment_graph : SegmentGraph
    omega_min : float
        The pruning threshold used (shape units).
    spacing : float
        The boundary sampling spacing used (shape units).
    """

    points: np.ndarray
    curve: np.ndarray
    potential: np.ndarray
    curve_length: np.ndarray
    skeleton: Skeleton2D
    parts: tuple[Part2D, ...]
    segment_graph: SegmentGraph
    omega_min: float
    spacing: float
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def to_json(self) -> dict:
        """The JSON document of ``recon skeleton --json``."""
        sk = self.skeleton
        return {
            "skeleton": {
                "vertices": sk.vertices.tolist(),
                "radius": sk.radius.tolist(),
                "edges": sk.edges.tolist(),
            },
            "parts": [
                {"kind": p.kind, "polygon": p.polygon.tolist(), "holes": [h.tolist() for h in p.holes]}
                for p in self.parts
            ],
            "segment_graph": {"edges": self.segment_graph.edges.tolist()},
            "omega_min": self.omega_min,
            "spacing": self.spacing,
        }


def _ring_area(ring: np.ndarray) -> float:
    x, y = ring[:, 0], ring[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
