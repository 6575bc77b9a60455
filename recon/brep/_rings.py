"""Point in polygon for a face's UV rings: the crossing test of ``matplotlib.path.Path.contains_points``, in numpy.

The B-rep distance classifies every sample's UV against its face's boundary rings; matplotlib's test was the only
reason ``recon convert`` imported matplotlib (0.15–0.2 s of its start-up, see bench/speed.md). This is the same
test on the same numbers — W. R. Franklin's / E. Haines's crossing count as matplotlib's ``point_in_path_impl``
has it, an implicitly closed ring, the same comparisons in the same floating-point order — so every answer is the
same, boundary points included (``tests/test_brep_rings.py`` compares them). numpy only.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ring_contains"]

#: Edge × point pairs evaluated at once (bounds the temporary arrays to a few tens of MB).
_PAIRS = 1 << 21


def ring_contains(ring: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n,) bool: ``matplotlib.path.Path(ring).contains_points(points)`` for a (r, 2) ring without NaNs.

    A point is inside when a ray towards +x crosses an odd number of the ring's edges (the last vertex joined to the
    first). An edge counts when its ends lie on either side of the point's y (``y >= ty`` tells the side) and its
    crossing is at or right of the point, decided without a division as matplotlib does:
    ``((y1 - ty) * (x0 - x1) >= (x1 - tx) * (y0 - y1)) == (y1 >= ty)``. Fewer than 3 vertices: nothing inside;
    a point with a non-finite coordinate is not inside. Only the pairs that straddle are evaluated: with the points
    sorted by y, an edge's are those with ``min(y0, y1) < ty <= max(y0, y1)``, one slice."""
    ring = np.asarray(ring, dtype=float)
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    finite = np.isfinite(pts).all(axis=1) if n else np.zeros(0, dtype=bool)
    if len(ring) < 3 or not finite.any():
        return np.zeros(n, dtype=bool)
    keep = np.flatnonzero(finite)
    order = keep[np.argsort(pts[keep, 1], kind="stable")]
    tys = pts[order, 1]
    x0, y0 = ring[:, 0], ring[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    lo = np.searchsorted(tys, np.minimum(y0, y1), side="right")
    hi = np.searchsorted(tys, np.maximum(y0, y1), side="right")
    count = np.zeros(n, dtype=np.int64)
    ends = np.cumsum(hi - lo)
    e = 0
    while e < len(ring):  # edges in batches of about _PAIRS straddling pairs
        f = max(e + 1, int(np.searchsorted(ends, (ends[e - 1] if e else 0) + _PAIRS, side="right")))
        length = hi[e:f] - lo[e:f]
        edge = np.repeat(np.arange(e, f), length)
        at = np.arange(len(edge)) - np.repeat(np.cumsum(length) - length, length) + np.repeat(lo[e:f], length)
        who = order[at]
        tx, ty = pts[who, 0], pts[who, 1]
        hit = ((y1[edge] - ty) * (x0[edge] - x1[edge]) >= (x1[edge] - tx) * (y0[edge] - y1[edge])) == (y1[edge] >= ty)
        count += np.bincount(who[hit], minlength=n)
        e = f
    return (count & 1).astype(bool)
