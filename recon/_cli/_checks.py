"""Checks every subcommand makes before it starts the work: its options, and where its outputs go.

An output is refused up front (one line, exit 2) when it would overwrite an input or another output — the same
file by any name: a symlink, a hard link, ``./x`` for ``x`` — or cannot be written: its folder is missing, is a
file, or is read-only, or the output is itself a folder. Nothing is created to find out.
"""

from __future__ import annotations

import math
import os

import numpy as np
from pathlib import Path

from ..errors import ExportError, InputError

__all__ = ["check_outputs", "positive_length", "at_least", "check_tolerance", "check_size", "MIN_SAMPLES",
           "MAX_TOLERANCE_SHARE", "MIN_DIAGONAL", "MAX_DIAGONAL"]

#: ``compare --samples``: fewer area samples and the shape → mesh p95 rests on fewer than 5 samples above it.
MIN_SAMPLES = 100

#: A fit tolerance above this share of the part's diagonal lets one surface take in features a twentieth of the
#: part's size: no result could then be told apart from a wrong one by its deviation.
MAX_TOLERANCE_SHARE = 0.05

#: OpenCascade's fixed length precision (Precision::Confusion): two points closer than this are one.
CONFUSION = 1e-7

#: The part sizes (bounding-box diagonal, in the file's units) recon converts. Below MIN_DIAGONAL the finest length
#: recon works to (the default tolerance's floor, 1e-4 × the diagonal) comes within 100 × CONFUSION, and results
#: drift. Above MAX_DIAGONAL a coordinate's round-off (diagonal × machine epsilon) exceeds CONFUSION. Measured in
#: bench/robustness.md: identical results from 0.07 to 7e8 on every fixture tried, drift outside.
MIN_DIAGONAL = 100 * CONFUSION / 1e-4
MAX_DIAGONAL = CONFUSION / float(np.finfo(float).eps)


def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)  # hard links and symlinks of an existing file
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)  # one of them does not exist yet


def check_outputs(inputs: list[tuple[str, str | None]], outputs: list[tuple[str, str | None]]) -> None:
    """Refuse outputs that are an input, another output, or cannot be written; ``(label, path)`` pairs, None
    paths skipped.

    Raises
    ------
    InputError
        An output names an input or another output.
    ExportError
        An output's folder is missing, not a folder or not writable, or the output is a folder.
    """
    ins = [(label, Path(p)) for label, p in inputs if p]
    outs = [(label, Path(p)) for label, p in outputs if p]
    for i, (label, out) in enumerate(outs):
        for in_label, src in ins:
            if _same(out, src):
                raise InputError(f"{label} {out} is the {in_label} {src}: refusing to overwrite an input")
        for other_label, other in outs[:i]:
            if _same(out, other):
                raise InputError(f"{label} {out} and {other_label} {other} are the same file")
        _writable(out)


def _writable(out: Path) -> None:
    if out.is_dir():
        raise ExportError(f"cannot write {out}: it is a folder")
    if out.is_file() and not out.stat().st_mode & 0o222:  # (by its mode bits: root passes os.access)
        raise ExportError(f"cannot write {out}: the file is read-only (a file you protected is not replaced)")
    folder = out.parent
    if not folder.exists():
        # (a parent that is a file shows here as a path that does not exist; say which)
        for up in folder.parents:
            if up.exists():
                if not up.is_dir():
                    raise ExportError(f"cannot write {out}: {up} is a file, not a folder")
                break
        raise ExportError(f"cannot write {out}: folder {folder} does not exist")
    if not folder.is_dir():
        raise ExportError(f"cannot write {out}: {folder} is a file, not a folder")
    try:
        read_only = bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):
        read_only = False
    if read_only:
        raise ExportError(f"cannot write {out}: the file system of {folder} is read-only")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ExportError(f"cannot write {out}: permission denied (folder {folder})")


def positive_length(option: str, value: float | None) -> None:
    """A length option: finite and > 0."""
    if value is not None and not (value > 0 and math.isfinite(value)):
        raise InputError(f"{option} must be a positive finite length, got {value}")


def at_least(option: str, value: int | None, minimum: int, why: str = "") -> None:
    if value is not None and value < minimum:
        raise InputError(f"{option} must be at least {minimum}{why}, got {value}")


def check_size(diagonal: float) -> None:
    """The part's bounding-box diagonal must lie in [:data:`MIN_DIAGONAL`, :data:`MAX_DIAGONAL`]."""
    if not MIN_DIAGONAL <= diagonal <= MAX_DIAGONAL:
        raise InputError(f"the part is {diagonal:.3g} units across (bounding-box diagonal); recon works on parts "
                         f"{MIN_DIAGONAL:g} to {MAX_DIAGONAL:.2g} units across (OpenCascade's fixed precision, "
                         f"{CONFUSION:g}); rescale the mesh (e.g. to millimetres)")


def check_tolerance(tolerance: float | None, diagonal: float) -> None:
    """``--tolerance`` against the part: at most :data:`MAX_TOLERANCE_SHARE` of its diagonal."""
    if tolerance is not None and tolerance < CONFUSION:
        raise InputError(f"--tolerance {tolerance:g} is below OpenCascade's precision {CONFUSION:g}: no solid can be "
                         "built to it")
    if tolerance is not None and tolerance > MAX_TOLERANCE_SHARE * diagonal:
        raise InputError(f"--tolerance {tolerance:g} is more than {MAX_TOLERANCE_SHARE:.0%} of the part's diagonal "
                         f"{diagonal:.4g}: a surface could then swallow whole features; use at most "
                         f"{MAX_TOLERANCE_SHARE * diagonal:.4g}")
