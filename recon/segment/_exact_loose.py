"""What the exact path looks at where a CAD kernel's export is not exact everywhere, or draws a face as one strip.

- *Tolerant edges.* A STEP edge of tolerance δ (OCC: ``BRep_Tool.Tolerance``) puts the vertices the mesher places on
  it on one of its two faces, exact to round-off, and off the other by up to δ (gmsh exports of real parts: every
  off vertex of the clamp exact on one face, 186 of 193 on the finned head; bench/exact.md, s35-strip). Each curved
  face beside such an edge then fails round-off at its rim and no seed passes. :func:`held_slack` gives the second
  pass its round-off per vertex: the run's tolerance only at a vertex that a face already found holds to round-off
  and that a triangle no face took shares, round-off everywhere else.
- *Zig-zag strips.* A cylinder drawn as one strip along its axis (every triangle from one end curve to the other) has
  no two coplanar triangles: each is its own atom, and a seed's ring crosses into the faces beside it. Its triangles
  meet across their long edges, its rims are their short ones: :func:`chain` walks a few steps along such edges.

numpy/scipy only; the surfaces are fitted by the caller.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["CHAIN_GROWTH", "CHAIN_MIN", "chain", "held_slack", "long_edge_neighbours"]

#: Steps a chain walks each way from its seed: 7 triangles, 9 vertices on the strip's two rails, a vertex more than a
#: torus's parameters on each side of the seed (the s32 measurement of this seed, bench/exact.md).
CHAIN_STEPS = 3
#: A chain of fewer triangles has at most 5 vertices: not more than a cylinder's parameters.
CHAIN_MIN = 4
#: A chain-seeded face must hold this many times the atoms it was fitted to: a strip of a free-form face may lie on a
#: cone to round-off over a few triangles (export seed 42: 7 → 9 atoms), a true face's strip grows along its length
#: (seed 49: 4-7 → 18-118).
CHAIN_GROWTH = 2


def held_slack(at: Any, curved: list, eps: float, tol: float) -> np.ndarray | None:
    """Round-off per vertex for the second pass, or None when it has nothing to look at: ``tol`` at the vertices a
    found face (a curved region ``(atoms, fit)`` of ``curved``, or a plane atom of more than two triangles: proven a
    plane) holds to round-off and that an atom no face took shares, ``eps`` elsewhere. (Not where two found faces
    meet: a vertex loose there would let either face take the other's small atoms.)"""
    taken = np.zeros(len(at.tris), bool)
    for r, _ in curved:
        taken[r] = True
    big = np.array([len(t) > 2 for t in at.tris])
    n = len(at.mesh.vertices)
    on_found, on_free = np.zeros(n, bool), np.zeros(n, bool)
    for a in np.flatnonzero(taken | big).tolist():
        on_found[at.verts[a]] = True
    for a in np.flatnonzero(~taken & ~big).tolist():
        on_free[at.verts[a]] = True
    held = on_found & on_free
    if not held.any() or tol <= eps:
        return None
    return np.where(held, tol, eps)


def long_edge_neighbours(mesh: Any) -> list[list[int]]:
    """Per triangle, the triangles across its edges that are neither triangle's shortest edge (a zig-zag strip's
    triangles meet across their long edges; its rims are the short ones)."""
    V, F = mesh.vertices, mesh.faces
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    edges = np.sort(np.asarray(mesh.face_adjacency_edges, dtype=np.int64).reshape(-1, 2), axis=1)
    lengths = np.linalg.norm(V[F[:, [1, 2, 0]]] - V[F], axis=2)  # edge (i, i+1)
    k = np.argmin(lengths, axis=1)
    rows = np.arange(len(F))
    short = np.sort(np.stack([F[rows, k], F[rows, (k + 1) % 3]], axis=1), axis=1)
    keep = ~(edges == short[pairs[:, 0]]).all(axis=1) & ~(edges == short[pairs[:, 1]]).all(axis=1)
    out: list[list[int]] = [[] for _ in range(len(F))]
    for a, b in pairs[keep].tolist():
        out[a].append(b)
        out[b].append(a)
    return out


def chain(at: Any, s: int, free: np.ndarray, nbr: list[list[int]]) -> list[int]:
    """The free one-triangle atoms reached from the one-triangle atom ``s`` across long edges (``nbr``) that are no
    crease, within :data:`CHAIN_STEPS` steps; empty when fewer than :data:`CHAIN_MIN`."""
    t0 = int(at.tris[s][0])
    seen, front, out = {t0}, [t0], [s]
    for _ in range(CHAIN_STEPS):
        nxt = []
        for t in front:
            for u in nbr[t]:
                a = int(at.labels[u])
                if u in seen or not free[a] or len(at.tris[a]) != 1 or not at.smooth(int(at.labels[t]), a):
                    continue
                seen.add(u)
                out.append(a)
                nxt.append(u)
        front = nxt
    return sorted(out) if len(out) >= CHAIN_MIN else []
