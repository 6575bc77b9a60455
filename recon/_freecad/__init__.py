"""Drive Debian's FreeCAD (``freecadcmd``, headless) in a subprocess: check recon's STEP files the way a user opens
them, and run the route users take today (mesh → Part shape → refine → solid → STEP) for side-by-side benchmarks.

FreeCAD is optional: :func:`freecadcmd` returns ``None`` where it is absent. Nothing here imports FreeCAD into recon's
own interpreter (it is built against the system Python, not ours).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from ..errors import ReconError

__all__ = ["freecadcmd", "inspect_step", "freecad_route"]

_HERE = Path(__file__).parent


def freecadcmd() -> str | None:
    """Path of ``freecadcmd`` (or ``FreeCADCmd``), or None where FreeCAD is not installed."""
    return shutil.which("freecadcmd") or shutil.which("FreeCADCmd")


def _run(script: str, env_args: dict, *, timeout: float) -> dict:
    exe = freecadcmd()
    if exe is None:
        raise ReconError("FreeCAD is not installed (no freecadcmd on PATH)")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out.json"
        env = dict(os.environ, RECON_FC_OUT=str(out), **{k: str(v) for k, v in env_args.items()})
        # freecadcmd treats extra arguments as files to open, so the arguments travel in the environment.
        proc = subprocess.run(
            [exe, str(_HERE / script)], env=env, capture_output=True, text=True, timeout=timeout, cwd=tmp
        )
        if not out.exists():
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
            raise ReconError(f"freecadcmd {script} failed: {' | '.join(tail)}")
        return json.loads(out.read_text())


def inspect_step(path: str | os.PathLike, *, timeout: float = 300) -> dict:
    """Open a STEP file in FreeCAD as a user would and describe what it holds.

    Returns
    -------
    dict
        ``{"objects": [{"label", "type", "valid", "volume", "faces", "solids", "closed"}], "face_names": [...],
        "seconds": float}``; ``face_names`` lists the labels FreeCAD shows for sub-shapes (named faces).
    """
    return _run("fc_inspect.py", {"RECON_FC_STEP": Path(path).resolve()}, timeout=timeout)


def freecad_route(mesh_path: str | os.PathLike, step_out: str | os.PathLike, *, timeout: float = 3600) -> dict:
    """The route users take today in FreeCAD: mesh → ``Part.Shape.makeShapeFromMesh`` → ``removeSplitter`` (refine)
    → solid → STEP. Returns ``{"faces", "valid", "seconds", "step_bytes", "stages": {...}}``."""
    t0 = time.perf_counter()
    res = _run(
        "fc_route.py",
        {"RECON_FC_MESH": Path(mesh_path).resolve(), "RECON_FC_STEP": Path(step_out).resolve()},
        timeout=timeout,
    )
    res["wall_seconds"] = time.perf_counter() - t0
    return res
