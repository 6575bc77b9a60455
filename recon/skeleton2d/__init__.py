"""The paper's 2D method: Voronoi skeleton with linear-time pruning (§2) and the dual Delaunay decomposition (§3)."""

from ._types import PART_KINDS, Part2D, SegmentGraph, Shape2D, Skeleton2D, SkeletonResult

__all__ = ["PART_KINDS", "Part2D", "SegmentGraph", "Shape2D", "Skeleton2D", "SkeletonResult"]
