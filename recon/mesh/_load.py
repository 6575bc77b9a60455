"""Read a mesh file into one triangle list, in the file's own triangle order, then clean it.

trimesh parses STL, PLY, 3MF and GLB, always with ``process=False`` so that it never merges vertices or
reorders triangles behind our back (see shared/STYLE.md). OBJ and OFF, and the polygon list of a PLY, are
read here (``_polygons.py``) because trimesh regroups their faces by material or by polygon size.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from ..errors import InputError, MeshError
from ._clean import clean_mesh
from ._polygons import ply_polygons, read_obj, read_off
from ._types import Mesh

__all__ = ["load_mesh", "read_triangles", "SUPPORTED_FORMATS"]

log = logging.getLogger(__name__)

#: File extension -> trimesh file type.
SUPPORTED_FORMATS = {".stl": "stl", ".obj": "obj", ".ply": "ply", ".off": "off", ".3mf": "3mf", ".glb": "glb"}


def load_mesh(path: str | os.PathLike, *, weld_tolerance: float | None = None) -> Mesh:
    """Read a triangle mesh and clean it (see :func:`recon.clean_mesh`).

    Parameters
    ----------
    path : str or PathLike
        STL (binary or ASCII), OBJ, PLY, OFF, 3MF or GLB, chosen by extension.
    weld_tolerance : float, optional
        Passed to :func:`recon.clean_mesh`; default ``1e-6`` × the bounding-box diagonal.

    Returns
    -------
    Mesh
        ``source_face`` indexes the file's triangles in the order :func:`read_triangles` gives.

    Raises
    ------
    InputError
        Missing file, unknown extension.
    MeshError
        Empty, unreadable or corrupt file; NaN/inf coordinates; no triangles (before or after cleaning).
    """
    vertices, faces = read_triangles(path)
    try:
        return clean_mesh(vertices, faces, weld_tolerance=weld_tolerance)
    except MeshError as err:
        raise MeshError(f"{path}: {err}") from None


def read_triangles(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """The raw triangles of a mesh file, unwelded and in file order.

    Polygons (OBJ, OFF, PLY) become fans of triangles in place. A file with several objects (GLB,
    3MF) is concatenated in the order its geometries appear in the file; a geometry placed
    several times appears once per placement, transformed, in scene-graph order. Point clouds and
    curves in a scene are skipped.

    Returns
    -------
    vertices : (n, 3) float
    faces : (m, 3) int
    """
    path = Path(path)
    ext = path.suffix.lower()
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if not path.is_file():
        raise InputError(f"{path}: not a file")
    if ext not in SUPPORTED_FORMATS:
        raise InputError(
            f"{path}: unknown mesh format {ext or '(no extension)'!r}; "
            f"expected one of {', '.join(SUPPORTED_FORMATS)}"
        )
    if path.stat().st_size == 0:
        raise MeshError(f"{path}: file is empty")

    if ext in (".obj", ".off"):
        reader = read_obj if ext == ".obj" else read_off
        try:
            vertices, faces = reader(path)
        except MeshError as err:
            raise MeshError(f"{path}: {err}") from None
        except (OSError, UnicodeError) as err:
            raise MeshError(f"{path}: cannot read as {ext[1:].upper()}: {_one_line(err)}") from err
        if len(faces) == 0:
            raise MeshError(f"{path}: the file has no triangles")
        return vertices, faces

    if ext == ".stl" and (binary := _binary_stl(path)) is not None:
        return binary
    import trimesh

    if ext == ".stl" and (problem := _binary_stl_problem(path)):
        raise MeshError(f"{path}: {problem}")
    try:
        scene = trimesh.load_scene(path, file_type=SUPPORTED_FORMATS[ext], process=False)
    except Exception as err:  # trimesh raises many kinds (ValueError, KeyError, struct.error, ...)
        if ext == ".stl" and (problem := _ascii_stl_problem(path)):
            raise MeshError(f"{path}: {problem}") from None
        raise MeshError(f"{path}: cannot read as {ext[1:].upper()}: {_one_line(err)}") from err

    placed_vertices: list[np.ndarray] = []
    placed_faces: list[np.ndarray] = []
    offset = 0
    for name, geom in scene.geometry.items():
        if not isinstance(geom, trimesh.Trimesh):
            log.warning("%s: skipping %s %r (not a triangle mesh)", path, type(geom).__name__, name)
            continue
        if len(geom.faces) == 0:
            continue
        nodes = scene.graph.geometry_nodes.get(name) or [None]
        for node in nodes:
            v = np.asarray(geom.vertices, dtype=np.float64)
            f = ply_polygons(geom) if ext == ".ply" else None
            f = np.asarray(geom.faces if f is None else f, dtype=np.int64)
            if node is not None:
                matrix = np.asarray(scene.graph[node][0], dtype=np.float64)
                if not np.allclose(matrix, np.eye(4)):
                    v = v @ matrix[:3, :3].T + matrix[:3, 3]
                    if np.linalg.det(matrix[:3, :3]) < 0:  # a mirror keeps the outside outside
                        f = f[:, [0, 2, 1]]
            placed_vertices.append(v)
            placed_faces.append(f + offset)
            offset += len(v)
    if not placed_faces:
        if ext == ".stl" and (problem := _ascii_stl_problem(path)):
            raise MeshError(f"{path}: {problem}")
        raise MeshError(f"{path}: the file has no triangles")
    log.debug("%s: read %d triangles from %d placements", path, sum(map(len, placed_faces)), len(placed_faces))
    return np.concatenate(placed_vertices), np.concatenate(placed_faces)


#: Binary STL: an 80-byte header, the triangle count (uint32), then 50 bytes per triangle.
_STL_HEADER, _STL_TRIANGLE = 84, 50


#: A binary STL triangle as trimesh reads it: normal, three corners (little-endian float32), attribute bytes.
_STL_DTYPE = np.dtype([("normals", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attributes", "<u2")])


def _binary_stl(path: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """A well-formed binary STL's triangles (its length matches its count, every corner finite) as trimesh gives them
    with ``process=False`` — the corners in file order as float64, faces ``0 … 3m − 1`` — read here without importing
    trimesh (0.3 s of ``recon convert``'s start-up: bench/speed.md); None for anything else, which trimesh reads."""
    with open(path, "rb") as fh:
        data = fh.read()
    if len(data) < _STL_HEADER:
        return None
    count = int.from_bytes(data[80:84], "little")
    if count == 0 or len(data) != _STL_HEADER + _STL_TRIANGLE * count:
        return None
    corners = np.frombuffer(data, dtype=_STL_DTYPE, offset=_STL_HEADER)["vertices"].reshape(-1, 3)
    if not np.isfinite(corners).all():
        return None
    return corners.astype(np.float64), np.arange(3 * count, dtype=np.int64).reshape(-1, 3)


def _looks_ascii_stl(head: bytes) -> bool:
    return head.lstrip().lower().startswith(b"solid") and b"facet" in head.lower()


def _binary_stl_problem(path: Path) -> str | None:
    """What is wrong with a binary STL's length, in the user's words, or None (also for an ASCII STL)."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(1024)
    count = int.from_bytes(head[80:84], "little") if len(head) >= _STL_HEADER else None
    expected = None if count is None else _STL_HEADER + _STL_TRIANGLE * count
    if size == expected or _looks_ascii_stl(head):  # (a binary header may begin with "solid" too)
        return None
    if count is None:
        return f"the file is truncated ({size} bytes; a binary STL has an {_STL_HEADER}-byte header)"
    found = (size - _STL_HEADER) // _STL_TRIANGLE
    expected = _STL_HEADER + _STL_TRIANGLE * count
    if size < expected:
        return f"the file is truncated (expected {count:,} triangles, found {found:,})"
    return (f"the file is longer than its triangle count says ({count:,} triangles are {expected:,} bytes, the file "
            f"has {size:,}): corrupt or not an STL")


def _ascii_stl_problem(path: Path) -> str | None:
    """What is wrong with an ASCII STL that could not be read, or None."""
    with open(path, "rb") as fh:
        data = fh.read()
    if not _looks_ascii_stl(data[:1024]):
        return None
    facets = data.lower().count(b"endfacet")
    if b"endsolid" not in data[-1024:].lower():
        return f"the file is truncated (an ASCII STL that stops after {facets:,} complete triangles, no 'endsolid')"
    return None


def _one_line(err: Exception) -> str:
    text = " ".join(str(err).split()) or type(err).__name__
    return text if len(text) <= 200 else text[:197] + "..."
