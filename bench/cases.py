"""What the benchmark measures: its case groups, the columns of every row, and the scaling meshes.

The groups and what each case does are described in :mod:`bench.run`.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

from recon.errors import InputError

__all__ = [
    "COLUMNS",
    "GROUPS",
    "STAGES",
    "Case",
    "fixture_cases",
    "mesh_cases",
    "freecad_cases",
    "scaling_cases",
    "scaling_mesh",
]

log = logging.getLogger(__name__)


GROUPS = ("fixtures", "meshes", "freecad", "scaling")
REPO = Path(__file__).resolve().parent.parent
#: the real meshes nobody on the project made (not in the repository)
MESH_DIR = REPO / ".." / "shared" / "meshes"
SCALING_DIR = REPO / "fixtures" / "large" / "scaling"
DEFAULT_OUT = REPO / "bench" / "out"
#: ``--quick`` runs FreeCAD only on meshes up to this many triangles (it takes ~70–550 s on 40k–112k)
QUICK_FREECAD_TRIANGLES = 25_000
#: The scaling part FreeCAD also runs on, with or without ``--quick``: issue 5's "≥ 100× faster at 100k triangles".
FREECAD_PART_TRIANGLES = 100_000
SCALING_SIZES = (10_000, 100_000, 1_000_000, 2_000_000)
SCALING_PART = "box_fillet"
#: seconds per case, by group
TIMEOUTS = {"fixtures": 900, "meshes": 1800, "freecad": 1800, "scaling": 7200}
#: resident memory (MiB) above which a case's subprocess is killed (it shares the machine), by group
MEMORY_LIMITS = {"fixtures": 8192, "meshes": 8192, "freecad": 8192, "scaling": 12288}
#: the stages timed per case (``recon.pipeline.STAGES`` plus writing the STEP file)
STAGES = ("load", "decompose", "fit", "brep", "deviation", "export")

#: Every row of ``bench.json`` has these keys (``None`` where not applicable or not measured).
COLUMNS = {
    "case": "unique case name",
    "group": "fixtures | meshes | freecad | scaling",
    "kind": "fixture | mesh | freecad | scaling",
    "source": "the mesh file measured",
    "status": "ok | invalid (not a valid closed solid) | error (exception) | timeout | crashed",
    "error": "one line: what failed, where",
    "triangles": "triangles after cleaning (input triangles for FreeCAD)",
    "faces_true": "faces of the true B-rep",
    "faces_ours": "faces of the result (recon, or FreeCAD for freecad rows)",
    "types_true": "true faces by surface type",
    "types_ours": "our faces by surface type",
    "type_agreement": "area share of true faces whose best-overlapping face of ours has the same surface type",
    "recovered": "share of true faces matched by one of our faces with area IoU >= 0.5",
    "mean_iou": "mean over true faces of the best area IoU with our faces",
    "dec_recovered": "as recovered, for the raw decomposition (before sharp strips dissolve into faces)",
    "dec_mean_iou": "as mean_iou, for the raw decomposition",
    "m2s_max": "mesh -> our shape: max |distance|, % of the mesh's bounding-box diagonal",
    "m2s_p95": "mesh -> our shape: 95th percentile, % of diagonal",
    "m2s_rms": "mesh -> our shape: RMS, % of diagonal",
    "s2m_max": "our shape -> mesh: max, % of diagonal",
    "s2m_p95": "our shape -> mesh: 95th percentile, % of diagonal",
    "s2m_rms": "our shape -> mesh: RMS, % of diagonal",
    "true_m2s_max": "mesh -> true STEP: max, % of diagonal",
    "true_m2s_p95": "mesh -> true STEP: 95th percentile, % of diagonal",
    "true_m2s_rms": "mesh -> true STEP: RMS, % of diagonal",
    "true_s2m_max": "true STEP -> mesh: max, % of diagonal",
    "true_s2m_p95": "true STEP -> mesh: 95th percentile, % of diagonal",
    "true_s2m_rms": "true STEP -> mesh: RMS, % of diagonal",
    "ours_true_max": "our shape -> true STEP (points exactly on ours, recon.deviation.model_deviation): max, % of diagonal",
    "ours_true_p95": "our shape -> true STEP: 95th percentile, % of diagonal",
    "ours_true_rms": "our shape -> true STEP: RMS, % of diagonal",
    "true_ours_max": "true STEP -> our shape (points exactly on the true faces): max, % of diagonal",
    "true_ours_p95": "true STEP -> our shape: 95th percentile, % of diagonal",
    "true_ours_rms": "true STEP -> our shape: RMS, % of diagonal",
    "expected": "solid (the mesh is closed) | shell (an open scan)",
    "valid": "the expected result: a valid closed solid with volume > 0 from a closed mesh, a valid shell from an "
    "open one (OpenCascade's check; FreeCAD's isValid and a solid for freecad rows)",
    "shape_type": "solid | shell | compound ...",
    "failed_faces": "parts that got no face of their own",
    "face_fits": "per face: [name, surface type, status, fit max % diag, fit RMS % diag, fit max / tolerance]",
    "seconds": "seconds per stage: load, decompose, fit, brep, deviation, export (FreeCAD: its own stages)",
    "convert_seconds": "load + decompose + fit + brep + export: mesh file to STEP file (what FreeCAD is timed on)",
    "wall_seconds": "whole subprocess, with interpreter start and imports",
    "peak_mb": "peak resident memory of the case's subprocess (FreeCAD: of freecadcmd), MiB",
    "stage_peak_mb": "peak resident memory while each stage ran, MiB",
    "step_bytes": "size of the STEP file written",
}


@dataclass(frozen=True)
class Case:
    """One benchmark case: what to measure, run in a subprocess by :func:`bench.run.run_case`.

    Attributes
    ----------
    name : str
    group : str
        One of :data:`GROUPS`.
    kind : str
        ``fixture`` (``spec["part"]``, ``spec["variant"]``), ``mesh`` (``spec["path"]``, optional
        ``spec["true_step"]``), ``freecad`` (``spec["path"]``) or ``scaling`` (``spec["triangles"]``).
    spec : dict
        Plain JSON for the worker.
    timeout : float
        Seconds before the subprocess is killed.
    max_memory_mb : float, optional
        Resident memory (MiB) at which it is killed; default :data:`MEMORY_LIMITS` of its group.
    """

    name: str
    group: str
    kind: str
    spec: dict = field(default_factory=dict)
    timeout: float = 900.0
    max_memory_mb: float | None = None


# ----------------------------------------------------------------------------------------------------------------
# Cases


def fixture_cases(*, root=None, timeout: float | None = None) -> list[Case]:
    """One case per committed fixture (part × variant)."""
    from recon.fixtures import list_fixtures

    t = TIMEOUTS["fixtures"] if timeout is None else timeout
    spec_root = None if root is None else str(root)
    return [
        Case(f"{p}/{v}", "fixtures", "fixture", {"part": p, "variant": v, "root": spec_root}, t)
        for p, v in list_fixtures(root=root)
    ]


def _real_meshes(mesh_dir: Path) -> list[Path]:
    if not mesh_dir.is_dir():
        return []
    return sorted(p for p in mesh_dir.iterdir() if p.suffix.lower() in (".off", ".stl", ".obj", ".ply"))


def mesh_cases(*, mesh_dir=None, timeout: float | None = None) -> list[Case]:
    """One case per real mesh in ``mesh_dir`` (default :data:`MESH_DIR`); none where the folder is absent."""
    mesh_dir = Path(MESH_DIR if mesh_dir is None else mesh_dir)
    t = TIMEOUTS["meshes"] if timeout is None else timeout
    cases = []
    for p in _real_meshes(mesh_dir):
        gt = p.with_name(p.stem + ".gt.step")
        spec = {"path": str(p.resolve())}
        if gt.exists():
            spec["true_step"] = str(gt.resolve())
        cases.append(Case(f"mesh/{p.stem}", "meshes", "mesh", spec, t))
    if not cases:
        log.warning("no real meshes in %s: the meshes group is empty", mesh_dir)
    return cases


def triangle_count(path: Path) -> int:
    """Triangles in a mesh file, read cheaply (OFF header, binary STL header; otherwise a full read)."""
    suffix = path.suffix.lower()
    with open(path, "rb") as fh:
        if suffix == ".off":
            words = []
            for line in fh:
                line = line.split(b"#")[0].strip()
                if line:
                    words += line.split()
                if len(words) >= 3 and words[0].upper().endswith(b"OFF"):
                    if len(words) >= 4:
                        return int(words[2])
                elif len(words) >= 3:
                    return int(words[1])
        if suffix == ".stl":
            head = fh.read(84)
            n = int.from_bytes(head[80:84], "little")
            if 84 + 50 * n == path.stat().st_size:
                return n
    from recon.mesh import read_triangles

    return int(len(read_triangles(path)[1]))


def freecad_cases(*, quick: bool = False, mesh_dir=None, fixture_root=None, timeout: float | None = None) -> list[Case]:
    """The FreeCAD route on the clean fixtures and the real meshes (``quick``: only the small ones).

    Empty where FreeCAD is not installed.
    """
    from recon._freecad import freecadcmd
    from recon.fixtures import FIXTURE_DIR, list_fixtures

    if freecadcmd() is None:
        log.warning("FreeCAD is not installed: no freecad cases")
        return []
    t = TIMEOUTS["freecad"] if timeout is None else timeout
    root = Path(FIXTURE_DIR if fixture_root is None else fixture_root)
    paths = [(f"{p}/{v}", root / f"{p}_{v}.stl") for p, v in list_fixtures(root=root) if v == "clean"]
    paths += [(f"mesh/{p.stem}", p) for p in _real_meshes(Path(MESH_DIR if mesh_dir is None else mesh_dir))]
    cases = []
    for name, path in paths:
        n = triangle_count(path)
        if quick and n > QUICK_FREECAD_TRIANGLES:
            log.info("--quick: FreeCAD skips %s (%d triangles)", name, n)
            continue
        cases.append(Case(f"freecad:{name}", "freecad", "freecad", {"path": str(path.resolve()), "of": name}, t))
    # The part issue 5 states the speed target on (≥ 100× at 100k triangles): run even with --quick. The mesh is
    # the scaling group's, made on first use (in the case's subprocess, outside FreeCAD's timing).
    n = FREECAD_PART_TRIANGLES
    cases.append(Case(f"freecad:scaling/{size_name(n)}", "freecad", "freecad",
                      {"path": str(scaling_mesh_path(n).resolve()), "of": f"scaling/{size_name(n)}", "triangles": n},
                      t))
    return cases


def scaling_cases(*, sizes=SCALING_SIZES, timeout: float | None = None) -> list[Case]:
    """``box_fillet`` at each size in ``sizes`` (triangles); the meshes are made on first use."""
    t = TIMEOUTS["scaling"] if timeout is None else timeout
    return [Case(f"scaling/{size_name(n)}", "scaling", "scaling", {"triangles": int(n)}, t) for n in sizes]


def size_name(n: int) -> str:
    return f"{n // 1_000_000}M" if n % 1_000_000 == 0 else f"{n // 1000}k" if n % 1000 == 0 else str(n)


# ----------------------------------------------------------------------------------------------------------------
# The scaling meshes


def _load_make_fixtures():
    import importlib.util

    script = REPO / "fixtures" / "make_fixtures.py"
    if not script.exists():
        raise InputError(f"scaling: needs {script} to make the meshes, not found")
    spec = importlib.util.spec_from_file_location("_recon_make_fixtures", script)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def make_scaling_mesh(triangles: int) -> None:
    """Make (and cache) a scaling mesh in a child process, so its memory and time stay out of the case's figures."""
    subprocess.run([sys.executable, "-m", "bench.run", "--make-scaling", str(triangles)],
                   check=True, stdin=subprocess.DEVNULL, capture_output=True, env=child_env())


