"""The one process layer: a function in a child process, a worker that serves jobs, a map shared with a child.

Three things in recon need another process: an OpenCascade call that can crash the process or spin for minutes
(a face built in a child, :func:`isolated`), a second core for the decomposition's seeds and fits (:class:`Worker`),
and a second core for placing the curve network's edges (:func:`shared_map`). All three go through here, with one
set of rules:

- They work with the ``fork`` and the ``spawn`` start methods. ``fork`` is used where it is safe (Linux): the
  child starts with the parent's memory, so closures and OpenCascade objects need no pickling. Elsewhere
  ``spawn``, which pickles the function and its arguments; where they cannot be pickled the work is done in
  this process, with the same result.
- Results come back through a pipe, never through files: nothing is left behind when either process is killed.
- A child dies with its parent (``PR_SET_PDEATHSIG`` on Linux; elsewhere a thread that watches the parent's pid),
  ignores SIGINT (Ctrl-C reaches the whole process group: the parent stops its children and raises
  ``KeyboardInterrupt``; a child never swallows it) and takes SIGTERM's default action.
- A child that crashes (a signal), runs past its time or raises is a typed :class:`Failure`, never an exception
  in the parent and never a hang.
"""

from __future__ import annotations

import enum
import logging
import multiprocessing
import os
import pickle
import signal
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Mapping

__all__ = ["Failure", "FailureKind", "Worker", "isolated", "shared_map", "start_method", "time_limits_fired"]

log = logging.getLogger(__name__)

#: Seconds between two looks at the parent's pid, where the kernel cannot be asked to kill the child with it.
PARENT_POLL = 0.5

#: What each :func:`isolated` child killed at its time limit in this process was doing, in order.
_TIMED_OUT: list[str] = []


def time_limits_fired() -> int:
    """How many :func:`isolated` children this process has killed at their time limit so far.

    A time limit is a safety net against a call that hangs; where it fires, what comes next depends on the machine's
    speed (issue 25). A caller whose result must not compares the count before and after its calls, and fails.
    (:class:`Worker`'s and :func:`shared_map`'s limits are not counted: the parent redoes the work, the same result.)
    """
    return len(_TIMED_OUT)


class FailureKind(enum.Enum):
    """How a child failed to give a result."""

    CRASHED = "crashed"  # ended without an answer: killed by a signal or exited
    TIMED_OUT = "timed out"  # no answer in time: killed
    RAISED = "raised"  # the function raised; ``Failure.error_type`` / ``message`` say what


@dataclass(frozen=True)
class Failure:
    """A child's failure to give a result: false in a boolean context, and never a value a function returns."""

    kind: FailureKind
    message: str
    signal: int | None = None  # (CRASHED by a signal)
    exit_code: int | None = None  # (CRASHED by an exit)
    error_type: str = ""  # (RAISED) the exception's class name

    def __bool__(self) -> bool:
        return False


def start_method() -> str:
    """``"fork"`` on Linux (the child needs no pickling), ``"spawn"`` elsewhere (macOS's system libraries are not
    safe in a forked child, Windows cannot fork)."""
    if sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods():
        return "fork"
    return "spawn"


def _context(method: str | None):
    return multiprocessing.get_context(method or start_method())


# --------------------------------------------------------------------------------------------------
# In the child
# --------------------------------------------------------------------------------------------------


def _die_with(parent: int) -> None:
    """Make this child end when the process ``parent`` ends, however it ends (SIGKILL included)."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            pr_set_pdeathsig = 1
            if libc.prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0) == 0:
                if os.getppid() != parent:  # the parent died before the request was in place
                    os._exit(1)
                return
        except (OSError, AttributeError):
            pass

    def watch():
        while os.getppid() == parent:
            time.sleep(PARENT_POLL)
        os._exit(1)

    threading.Thread(target=watch, name="recon-parent-watch", daemon=True).start()


def _become_child(parent: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops us on Ctrl-C; we must not turn it into an error
    if hasattr(signal, "SIGTERM"):
        signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the parent's handler (it may clean the parent's files)
    _die_with(parent)


def _run_one(conn, parent: int, fn: Callable, args: tuple) -> None:
    """:func:`isolated`'s child: ``fn(*args)`` sent back as ``("ok", value)`` or ``("raised", type, message)``."""
    _become_child(parent)
    try:
        out: tuple = ("ok", fn(*args))
    except BaseException as err:  # noqa: BLE001  (the parent decides what an error means)
        out = ("raised", type(err).__name__, str(err))
    try:
        conn.send(out)
    except Exception as err:  # noqa: BLE001  (an answer that cannot be pickled)
        conn.send(("raised", type(err).__name__, f"the child's answer could not be sent back: {err}"))
    conn.close()


