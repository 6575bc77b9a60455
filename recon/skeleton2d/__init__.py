"""The paper's 2D method: Voronoi skeleton with linear-time pruning (§2) and the dual Delaunay decomposition (§3)."""

from ._plot import plot_decomposition
from ._skeleton import default_omega_min, default_spacing, resample_curves, skeletonize
from ._readers import load_shape, shape_from_curves, shape_from_mask
from ._types import PART_KINDS, Part2D, SegmentGraph, Shape2D, Skeleton2D, SkeletonResult

__all__ = ["PART_KINDS", "Part2D", "SegmentGraph", "Shape2D", "Skeleton2D", "SkeletonResult",
           "load_shape", "plot_decomposition", "shape_from_curves", "shape_from_mask",
           "default_omega_min", "default_spacing", "resample_curves", "skeletonize"]
