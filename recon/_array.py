"""Array helpers every stage uses: point validation, unit vectors, row norms and sums, bit for bit numpy's.

This module imports nothing of recon, so the mesh layer and the fitters can both stand on it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["HELPER_COS", "as_points", "axis_helper", "x_or_y_helper",
           "col_means", "col_sums", "columns", "cross3", "extent", "height_radius", "perpendicular_frame",
           "row_norms", "row_sums", "unique_inverse", "unit"]


def as_points(points, name: str = "points", *, min_count: int = 1,
              error: type[Exception] = ValueError) -> np.ndarray:
    """Validate ``points`` as an (n, 3) finite float array with n ≥ ``min_count``; raise ``error`` otherwise
    (the caller's error class: this module imports nothing of recon)."""
    try:
        a = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as err:
        raise error(f"`{name}` must be an (n, 3) float array") from err
    if a.ndim != 2 or a.shape[1] != 3:
        raise error(f"`{name}` must be an (n, 3) float array, got shape {a.shape}")
    if len(a) < min_count:
        raise error(f"`{name}` needs at least {min_count} points, got {len(a)}")
    if not np.all(np.isfinite(a)):
        raise error(f"`{name}` contains NaN or inf")
    return a


def cross3(a, b) -> np.ndarray:
    """``np.cross(a, b)`` of two 3-vectors, bit for bit (numpy forms the same products and differences), without
    its array machinery: the fitters' frames call it thousands of times."""
    a0, a1, a2 = a.tolist() if isinstance(a, np.ndarray) else a
    b0, b1, b2 = b.tolist() if isinstance(b, np.ndarray) else b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def row_sums(x: np.ndarray) -> np.ndarray:
    """``np.add.reduce(x, axis=1)`` (= ``x.sum(axis=1)``) of a real (n, k) array, bit for bit.

    numpy reduces a C-ordered (n, 3) array along its short axis as ``(x0 + x1) + x2`` row by row, at about 5x the
    cost of adding the columns: for three columns they are added (the same two additions in the same order)."""
    if x.ndim == 2 and x.shape[1] == 3:
        s = x[:, 0] + x[:, 1]
        s += x[:, 2]
        return s
    return np.add.reduce(x, axis=1)


def _columns_adjacent(x) -> bool:
    return x.ndim == 2 and x.shape[1] >= 2 and x.dtype == np.float64 and x.strides[1] == x.itemsize


def col_sums(x: np.ndarray) -> np.ndarray:
    """``x.sum(axis=0)`` of a real (n, k) array, bit for bit.

    numpy sums each column over the rows in order, one row (k values) per inner loop: ~25 ns a row. With k >= 2
    adjacent columns (C order, or rows strided) ``einsum`` adds in the same order at a quarter of the cost; with
    the rows adjacent (Fortran order) it sums pairwise, so that case keeps the reduction (checked k = 2..7,
    n = 1..10^5)."""
    if _columns_adjacent(x):
        return np.einsum("ij->j", x)
    return x.sum(axis=0)


def col_means(x: np.ndarray) -> np.ndarray:
    """``x.mean(axis=0)`` of a real (n, k) array, bit for bit: :func:`col_sums` divided by n, as numpy divides."""
    if _columns_adjacent(x):
        return np.einsum("ij->j", x) / x.shape[0]
    return x.mean(axis=0)


def extent(x: np.ndarray) -> float:
    """``float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))``, the bounding-box diagonal of (n, k) points.

    Each column's max and min as one reduction along it (numpy's along axis 0 takes one inner loop per row); the
    extremes are the same values (a zero's sign aside, which the squared norm does not see), and the norm of the
    1-D difference is numpy's ``sqrt(d.dot(d))``. From 64 points on, a column at a time: a reduction of a strided
    1-D column is vectorised where one along an axis of a 2-D array is not (2,000 points: 107 -> 19 us)."""
    if x.ndim == 2 and len(x) >= 64:
        cols = [x[:, j] for j in range(x.shape[1])]
        d = np.array([c.max() - c.min() for c in cols])
        return float(np.sqrt(d.dot(d)))
    t = x.T
    d = t.max(axis=1) - t.min(axis=1)
    return float(np.sqrt(d.dot(d)))


def height_radius(points: np.ndarray, origin: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each point's height ``h`` along the line through ``origin`` along ``axis`` (unit) and its distance ``ρ`` from
    that line, for points (n, 3): the (ρ, z) half-plane of a surface of revolution. ``ρ² = |w|² − h²`` is clamped at
    0: round-off makes it slightly negative on the axis."""
    w = points - origin
    h = w @ axis
    return h, np.sqrt(np.maximum(np.einsum("ij,ij->i", w, w) - h * h, 0.0))


def row_norms(x: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """``np.linalg.norm(x, axis=1, keepdims=keepdims)`` of a real (n, k) array, bit for bit (the same square,
    row sum and root), without its dispatch."""
    if x.ndim == 2 and x.shape[1] == 3:
        s = row_sums(x * x)
        np.sqrt(s, out=s)
        return s[:, None] if keepdims else s
    return np.sqrt(np.add.reduce(x * x, axis=1, keepdims=keepdims))


def columns(*cols) -> np.ndarray:
    """``np.column_stack(cols)`` (= ``np.c_[...]``) of 1-D columns (or (n, k) blocks): the same C-ordered matrix, filled in place."""
    n = len(cols[0])
    widths = [1 if np.ndim(c) == 1 else c.shape[1] for c in cols]
    out = np.empty((n, sum(widths)))
    j = 0
    for c, w in zip(cols, widths):
        if w == 1:
            out[:, j] = c
        else:
            out[:, j : j + w] = c
        j += w
    return out


#: |cos| to the x axis above which the helper axis is y: below it |d × x| ≥ sin 25.8° (scale-free).
HELPER_COS = 0.9


def x_or_y_helper(d) -> np.ndarray:
    """The x axis, or the y axis where ``d`` (unit) lies within 25.8° of x: a vector ``d × helper`` is well
    conditioned for. Not :func:`axis_helper` (the least aligned axis): the frames that use this one — and so
    every fit and face built on them — would change at the last bit."""
    return np.array([1.0, 0.0, 0.0]) if abs(d[0]) < HELPER_COS else np.array([0.0, 1.0, 0.0])


def axis_helper(d: np.ndarray) -> tuple[float, float, float]:
    """``np.eye(3)[np.argmin(np.abs(d))]`` as a tuple: the coordinate axis least aligned with ``d``."""
    k = int(np.argmin(np.abs(d)))
    return (1.0, 0.0, 0.0) if k == 0 else (0.0, 1.0, 0.0) if k == 1 else (0.0, 0.0, 1.0)


def perpendicular_frame(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (e1, e2) with (e1, e2, d) a right-handed orthonormal frame."""
    d = d / np.sqrt(d.dot(d))  # np.linalg.norm(d)
    e1 = cross3(d, axis_helper(d))
    e1 /= np.sqrt(e1.dot(e1))
    return e1, cross3(d, e1)


def unit(v) -> np.ndarray:
    """``v`` (3,) scaled to length 1 (as a float array)."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def unique_inverse(idx: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(idx, return_inverse=True)`` of indices into ``range(n)``, by a mask when ``idx`` is not small
    beside ``n``: a large region's unique vertices without sorting its corners (1M triangles: a third of a refit)."""
    if len(idx) * 32 < n:
        return np.unique(idx, return_inverse=True)
    mask = np.zeros(n, bool)
    mask[idx] = True
    verts = np.flatnonzero(mask)
    lut = np.empty(n, np.int64)
    lut[verts] = np.arange(len(verts))
    return verts, lut[idx]
