"""List recon's tuned numeric constants and check each says, in a comment, what it scales with.

A constant is a module-level assignment of a number (``NAME = 0.25``, also ``-1``, ``2 * 3``) or a float literal
inside a function other than the arithmetic ones (0, 0.5, 1, 2, ...), the floating-point guards (≤ 1e-9) and
default arguments (documented parameters).
Its comment is the ``#`` / ``#:`` block right above it or a comment on its line. ``--check`` exits 1 when a
constant has none, or when any comment in recon/ names a benchmark mesh (that evidence belongs in bench/*.md,
see bench/constants.md).

    python -m bench.list_constants            # the table (module, line, name, value, comment)
    python -m bench.list_constants --check    # exit 1 on a missing comment or a mesh name in a comment
"""

from __future__ import annotations

import argparse
import ast
import io
import re
import sys
import tokenize
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "recon"

#: Literals that are arithmetic, not tuning: halves, unit steps, small counts, percent scales.
#: Drawing code: its literals are styles (colours, line widths, alpha, figure sizes), not thresholds.
DRAWING = ("preview.py", "skeleton2d/_plot.py")

PLAIN = {0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 10.0, 100.0, 0.25, 0.75, 1.5, 180.0, 360.0, 90.0, 1000.0}
#: Below this a float literal is a floating-point guard (division by zero, round-off), not a tuned value.
GUARD = 1e-9

#: Names of the benchmark meshes and suites a code comment must not cite (their evidence is in bench/*.md).
MESH_NAMES = re.compile(r"rocker[-_ ]?arm|casting|\bjoint\b|(?<!\.)\babc\b|abc_\d|fandisk|crank|bearing|mpeg7",
                        re.IGNORECASE)


@dataclass
class Constant:
    module: str
    line: int
    name: str
    value: str
    comment: str


def _comments(source: str) -> dict[int, str]:
    out = {}
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            out[tok.start[0]] = tok.string.lstrip("#:").strip()
    return out


def _comment_for(line: int, lines: list[str], comments: dict[int, str]) -> str:
    """The comment on ``line`` or the block of comment-only lines right above it (a multi-line statement's first
    line counts)."""
    if line in comments and not lines[line - 1].lstrip().startswith("#"):
        return comments[line]
    block = []
    k = line - 1
    while k >= 1 and lines[k - 1].lstrip().startswith("#"):
        block.append(comments.get(k, ""))
        k -= 1
    return " ".join(reversed(block)).strip()


def _number(node: ast.AST) -> bool:
    """A numeric literal or arithmetic of numeric literals (``-1``, ``2 * 3``, ``1 / 3``)."""
    if isinstance(node, ast.Constant):
        return isinstance(node.value, (int, float)) and not isinstance(node.value, bool)
    if isinstance(node, ast.UnaryOp):
        return _number(node.operand)
    if isinstance(node, ast.BinOp):
        return _number(node.left) and _number(node.right)
    return False


def _tuned_literal(node: ast.Constant) -> bool:
    v = node.value
    return isinstance(v, float) and abs(v) > GUARD and abs(v) not in PLAIN


def constants(path: Path) -> list[Constant]:
    source = path.read_text()
    tree = ast.parse(source)
    lines = source.splitlines()
    comments = _comments(source)
    rel = str(path.relative_to(ROOT.parent))
    out = []
    module_level = set()
    for node in tree.body:
        target = value = None
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            target, value = node.targets[0].id, node.value
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value is not None:
            target, value = node.target.id, node.value
        if target and value is not None and _number(value) and target.lstrip("_").isupper():
            module_level.update(id(n) for n in ast.walk(value))
            out.append(Constant(rel, node.lineno, target, ast.unparse(value),
                                _comment_for(node.lineno, lines, comments)))
    # Consecutive constants under one comment block share it (``#: ... SPLIT_COVER ... each at least SPLIT_MIN_SHARE``).
    for prev, cur in zip(out, out[1:]):
        if not cur.comment and cur.line == prev.line + 1:
            cur.comment = prev.comment
    # A function's default arguments are public parameters its docstring documents, not hidden constants.
    defaults = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                for d in (*f.args.defaults, *f.args.kw_defaults) if d is not None for n in ast.walk(d)}
    # A literal inside a commented module-level table (a dict or tuple of numbers) has that table's comment.
    tables = {}
    for node in tree.body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None and not _number(node.value):
            text = _comment_for(node.lineno, lines, comments)
            if text:
                tables.update({id(n): text for n in ast.walk(node.value)})
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and id(node) in tables and _tuned_literal(node):
            out.append(Constant(rel, node.lineno, "(table)", repr(node.value), tables[id(node)]))
        elif (isinstance(node, ast.Constant) and id(node) not in module_level and id(node) not in defaults
                and _tuned_literal(node)):
            out.append(Constant(rel, node.lineno, "(inline)", repr(node.value),
                                _comment_for(node.lineno, lines, comments)))
    return sorted(out, key=lambda c: c.line)


def mesh_comments(path: Path) -> list[tuple[int, str]]:
    """Comments (and docstrings are not comments: those may cite a paper) that name a benchmark mesh."""
    return [(line, text) for line, text in _comments(path.read_text()).items() if MESH_NAMES.search(text)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 on a constant without a comment or a comment "
                                                          "naming a benchmark mesh")
    args = ap.parse_args(argv)
    files = sorted(ROOT.rglob("*.py"))
    drawing = {ROOT / d for d in DRAWING}
    problems = []
    if not args.check:
        print("| module | line | name | value | comment |")
        print("|---|---|---|---|---|")
    for path in files:
        for c in constants(path):
            if path in drawing and c.name == "(inline)":
                continue
            if not args.check:
                print(f"| {c.module} | {c.line} | {c.name} | {c.value} | {c.comment[:100]} |")
            if not c.comment:
                problems.append(f"{c.module}:{c.line}: {c.name} = {c.value} has no comment saying what it scales with")
        for line, text in mesh_comments(path):
            problems.append(f"{path.relative_to(ROOT.parent)}:{line}: comment names a benchmark mesh: {text[:90]}")
    if args.check:
        for p in problems:
            print(p)
        print(f"{len(problems)} problem(s) in {len(files)} files")
    return 1 if args.check and problems else 0


if __name__ == "__main__":
    sys.exit(main())
