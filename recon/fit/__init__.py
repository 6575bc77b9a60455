"""Surface and curve fitting (numpy/scipy only; ``recon.brep`` turns the parameters into OpenCascade objects)."""

from ._curves import fit_bspline_curve, fit_circle, fit_curve, fit_line
from ._noise import default_tolerance, estimate_normals, noise_sigma
from ._blend import fit_rolling_ball, ruled_surface
from ._bspline import fit_bspline_surface
from ._primitives import fit_cone, fit_cylinder, fit_plane, fit_sphere, fit_torus
from ._select import fit_surface
from ._geometry import BSplineCurve, BSplineSurface, Circle, Cone, Cylinder, Line, Plane, Sphere, Torus
from ._types import CURVE_TYPES, SURFACE_TYPES, CurveFit, SurfaceFit, deviation_stats, within_tolerance

__all__ = [
    "CURVE_TYPES",
    "SURFACE_TYPES",
    "BSplineCurve",
    "BSplineSurface",
    "Circle",
    "Line",
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
    "fit_bspline_curve",
    "fit_bspline_surface",
    "fit_circle",
    "fit_curve",
    "fit_line",
    "fit_cone",
    "fit_cylinder",
    "fit_plane",
    "fit_sphere",
    "fit_surface",
    "fit_torus",
    "fit_rolling_ball",
    "noise_sigma",
    "ruled_surface",
    "within_tolerance",
]