def scaling_mesh_path(triangles: int, *, folder: Path = SCALING_DIR) -> Path:
    return folder / f"{SCALING_PART}_{size_name(triangles)}.stl"


def scaling_mesh(triangles: int, *, folder: Path = SCALING_DIR) -> Path:
    """``box_fillet`` with about ``triangles`` triangles: the fixtures' remesher at n / 4^k, then k subdivisions
    with projection onto the true faces (k the least with n / 4^k ≤ 8000). Cached in ``folder``."""
    path = scaling_mesh_path(triangles, folder=folder)
    if path.exists() and path.with_suffix(".labels.npy").exists():
        return path
    mf = _load_make_fixtures()
    folder.mkdir(parents=True, exist_ok=True)
    solid = mf.build_part(SCALING_PART)
    table = mf.face_table(solid)
    area = sum(e["area"] for e in table)
    k = 0
    while triangles / 4**k > 8000:
        k += 1
    V, T, L, kind, owner, feature, face_proj, edge_proj = mf.scanlike_mesh(solid, table, mf.h_for(area, triangles / 4**k))
    mesh = (V, T, L, kind, owner, feature)
    for _ in range(k):
        mesh = mf.subdivide(*mesh, face_proj, edge_proj)
    mf._write_mesh(path, mesh[0], mesh[1], mesh[2])
    log.info("scaling mesh %s: %d triangles", path.name, len(mesh[1]))
    return path


def child_env() -> dict:
    """The environment of a subprocess of the benchmark: this checkout first on the path, so that it finds ``bench``
    (it runs in a temporary folder) and measures the same ``recon`` as the process that started it."""
    path = os.environ.get("PYTHONPATH")
    return {**os.environ, "PYTHONPATH": str(REPO) + (os.pathsep + path if path else "")}
