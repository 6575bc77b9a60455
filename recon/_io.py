"""Writing outputs so that a failure never leaves a half-written file, and no run leaves a temporary one.

A result is written to a temporary file beside its destination (the rename onto it must stay on one file
system to be atomic) and renamed into place when complete. The temporary's name carries its owner's process id
and start time, ``.NAME.recon-PID-START.XXXX.SUFFIX``: an error or a signal removes it (the CLI's watchdog too,
through :func:`remove_temporaries`), and what a killed process (SIGKILL, a crash) could not remove, the next
write into that folder removes, once the owner is gone.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import tempfile
import threading
from pathlib import Path

from .errors import ExportError

__all__ = ["atomic_path", "write_json", "remove_temporaries", "stop_commits", "commits_stopped"]

#: Free space under which a failed write is put down to a full disk: a writer's buffer at most.
DISK_FULL_BYTES = 1 << 20

_LIVE: set[str] = set()
_LIVE_LOCK = threading.Lock()
_STOPPED: list[str] = []
_OWNER_RE = re.compile(r"^\..*\.recon-(\d+)-(\d+)\.[^.]+(\.[^.]*)?$")


def _start_time(pid: int) -> int:
    """The process's start time in clock ticks since boot (Linux), 0 where unknown: with the pid it names one
    process for good (a pid alone is reused)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            return int(fh.read().rsplit(b")", 1)[1].split()[19])
    except (OSError, IndexError, ValueError):
        return 0


def _alive(pid: int, start: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process: alive
    return start == 0 or _start_time(pid) in (0, start)


def _sweep(folder: Path) -> None:
    """Remove the temporaries of dead recon runs in ``folder`` (only this user's files)."""
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    uid = os.getuid() if hasattr(os, "getuid") else None
    for entry in entries:
        m = _OWNER_RE.match(entry.name)
        if not m:
            continue
        try:
            if uid is not None and entry.stat(follow_symlinks=False).st_uid != uid:
                continue
            if not _alive(int(m.group(1)), int(m.group(2))):
                os.unlink(entry.path)
        except OSError:
            pass


def stop_commits(reason: str) -> None:
    """From now on no :func:`atomic_path` renames a result into place (the run was interrupted)."""
    _STOPPED.append(reason)


def commits_stopped() -> str | None:
    """Why :func:`stop_commits` was called, or None."""
    return _STOPPED[0] if _STOPPED else None


def remove_temporaries() -> None:
    """Remove every temporary file this process holds open in :func:`atomic_path` (for a signal's hard exit)."""
    with _LIVE_LOCK:
        for tmp in list(_LIVE):
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        _LIVE.clear()


def _disk_full(folder: Path) -> bool:
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError):
        return False
    # a writer fails on its last buffer (a few KiB to 1 MiB) and says only that it failed (OpenCascade: a status)
    return st.f_bavail * st.f_frsize < DISK_FULL_BYTES


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path``; rename it onto ``path`` only if the block succeeds.

    The temporary name keeps the suffix, so writers that choose a format by extension still work.

    Raises
    ------
    ExportError
        The folder does not exist or cannot be written, or the disk filled up (the temporary is removed).
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise ExportError(f"cannot write {path}: folder {path.parent} does not exist")
    _sweep(path.parent)
    pid = os.getpid()
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.recon-{pid}-{_start_time(pid)}.", suffix=path.suffix,
                                   dir=path.parent)
    except OSError as err:
        raise _export_error(err, path) from err
    os.close(fd)
    with _LIVE_LOCK:
        _LIVE.add(tmp)
    try:
        yield Path(tmp)
        if _STOPPED:
            raise KeyboardInterrupt(_STOPPED[0])
        # mkstemp makes the file private (0600); give it the mode a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except OSError as err:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise _export_error(err, path) from err
    except Exception as err:  # a writer's own error (OpenCascade reports a full disk as a failed status)
        full = _disk_full(path.parent)  # (before the temporary's removal frees its space)
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if full:
            raise ExportError(f"disk full while writing {path}") from err
        raise
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    finally:
        with _LIVE_LOCK:
            _LIVE.discard(tmp)


def _export_error(err: OSError, path: Path) -> ExportError:
    if err.errno in (errno.ENOSPC, errno.EDQUOT):
        return ExportError(f"disk full while writing {path}")
    if err.errno in (errno.EACCES, errno.EPERM):
        return ExportError(f"cannot write {path}: permission denied")
    if err.errno == errno.EROFS:
        return ExportError(f"cannot write {path}: the file system is read-only")
    return ExportError(f"cannot write {path}: {err.strerror or err}")


def write_json(path: str | os.PathLike, data) -> None:
    """Write ``data`` as strict JSON atomically: a NaN or an infinity raises ``ValueError`` before the file exists
    (JSON has no word for them; other tools cannot read a file that holds them)."""
    text = json.dumps(data, allow_nan=False)
    with atomic_path(path) as tmp:
        with open(tmp, "w") as fh:
            fh.write(text)
