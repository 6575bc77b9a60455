"""Surface and curve fitting (numpy/scipy only; ``recon.brep`` turns the parameters into OpenCascade objects)."""

from ._curves import fit_bspline_curve, fit_circle, fit_curve, fit_edge_curve, fit_line, point_curve, polyline_curve
from ._noise import default_tolerance, estimate_normals, noise_sigma, ring_noise
from ._blend import fit_rolling_ball, ruled_surface
from ._bspline import chord_guides, fit_bspline_surface, fit_exact_bspline
from ._primitives import fit_cone, fit_cylinder, fit_plane, fit_sphere, fit_torus
from ._select import ANALYTIC_FITTERS, MISFIT_SCALE, fit_surface, residual_scale
from ._quickfit import quick_fit, surface_normals
from ._geometry import (CLOSED_KINDS, BSplineCurve, BSplineSurface, Circle, Cone, CurveKind, Cylinder, EdgeCurve, Line, Plane, Sphere,
                        SurfaceKind, Torus)
from ._types import (ACCEPT_MAX_FACTOR, CURVE_TYPES, MAD_TO_SIGMA, SURFACE_TYPES, CurveFit, SurfaceFit, deviation_stats,
                     within_tolerance)

__all__ = [
    "ACCEPT_MAX_FACTOR",
    "ANALYTIC_FITTERS",
    "CLOSED_KINDS",
    "CURVE_TYPES",
    "MAD_TO_SIGMA",
    "MISFIT_SCALE",
    "SURFACE_TYPES",
    "BSplineCurve",
    "BSplineSurface",
    "Circle",
    "Line",
    "Cone",
    "CurveFit",
    "CurveKind",
    "EdgeCurve",
    "Cylinder",
    "Plane",
    "Sphere",
    "Torus",
    "SurfaceFit",
    "SurfaceKind",
    "default_tolerance",
    "deviation_stats",
    "estimate_normals",
    "fit_bspline_curve",
    "chord_guides",
    "fit_bspline_surface",
    "fit_exact_bspline",
    "fit_circle",
    "fit_curve",
    "fit_edge_curve",
    "fit_line",
    "fit_cone",
    "fit_cylinder",
    "fit_plane",
    "fit_sphere",
    "fit_surface",
    "fit_torus",
    "fit_rolling_ball",
    "noise_sigma",
    "ring_noise",
    "point_curve",
    "polyline_curve",
    "quick_fit",
    "residual_scale",
    "ruled_surface",
    "surface_normals",
    "within_tolerance",
]
