"""SIGINT and SIGTERM for the ``recon`` command: one line, exit 128 + the signal, nothing left behind.

Installed first thing in :func:`recon.cli.main`, before numpy, scipy or OpenCascade load. The handler raises
:class:`Interrupted` so the run unwinds (``atomic_path`` removes its temporary file, workers are stopped). Three
things can keep that from ending the run, and each is covered:

- an import in progress turns the exception into ``ImportError: initialization failed``, and trimesh's optional
  imports catch ``BaseException``: the signal is remembered, so whatever surfaces, :meth:`SignalGuard.exit_code`
  says 130/143, and ``atomic_path`` will not rename a result into place after it;
- a C call holds the main thread (BLAS, a kernel operation): Python runs the handler only when it returns. The C
  signal handler writes the signal to a wake-up pipe a watchdog thread reads; if the run has not ended
  :data:`GRACE` seconds later, the watchdog removes the temporaries, prints the line and exits;
- a second signal while unwinding: the same hard exit at once.
"""

from __future__ import annotations

import os
import signal
import sys
import threading

from .. import _io

__all__ = ["Interrupted", "SignalGuard", "GRACE"]

#: Seconds the run may take to unwind after a signal before the watchdog ends it: a kernel call that holds the
#: main thread is not waited for (a user who pressed Ctrl-C expects the prompt back within a blink or two).
GRACE = 2.0

_NAMES = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM"}

#: The guard of the run in progress; a fork hook cannot be unregistered, so it reaches the guard through this.
_ACTIVE: "SignalGuard | None" = None


def _after_fork_in_child() -> None:
    if _ACTIVE is not None:
        _ACTIVE._in_child()


os.register_at_fork(after_in_child=_after_fork_in_child)


class Interrupted(KeyboardInterrupt):
    """Raised in the main thread by the handler; ``signum`` is the signal."""

    def __init__(self, signum: int):
        super().__init__(_NAMES.get(signum, str(signum)))
        self.signum = signum


class SignalGuard:
    """The handlers, the watchdog and the remembered signal of one ``recon`` run (in the process that made it)."""

    def __init__(self, prog: str = "recon"):
        self.prog = prog
        self.signum: int | None = None
        self.owner = os.getpid()
        self._finished = threading.Event()
        self._lock = threading.Lock()
        self._previous: dict = {}
        self._read = self._write = -1
        self._armed = False  # until installed, a signal is only remembered (raising would break the install)
        self._settled = False  # once the run's outcome is being reported, likewise
        if threading.current_thread() is not threading.main_thread():
            return  # signal handlers can only be set there; called from a thread, the caller owns signals
        self._read, self._write = os.pipe()
        os.set_blocking(self._write, False)  # set_wakeup_fd needs it: the C handler must never block
        for sig in _NAMES:
            self._previous[sig] = signal.signal(sig, self._on_signal)
        self._previous_fd = signal.set_wakeup_fd(self._write, warn_on_full_buffer=False)
        global _ACTIVE
        _ACTIVE = self
        threading.Thread(target=self._watch, name="recon-signals", daemon=True).start()
        self._armed = True

    def settle(self) -> None:
        """The run is over and its outcome about to be reported: a signal now is recorded, not raised."""
        self._settled = True

    def check(self) -> None:
        """Raise :class:`Interrupted` if a signal came while the handlers were being installed."""
        if self.signum is not None:
            raise Interrupted(self.signum)

    def uninstall(self) -> None:
        """Put back the handlers found (main() called in a Python session or a test runs more than once)."""
        global _ACTIVE
        self._finished.set()
        if self._write < 0:
            return
        signal.set_wakeup_fd(self._previous_fd)
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        if _ACTIVE is self:
            _ACTIVE = None
        try:
            os.write(self._write, b"\0")  # wakes the watchdog, which sees the run finished and closes its end
        except OSError:  # it had already woken (a signal came) and closed it
            pass
        finally:
            os.close(self._write)
            self._write = -1

    # -- handlers ------------------------------------------------------------------------------------------------
    def _on_signal(self, signum, frame):
        if os.getpid() != self.owner:  # a forked child without _in_child (cannot happen on fork; kept safe)
            raise KeyboardInterrupt
        if self.signum is not None:  # a second signal while unwinding: the user means it
            self._hard_exit(signum)
            return
        self.signum = signum
        _io.stop_commits(f"interrupted ({_NAMES.get(signum, signum)})")
        if self._armed and not self._settled:
            raise Interrupted(signum)

    def _in_child(self):
        """A forked worker: it does not report nor watch; the parent stops it. SIGTERM kills it as usual, SIGINT
        (the whole process group gets Ctrl-C) raises KeyboardInterrupt in it."""
        self.owner = -1
        try:
            signal.set_wakeup_fd(-1)
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            signal.signal(signal.SIGINT, signal.default_int_handler)
        except ValueError:  # forked from a thread other than the main one: nothing was inherited there to undo
            pass
        for fd in (self._read, self._write):
            if fd >= 0:
                try:
                    os.close(fd)
                except OSError:
                    pass

    def _watch(self):
        try:
            self._watch_loop()
        finally:
            os.close(self._read)

    def _watch_loop(self):
        while True:
            try:
                data = os.read(self._read, 64)
            except OSError:
                return
            if not data or self._finished.is_set():
                return
            hits = [b for b in data if b in _NAMES]
            if not hits or os.getpid() != self.owner:
                continue
            if self._finished.wait(GRACE):
                return
            self._hard_exit(self.signum or hits[0])

    def _hard_exit(self, signum: int):
        with self._lock:
            if self._finished.is_set():
                return
            self._finished.set()
            _io.remove_temporaries()
            _write_line(f"{self.prog}: interrupted ({_NAMES.get(signum, signum)})")
            os._exit(128 + signum)

    # -- the end of the run --------------------------------------------------------------------------------------
    def exit_code(self) -> int | None:
        """128 + the signal once one arrived, else None."""
        return None if self.signum is None else 128 + self.signum

    def message(self) -> str:
        return f"interrupted ({_NAMES.get(self.signum, self.signum)})"

    def finish(self) -> bool:
        """Mark the run ended (the watchdog stands down). False when the watchdog already ended it."""
        with self._lock:
            if self._finished.is_set():
                return False
            self._finished.set()
            return True


def _write_line(text: str) -> None:
    try:
        os.write(sys.stderr.fileno(), (text + "\n").encode())
    except (OSError, ValueError):
        pass
