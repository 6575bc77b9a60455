"""B-rep stage: the only package that imports build123d / OCP (see shared/DESIGN.md).

Curve network + one surface per part → a closed, valid solid (:func:`build_solid`), written as STEP
with a name and colour per face, BREP or STL (:func:`write_shape`).
"""

from ._build import build_solid
from ._export import read_step_faces, write_shape
from ._result import KIND_COLOURS, BrepResult, FaceRecord, FaceStatus, Validity, shape_validity
from ._step_read import read_step  # noqa: F401  (recon compare; see recon.deviation)
from ._surfaces import SurfaceModel, surface_model
from ._tessellate import labelled_tessellation, result_tessellation

__all__ = [
    "KIND_COLOURS",
    "BrepResult",
    "FaceRecord",
    "FaceStatus",
    "SurfaceModel",
    "Validity",
    "build_solid",
    "labelled_tessellation",
    "result_tessellation",
    "read_step_faces",
    "shape_validity",
    "surface_model",
    "write_shape",
]
