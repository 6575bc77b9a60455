"""Proofs that exact vertices lie on no analytic surface: the exact path's early exit for free-form regions.

A sphere, a cylinder, a cone and a torus are each the zero set of a polynomial in a fixed linear span of monomials
(in coordinates centred on the points and scaled to the unit ball, s = x² + y² + z²):

- sphere: {1, x, y, z, s} (5);
- cylinder, cone: every quadric, {1, x, y, z, x², y², z², xy, yz, zx} (10);
- torus: every Darboux cyclide, the quadrics with {s·x, s·y, s·z, s²} (14): (|p−c|² + R² − r²)² = 4R² |(p−c)×a|²
  expands into just these.

A point δ off the zero set of f has |f| = δ |∇f| to first order, so if a surface of the family holds every point
within ``eps``, its coefficient vector c gives Σ f² ≤ eps² Σ |∇f|², i.e. |M c| ≤ eps |J c| with M the points'
monomials and J their stacked gradients (the constant, whose gradient is 0, is taken out by centring M's columns).
The smallest generalised singular value min |M c| / |J c| above that bound proves that no surface of the family
holds them: two small SVDs instead of a nonlinear fit that would fail. Each surface is weighed by its own gradient at
the points, not by the largest gradient any unit coefficient vector has (stop 39: a torus band's quadrics, ruled out
where the bound by the largest gradient was 5× looser; bench/exact.md "s39-time"). numpy only.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FAMILY_OF", "impossible_types"]

#: The monomial family each curved type belongs to (see the module's text).
FAMILY_OF = {"sphere": "sphere", "cylinder": "quadric", "cone": "quadric", "torus": "cyclide"}
_COLUMNS = {"sphere": 5, "quadric": 10, "cyclide": 14}
#: |f| / |∇f| is the distance to the surface within a factor 1 + O(eps / radius) ≪ 2 (round-off is far below any
#: radius a CAD face has); a factor of 2 covers it and the SVDs' round-off with room to spare (the test must never
#: reject a surface that holds the points).
MARGIN = 2.0
#: A coefficient vector's gradient is floored at this share of the largest one's (|J c|² + (FLOOR σ₁ |c|)²): that only
#: lowers the smallest ratio (a weaker proof, never a false one) and keeps the whitening finite where the points leave
#: a polynomial's gradient 0 (a double plane through coplanar points).
FLOOR = 1e-6


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


def least_ratio(M: np.ndarray, J: np.ndarray) -> float:
    """min over coefficient vectors c of |M c| / |J c| (see the module's text): column 0 of ``M`` is the constant,
    taken out by centring the others; ``J`` (n, 3, k) holds the gradients of ``M``'s columns."""
    A = M[:, 1:] - M[:, 1:].mean(axis=0)
    _, S, Vt = np.linalg.svd(J[:, :, 1:].reshape(-1, M.shape[1] - 1), full_matrices=False)
    S = np.sqrt(S * S + (FLOOR * S[0]) ** 2)
    return float(np.linalg.svd((A @ Vt.T) / S, compute_uv=False)[-1])


def impossible_types(P: np.ndarray, eps: float) -> set[str]:
    """The curved types (of :data:`FAMILY_OF`) no surface of which holds every point of ``P`` within ``eps``, as
    proven by the smallest generalised singular value of the family's monomials and their gradients (see the
    module's text). A family with as many columns as points, or more, always has a surface through them: it is never
    ruled out."""
    P = np.asarray(P, dtype=float)
    n = len(P)
    c = P.mean(axis=0)
    r = float(np.linalg.norm(P - c, axis=1).max())
    if r <= 0 or n <= _COLUMNS["sphere"]:
        return set()
    M, J = _monomials((P - c) / r)
    out: set[str] = set()
    for family, cols in _ORDER.items():
        if n > len(cols) and least_ratio(M[:, cols], J[:, :, cols]) > MARGIN * eps / r:
            out.update(t for t, f in FAMILY_OF.items() if f == family)
    return out
