"""Surface decomposition (Wekel & Hellwich §4): smooth patches, and the junction / linear / terminal parts of
the critical region, from a skeleton pruned by the paper's ω rule."""

from ._core import DEFAULT_THRESHOLD, decompose
from ._evaluate import FaceRecovery, face_recovery
from ._regions import split_by_fitting
from ._types import PART_KINDS, BoundaryCurves, Decomposition, Part, PartKind, SurfaceSkeleton

__all__ = [
    "BoundaryCurves",
    "DEFAULT_THRESHOLD",
    "Decomposition",
    "FaceRecovery",
    "PART_KINDS",
    "Part",
    "PartKind",
    "SurfaceSkeleton",
    "decompose",
    "face_recovery",
    "split_by_fitting",
]
