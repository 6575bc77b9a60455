"""The Dask task: one part, run in the worker's runner process, its outputs published through fsspec.

The task itself never runs OpenCascade. It stages the mesh (a copy only when it is not on a local disk), hands
it to a :mod:`recon.batch._runner` process, watches that process's time and memory, and copies the results to
the output folder. A part that crashes, hangs or overruns memory ends only its runner; the task returns the
part's ``error`` row and the worker goes on with a fresh runner.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import logging
import os
import posixpath
import selectors
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from ._inputs import is_local, fs_of

__all__ = ["run_part"]

log = logging.getLogger(__name__)

#: Seconds a runner may take to import recon and OpenCascade before it counts as broken (imports take 3–8 s on
#: a loaded 2-core machine; a tenfold margin).
START_TIMEOUT = 120.0
#: How often the task looks at its runner's memory and clock (a part runs for seconds to minutes).
POLL = 0.2

_runners: dict[int, "_Runner"] = {}
_lock = threading.Lock()


class _Runner:
    """One runner process and the read side of its protocol pipe."""

    def __init__(self):
        import recon

        self.log = tempfile.TemporaryFile()
        env = dict(os.environ)
        # The runner imports the same recon as this worker, installed or not.
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(Path(recon.__file__).parents[1]), env.get("PYTHONPATH")]))
        env.setdefault("OMP_NUM_THREADS", "1")  # one core per worker: BLAS threads would compete with the others
        self.proc = subprocess.Popen([sys.executable, "-m", "recon.batch._runner"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=self.log, env=env)
        assert self.proc.stdin is not None and self.proc.stdout is not None  # (PIPE both)
        self.stdin, self.stdout = self.proc.stdin, self.proc.stdout
        self.buf = b""
        ready = self.read(START_TIMEOUT, memory_limit=None)
        if "ready" not in ready:
            raise RuntimeError(ready.get("error", "the conversion process did not start"))

    def read(self, timeout: float | None, *, memory_limit: int | None) -> dict:
        """The next line from the runner, or ``{"error": ...}`` when it dies, overruns ``timeout`` seconds or
        ``memory_limit`` bytes (then it is killed)."""
        t0 = time.monotonic()
        fd = self.stdout.fileno()
        with selectors.DefaultSelector() as sel:
            sel.register(fd, selectors.EVENT_READ)
            while b"\n" not in self.buf:
                if sel.select(POLL):
                    chunk = os.read(fd, 65536)
                    if chunk:
                        self.buf += chunk
                        continue
                    return {"error": self._death()}
                if self.proc.poll() is not None:
                    return {"error": self._death()}
                if timeout is not None and time.monotonic() - t0 > timeout:
                    self.kill()
                    return {"error": f"timed out after {timeout:g} s"}
                if memory_limit and self.rss() > memory_limit:
                    self.kill()
                    return {"error": f"killed by the memory limit: the part's process passed "
                                     f"{memory_limit / 2**20:,.0f} MiB"}
        line, _, self.buf = self.buf.partition(b"\n")
        return json.loads(line)

    def rss(self) -> int:
        import psutil

        try:
            proc = psutil.Process(self.proc.pid)
            return sum(p.memory_info().rss for p in [proc, *proc.children(recursive=True)])
        except psutil.Error:
            return 0

    def _death(self) -> str:
        rc = self.proc.wait()
        if rc < 0:
            try:
                sig = signal.Signals(-rc).name
            except ValueError:
                sig = f"signal {-rc}"
            why = " (out of memory?)" if -rc == signal.SIGKILL else ""
            return f"the conversion process crashed: {sig}{why}"
        return f"the conversion process ended with exit code {rc}{self._last_log_line()}"

    def _last_log_line(self) -> str:
        self.log.seek(0)
        lines = [ln for ln in self.log.read().decode(errors="replace").splitlines() if ln.strip()]
        return f": {lines[-1][:200]}" if lines else ""

    def run(self, job: dict, *, timeout: float | None, memory_limit: int | None) -> dict:
        # The log holds this part's output only (the runner shares the file's offset): its last line is about it.
        self.log.seek(0)
        self.log.truncate()
        self.stdin.write((json.dumps(job) + "\n").encode())
        self.stdin.flush()
        return self.read(timeout, memory_limit=memory_limit)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def kill(self) -> None:
        with contextlib.suppress(OSError):
            self.proc.kill()
        self.proc.wait()


@atexit.register
def _close_runners() -> None:
    with _lock:
        for runner in _runners.values():
            runner.kill()
        _runners.clear()


def _runner() -> _Runner:
    """This thread's runner, started on first use or after the last one died."""
    key = threading.get_ident()
    with _lock:
        runner = _runners.get(key)
    if runner is None or not runner.alive():
        runner = _Runner()
        with _lock:
            _runners[key] = runner
    return runner


