"""The ``recon`` command line. Thin: parse, call the library, turn errors into one line.

Each subcommand lives in ``recon/_cli/<name>.py`` with ``add_parser(subparsers)`` (which registers the
parser and sets ``func``) so that stages can add commands without touching each other.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from .errors import ReconError

__all__ = ["main", "SUBCOMMANDS"]

#: Subcommand modules under ``recon._cli``, in the order ``recon --help`` lists them.
SUBCOMMANDS = ["convert", "batch", "decompose", "compare", "skeleton"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="recon",
        description="Turn a triangle mesh of a manufactured part into an editable B-rep (STEP), "
        "by the Voronoi skeleton decomposition of Wekel & Hellwich.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details to stderr")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        importlib.import_module(f"recon._cli.{name}").add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(message)s")
    try:
        return int(args.func(args) or 0)
    except ReconError as err:
        print(f"recon {args.command}: error: {err}", file=sys.stderr)
        return 2
    except MemoryError as err:  # numpy's _ArrayMemoryError included: one line, not a traceback
        print(f"recon {args.command}: error: out of memory ({err or 'an allocation failed'})", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print(f"recon {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
