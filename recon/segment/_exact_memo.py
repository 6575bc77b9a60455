"""What the exact path already asked: the curved surfaces found for a set of vertices, and the unions none was found
for. The path asks the same question again (the next merge round, the second pass, a region growing back over an atom
it was refused) and a set that holds a failed union again; both answers are known. numpy only."""

from __future__ import annotations

import hashlib

import numpy as np

__all__ = ["Failures", "per_vertex", "question"]


def per_vertex(eps: float | np.ndarray, ids: np.ndarray) -> np.ndarray:
    """The round-off of each vertex ``ids``: ``eps`` is one for all, or an array over the mesh's vertices."""
    return np.full(len(ids), float(eps)) if np.ndim(eps) == 0 else np.asarray(eps)[ids]


def question(ids: np.ndarray, tris: np.ndarray, e: np.ndarray, sag: float, first: bool, above: str | None) -> bytes:
    """A digest of a fit's question: the vertices ``ids``, the triangles ``tris`` (any order), each vertex's round-off
    ``e``, the sag and which types are asked for (128 bits: no two questions of one run share it)."""
    h = hashlib.blake2b(digest_size=16)
    for part in (np.asarray(ids, dtype=np.int64), np.sort(np.asarray(tris, dtype=np.int64)), np.asarray(e, dtype=float),
                 np.array([sag], dtype=float), np.frombuffer(f"{first}|{above}".encode(), np.uint8)):
        h.update(part.tobytes())
        h.update(b"|")
    return h.digest()


class Failures:
    """Unions for which no surface was found, with each vertex's round-off: a set that holds one of them, at no looser
    round-off on its vertices, has none either (no surface holds a set that holds a part it failed on)."""

    def __init__(self) -> None:
        # by each failed union's smallest vertex: a set holds only the unions whose smallest vertex it holds
        self.by_first: dict[int, list[tuple[frozenset, np.ndarray, np.ndarray]]] = {}

    def implied(self, ids: np.ndarray, e: np.ndarray) -> bool:
        """Whether the vertices ``ids`` (sorted) at round-off ``e`` hold a failed union at its round-off or a
        tighter one."""
        have = set(ids.tolist())
        return any(f <= have and bool(np.all(e[np.searchsorted(ids, f_ids)] <= f_e))
                   for v in have.intersection(self.by_first) for f, f_ids, f_e in self.by_first[v])

    def add(self, ids: np.ndarray, e: np.ndarray) -> None:
        """Record that no surface holds the vertices ``ids`` (sorted, not empty) at round-off ``e``."""
        self.by_first.setdefault(int(ids[0]), []).append((frozenset(ids.tolist()), np.asarray(ids), np.asarray(e)))
