"""The exact path's weak faces: a curved face of a few atoms that is told from planes meeting at an angle only by its
sag (how far its triangles' chords lie from it), judged against the faces drawn with more. numpy only."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..fit import SurfaceFit
from ._exact_rings import undrawn_torus

__all__ = ["chord_points", "edge_midpoints", "weak_dropped", "WEAK_ATOMS", "WEAK_SAG_MARGIN"]


def edge_midpoints(V: np.ndarray, F: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """The midpoints of the triangles' edges (each edge once per triangle it bounds)."""
    P = V[F[tris]]
    return np.concatenate([(P[:, 0] + P[:, 1]) / 2, (P[:, 1] + P[:, 2]) / 2, (P[:, 2] + P[:, 0]) / 2])


def chord_points(V: np.ndarray, F: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """The centroids and edge midpoints of triangles: where a chord lies farthest from the surface it spans."""
    return np.concatenate([V[F[tris]].mean(axis=1), edge_midpoints(V, F, tris)])


#: A curved face of fewer atoms than this (a fillet one or two strips wide) is told from planes meeting at an angle
#: only by its sag: it is kept when its chords lie no farther from it than the chords of the faces drawn with more.
WEAK_ATOMS = 4
#: ... with this margin: an exporter's chord tolerance bounds every face's sag, the faces measured reach it only
#: where the chord criterion, not the angle criterion, placed their vertices.
WEAK_SAG_MARGIN = 1.5


def _sags(at: Any, region: list, fits: tuple) -> tuple[float, ...]:
    """How far the region's chords lie from each of ``fits`` (one fit given twice is measured once)."""
    tris = np.concatenate([at.tris[a] for a in region])
    P = chord_points(at.mesh.vertices, at.mesh.faces, tris)
    seen: dict = {}
    return tuple(seen.setdefault(id(f), float(np.max(np.abs(f.distance(P))))) for f in fits)


def weak_dropped(at: Any, regions: list, notes: list, eps: float) -> list:
    """The curved regions ``(atoms, seed's fit, best fit)`` without those of fewer than :data:`WEAK_ATOMS` atoms whose
    sag exceeds the sag of the well-drawn curved faces (× :data:`WEAK_SAG_MARGIN`; any sag when there is none; a torus
    its exporter cannot have drawn, :func:`undrawn_torus`, is not one): planes
    meeting at a small angle, whose vertices a cylinder also holds (a polygon's two sides lie on the circle through
    their corners). A weak region is judged by the nearer of its two surfaces; each kept one gets its best fit when that
    passes, else its seed's."""
    sags = [_sags(at, r, (f, b)) for r, f, b in regions]
    strong = [sb for (r, _, b), (_, sb) in zip(regions, sags)  # a strong region's face is its best fit
              if len(r) >= WEAK_ATOMS and not undrawn_torus(at.mesh.vertices[at.points(r)[0]], b, eps)]
    limit = WEAK_SAG_MARGIN * max(strong) if strong else 0.0
    kept = []
    for (r, f, b), (s, sb) in zip(regions, sags):
        if len(r) >= WEAK_ATOMS or sb <= limit:
            kept.append((r, b))
        elif s <= limit:
            kept.append((r, f))
        else:
            notes.append(f"{len(r)} plane pieces a {b.type} holds to round-off kept as planes: its chords lie "
                         f"{min(s, sb):.3g} from it, the well-drawn curved faces' at most {limit / WEAK_SAG_MARGIN:.3g}")
    return kept
