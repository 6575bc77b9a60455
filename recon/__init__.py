"""recon: triangle mesh → editable B-rep, by the skeleton decomposition of Wekel & Hellwich.

The public API is declared here once; implementation modules are private.
"""

from .batch import BatchRow, convert_many
from .curves import CurveNetwork, curve_network
from .decompose import Decomposition, decompose, face_recovery
from .deviation import DeviationReport, DeviationStats, FaceDeviation, deviation, plot_deviation
from .errors import BrepError, DecompositionError, ExportError, FitError, InputError, MeshError, ReconError
from .fit import CurveFit, SurfaceFit, fit_curve, fit_surface, noise_sigma
from .mesh import CleanReport, Mesh, clean_mesh, input_labels, load_mesh
from .pipeline import Conversion, convert
from .skeleton2d import (
    Part2D,
    SegmentGraph,
    Shape2D,
    Skeleton2D,
    SkeletonResult,
    default_omega_min,
    default_spacing,
    load_shape,
    plot_decomposition,
    shape_from_curves,
    resample_curves,
    shape_from_mask,
    skeletonize,
)

__version__ = "0.1.0"

__all__ = [
    "BatchRow",
    "BrepError",
    "CleanReport",
    "Conversion",
    "convert",
    "convert_many",
    "CurveFit",
    "CurveNetwork",
    "Decomposition",
    "DecompositionError",
    "decompose",
    "face_recovery",
    "DeviationReport",
    "DeviationStats",
    "ExportError",
    "FaceDeviation",
    "FitError",
    "SurfaceFit",
    "fit_curve",
    "fit_surface",
    "noise_sigma",
    "InputError",
    "Mesh",
    "MeshError",
    "Part2D",
    "ReconError",
    "SegmentGraph",
    "Shape2D",
    "Skeleton2D",
    "SkeletonResult",
    "default_omega_min",
    "default_spacing",
    "deviation",
    "curve_network",
    "load_shape",
    "plot_decomposition",
    "plot_deviation",
    "shape_from_curves",
    "resample_curves",
    "shape_from_mask",
    "skeletonize",
]
