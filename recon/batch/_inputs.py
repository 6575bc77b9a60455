"""Which files a batch converts, what each one's outputs are called, and which ones a rerun may skip.

Every location is an fsspec URL or a local path (``fsspec.core.url_to_fs`` turns a plain path into the local
file system), so the same code finds inputs on a disk, in a bucket or in memory.
"""

from __future__ import annotations

import json
import posixpath
from dataclasses import dataclass

from ..errors import InputError
from ..mesh import SUPPORTED_FORMATS

__all__ = ["Part", "find_parts", "name_parts", "run_key", "finished_reports", "report_ok", "is_local", "OUTPUT_FORMATS"]

#: ``--format`` → the output file's suffix (the writer chooses the format by it).
OUTPUT_FORMATS = {"step": ".step", "iges": ".igs", "brep": ".brep", "stl": ".stl"}

REPORT_SUFFIX = ".report.json"
PREVIEW_SUFFIX = ".preview.png"


@dataclass(frozen=True)
class Part:
    """One input mesh and where its results go.

    Attributes
    ----------
    url : str
        The input as fsspec names it (a plain absolute path for local files).
    size : int
        Bytes; with ``mtime`` it tells a rerun whether the input changed.
    mtime : float or None
    name : str
        The outputs' stem in the output folder (``NAME.step``, ``NAME.report.json``).
    note : str
        Why ``name`` is not the input's own stem ("" when it is).
    """

    url: str
    size: int
    mtime: float | None
    name: str = ""
    note: str = ""


def fs_of(location: str):
    import fsspec

    try:
        return fsspec.core.url_to_fs(location)
    except (ValueError, ImportError) as err:  # an unknown protocol, or its package missing
        raise InputError(f"{location}: {err}") from None


def _is_mesh(path: str) -> bool:
    base = posixpath.basename(path)
    # Hidden files are skipped: recon's own atomic writes stage under ".NAME.XXXX.stl" names.
    return not base.startswith(".") and posixpath.splitext(base)[1].lower() in SUPPORTED_FORMATS


def _mtime(info: dict) -> float | None:
    value = info.get("mtime", info.get("LastModified", info.get("created")))
    if value is None:
        return None
    return float(value.timestamp()) if hasattr(value, "timestamp") else float(value)


def is_local(fs) -> bool:
    from fsspec.implementations.local import LocalFileSystem

    return isinstance(fs, LocalFileSystem)


def _part(fs, path: str, info: dict) -> Part:
    # Local files keep a plain path (file:// included): the conversion reads them in place, with no copy.
    url = path if is_local(fs) else fs.unstrip_protocol(path)
    return Part(url=url, size=int(info.get("size") or 0), mtime=_mtime(info))


def find_parts(specs: list[str], *, exclude: str | None = None) -> list[Part]:
    """The mesh files named by ``specs`` (files, folders searched recursively, glob patterns), sorted by URL.

    A file given twice counts once. ``exclude`` (the output folder) is left out of folder searches, so that a
    rerun never takes its own STL outputs for inputs.

    Raises
    ------
    InputError
        A spec that names nothing, a file that is not a mesh format recon reads, or no spec at all.
    """
    if not specs:
        raise InputError("no input given")
    ex_fs, ex_path = fs_of(exclude) if exclude else (None, None)
    found: dict[str, Part] = {}
    exts = ", ".join(e[1:] for e in SUPPORTED_FORMATS)
    for spec in specs:
        fs, path = fs_of(str(spec))
        listing: dict[str, dict] = {}
        if any(c in path for c in "*?["):
            hits = fs.glob(path, detail=True)
            for p, info in hits.items():
                listing.update(fs.find(p, detail=True) if info.get("type") == "directory" else {p: info})
        elif fs.isdir(path):
            listing = fs.find(path, detail=True)
        elif fs.isfile(path):
            if not _is_mesh(path):
                raise InputError(f"{spec}: not a mesh format recon reads ({exts})")
            listing = {path: fs.info(path)}
        else:
            raise InputError(f"{spec}: no such file or folder")
        searched = len(listing) != 1 or not fs.isfile(path)  # a file named outright is taken as it is
        meshes = {p: info for p, info in listing.items() if _is_mesh(p) and not (
            searched and ex_path is not None and type(ex_fs) is type(fs) and _inside(p, ex_path))}
        if not meshes:
            raise InputError(f"{spec}: no mesh files ({exts}) found")
        for p, info in meshes.items():
            part = _part(fs, p, info)
            found.setdefault(part.url, part)
    return [found[u] for u in sorted(found)]


def _inside(path: str, folder: str) -> bool:
    folder = folder.rstrip("/")
    return path == folder or path.startswith(folder + "/")


def name_parts(parts: list[Part]) -> list[Part]:
    """Give every part an output stem: its own, or ``STEM~2``, ``STEM~3``… when an earlier part (by sorted URL)
    holds it. Compared without case, because macOS and Windows disks do not tell ``Part`` from ``part``."""
    taken: dict[str, str] = {}
    named = []
    for part in sorted(parts, key=lambda p: p.url):
        stem = posixpath.splitext(posixpath.basename(part.url.rstrip("/")))[0]
        name, k = stem, 1
        while name.casefold() in taken:
            k += 1
            name = f"{stem}~{k}"
        note = "" if k == 1 else f"named {name}: {stem} is the output name of {taken[stem.casefold()]}"
        taken[name.casefold()] = part.url
        named.append(Part(part.url, part.size, part.mtime, name, note))
    return named


def run_key(part: Part, *, version: str, tolerance: float | None, fmt: str, deviation: bool = True) -> dict:
    """What a finished part's report must record for a rerun to skip it: the same input (URL, size, time), the
    same recon and the options that change the result (a result whose deviation was not measured is not the
    verified one a run with the deviation asks for)."""
    return {"recon": version, "input": part.url, "size": part.size, "mtime": part.mtime,
            "tolerance": tolerance, "format": fmt, "deviation": deviation}


def finished_reports(out: str, parts: list[Part], keys: list[dict]) -> list[dict | None]:
    """For each part, the report of an earlier run that made it with its key and called it good, if its outputs
    are all there; else None (the part is converted again).

    One listing of the output folder and one batched read of the reports (concurrent on object stores), not a
    request per part and per file."""
    fs, root = fs_of(out)
    try:
        present = set(fs.find(root, maxdepth=1)) if fs.isdir(root) else set()
    except OSError:
        present = set()
    wanted = {}
    for part, key in zip(parts, keys):
        report_path = posixpath.join(root, part.name + REPORT_SUFFIX)
        if report_path in present and posixpath.join(root, part.name + OUTPUT_FORMATS[key["format"]]) in present:
            wanted[report_path] = (part, key)
    texts = fs.cat(list(wanted), on_error="omit") if wanted else {}
    found = {}
    for path, (part, key) in wanted.items():
        try:
            report = json.loads(texts[path])
        except (KeyError, ValueError):
            continue
        if isinstance(report, dict) and report.get("batch") == key and report_ok(report):
            found[part.url] = report
    return [found.get(part.url) for part in parts]


def report_ok(report: dict) -> bool:
    """recon's own verdict on a result: the acceptance rules of :mod:`recon.verdict`."""
    return bool((report.get("verdict") or {}).get("ok"))
