"""recon: triangle mesh → editable B-rep, by the skeleton decomposition of Wekel & Hellwich.

The public API is declared here once; implementation modules are private.
Names load on first use (PEP 562, as scikit-image's lazy_loader): ``import recon`` stays light, so the ``recon``
command can set up its signal handlers and thread limits before numpy, scipy or OpenCascade load.
"""

import importlib
import sys
import types

#: Public name -> the submodule that defines it.
_SOURCES = {
    **dict.fromkeys(["CurveNetwork", "curve_network"], ".network"),
    **dict.fromkeys(["Decomposition", "decompose", "face_recovery"], ".decompose"),
    **dict.fromkeys(["DeviationReport", "DeviationStats", "FaceDeviation", "deviation", "plot_deviation"],
                    ".deviation"),
    **dict.fromkeys(["BrepError", "DecompositionError", "ExportError", "FitError", "InputError", "MeshError",
                     "ReconError"], ".errors"),
    **dict.fromkeys(["CurveFit", "SurfaceFit", "fit_curve", "fit_surface", "noise_sigma"], ".fit"),
    **dict.fromkeys(["CleanReport", "Mesh", "clean_mesh", "input_labels", "load_mesh"], ".mesh"),
    **dict.fromkeys(["Conversion", "convert"], ".pipeline"),
    **dict.fromkeys(["BatchRow", "convert_many"], ".batch"),
    **dict.fromkeys(["Part2D", "SegmentGraph", "Shape2D", "Skeleton2D", "SkeletonResult", "default_omega_min",
                     "default_spacing", "load_shape", "plot_decomposition", "shape_from_curves", "resample_curves",
                     "shape_from_mask", "skeletonize"], ".skeleton2d"),
}


class _Package(types.ModuleType):
    """``recon.deviation`` and ``recon.decompose`` name a function and the submodule that defines it. Importing a
    submodule sets it as the package's attribute; the function is what the package has always offered there."""

    def __setattr__(self, name, value):
        if isinstance(value, types.ModuleType) and _SOURCES.get(name) == f".{name}" and hasattr(value, name):
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name: str):
    if name in _SOURCES:
        value = getattr(importlib.import_module(_SOURCES[name], __name__), name)
        globals()[name] = value  # once loaded, a plain attribute
        return value
    try:  # ``recon.fit`` and the like, as when this file imported them all
        return importlib.import_module(f".{name}", __name__)
    except ModuleNotFoundError as err:
        if err.name != f"{__name__}.{name}":
            raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))


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
