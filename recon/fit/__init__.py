"""Surface and curve fitting (numpy/scipy only; ``recon.brep`` turns the parameters into OpenCascade objects)."""

from ._noise import default_tolerance, estimate_normals, noise_sigma
from ._bspline import BSplineSurface, fit_bspline_surface
from ._primitives import fit_cone, fit_cylinder, fit_plane, fit_sphere, fit_torus
from ._select import fit_surface
from ._surfaces import Cone, Cylinder, Plane, Sphere, Torus
from ._types import CURVE_TYPES, SURFACE_TYPES, CurveFit, SurfaceFit, deviation_stats, within_tolerance

__all__ = [
    "CURVE_TYPES",
    "SURFACE_TYPES",
    "BSplineSurface",
    "Cone",
    "CurveFit",
    "Cylinder",
    "Plane",
    "Sphere",
    "Torus",
    "SurfaceFit",
    "default_tolerance",
    "deviation_stats",
    "estimate_normals",
    "fit_bspline_surface",
    "fit_cone",
    "fit_cylinder",
    "fit_plane",
    "fit_sphere",
    "fit_surface",
    "fit_torus",
    "noise_sigma",
    "within_tolerance",
]