# --------------------------------------------------------------------------------------------------
# In the parent
# --------------------------------------------------------------------------------------------------


def _start(proc, what: str) -> str:
    """Start ``proc``; "" when it runs, else why not (no child here, or its function cannot be pickled)."""
    try:
        proc.start()
        return ""
    except (OSError, AssertionError) as err:  # multiprocessing asserts that a daemon has no children
        return f"no child process ({err or type(err).__name__})"
    except (pickle.PicklingError, TypeError, AttributeError) as err:  # spawn: a closure or an OCC object
        return f"cannot hand it to a spawned process ({type(err).__name__}: {err})"


def _stop(proc) -> None:
    if proc.is_alive():
        proc.kill()
    proc.join()


def isolated(fn: Callable[..., Any], *args: Any, timeout: float, what: str = "",
             method: str | None = None) -> Any:
    """``fn(*args)`` computed in a child process that is killed after ``timeout`` seconds.

    Returns the value, or a :class:`Failure` when the child crashed, ran out of time or raised. Where no child
    can be had (inside a daemonic process; under ``spawn`` a function or argument that cannot be pickled) ``fn``
    runs in this process, an exception it raises still coming back as a ``RAISED`` failure.

    Parameters
    ----------
    fn : callable
        Its value must be picklable (it crosses the pipe).
    timeout : float
        Seconds the child may take.
    what : str
        What ``fn`` does, for the failure's message.
    method : str, optional
        ``"fork"`` or ``"spawn"``; default :func:`start_method`.

    Examples
    --------
    >>> isolated(divmod, 7, 2, timeout=30)
    (3, 1)
    >>> isolated(os.abort, timeout=30).kind
    <FailureKind.CRASHED: 'crashed'>
    """
    what = what or getattr(fn, "__name__", "the child")
    mp = _context(method)
    recv, send = mp.Pipe(duplex=False)
    proc = mp.Process(target=_run_one, args=(send, os.getpid(), fn, args), daemon=True, name="recon-isolated")
    why = _start(proc, what)
    send.close()
    if why:
        recv.close()
        log.info("%s runs in this process: %s", what, why)
        try:
            return fn(*args)
        except Exception as err:  # noqa: BLE001  (the same record as from a child)
            return Failure(FailureKind.RAISED, str(err), error_type=type(err).__name__)
    try:
        # A child that ends closes its end of the pipe: poll() is True then too, with nothing to read.
        if not recv.poll(max(0.0, timeout)):
            _TIMED_OUT.append(what)
            return Failure(FailureKind.TIMED_OUT, f"{what} did not finish within {timeout:g} s")
        try:
            answer = recv.recv()
        except (EOFError, OSError):  # it ended without an answer
            answer = None
        if answer is not None:
            if answer[0] == "ok":
                return answer[1]
            return Failure(FailureKind.RAISED, answer[2], error_type=answer[1])
        proc.join()
        code = proc.exitcode
        if code is not None and code < 0:
            return Failure(FailureKind.CRASHED, f"{what} crashed (signal {-code})", signal=-code)
        return Failure(FailureKind.CRASHED, f"{what} ended without an answer (exit code {code})", exit_code=code)
    finally:
        recv.close()
        _stop(proc)


# --------------------------------------------------------------------------------------------------
# A worker serving jobs
# --------------------------------------------------------------------------------------------------


def _serve(conn, parent_end, parent: int, state: Any, jobs: Mapping[str, Callable]) -> None:
    """:class:`Worker`'s child: ``(name, args)`` in, ``(True, jobs[name](state, *args))`` or ``(False, why)`` out,
    until the parent closes its end."""
    parent_end.close()  # (forked: a copy of the parent's end, which would keep the pipe open after the parent's)
    _become_child(parent)
    while True:
        try:
            name, args = conn.recv()
        except (EOFError, OSError):
            return
        try:
            out = (True, jobs[name](state, *args))
        except Exception as err:  # noqa: BLE001  (the parent does the job itself, and meets the error there)
            out = (False, f"{type(err).__name__}: {err}")
        conn.send(out)


