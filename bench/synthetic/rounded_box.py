"""A rounded box with exact per-triangle ground truth, without a CAD kernel (for tests and benchmarks).

A box with every edge filleted at radius ``ρ`` is the Minkowski sum of a smaller box and a ball of radius
``ρ``. A uniform grid on the outer box's surface is mapped onto it: each grid point ``p`` goes to
``q + ρ·(p − q)/|p − q|`` where ``q`` is ``p`` clamped to the inner box. Points whose clamp moves one
coordinate land on a plane (unchanged), two coordinates on a fillet (a quarter cylinder), three on a
corner (a sphere octant). The grid is aligned with the inner box, so every triangle lies on exactly one
true face: 6 planes, 12 fillets and 8 corners (26 faces).
"""

from __future__ import annotations

import numpy as np

__all__ = ["rounded_box"]


def rounded_box(size=(40.0, 30.0, 20.0), radius=3.0, *, spacing=0.5, sigma=0.0, rng=None):
    """Triangulated rounded box and the true face of each triangle.

    Parameters
    ----------
    size : (3,) float
        Outer extents.
    radius : float
        Fillet radius ``ρ`` (0 gives a sharp box). ``size/2 − ρ`` and ``ρ`` should be multiples of ``spacing``.
    spacing : float
        Grid spacing on the outer box (about the edge length).
    sigma : float
        Standard deviation of Gaussian vertex noise (isotropic, mesh units).
    rng : numpy.random.Generator, optional

    Returns
    -------
    vertices : (n, 3) float
    faces : (m, 3) int
    labels : (m,) int
        True face per triangle, 0 … 25 (0 … 5 for a sharp box).
    """
    half = np.asarray(size, dtype=float) / 2.0
    inner = half - radius
    verts, faces = [], []
    offset = 0
    for axis in range(3):
        u_ax, v_ax = [a for a in range(3) if a != axis]
        nu = int(round(2 * half[u_ax] / spacing))
        nv = int(round(2 * half[v_ax] / spacing))
        u = np.linspace(-half[u_ax], half[u_ax], nu + 1)
        v = np.linspace(-half[v_ax], half[v_ax], nv + 1)
        uu, vv = np.meshgrid(u, v, indexing="ij")
        idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
        a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
        for sign in (-1.0, 1.0):
            p = np.zeros((uu.size, 3))
            p[:, axis] = sign * half[axis]
            p[:, u_ax] = uu.ravel()
            p[:, v_ax] = vv.ravel()
            quad_a = np.stack([a, b, c], axis=1)
            quad_b = np.stack([a, c, d], axis=1)
            f = np.concatenate([quad_a, quad_b])
            # outward orientation: (u, v, axis) right-handed for the + side
            right = (u_ax, v_ax, axis) in ((0, 1, 2), (1, 2, 0), (2, 0, 1))
            if (sign > 0) != right:
                f = f[:, ::-1]
            verts.append(p)
            faces.append(f + offset)
            offset += len(p)
    p = np.concatenate(verts)
    f = np.concatenate(faces)
    # weld the grid points the six sides share
    key = np.round(p / (spacing * 1e-3)).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    p = p[first]
    f = inv.ravel()[f]
    labels = _true_face(p[f].mean(axis=1), inner)
    q = np.clip(p, -inner, inner)
    dvec = p - q
    norm = np.linalg.norm(dvec, axis=1, keepdims=True)
    out = q + radius * dvec / np.maximum(norm, 1e-300) if radius > 0 else p
    if sigma:
        rng = np.random.default_rng(0) if rng is None else rng
        out = out + rng.normal(0.0, sigma, out.shape)
    return out, f.astype(np.int64), labels


def _true_face(centroids, inner):
    """Face id from which coordinates the clamp to the inner box moves (by the triangle centroid)."""
    out = np.abs(centroids) > inner + 1e-9
    sign = centroids > 0
    n_out = out.sum(axis=1)
    labels = np.empty(len(centroids), dtype=np.int64)
    # planes 0..5: axis*2 + side
    one = n_out == 1
    ax = np.argmax(out, axis=1)
    labels[one] = ax[one] * 2 + sign[one, ax[one]]
    # fillets 6..17: along the axis that is NOT out; 4 per axis by the two signs
    two = n_out == 2
    free = np.argmin(out, axis=1)
    s = sign.astype(np.int64)
    other = np.where(free[:, None] == 0, s[:, [1, 2]], np.where(free[:, None] == 1, s[:, [0, 2]], s[:, [0, 1]]))
    labels[two] = 6 + free[two] * 4 + other[two, 0] * 2 + other[two, 1]
    # corners 18..25
    three = n_out == 3
    labels[three] = 18 + s[three, 0] * 4 + s[three, 1] * 2 + s[three, 2]
    if (n_out == 0).any():  # cannot happen for points on the outer box
        labels[n_out == 0] = -1
    return labels
