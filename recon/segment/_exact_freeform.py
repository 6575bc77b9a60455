"""Proofs that exact vertices lie on no analytic surface: the exact path's early exit for free-form regions.

A sphere, a cylinder, a cone and a torus are each the zero set of a polynomial in a fixed linear span of monomials
(in coordinates centred on the points and scaled to the unit ball, s = x² + y² + z²):

- sphere: {1, x, y, z, s} (5);
- cylinder, cone: every quadric, {1, x, y, z, x², y², z², xy, yz, zx} (10);
- torus: every Darboux cyclide, the quadrics with {s·x, s·y, s·z, s²} (14): (|p−c|² + R² − r²)² = 4R² |(p−c)×a|²
  expands into just these.

If a surface of the family holds every point within ``eps``, its coefficient vector c (|c| = 1) gives
|M c| ≤ √n · eps · G with M the points' monomials and G the largest norm of the monomials' Jacobian over the points
(a point ``eps`` off the surface has |f| ≤ eps |∇f| ≤ eps G). So the smallest singular value of M above that bound
proves that no surface of the family holds them: one SVD instead of a nonlinear fit that would fail. numpy only.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FAMILY_OF", "impossible_types"]

#: The monomial family each curved type belongs to (see the module's text).
FAMILY_OF = {"sphere": "sphere", "cylinder": "quadric", "cone": "quadric", "torus": "cyclide"}
_COLUMNS = {"sphere": 5, "quadric": 10, "cyclide": 14}
#: |∇f| varies over the ``eps``-neighbourhood of a point by O(eps / radius) ≪ 1; a factor of 2 covers it and the
#: round-off of the SVD with room to spare (the test must never reject a surface that holds the points).
MARGIN = 2.0


def _monomials(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n, 14) the cyclide monomials of the points and (n, 3, 14) their Jacobians (:data:`_ORDER`: the columns
    each family takes)."""
    x, y, z = P[:, 0], P[:, 1], P[:, 2]
    s = x * x + y * y + z * z
    one, zero = np.ones_like(x), np.zeros_like(x)
    cols = [one, x, y, z, s, x * x, y * y, x * y, y * z, z * x, s * x, s * y, s * z, s * s]
    # d/dx, d/dy, d/dz of each column
    jx = [zero, one, zero, zero, 2 * x, 2 * x, zero, y, zero, z, s + 2 * x * x, 2 * x * y, 2 * x * z, 4 * s * x]
    jy = [zero, zero, one, zero, 2 * y, zero, 2 * y, x, z, zero, 2 * x * y, s + 2 * y * y, 2 * y * z, 4 * s * y]
    jz = [zero, zero, zero, one, 2 * z, zero, zero, zero, y, x, 2 * x * z, 2 * y * z, s + 2 * z * z, 4 * s * z]
    M = np.stack(cols, axis=1)
    J = np.stack([np.stack(jx, axis=1), np.stack(jy, axis=1), np.stack(jz, axis=1)], axis=1)  # (n, 3, 14)
    return M, J


#: Columns of :func:`_monomials` each family spans: s with x², y² stands for z² (s − x² − y²), the same span.
_ORDER = {"sphere": [0, 1, 2, 3, 4], "quadric": list(range(10)), "cyclide": list(range(14))}


def impossible_types(P: np.ndarray, eps: float) -> set[str]:
    """The curved types (of :data:`FAMILY_OF`) no surface of which holds every point of ``P`` within ``eps``, as
    proven by the smallest singular value of the family's monomials (see the module's text). A family with as many
    columns as points, or more, always has a surface through them: it is never ruled out."""
    P = np.asarray(P, dtype=float)
    n = len(P)
    c = P.mean(axis=0)
    r = float(np.linalg.norm(P - c, axis=1).max())
    if r <= 0 or n <= _COLUMNS["sphere"]:
        return set()
    Q = (P - c) / r
    M, J = _monomials(Q)
    out: set[str] = set()
    for family, cols in _ORDER.items():
        if n <= len(cols):
            continue
        sigma = float(np.linalg.svd(M[:, cols], compute_uv=False)[-1])
        grad = float(np.linalg.norm(J[:, :, cols], ord=2, axis=(1, 2)).max())
        if sigma > MARGIN * np.sqrt(n) * (eps / r) * grad:
            out.update(t for t, f in FAMILY_OF.items() if f == family)
    return out
