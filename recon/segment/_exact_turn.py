"""The angular step a face is drawn at: how far its surface's normals turn across each of its triangles.

The exact path tells a curved face's triangles from a coincidence of a few vertices on a surface (a cube's corners
on a sphere, a cylinder's cap rim on the cylinder) by their chord sag: at most the share of the diagonal a CAD
export's chord tolerance allows (``SAG_SHARE``). A mesh tool draws a face at fixed angular steps instead, and a
face whose curvature varies then has its largest sag where it is flattest: a torus's outer equator, farthest from
its axis. There a face proven within the sag stops, and its last band's quads, whose vertices its surface holds to
round-off, become faces of their own (a two-quad cylinder tangent to the equator holds their six vertices).

A face already proven (within the sag, by more vertices than its surface's parameters) therefore also holds a
neighbour whose vertices it holds to round-off when its surface turns across each of the neighbour's triangles no
more than across the face's own: the same surface drawn at the same step. A coincidence spans a larger turn than the
face's own triangles: a cap's chord turns the cylinder's normal by up to 180°, a cube's face the sphere's by 70°.
numpy only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["drawn_alike", "largest_turn"]


def _turns(fit: Any, V: np.ndarray, F: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(len(tris),) the largest angle between the surface's normals at the feet of a triangle's corners."""
    _, n = fit.surface.project(V[F[tris]].reshape(-1, 3))
    n = n.reshape(-1, 3, 3)
    cos = np.minimum.reduce([np.einsum("ij,ij->i", n[:, i], n[:, j]) for i, j in ((0, 1), (1, 2), (2, 0))])
    return np.arccos(np.clip(cos, -1.0, 1.0))


def largest_turn(fit: Any, V: np.ndarray, F: np.ndarray, tris: np.ndarray) -> float:
    """The largest turn of ``fit``'s normals across one of the triangles ``tris``: the step the face is drawn at."""
    return float(_turns(fit, V, F, tris).max(initial=0.0))


def drawn_alike(fit: Any, V: np.ndarray, F: np.ndarray, tris: np.ndarray, turn: float, eps: np.ndarray) -> bool:
    """Whether ``fit``'s normals turn across every triangle of ``tris`` by at most ``turn`` (a face's own
    :func:`largest_turn`), each within its round-off: two surfaces that hold a triangle's corners within ``eps`` (its
    corners' largest round-off, (len(tris),)) tilt apart over it by at most 2 eps / its shortest edge."""
    P = V[F[tris]]
    edge = np.min([np.linalg.norm(P[:, i] - P[:, j], axis=1) for i, j in ((0, 1), (1, 2), (2, 0))], axis=0)
    slack = 2.0 * eps / np.maximum(edge, np.finfo(float).tiny)
    return bool(np.all(_turns(fit, V, F, tris) <= turn + slack))
