"""The ``recon`` command line. Thin: parse, call the library, turn errors into one line.

Each subcommand lives in ``recon/_cli/<name>.py`` with ``add_parser(subparsers)`` (which registers the
parser and sets ``func``) so that stages can add commands without touching each other.

Output: the result's summary goes to stdout (``recon convert a.stl b.step > summary.txt`` keeps it); warnings,
progress and errors go to stderr; ``-q`` prints errors only.

Exit codes: 0 a result written and good, 1 a result written that is not (the subcommand says why), or none written
because no file could hold it (:class:`~recon.errors.UnwritableError`: "error: no result: …"), 2 bad input,
an option out of range, an output that cannot be written, or not enough memory (one line on stderr), 3 no result:
an internal error (a bug: one line, the traceback with ``-v``) or a B-rep ``convert`` could not build or write (a
:class:`~recon.errors.BrepError`: "error: no result: …"), 128 + the signal when interrupted (130 SIGINT,
143 SIGTERM), 141 without a word when the reader of stdout or stderr went away (``recon convert … | head -1``: what
a process killed by SIGPIPE returns, as Unix tools do; the output file is complete, the summary comes after it).
"""

from __future__ import annotations

import argparse
import errno
import importlib
import logging
import os
import platform
import sys

# Before anything imports numpy: one BLAS thread unless the user chose. recon's linear algebra is small (fits of
# a few thousand points) and it uses a second process instead; OpenBLAS reserves a buffer per thread at import,
# which under a memory limit (ulimit -v) fails and leaves it spinning. (recon's work pins one thread whatever this.)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
# The same arithmetic on every x86-64 CPU (issue 25, bench/determinism.md): OpenBLAS's and numpy's per-CPU kernels
# round differently (a Xeon's AVX-512, an EPYC's AVX2); Nehalem's kernels and numpy's baseline loops run on all.
if platform.machine().lower() in ("x86_64", "amd64"):
    os.environ.update(OPENBLAS_CORETYPE="Nehalem", NPY_ENABLE_CPU_FEATURES="SSE2")
    os.environ.pop("NPY_DISABLE_CPU_FEATURES", None)  # (numpy refuses both set)

__all__ = ["main", "SUBCOMMANDS", "EXIT_OK", "EXIT_NOT_GOOD", "EXIT_BAD_INPUT", "EXIT_INTERNAL", "EXIT_BROKEN_PIPE"]

#: Subcommand modules under ``recon._cli``, in the order ``recon --help`` lists them.
SUBCOMMANDS = ["convert", "batch", "decompose", "compare", "skeleton"]

EXIT_OK, EXIT_NOT_GOOD, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3
EXIT_BROKEN_PIPE = 128 + 13  # SIGPIPE's number on Linux and macOS (signal.SIGPIPE is absent on Windows)

log = logging.getLogger("recon")

_EPILOG = ("output: the summary on stdout; warnings, progress and errors on stderr (-q: errors only). "
           "exit codes: 0 done and good; 1 a result written that is not good (the summary says why); 2 bad input, "
           "option or output path, or not enough memory; 3 no result: recon could not build the B-rep, or an internal "
           "error (run with -v for the traceback); "
           "130 interrupted (SIGINT), 143 terminated (SIGTERM), 141 the reader of the output went away (| head)")


class _Parser(argparse.ArgumentParser):
    """argparse's usage errors in one line (its default prints the whole usage first)."""

    def error(self, message):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _verbosity(parser: argparse.ArgumentParser) -> None:
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                       help="also log the stages' details, and the traceback of an error, to stderr (default: off)")
    group.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                       help="print errors only, one line on stderr: no summary on stdout, no progress or warnings "
                       "(default: off; the exit code still tells the result)")


