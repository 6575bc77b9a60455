"""The decomposition's second process: what it can be asked to do, and the guard that keeps it from stalling or
changing the decomposition (:mod:`recon._parallel` underneath)."""

from __future__ import annotations

import logging

from .._parallel import Failure, Worker
from ._growing import _grow_seed
from ._regionfit import _Ctx, _fit

log = logging.getLogger(__name__)

#: How long the parent waits for the worker's answer to one job before it stops the worker and does the work
#: itself (a worker that died answers at once: its end of the pipe closes). A job is one seed's growth or half a
#: refinement pass's fits, a few seconds on the largest meshes: this bounds a hung worker's cost (bench/decompose.md).
WORKER_TIMEOUT = 120.0


def _grow_job(ctx: _Ctx, seed, free, types):
    return _grow_seed(ctx, seed, free, types)


def _fits_job(ctx: _Ctx, jobs):
    return [_fit(ctx, faces, (kind,), polish=True) for faces, kind in jobs]


#: What the worker can be asked to do: name -> function(ctx, *args).
_JOBS = {"grow": _grow_job, "fits": _fits_job}


class _Worker:
    """The decomposition's second process (:class:`recon._parallel.Worker` holding the context, serving
    :data:`_JOBS`): :meth:`submit`, then :meth:`get`.

    It can never stall the parent nor change the result: when it dies, fails a job or gives no answer within
    :data:`WORKER_TIMEOUT`, :meth:`get` returns None, the worker is stopped for good, and the callers do the work
    themselves, as with one process. (A process forked from a threaded one can deadlock in the child on a lock
    another thread held at the fork; the timeout bounds what that costs.)
    """

    def __init__(self, ctx: _Ctx):
        self._worker = Worker(ctx, _JOBS, name="recon-decompose")

    @property
    def alive(self) -> bool:
        return self._worker.alive

    @staticmethod
    def available() -> bool:
        """Whether a second process can be had here: with fork (Linux) or spawn (elsewhere), see
        :func:`recon._parallel.start_method`."""
        return True

    @classmethod
    def start(cls, ctx: _Ctx) -> "_Worker | None":
        """A worker, or None where none can be had (then one process does all): inside a daemonic process (which
        may not have children), or when starting it fails."""
        try:
            return cls(ctx)
        except OSError as err:
            log.warning("decomposition: no second process (%s), going on in one", err or type(err).__name__)
            return None

    def submit(self, name: str, *args) -> bool:
        """Send a job of :data:`_JOBS`; False when the worker is gone (nothing was sent)."""
        was = self._worker.alive
        sent = self._worker.submit(name, *args)
        if was and not sent:
            self._stop()
        return sent

    def get(self):
        """The answer to the job submitted last, or None (the caller then does it itself)."""
        if not self._worker.alive:
            return None
        got = self._worker.get(WORKER_TIMEOUT)
        if isinstance(got, Failure):
            self._stop()
            return None
        return got

    def _stop(self) -> None:
        log.warning("decomposition: second process stopped, going on in one: %s", self._worker.stopped)

    def close(self) -> None:
        self._worker.close()
