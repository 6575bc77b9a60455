"""Progress of a conversion, as the command line shows it: fed by the ``progress(stage, fraction)`` callback of
:func:`recon.convert`, whose long stages also report their items (parts fitted, faces built, samples measured) as
:class:`Count` fractions.

On a terminal: one line per stage on stderr, redrawn in place while the stage runs ("fit  parts fitted 37/71,
about 2 s left") and ending with the stage's time. Off a terminal (a log file, a pipe, CI): a plain line at most
every ``interval`` seconds, and none in a run shorter than that, so that a short run's stderr stays empty.

Stdlib only: the stages never import this module (the data flows one way, from them through the callback).
"""

from __future__ import annotations

import os
import time
from typing import Callable, TextIO

__all__ = ["Count", "StageProgress", "interval_from_env"]

#: Off a terminal, the least time between two progress lines, and before the first: a log gains a line a few
#: times a minute on a long run and none on a short one (the CLI's stderr then stays empty).
PLAIN_INTERVAL = 5.0

#: On a terminal, the least time between two redraws of the line: ten a second reads as live and costs nothing.
TTY_INTERVAL = 0.1

#: The environment variable that sets the plain-line interval (seconds): for tests, which cannot wait 5 s per line.
INTERVAL_ENV = "RECON_PROGRESS_INTERVAL"


class Count(float):
    """What a stage reports between its start (0.0) and its end (1.0): the float ``done / total`` of its current
    step's items, so that a plain ``progress(stage, fraction)`` callback reads it, carrying the counts.

    Attributes
    ----------
    done, total : int
        Items of the step done, and in all (0 < done < total).
    what : str
        The items, as a display names them: "parts fitted", "faces built", "samples measured".
    """

    done: int
    total: int
    what: str

    def __new__(cls, done: int, total: int, what: str) -> Count:
        self = super().__new__(cls, done / total if total else 1.0)
        self.done, self.total, self.what = int(done), int(total), str(what)
        return self


def interval_from_env(default: float = PLAIN_INTERVAL) -> float:
    """The plain-line interval: :data:`INTERVAL_ENV` if set to a number ≥ 0, else ``default``."""
    try:
        value = float(os.environ.get(INTERVAL_ENV, ""))
    except ValueError:
        return default
    return value if value >= 0 else default


def _left(s: float) -> str:
    if s < 1:
        return "under 1 s left"
    return f"about {s:.0f} s left" if s < 90 else f"about {s / 60:.0f} min left"


class StageProgress:
    """A ``progress(stage, fraction)`` callback that draws what it is told on ``stream`` (see the module's doc).

    Parameters
    ----------
    stream : text stream
    tty : bool
        Redraw one line in place (a terminal) or print plain lines (anything else).
    interval : float
        Off a terminal: the least seconds between two lines, and before the first.
    clock : callable() -> float
        Seconds (monotonic); tests pass their own.
    """

    def __init__(self, stream: TextIO, *, tty: bool, interval: float = PLAIN_INTERVAL,
                 clock: Callable[[], float] = time.monotonic):
        self.stream, self.tty, self.interval, self.clock = stream, tty, float(interval), clock
        self.t_run = clock()
        self.t_stage = self.t_step = self.t_shown = self.t_last = self.t_run
        self.stage, self.what, self.pending = "", "", False

    def __call__(self, stage: str, fraction: float) -> None:
        now = self.clock()
        if fraction == 0.0:
            self.stage, self.what, self.t_stage = stage, "", now
            if self.tty:
                self._draw(f"  {stage:<10} …")
        elif fraction >= 1.0:
            if self.tty:
                self._draw(f"  {stage:<10} {now - self.t_stage:6.2f} s", end="\n")
            self.what = ""
        elif isinstance(fraction, Count):
            self._count(stage, fraction, now)
        self.t_last = now

    def _count(self, stage: str, c: Count, now: float) -> None:
        if c.what != self.what or stage != self.stage:  # a new step, begun at the last call: its rate starts afresh
            self.stage, self.what, self.t_step = stage, c.what, self.t_last
        if self.tty:
            if now - self.t_shown >= TTY_INTERVAL:
                self._draw(f"  {stage:<10} {self._text(c, now)}")
                self.t_shown = now
        elif now - self.t_run >= self.interval and now - self.t_shown >= self.interval:
            print(f"recon: {stage}: {self._text(c, now)}", file=self.stream, flush=True)
            self.t_shown = now

    def _text(self, c: Count, now: float) -> str:
        text = f"{c.what} {c.done:,}/{c.total:,} ({100.0 * c.done / c.total:.0f} %)"
        spent = now - self.t_step
        if spent > 0 and c.done > 0:  # the rate so far, over the items left
            text += f", {_left(spent / c.done * (c.total - c.done))}"
        return text

    def _draw(self, text: str, end: str = "") -> None:
        # "\r" and erase-to-end-of-line: the new text replaces the line, shorter or not
        self.stream.write(f"\r\x1b[K{text}{end}")
        self.stream.flush()
        self.pending = not end

    def clear(self) -> None:
        """Erase a half-drawn line (a terminal), so that a log message starts at the margin."""
        if self.tty and self.pending:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self.pending = False
