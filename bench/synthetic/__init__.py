"""Seeded synthetic shapes with exact ground truth, for tests and benchmarks (not part of recon).

- :mod:`.samples`: points on known surface patches (plane, sphere, cylinder, cone, torus) with their true normals,
  Gaussian noise, random poses;
- :mod:`.rounded_box`: a triangulated rounded box with the true face of every triangle, without a CAD kernel.
"""

from .rounded_box import rounded_box
from .samples import (
    add_noise,
    random_rotation,
    sample_cone,
    sample_cylinder,
    sample_plane,
    sample_sphere,
    sample_torus,
)

__all__ = [
    "add_noise",
    "random_rotation",
    "rounded_box",
    "sample_cone",
    "sample_cylinder",
    "sample_plane",
    "sample_sphere",
    "sample_torus",
]
