"""Ground truth on disk: each part's true STEP and metadata, each (part, regime) mesh with its true face per triangle.

Layout of the cache folder (git-ignored; everything is regenerated from the seed):

- ``parts/seed_NNNNN.step`` and ``.json`` (the part's metadata, :func:`bench.corpus.parts.part`, plus what the STEP
  round trip changed); the STEP is the truth: the meshes are made from the solid read back from it (a real part,
  :mod:`bench.corpus.real`, has only its ``.json`` here: its truth is the shared STEP file);
- ``REGIME/seed_NNNNN.stl`` (``.obj`` for ``export-obj``), ``.labels.npy`` (true face per triangle; for the OBJ per
  polygon) and ``.json`` (the regime's drawn parameters, triangle count, mesh→true deviation).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .parts import part
from .real import is_real, real_meta, real_step, unified_faces
from .regimes import is_watertight, planar_polygons, tessellate_info, write_obj

DEFAULT_CACHE = Path(__file__).resolve().parent / "out" / "cache"


@dataclass(frozen=True)
class Truth:
    seed: int
    regime: str
    step: Path
    mesh: Path
    meta: dict  # the part's metadata
    info: dict  # the mesh's: regime parameters, triangles, watertight


def _stem(seed: int) -> str:
    return f"seed_{int(seed):05d}"


def true_part(seed: int, cache: Path = DEFAULT_CACHE):
    """``(step path, meta)`` of the part, generated once into ``cache/parts``."""
    folder = Path(cache) / "parts"
    step, js = folder / f"{_stem(seed)}.step", folder / f"{_stem(seed)}.json"
    if is_real(seed):  # the shared file is the truth, read where it lies; only its metadata is cached
        step = real_step(seed)
        if not js.exists():
            from recon._io import write_json

            folder.mkdir(parents=True, exist_ok=True)
            write_json(js, real_meta(seed, read_part(step)))
        return step, json.loads(js.read_text())
    if step.exists() and js.exists():
        return step, json.loads(js.read_text())
    from build123d import export_step

    from recon._io import atomic_path, write_json

    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    solid, meta = part(seed)
    with atomic_path(step) as tmp:
        export_step(solid, str(tmp))
    back = read_part(step)
    # the STEP is the truth (meshes are made from it); what writing it changed is recorded
    meta["step_volume_error"] = float(back.volume / solid.volume - 1)
    meta["step_faces"] = len(back.faces())
    meta["faces_unified"] = unified_faces(back)  # (the count a mesh can prove: bench/corpus/README.md, faces)
    meta["generate_seconds"] = round(time.perf_counter() - t0, 3)  # the part and its STEP round trip
    write_json(js, meta)
    return step, meta


def read_part(step: Path):
    """The one solid of a true STEP file (build123d)."""
    from build123d import import_step

    solids = import_step(str(step)).solids()
    if len(solids) != 1:
        raise RuntimeError(f"{step}: {len(solids)} solids")
    return solids[0]


def materialise_apart(seed: int, regime: str, cache: Path = DEFAULT_CACHE) -> Truth:
    """:func:`materialise`, with the making (when the case is not cached) in a spawned process.

    Building a part (its booleans) and checking its mesh (:func:`bench.corpus.regimes.off_part`) start OpenCascade's
    thread pool, and a child forked later from a process holding that pool deadlocks when it meshes: the corpus
    measures in a forked child, which sat idle to its 400 s limit on every case made in the same worker (bench/scan.md
    "s39-rim"). Reading a cached case starts no pool."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    ext = ".obj" if regime == "export-obj" else ".stl"
    folder = Path(cache) / regime
    if not ((folder / f"{_stem(seed)}{ext}").exists() and (folder / f"{_stem(seed)}.json").exists()):
        with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
            pool.submit(materialise, seed, regime, Path(cache)).result()  # a generator error is raised here
    return materialise(seed, regime, cache)


def materialise(seed: int, regime: str, cache: Path = DEFAULT_CACHE) -> Truth:
    """The true STEP and the mesh of ``seed`` in ``regime`` on disk (made once, then read from ``cache``)."""
    import trimesh

    from recon._io import atomic_path, write_json

    step, meta = true_part(seed, cache)
    folder = Path(cache) / regime
    ext = ".obj" if regime == "export-obj" else ".stl"
    mesh, js = folder / f"{_stem(seed)}{ext}", folder / f"{_stem(seed)}.json"
    if mesh.exists() and js.exists():
        return Truth(seed, regime, step, mesh, meta, json.loads(js.read_text()))
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    solid = read_part(step)
    v, t, lab, info = tessellate_info(solid, regime, seed)
    info.update(triangles=int(len(t)), vertices=int(len(v)), watertight=is_watertight(t))
    if regime == "export-obj":
        polys, lab = planar_polygons(v, t, lab, [k == "plane" for k in meta["face_types"]])
        info["polygons"] = len(polys)
        with atomic_path(mesh) as tmp:
            write_obj(tmp, v, polys)
    else:
        with atomic_path(mesh) as tmp:
            trimesh.Trimesh(v, t, process=False).export(tmp, file_type="stl")
    with atomic_path(mesh.with_suffix(".labels.npy")) as tmp:
        with open(tmp, "wb") as fh:
            np.save(fh, lab.astype(np.int32))
    info["generate_seconds"] = round(time.perf_counter() - t0, 3)  # reading the STEP, meshing, writing the mesh
    write_json(js, info)
    return Truth(seed, regime, step, mesh, meta, info)