def _worker():
    try:
        from distributed import get_worker

        return get_worker()
    except (ImportError, ValueError):  # not in a Dask task (called directly)
        return None


def _worker_memory_limit() -> int | None:
    return getattr(getattr(_worker(), "memory_manager", None), "memory_limit", None) or None


def _stage_folder() -> str:
    """A fresh folder for one part's input copy and results, inside the worker's Dask work directory: if the worker
    is killed mid-part (SIGKILL, the machine's OOM killer) the folder outlives it, and the next worker Dask starts
    on this machine purges the dead worker's directory (its lock file is free)."""
    return tempfile.mkdtemp(prefix="recon-batch-", dir=getattr(_worker(), "local_directory", None))


def _publish(src: str, dest_fs, dest: str) -> None:
    """Copy a staged file to the output folder; on a local disk atomically (a reader never sees half a file)."""
    if is_local(dest_fs):
        from .._io import atomic_path

        with atomic_path(dest) as tmp:
            shutil.copyfile(src, tmp)
    else:
        dest_fs.put_file(src, dest)


def run_part(job: dict) -> dict:
    """Convert one part on this worker; return its summary row as a dict (never raises for the part's faults).

    ``job``: ``url``, ``name``, ``out`` (the output folder), ``suffix`` (of the shape), ``tolerance``,
    ``preview``, ``deviation``, ``timeout`` (seconds or None), ``key`` (stored in the report for reruns),
    ``memory_limit`` (bytes or None: the worker's).
    """
    t0 = time.perf_counter()
    row = {"input": job["url"], "output": "", "status": "error", "faces": None, "valid": None,
           "mesh_to_shape_p95_pct": None, "seconds": 0.0, "message": job.get("note", "")}
    stage = _stage_folder()
    try:
        runner = _runner()
        t0 = time.perf_counter()  # a part's time is its own: a runner's start-up (imports) is the worker's
        in_fs, in_path = fs_of(job["url"])
        mesh = in_path
        if not is_local(in_fs):
            mesh = os.path.join(stage, "input" + posixpath.splitext(in_path)[1].lower())
            in_fs.get_file(in_path, mesh)
        spec = {"mesh": mesh, "stage": stage, "name": job["name"], "suffix": job["suffix"],
                "tolerance": job["tolerance"], "preview": job["preview"], "deviation": job.get("deviation", True),
                "key": job["key"],
                "input_name": posixpath.basename(in_path)}
        limit = job.get("memory_limit") or _worker_memory_limit()
        result = runner.run(spec, timeout=job["timeout"], memory_limit=limit)
        if "error" in result:
            row["message"] = _join(result["error"].replace(mesh, job["url"]), row["message"])
            return row
        out_fs, out_root = fs_of(job["out"])
        for src in result["files"]:
            _publish(src, out_fs, posixpath.join(out_root, os.path.basename(src)))
        row.update(output=posixpath.join(job["out"], job["name"] + job["suffix"]),
                   status="ok" if result["good"] else "invalid", faces=result["faces"], valid=result["valid"],
                   mesh_to_shape_p95_pct=result["p95"], message=_join(result["why"], row["message"]))
        if limit and runner.alive() and runner.rss() > limit / 2:
            # A heap the last part left above half the limit would count against the next part: start afresh.
            runner.kill()
        return row
    except Exception as err:  # staging, publishing or starting a runner: this part's error, not the batch's end
        row["message"] = _join(" ".join(f"{type(err).__name__}: {err}".split())[:300], row["message"])
        return row
    finally:
        row["seconds"] = round(time.perf_counter() - t0, 3)
        shutil.rmtree(stage, ignore_errors=True)


def _join(*parts: str) -> str:
    return "; ".join(p for p in parts if p)
