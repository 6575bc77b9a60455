"""The twelve real CAD parts of ``../shared/parts`` as corpus cases: STEP files nobody here wrote, meshed in the same
regimes as the generated parts and judged the same way.

A real part is keyed like a generated one, by an integer: :data:`REAL_BASE` plus its index among the files sorted by
name (``--real`` picks them; ``--seeds 0-3`` then means the first four). Its truth is the shared STEP file itself,
read where it lies (never copied into the cache or the repository); the cache keeps only its metadata and meshes.
"""

from __future__ import annotations

from pathlib import Path

#: Keys of real parts start here, far above any generated seed.
REAL_BASE = 1_000_000
#: ../shared/parts beside the checkout, as CI lays it out.
REAL_DIR = Path(__file__).resolve().parents[3] / "shared" / "parts"


def real_files(folder: Path = REAL_DIR) -> list[Path]:
    """The real parts' STEP files, sorted by name (their order gives their keys)."""
    return sorted(p for p in folder.glob("*") if p.suffix.lower() in (".step", ".stp"))


def is_real(seed: int) -> bool:
    return int(seed) >= REAL_BASE


def real_seeds(indices: list[int] | None = None, folder: Path = REAL_DIR) -> list[int]:
    """The keys of the real parts (``indices`` into :func:`real_files`, default all)."""
    n = len(real_files(folder))
    picked = list(range(n)) if indices is None else indices
    bad = [i for i in picked if not 0 <= i < n]
    if bad:
        raise ValueError(f"real parts are numbered 0-{n - 1} ({folder}), got {bad}")
    return [REAL_BASE + i for i in picked]


def real_step(seed: int, folder: Path = REAL_DIR) -> Path:
    """The shared STEP file of a real part's key."""
    files = real_files(folder)
    i = int(seed) - REAL_BASE
    if not 0 <= i < len(files):
        raise ValueError(f"no real part {seed}: {len(files)} STEP files in {folder}")
    return files[i]


def real_meta(seed: int, solid) -> dict:
    """The metadata of a real part: :func:`bench.corpus.parts.solid_meta`, its family ``real:NAME``, its source file
    and its face count with same-surface neighbours joined (:func:`unified_faces`)."""
    from .parts import solid_meta

    step = real_step(seed)
    meta = dict(seed=int(seed), family=f"real:{step.stem}", ops=[], dropped=[], traits=[], **solid_meta(solid))
    if "bspline" in meta["face_types"]:
        meta["traits"].append("freeform")
    return dict(meta, source=step.name, faces_unified=unified_faces(solid))


def unified_faces(solid) -> int | None:
    """The part's face count once neighbouring faces on one surface are one face (``ShapeUpgrade_UnifySameDomain``);
    None where OpenCascade cannot unify it. Some CAD programs split every full cylinder or cone into two halves
    (SolidWorks: the axle 77 → 47 faces, the coupling 79 → 46), which a designer drew as one face and recon gives as
    one: this count is the one to compare recon's with."""
    from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopTools import TopTools_IndexedMapOfShape
    from OCP.TopExp import TopExp

    unify = ShapeUpgrade_UnifySameDomain(solid.wrapped, True, True, False)
    try:
        unify.Build()
    except Exception:  # noqa: BLE001  (Standard_Failure, e.g. "Courbes non jointives" on the pump casing)
        return None
    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(unify.Shape(), TopAbs_FACE, faces)
    return faces.Extent()