class Worker:
    """A second process holding ``state`` and answering one job at a time: :meth:`submit`, then :meth:`get`.

    ``jobs`` maps a name to ``function(state, *args)``. Under ``fork`` the worker shares ``state`` with the parent
    as it was at the start (copy on write); under ``spawn`` ``state`` and ``jobs`` are pickled. A worker that
    fails a job, dies or gives no answer in time is stopped for good (:attr:`alive` False, the reason in
    :attr:`stopped`); :meth:`get` then returns a :class:`Failure` and the caller does the work itself.
    """

    def __init__(self, state: Any, jobs: Mapping[str, Callable], *, name: str = "recon-worker",
                 method: str | None = None):
        mp = _context(method)
        self._conn, child = mp.Pipe()
        self._proc = mp.Process(target=_serve, args=(child, self._conn, os.getpid(), state, jobs), daemon=True,
                                name=name)
        why = _start(self._proc, name)
        child.close()
        if why:
            self._conn.close()
            raise OSError(why)
        self.alive = True
        self.stopped = ""

    def submit(self, name: str, *args: Any) -> bool:
        """Send a job; False when the worker is gone (nothing was sent)."""
        if not self.alive:
            return False
        try:
            self._conn.send((name, args))
        except (OSError, ValueError) as err:
            self._fail(FailureKind.CRASHED, f"cannot reach it ({err})")
            return False
        return True

    def get(self, timeout: float) -> Any:
        """The answer to the job submitted last, or a :class:`Failure` (the worker is stopped then)."""
        if not self.alive:
            return Failure(FailureKind.CRASHED, self.stopped or "the worker is stopped")
        try:
            if not self._conn.poll(timeout):
                return self._fail(FailureKind.TIMED_OUT, f"no answer in {timeout:g} s")
            ok, value = self._conn.recv()
        except (EOFError, OSError):
            self._proc.join(1.0)
            return self._fail(FailureKind.CRASHED, f"it ended (exit code {self._proc.exitcode})")
        if not ok:
            return self._fail(FailureKind.RAISED, f"a job failed: {value}")
        return value

    def _fail(self, kind: FailureKind, why: str) -> Failure:
        self.stopped = why
        self.close()
        return Failure(kind, why)

    def close(self) -> None:
        """Stop the worker (it ends at once: its jobs are the caller's to redo)."""
        self.alive = False
        self._conn.close()
        _stop(self._proc)


# --------------------------------------------------------------------------------------------------
# A map shared with a second process
# --------------------------------------------------------------------------------------------------


def _take(counter, lock) -> int:
    with lock:
        i = counter.value
        counter.value = i + 1
    return i


def _share(conn, parent: int, one: Callable[[int], Any], n: int, counter, lock) -> None:
    """:func:`shared_map`'s child: ``one(i)`` for each next ``i`` not yet taken, sent back as one dict."""
    _become_child(parent)
    made = {}
    try:
        while (i := _take(counter, lock)) < n:
            made[i] = one(i)
    except BaseException:  # noqa: BLE001  (what it made is still good; the parent makes the rest)
        pass
    finally:
        conn.send(made)
        conn.close()


def shared_map(one: Callable[[int], Any], n: int, *, grace: float, method: str | None = None) -> dict:
    """``{i: one(i)}`` for some of ``i`` in 0 … n − 1, made by this process and a second one, each taking the next
    ``i`` not yet taken.

    The ``i`` missing are the caller's to make: all of them where no second process can be had (inside a
    daemonic process; under ``spawn`` a ``one`` that cannot be pickled), or the ones the second process did not
    finish (it died, raised, or gave no answer ``grace`` seconds — or twice the time this process took for its
    own share, if longer — after this one was done). ``one`` must depend on ``i`` and the state at the start
    alone (what the second process changes is lost) and give picklable answers. An exception in ``one`` here
    propagates.
    """
    mp = _context(method)
    counter, lock = mp.RawValue("q", 0), mp.Lock()
    recv, send = mp.Pipe(duplex=False)
    proc = mp.Process(target=_share, args=(send, os.getpid(), one, n, counter, lock), daemon=True,
                      name="recon-shared-map")
    why = _start(proc, "shared_map")
    send.close()
    if why:
        recv.close()
        log.info("shared_map: one process (%s)", why)
        return {}
    made = {}
    theirs = {}
    try:
        start = time.monotonic()
        while (i := _take(counter, lock)) < n:
            made[i] = one(i)
        now = time.monotonic()
        # it has one item left at most: waiting longer than this process took for all of its own means it hangs.
        # (Time decides only which process makes an item, never its value: the map is the same on any machine.)
        give_up = now + max(grace, 2.0 * (now - start))
        while True:
            if recv.poll(0.01):  # 10 ms: the answer's latency, far below any face build
                theirs = recv.recv()
                break
            if not proc.is_alive():  # (its answer may still be on its way)
                give_up = min(give_up, time.monotonic() + 1.0)
            if time.monotonic() > give_up:
                log.warning("shared_map: the second process gave no answer; its items are made here")
                break
    except (EOFError, OSError, pickle.UnpicklingError):
        theirs = {}
    finally:
        recv.close()
        proc.join(timeout=1.0)
        _stop(proc)
    made.update(theirs)
    return made
