"""Ground-truth fixtures: scan-like meshes of CAD parts with the true B-rep face of every triangle.

The files live in ``fixtures/data`` (made by ``fixtures/make_fixtures.py``; see ``fixtures/README.md``). Loading
them needs only numpy, trimesh and json: the CAD kernel is needed to *make* fixtures, never to read them.

Per part: ``<part>.step`` (the true solid), ``<part>.json`` (true faces, diagonal, volume, per-variant facts) and,
per variant, ``<part>_<variant>.stl`` + ``<part>_<variant>.labels.npy`` (int32 true face index per STL triangle,
in the STL's order; -1 would mean "no true face").
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["FIXTURE_DIR", "VARIANTS", "Fixture", "TrueFace", "list_fixtures", "load_fixture", "weld"]

log = logging.getLogger(__name__)

#: where the committed fixtures are (the repository's ``fixtures/data``); ``RECON_FIXTURE_DIR`` overrides it
FIXTURE_DIR = Path(os.environ.get("RECON_FIXTURE_DIR", Path(__file__).resolve().parent.parent / "fixtures" / "data"))
#: the committed variants: clean; noise along the normals with σ = 0.05 % / 0.2 % of the diagonal; h × 4; a hole
VARIANTS = ("clean", "noisy05", "noisy20", "coarse", "open")


@dataclass(frozen=True)
class TrueFace:
    """One face of the true B-rep.

    Attributes
    ----------
    index : int
        Position in the solid's face order (``TopExp_Explorer``), the value found in the labels.
    type : str
        ``plane``, ``cylinder``, ``cone``, ``sphere``, ``torus``, ``bspline`` or ``other`` (OCC's GeomAbs type).
    area : float
    reversed : bool
        The face is REVERSED on its surface: its outward normal is minus the surface normal.
    params : dict
        Analytic parameters: plane ``point``, ``normal`` (outward); cylinder ``point``, ``axis``, ``radius``;
        cone ``apex``, ``axis``, ``semi_angle`` (signed, OCC's), ``point``, ``ref_radius``; sphere ``center``,
        ``radius``; torus ``center``, ``axis``, ``major_radius``, ``minor_radius``; empty for B-splines.
    """

    index: int
    type: str
    area: float
    reversed: bool
    params: dict = field(compare=False)


@dataclass(frozen=True)
class Fixture:
    """A fixture mesh with its ground truth.

    Attributes
    ----------
    part, variant : str
    vertices : (n, 3) float
        Welded vertices (exact duplicates of the STL merged, in order of first use).
    faces : (m, 3) int
        Triangles, in the STL's order.
    labels : (m,) int
        True face index of each triangle (index into ``true_faces``), -1 for none.
    true_faces : tuple of TrueFace
    diagonal : float
        Bounding-box diagonal of the true solid.
    volume, area : float
        Of the true solid (OpenCascade).
    step_path, stl_path : Path
    info : dict
        This variant's facts from the JSON (``h``, ``triangles``, ``sigma`` for noisy variants,
        ``hole_centre``/``hole_radius``/``hole_face`` for ``open``, ...).
    """

    part: str
    variant: str
    vertices: np.ndarray
    faces: np.ndarray
    labels: np.ndarray
    true_faces: tuple
    diagonal: float
    volume: float
    area: float
    step_path: Path
    stl_path: Path
    info: dict = field(compare=False)

    @property
    def face_types(self) -> tuple:
        """Type of each true face, indexable by label."""
        return tuple(f.type for f in self.true_faces)

    @property
    def face_areas(self) -> np.ndarray:
        """(k,) float: area of each true face."""
        return np.array([f.area for f in self.true_faces])


def list_fixtures(*, root: str | os.PathLike | None = None) -> list:
    """All fixtures present, as sorted ``(part, variant)`` pairs (a part counts once its JSON exists)."""
    root = Path(root) if root is not None else FIXTURE_DIR
    found = []
    for meta in sorted(root.glob("*.json")):
        part = meta.stem
        for stl in sorted(root.glob(f"{part}_*.stl")):
            variant = stl.stem[len(part) + 1 :]
            if "_" not in variant and stl.with_suffix(".labels.npy").exists():
                found.append((part, variant))
    return found


def weld(corners: np.ndarray) -> tuple:
    """Merge corners that are equal in float32 (what an STL stores), keeping the triangle order.

    Parameters
    ----------
    corners : (m, 3, 3) float
        The three corner positions of every triangle (what an STL stores).

    Returns
    -------
    vertices : (n, 3) float
        Unique positions in order of first use.
    faces : (m, 3) int
    """
    corners = np.asarray(corners)
    if corners.ndim != 3 or corners.shape[1:] != (3, 3):
        raise InputError(f"corners must have shape (m, 3, 3), got {corners.shape}")
    flat = corners.reshape(-1, 3)
    # STL stores float32, and the fixture writer rounds each vertex the same way in every triangle that uses it,
    # so "equal as float32" is the right (and only) tolerance; sorting 96-bit keys is ~10× faster than unique(axis=0)
    bits = (flat.astype(np.float32) + np.float32(0.0)).view(np.uint32).astype(np.uint64)  # + 0.0: -0.0 → 0.0
    hi, lo = (bits[:, 0] << np.uint64(32)) | bits[:, 1], bits[:, 2]
    order = np.lexsort((lo, hi))
    new_group = np.ones(len(order), dtype=bool)
    new_group[1:] = (hi[order][1:] != hi[order][:-1]) | (lo[order][1:] != lo[order][:-1])
    group = np.empty(len(order), dtype=np.int64)
    group[order] = np.cumsum(new_group) - 1
    # renumber groups in order of first use, so the vertex order depends only on the triangle order
    first = order[new_group]  # lexsort is stable: a group's first sorted entry is its first use
    rank = np.empty_like(first)
    rank[np.argsort(first)] = np.arange(len(first))
    vertices = flat[np.sort(first)].astype(np.float64)
    faces = rank[group].reshape(-1, 3)
    return vertices, faces


def load_fixture(part: str, variant: str = "clean", *, root: str | os.PathLike | None = None) -> Fixture:
    """Load one fixture.

    Parameters
    ----------
    part : str
        e.g. ``"box_fillet"``; see :func:`list_fixtures`.
    variant : str
        One of :data:`VARIANTS` (or ``"large"`` from a ``--large`` folder given as ``root``).
    root : path, optional
        Folder holding the files; default :data:`FIXTURE_DIR`.
    """
    import trimesh

    root = Path(root) if root is not None else FIXTURE_DIR
    meta_path = root / f"{part}.json"
    stl_path = root / f"{part}_{variant}.stl"
    labels_path = root / f"{part}_{variant}.labels.npy"
    if not meta_path.exists():
        known = sorted({p for p, _ in list_fixtures(root=root)})
        raise InputError(f"part: no fixture {part!r} in {root} (known: {', '.join(known) or 'none'})")
    if not stl_path.exists() or not labels_path.exists():
        raise InputError(f"variant: no {variant!r} variant of {part!r} in {root} (expected {stl_path.name})")
    with open(meta_path) as fh:
        meta = json.load(fh)
    mesh = trimesh.load(stl_path, process=False, force="mesh")
    vertices, faces = weld(np.asarray(mesh.vertices)[np.asarray(mesh.faces)])
    labels = np.load(labels_path).astype(np.int64)
    if labels.shape != (len(faces),):
        raise InputError(f"{labels_path}: expected {len(faces)} labels (one per STL triangle), got {labels.shape}")
    true_faces = tuple(
        TrueFace(int(f["index"]), f["type"], float(f["area"]), bool(f.get("reversed", False)), f["params"])
        for f in meta["faces"]
    )
    return Fixture(
        part=part,
        variant=variant,
        vertices=vertices,
        faces=faces,
        labels=labels,
        true_faces=true_faces,
        diagonal=float(meta["diagonal"]),
        volume=float(meta["volume"]),
        area=float(meta["area"]),
        step_path=root / f"{part}.step",
        stl_path=stl_path,
        info=meta["variants"].get(variant, {}),
    )
