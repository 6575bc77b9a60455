"""Readers for the polygon formats whose face order trimesh does not keep.

trimesh groups OBJ faces by material and object, and puts the triangles of a mixed OFF/PLY file before
its quads, so "the input file's triangle order" would be lost. These readers keep it: every polygon
becomes a fan of triangles ``(p0, p_i, p_i+1)`` in place.
"""

from __future__ import annotations

import numpy as np

from ..errors import MeshError

__all__ = ["fan_triangles", "read_obj", "read_off", "ply_polygons"]


def fan_triangles(lengths: np.ndarray, flat: np.ndarray) -> np.ndarray:
    """Triangulate packed polygons as fans, keeping polygon order.

    Parameters
    ----------
    lengths : (p,) int
        Corner count of each polygon (polygons with fewer than 3 corners give no triangle).
    flat : (sum(lengths),) int
        Corner vertex indices, polygon after polygon.

    Returns
    -------
    (t, 3) int
    """
    lengths = np.asarray(lengths, dtype=np.int64)
    flat = np.asarray(flat, dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    n_tri = np.maximum(lengths - 2, 0)
    poly = np.repeat(np.arange(len(lengths)), n_tri)
    local = np.arange(int(n_tri.sum())) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
    start = offsets[poly]
    return np.column_stack([flat[start], flat[start + local + 1], flat[start + local + 2]])


def read_obj(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and fan-triangulated faces of a Wavefront OBJ, in file order (all objects and groups).

    Only ``v`` and ``f`` records matter; texture/normal indices (``f 1/2/3``) and negative (relative)
    indices are understood; materials, lines and curves are ignored.
    """
    coords: list[str] = []
    lengths: list[int] = []
    flat: list[int] = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for number, line in enumerate(fh, 1):
            head = line[:2]
            if head == "v ":
                coords.append(line)
            elif head == "f ":
                try:
                    idx = [int(tok.split("/", 1)[0]) for tok in line.split()[1:]]
                except ValueError:
                    raise MeshError(f"line {number}: bad face record {line.strip()[:60]!r}") from None
                n = len(coords)
                flat.extend(i - 1 if i > 0 else n + i for i in idx)
                lengths.append(len(idx))
    try:
        vertices = np.array([c.split()[1:4] for c in coords], dtype=np.float64).reshape(-1, 3)
    except ValueError:
        raise MeshError("a 'v' record does not hold three numbers") from None
    return vertices, fan_triangles(np.array(lengths), np.array(flat))


def read_off(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and fan-triangulated faces of an ASCII OFF file (also COFF/NOFF/...: extra columns ignored)."""
    with open(path, "rb") as fh:
        data = fh.read()
    if b"\0" in data[:1024]:
        raise MeshError("binary OFF is not supported; save it as ASCII OFF")
    lines = []
    for raw in data.decode("utf-8", errors="replace").splitlines():
        text = raw.split("#", 1)[0].strip()
        if text:
            lines.append(text)
    if not lines or not lines[0].split()[0].upper().endswith("OFF"):
        raise MeshError("not an OFF file: the first line must be 'OFF'")
    header = lines[0].split()[1:]
    body = 1
    if len(header) < 2:
        if len(lines) < 2:
            raise MeshError("OFF header has no vertex and face counts")
        header = lines[1].split()
        body = 2
    try:
        n_vertices, n_faces = int(header[0]), int(header[1])
    except (ValueError, IndexError):
        raise MeshError(f"OFF counts line {' '.join(header)!r} is not 'vertices faces edges'") from None
    if len(lines) < body + n_vertices + n_faces:
        raise MeshError(
            f"OFF file is truncated: header promises {n_vertices} vertices and {n_faces} faces, "
            f"the file has {len(lines) - body} records"
        )
    try:
        vertices = np.array(
            [ln.split()[:3] for ln in lines[body : body + n_vertices]], dtype=np.float64
        ).reshape(-1, 3)
    except ValueError:
        raise MeshError("an OFF vertex line does not start with three numbers") from None
    lengths = np.empty(n_faces, dtype=np.int64)
    flat: list[int] = []
    try:
        for i, ln in enumerate(lines[body + n_vertices : body + n_vertices + n_faces]):
            tok = ln.split()
            k = int(tok[0])
            lengths[i] = k
            if len(tok) < k + 1:
                raise ValueError
            flat.extend(map(int, tok[1 : k + 1]))
    except (ValueError, IndexError):
        raise MeshError(f"OFF face record {i + 1} is malformed: {ln[:60]!r}") from None
    return vertices, fan_triangles(lengths, np.array(flat, dtype=np.int64))


def ply_polygons(mesh) -> np.ndarray | None:
    """Fan-triangulated faces from the raw PLY face list trimesh keeps in ``metadata['_ply_raw']``.

    Returns ``None`` when the raw list is not there (then trimesh's own faces are used).
    """
    raw = (getattr(mesh, "metadata", None) or {}).get("_ply_raw")
    if not raw or "face" not in raw:
        return None
    data = raw["face"]["data"]
    names = [n for n in (getattr(data, "dtype", None) and data.dtype.names or data.keys()) if "vertex_ind" in n]
    if not names:
        return None
    faces = data[names[0]]
    if faces.dtype.names:  # structured (count, indices) records of fixed size
        faces = faces[faces.dtype.names[-1]]
    if faces.dtype != object:
        faces = np.asarray(faces).reshape(len(faces), -1)
        return fan_triangles(np.full(len(faces), faces.shape[1]), faces.ravel())
    lengths = np.fromiter((len(p) for p in faces), dtype=np.int64, count=len(faces))
    flat = np.concatenate([np.asarray(p, dtype=np.int64) for p in faces]) if len(faces) else np.empty(0, np.int64)
    return fan_triangles(lengths, flat)
