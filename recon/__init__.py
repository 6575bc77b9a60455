"""recon: triangle mesh → editable B-rep, by the skeleton decomposition of Wekel & Hellwich.

The public API is declared here once; implementation modules are private.
Names load on first use (PEP 562, as scikit-image's lazy_loader): ``import recon`` stays light, so the ``recon``
command can set up its signal handlers and thread limits before numpy, scipy or OpenCascade load.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from typing import Any

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
    **dict.fromkeys(["build_solid", "write_shape"], ".brep"),
    **dict.fromkeys(["BatchRow", "convert_many"], ".batch"),
    **dict.fromkeys(["to_cadquery"], ".brep._cadquery"),
    **dict.fromkeys(["Part2D", "SegmentGraph", "Shape2D", "Skeleton2D", "SkeletonResult", "default_omega_min",
                     "default_spacing", "load_shape", "plot_decomposition", "shape_from_curves", "resample_curves",
                     "shape_from_mask", "skeletonize"], ".skeleton2d"),
}


def _register_lazily(name: str) -> None:
    """Put the submodule ``recon.<name>`` in ``sys.modules`` now, its code to run on first use (stdlib LazyLoader).

    ``recon.decompose`` and ``recon.deviation`` name a public function and the submodule that defines it. Python binds
    a submodule as an attribute of its package when the import system first loads it, so whichever module imported
    ``recon.decompose`` first would have replaced the function. Registered here, they are never loaded through that
    path: ``recon.<name>`` stays the function, ``import recon.<name>`` and ``from recon.<name> import x`` work as ever.
    (Where LazyLoader is not thread-safe, as in CPython 3.11 (CPython issue 114763), two threads whose first use of one
    of these modules coincides may see it half-run; recon's own parallelism is processes, each importing in one thread.)
    """
    spec = importlib.util.find_spec(f"{__name__}.{name}")
    assert spec is not None and spec.loader is not None, name  # (our own files)
    spec.loader = importlib.util.LazyLoader(spec.loader)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)


for _name in [name for name, source in _SOURCES.items() if source == f".{name}"]:  # decompose, deviation
    if f"{__name__}.{_name}" not in sys.modules:
        _register_lazily(_name)
del _name


def __getattr__(name: str) -> Any:
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


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


__version__ = "0.1.0"

__all__ = [
    "BatchRow",
    "BrepError",
    "build_solid",
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
    "to_cadquery",
    "write_shape",
]
