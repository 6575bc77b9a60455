"""The process that converts parts for one Dask worker thread (``python -m recon.batch._runner``).

The worker's task starts it once and hands it one part at a time, so OpenCascade and the pipeline are imported
once per worker, not once per part, while a segfault, an abort or a runaway allocation still kills only this
process: the task sees it die, makes the part's ``error`` row and starts a fresh one for the next part.

Protocol: one JSON object per line. The runner writes ``{"ready": pid}`` once imported, then reads a job per
line on stdin and answers one result per line on its original stdout; everything else the process prints
(OpenCascade's STEP writer prints statistics on fd 1) goes to stderr.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import sys
import threading
import time
from pathlib import Path

#: Test-only: a runner whose job's input file is named this aborts (SIGABRT), as a segfault in the CAD kernel
#: would end it. Set in the environment of the workers; it has no effect otherwise.
ABORT_ENV = "RECON_TEST_ABORT"
#: Test-only, likewise: a part whose input file is named this hangs (a runaway conversion) until a file named as
#: the input plus ".release" appears beside it.
HANG_ENV = "RECON_TEST_HANG"


def _one_line(text: object, limit: int = 300) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _watch_parent(parent: int) -> None:
    # The worker may die while a part runs (killed, its cluster closed): a runner left behind would hold a core.
    while os.getppid() == parent:
        time.sleep(1.0)
    os._exit(3)


def convert_job(job: dict) -> dict:
    """Convert one staged mesh; write the shape, the preview and the report (last: its presence with an ok verdict
    marks the part finished) into ``job["stage"]``. Returns the figures of the summary row."""
    from .._io import write_json
    from ..pipeline import convert
    from ..verdict import write_checked
    from ._inputs import PREVIEW_SUFFIX, REPORT_SUFFIX, report_ok

    if os.environ.get(ABORT_ENV) and os.environ[ABORT_ENV] == job["input_name"]:
        os.abort()
    while os.environ.get(HANG_ENV) == job["input_name"] and not os.path.exists(job["mesh"] + ".release"):
        # poll period in seconds of the test hook's hang (wall time, not geometry)
        time.sleep(0.2)
    stage, name = Path(job["stage"]), job["name"]
    # jobs=1: the batch's parallelism is one part per worker; a second process per part would only compete.
    result = convert(job["mesh"], tolerance=job["tolerance"], deviation=job.get("deviation", True), jobs=1)
    files = [stage / (name + job["suffix"])]
    write_checked(result, files[0], name=name)  # the verdict judges the file as written, as `recon convert` does
    report = dict(result.report, batch=job["key"])
    if job["preview"]:
        from ..preview import render_result

        files.append(stage / (name + PREVIEW_SUFFIX))
        render_result(files[-1], result, title=f"{name}: {report['n_faces']} faces")
    files.append(stage / (name + REPORT_SUFFIX))
    write_json(files[-1], report)
    dev = report.get("deviation") or {}
    return {
        "files": [str(p) for p in files],
        "good": report_ok(report),
        "faces": report["n_faces"],
        "valid": bool(report["validity"]["ok"]),
        "p95": (dev.get("mesh_to_shape") or {}).get("p95_pct"),
        "why": _why(report),
    }


def _why(report: dict) -> str:
    """One line on why a written result is not good (the verdict's failed rules), or that a good one's deviation
    was not measured ("" for a good, verified result)."""
    from ._inputs import report_ok

    if report_ok(report):
        return "" if report["verdict"].get("within_tolerance") is not None else \
            "deviation NOT verified (not measured: --no-deviation)"
    failed = [r for r in report["verdict"]["rules"] if r["ok"] is False]
    words = "; ".join(f"{r['rule']}: {r['detail'] or r['value']}"
                      + (f" ({', '.join(r['faces'][:3])})" if r["faces"] else "") for r in failed)
    # the rules' names first: the details of several failed rules pass the line's length, and get cut
    return _one_line(f"not good: {', '.join(r['rule'] for r in failed)}: {words}", 200)


def main() -> None:
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    # Ctrl-C reaches the whole process group; the worker decides, and this process ends with it.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(os.getppid(),), daemon=True).start()
    logging.basicConfig(level=logging.WARNING, format="%(name)s: %(message)s")
    from .. import pipeline  # noqa: F401  (imported before "ready": a job's time is the conversion alone)
    from .. import brep  # noqa: F401
    from ..errors import ReconError

    proto.write(json.dumps({"ready": os.getpid()}) + "\n")
    for line in sys.stdin:
        job = json.loads(line)
        try:
            result = convert_job(job)
        except ReconError as err:
            result = {"error": _one_line(err)}
        except MemoryError:
            result = {"error": "out of memory"}
        except Exception as err:  # any other failure of one part is that part's row, not the runner's end
            logging.getLogger(__name__).exception("part %s", job.get("input_name"))
            result = {"error": _one_line(f"{type(err).__name__}: {err}")}
        proto.write(json.dumps(result) + "\n")


if __name__ == "__main__":
    main()
