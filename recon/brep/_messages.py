"""OpenCascade's own messages into recon's log.

OCCT prints warnings such as "Warning: WireFromList: can't find the next edge" through its default messenger, whose
printer writes them to the C++ ``std::cout`` (in ANSI colours, terminal or not): they broke the command line's
progress line and landed in a summary piped to a file. A ``Message_Printer`` cannot be subclassed from Python (OCP
binds it without a trampoline: "No constructor defined"), so while :func:`occ_messages` is active the messenger's
printers are replaced by OCCT's own file printer, writing to an unlinked temporary file, and what it wrote is logged
at debug level (logger ``recon.brep.occ``) when the context ends.
"""

from __future__ import annotations

import contextlib
import logging
import os
import tempfile
import threading
from collections.abc import Iterator

from OCP.Message import Message, Message_Gravity, Message_PrinterOStream

__all__ = ["occ_messages"]

log = logging.getLogger("recon.brep.occ")

_lock = threading.RLock()
_state: dict = {"depth": 0, "saved": [], "reader": None, "printer": None}


def _install() -> None:
    messenger = Message.DefaultMessenger_s()
    printers = messenger.Printers()
    _state["saved"] = [printers.Value(i) for i in range(1, printers.Length() + 1)]
    if _state["printer"] is None:
        # The file is opened by us (to read) and by OCCT (to append: it writes at the end even after we truncate),
        # then unlinked: nothing is left in TMPDIR, whatever happens to the process.
        try:
            fd, path = tempfile.mkstemp(prefix=".recon-occ-", suffix=".log")
        except OSError as err:  # no writable TMPDIR: the messages are dropped rather than printed
            log.debug("OpenCascade's messages are dropped: no temporary file (%s)", err)
            _state["printer"] = Message_PrinterOStream(os.devnull, True, Message_Gravity.Message_Trace)
        else:
            try:
                printer = Message_PrinterOStream(path, True, Message_Gravity.Message_Trace)
            finally:
                os.unlink(path)
            printer.SetToColorize(False)
            _state["printer"], _state["reader"] = printer, os.fdopen(fd, "r", encoding="utf-8", errors="replace")
    for p in _state["saved"]:
        messenger.RemovePrinter(p)
    messenger.AddPrinter(_state["printer"])


def _restore() -> None:
    messenger = Message.DefaultMessenger_s()
    messenger.RemovePrinter(_state["printer"])
    for p in _state["saved"]:
        messenger.AddPrinter(p)
    _state["saved"] = []


def drain() -> list[str]:
    """The messages OpenCascade sent since the last drain, each logged at debug level."""
    reader = _state["reader"]
    if reader is None:
        return []
    with _lock:
        text = reader.read()
        os.ftruncate(reader.fileno(), 0)
        reader.seek(0)
    lines = [line for line in text.splitlines() if line.strip()]
    for line in lines:
        log.debug("%s", line)
    return lines


@contextlib.contextmanager
def occ_messages() -> Iterator[None]:
    """Within it, OpenCascade's messenger writes to recon's log (debug level) instead of the process's stdout.

    Re-entrant; the messenger's own printers are put back when the outermost context ends.
    """
    with _lock:
        if _state["depth"] == 0:
            _install()
        _state["depth"] += 1
    try:
        yield
    finally:
        with _lock:
            _state["depth"] -= 1
            if _state["depth"] == 0:
                _restore()
        drain()
