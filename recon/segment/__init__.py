"""The segment stage: the decomposition's parts refined into the faces of the B-rep, each with its surface.

It starts from :func:`face_labels` (the parts with the sharp features dissolved) and runs :data:`PASSES`, a list of
passes ``(labels, fits, ctx) -> labels`` (``print(describe())`` shows their order); after every pass that changed
something the labels are tidied (:func:`tidy`) and the faces refitted. :class:`SegmentContext` carries the mesh,
the tolerance, the noise and the memo of fits made. numpy/scipy only.
"""

from ._exact import as_decomposition, coplanar_pairs, exact_faces, exact_tessellation, plane_atoms, roundoff
from ._context import SegmentContext, fit_parts, vertex_normals
from ._grow import dissolve_explained, dissolve_misfits, grow_faces
from ._merge import merge_round_bands, merge_same_surface
from ._sharp import face_labels
from ._split import split_unfitted, trim_to_surface
from ._stage import PASSES, Pass, Rounds, describe, refine, segment
from ._tidy import cut_unbounded, tidy

__all__ = [
    "as_decomposition",
    "coplanar_pairs",
    "exact_faces",
    "exact_tessellation",
    "plane_atoms",
    "roundoff",
    "PASSES",
    "Pass",
    "Rounds",
    "SegmentContext",
    "cut_unbounded",
    "describe",
    "dissolve_explained",
    "dissolve_misfits",
    "face_labels",
    "fit_parts",
    "grow_faces",
    "merge_round_bands",
    "merge_same_surface",
    "refine",
    "segment",
    "split_unfitted",
    "tidy",
    "trim_to_surface",
    "vertex_normals",
]
