"""The default tolerance: one rule, ``max(4 σ, floor · diagonal)``, for every stage that needs one.

The rule and its numbers live here alone; :func:`recon.fit.default_tolerance` (a point set fitted on its own),
the decomposition (a mesh) and :func:`recon.convert` call :func:`tolerance_for`. Imports nothing of recon.
"""

from __future__ import annotations

import math

__all__ = ["FIT_FLOOR", "MESH_FLOOR", "SIGMAS_PER_TOLERANCE", "SMOOTH_TURN", "tolerance_for"]

#: The tolerance in noise σ: the 99th percentile of |N(0, σ)| is 2.58σ, so a fit of the right type passes the
#: acceptance rule (p99 ≤ tol, max ≤ 2·tol) with room for its own parameter error, and the max over 10⁵ points
#: (≈ 4.9σ) stays under 2·tol = 8σ.
SIGMAS_PER_TOLERANCE = 4.0
#: Floor for a point set fitted on its own, as a share of its diagonal: a noise-free point set is not asked to
#: agree at the level of float round-off.
FIT_FLOOR = 1e-4
#: Floor for a mesh, as a share of its diagonal: a tessellated CAD model has exact planes (zero noise) but its
#: curved faces carry the exporter's rounding and chordal placement, a few 1e-4 of the diagonal.
MESH_FLOOR = 5e-4
#: Neighbouring triangles that turn by less than this may tessellate one curved face (CAD exporters bound the turn by
#: their angular deflection: 0.5 rad ≈ 29° by default in OpenCascade and FreeCAD, a doubly curved face's facets turn
#: by more across their diagonals); a larger turn is a crease, where the B-rep's edge lies on the mesh's edge and the
#: faces meet the triangles without sag. A box's 90° and an octagonal prism's 45° are creases.
SMOOTH_TURN = math.radians(45.0)


def tolerance_for(sigma: float, diagonal: float, *, floor: float = FIT_FLOOR) -> float:
    """``max(SIGMAS_PER_TOLERANCE · sigma, floor · diagonal)``: the default tolerance for noise ``sigma`` on a part
    of bounding-box ``diagonal``.

    >>> tolerance_for(0.01, 100.0)
    0.04
    >>> tolerance_for(0.0, 100.0, floor=MESH_FLOOR)
    0.05
    """
    return max(SIGMAS_PER_TOLERANCE * float(sigma), floor * diagonal)