def _version() -> str:
    """The installed distribution's version (pyproject's), which is what a bug report needs."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("recon")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


class _VersionAction(argparse._VersionAction):
    """``--version``, the version looked up only when asked (``importlib.metadata`` is 0.03 s of every run's start)."""

    def __call__(self, parser, namespace, values, option_string=None):
        self.version = f"recon {_version()}"
        super().__call__(parser, namespace, values, option_string)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="recon",
        description="Turn a triangle mesh of a manufactured part into an editable B-rep (STEP), "
        "by the Voronoi skeleton decomposition of Wekel & Hellwich.",
        epilog=_EPILOG,
    )
    parser.add_argument("--version", action=_VersionAction)
    _verbosity(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        p = importlib.import_module(f"recon._cli.{name}").add_parser(sub)
        _verbosity(p)  # `recon convert -v ...` as well as `recon -v convert ...`
        p.epilog = p.epilog or _EPILOG
    return parser


def main(argv: list[str] | None = None) -> int:
    from ._cli._signals import SignalGuard

    guard = SignalGuard()  # first: a signal from here on gives one line and 128 + its number
    command, verbose, line = "recon", False, None
    try:
        try:
            guard.check()
            args = build_parser().parse_args(argv)
            command, verbose = f"recon {args.command}", getattr(args, "verbose", False)
            guard.prog = command
            args.verbose, args.quiet = verbose, getattr(args, "quiet", False)
            level = logging.INFO if verbose else logging.ERROR if args.quiet else logging.WARNING
            logging.basicConfig(level=level, format="%(message)s")
            _check_address_space(args.command)
            code = int(args.func(args) or 0)
        except SystemExit:  # argparse: --help (0) or a usage error (2, its one line already printed)
            if guard.signum is None:
                raise
            code = EXIT_OK
        except BaseException as err:  # noqa: BLE001  every error becomes one line; see _one_line
            guard.settle()  # from here a signal is only recorded: the report of this error must get out
            code, line = _one_line(err, guard, verbose, command)
            if verbose and guard.signum is None and not isinstance(err, BrokenPipeError):
                log.error("traceback:", exc_info=err)
        guard.settle()
        if guard.signum is not None:  # (also a signal whose exception something swallowed: the run stops here)
            code, line = guard.exit_code(), guard.message()
        if line:
            print(f"{command}: {line}", file=sys.stderr)
        return code
    finally:
        if not guard.finish():  # the watchdog is ending the process
            import time

            time.sleep(60)
        guard.uninstall()


#: Address space (ulimit -v) below which convert and compare cannot even load their libraries: numpy, scipy,
#: trimesh and OpenCascade map 0.95 GiB (VmPeak of a 300-triangle convert, bench/robustness.md); under that
#: limit the loader fails, or glibc aborts the process when a thread starts, before recon can say anything.
MIN_ADDRESS_SPACE = 1 << 30


def _check_address_space(command: str) -> None:
    import resource

    from .errors import ReconError

    if command not in ("convert", "compare"):
        return
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY and soft < MIN_ADDRESS_SPACE:
        raise ReconError(f"not enough memory: the address-space limit (ulimit -v) is {soft >> 20} MiB; recon {command} "
                         f"needs at least {MIN_ADDRESS_SPACE >> 20} MiB to load its libraries, plus about 1 GiB per "
                         "million triangles")


def _one_line(err: BaseException, guard, verbose: bool = False, command: str = "recon") -> tuple[int, str]:
    """The exit code and the one line an error is reported with."""
    from .errors import BrepError, ReconError, UnwritableError

    if guard.signum is not None:  # an import turns it into ImportError, a worker into anything
        return guard.exit_code(), guard.message()
    if isinstance(err, KeyboardInterrupt):
        return 130, "interrupted (SIGINT)"
    if isinstance(err, BrokenPipeError):
        _drop_closed_streams()
        return EXIT_BROKEN_PIPE, ""  # the reader stopped reading: nothing to tell, and nowhere to tell it
    # convert's own B-rep that could not be built or written (nothing written) is recon's failure, not bad input; in
    # compare a BrepError is about the user's shape
    if isinstance(err, UnwritableError) and command == "recon convert":  # a result that is not right, not a crash
        return EXIT_NOT_GOOD, f"error: no result: {err}"
    if isinstance(err, BrepError) and command == "recon convert":
        return EXIT_INTERNAL, f"error: no result: {err}"
    if isinstance(err, ReconError):
        return EXIT_BAD_INPUT, f"error: {err}"
    if isinstance(err, MemoryError) or _out_of_memory(err):  # numpy's _ArrayMemoryError included
        return EXIT_BAD_INPUT, f"error: not enough memory ({_short(err) or 'an allocation failed'}); free memory or " \
                               "raise the limit (ulimit -v), or use a smaller mesh"
    if isinstance(err, OSError) and err.errno is not None:
        where = f" {err.filename}" if err.filename else ""
        if err.errno in (errno.ENOSPC, errno.EDQUOT):
            return EXIT_BAD_INPUT, f"error: disk full while writing{where}"
        if err.errno in (errno.EACCES, errno.EPERM):
            return EXIT_BAD_INPUT, f"error: permission denied:{where or ' ' + _short(err)}"
        return EXIT_BAD_INPUT, f"error: {err.strerror or _short(err)}:{where}".rstrip(":")
    hint = "the traceback is above" if verbose else "run with -v for the traceback"
    return EXIT_INTERNAL, f"internal error: {type(err).__name__}: {_short(err)} ({hint})"


def _drop_closed_streams() -> None:
    """Point a standard stream whose pipe is closed at /dev/null, so that Python's flush at exit does not print
    "Exception ignored … BrokenPipeError" (the Python documentation's recipe for SIGPIPE)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except BrokenPipeError:
            try:
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, stream.fileno())
                os.close(devnull)
            except (OSError, ValueError):  # (a stream without a descriptor: pytest's capture, a notebook)
                pass
        except (OSError, ValueError):
            pass


def _out_of_memory(err: BaseException) -> bool:
    # the dynamic loader reports an address-space limit as "failed to map segment" / "cannot allocate memory"
    text = str(err).lower()
    return isinstance(err, (ImportError, OSError)) and ("failed to map segment" in text or
                                                        "cannot allocate memory" in text)


def _short(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return text if len(text) <= 200 else text[:197] + "..."


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
