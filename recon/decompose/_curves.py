"""Boundary polylines between neighbouring parts, packed shapely-style."""

from __future__ import annotations

import numpy as np

from ._topology import Topology, unique
from ._types import BoundaryCurves

__all__ = ["boundary_curves"]


def boundary_curves(V, topo: Topology, labels, n_parts: int):
    """Polylines along the mesh edges where the part label changes.

    Edges between the same two parts are chained at vertices where exactly two of them meet; a chain
    stops where three or more part borders meet (a curve network vertex).

    Returns
    -------
    curves : BoundaryCurves
    neighbours : list of (k,) int
        Neighbouring part ids of each part.
    """
    h = np.flatnonzero(topo.twin > np.arange(len(topo.twin)))
    la = labels[h // 3]
    lb = labels[topo.twin[h] // 3]
    diff = la != lb
    h, la, lb = h[diff], la[diff], lb[diff]
    pa, pb = np.minimum(la, lb), np.maximum(la, lb)
    neighbours = [[] for _ in range(n_parts)]
    if len(h):
        # np.unique of the (pa, pb) rows, as integer keys (the same lexicographic order; axis=0 is ~10x slower)
        key = unique(pa * np.int64(n_parts) + pb)
        for a, b in zip((key // n_parts).tolist(), (key % n_parts).tolist()):
            neighbours[a].append(b)
            neighbours[b].append(a)
    neighbours = [np.array(sorted(x), dtype=np.int64) for x in neighbours]
    ed = topo.edges[topo.half_edge[h]]
    coords, vids, offsets, parts, closed = [], [], [0], [], []
    if len(h):
        order = np.lexsort((pb, pa))
        ed, pa, pb = ed[order], pa[order], pb[order]
        brk = np.flatnonzero(np.diff(pa * np.int64(n_parts) + pb)) + 1
        for lo, hi in zip(np.r_[0, brk], np.r_[brk, len(ed)]):
            for chain, is_closed in _chains(ed[lo:hi]):
                vids.append(chain)
                offsets.append(offsets[-1] + len(chain))
                parts.append((int(pa[lo]), int(pb[lo])))
                closed.append(is_closed)
    vid = np.concatenate(vids) if vids else np.zeros(0, np.int64)
    curves = BoundaryCurves(
        coords=V[vid],
        vertex_ids=vid,
        offsets=np.asarray(offsets, dtype=np.int64),
        parts=np.asarray(parts, dtype=np.int64).reshape(-1, 2),
        closed=np.asarray(closed, dtype=bool),
    )
    return curves, neighbours


def _chains(edges: np.ndarray):
    """Split an edge set into maximal simple chains; yields (vertex ids, closed)."""
    adj: dict[int, list[int]] = {}
    for i, (a, b) in enumerate(edges.tolist()):
        adj.setdefault(a, []).append(i)
        adj.setdefault(b, []).append(i)
    used = np.zeros(len(edges), bool)
    ends = [v for v, es in adj.items() if len(es) != 2]

    def walk(v, e):
        chain = [v]
        while True:
            used[e] = True
            a, b = edges[e]
            v = b if a == v else a
            chain.append(v)
            nxt = [x for x in adj[v] if not used[x]]
            if len(adj[v]) != 2 or not nxt:
                return chain
            e = nxt[0]

    for v in ends:
        for e in adj[v]:
            if not used[e]:
                yield np.asarray(walk(v, e), np.int64), False
    for e in range(len(edges)):
        if not used[e]:
            v = int(edges[e][0])
            chain = walk(v, e)
            yield np.asarray(chain[:-1], np.int64), True
