"""Running the ``recon`` CLI the way a user does, and checking that it kept its promises: one line on stderr for
an error, no traceback, the inputs byte for byte unchanged, no file left in the output folder nor in a private
TMPDIR. Shared by the bad-input corpus, the interrupt tests and the fuzz test."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from recon.cli import main

REPO = Path(__file__).resolve().parent.parent
FIXTURES = REPO / "fixtures" / "data"


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def snapshot(folder: Path) -> dict:
    """name -> sha256 of every file in ``folder`` (recursively; symlinks as their target text)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_symlink():
            out[str(p.relative_to(folder))] = "link:" + os.readlink(p)
        elif p.is_file():
            out[str(p.relative_to(folder))] = digest(p)
    return out


@dataclass
class Run:
    code: int
    stderr: str
    work: Path
    tmp: Path
    before: dict = field(default_factory=dict)

    @property
    def lines(self) -> list:
        return [line for line in self.stderr.splitlines() if line.strip()]

    def new_files(self) -> set:
        return set(snapshot(self.work)) - set(self.before)

    def assert_inputs_unchanged(self) -> None:
        after = snapshot(self.work)
        changed = {k for k, v in self.before.items() if after.get(k) != v}
        assert not changed, f"inputs changed or removed: {changed}"

    def assert_one_line_error(self, code: int, words: str) -> None:
        assert self.code == code, (self.code, self.stderr)
        assert "Traceback" not in self.stderr, self.stderr
        assert len(self.lines) == 1, self.stderr
        assert words.lower() in self.stderr.lower(), self.stderr
        self.assert_inputs_unchanged()
        assert self.new_files() == set(), self.new_files()
        assert list(self.tmp.iterdir()) == [], list(self.tmp.iterdir())


def run_in_process(argv: list, work: Path, capfd, monkeypatch) -> Run:
    """``main(argv)`` here (the libraries stay imported: fast), with TMPDIR a private, empty folder."""
    tmp = work.parent / (work.name + "_tmp")
    tmp.mkdir(exist_ok=True)
    before = snapshot(work)
    capfd.readouterr()
    old = os.getcwd(), os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"], tempfile.tempdir = str(tmp), str(tmp)
    os.chdir(work)  # relative paths as a user types them
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse's usage errors and --help
        code = exc.code
    finally:
        os.chdir(old[0])
        if old[1] is None:
            del os.environ["TMPDIR"]
        else:
            os.environ["TMPDIR"] = old[1]
        tempfile.tempdir = old[2]
    return Run(code=code, stderr=capfd.readouterr().err, work=work, tmp=tmp, before=before)


def cli_command(*args) -> list:
    return [sys.executable, "-m", "recon", *map(str, args)]


def cli_env(tmp: Path) -> dict:
    return dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))


def run_subprocess(argv: list, work: Path, *, timeout: float = 300, preexec_fn=None) -> Run:
    tmp = work.parent / (work.name + "_tmp")
    tmp.mkdir(exist_ok=True)
    before = snapshot(work)
    proc = subprocess.run(cli_command(*argv), cwd=work, env=cli_env(tmp), capture_output=True, text=True,
                          timeout=timeout, preexec_fn=preexec_fn)
    return Run(code=proc.returncode, stderr=proc.stderr, work=work, tmp=tmp, before=before)


def copy_fixture(name: str, work: Path) -> Path:
    dst = work / name
    shutil.copyfile(FIXTURES / name, dst)
    return dst


def binary_stl(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A binary STL of the triangles (normals zero: readers recompute them)."""
    tri = np.asarray(vertices, dtype="<f4")[np.asarray(faces)]
    rec = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tri
    return b"recon test".ljust(80, b" ") + np.uint32(len(tri)).tobytes() + rec.tobytes()


def cube_mesh(size: float = 10.0) -> tuple:
    v = np.array([[x, y, z] for x in (0, size) for y in (0, size) for z in (0, size)], dtype=float)
    f = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                  [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])
    return v, f


def read_stl(path: Path) -> tuple:
    from recon.mesh import read_triangles

    return read_triangles(path)


def step_is_valid_solid(path: Path, *, shell: bool = False) -> bool:
    """Re-read a written STEP file: one valid closed solid (or, with ``shell``, a valid shell: an open mesh's
    accepted result)."""
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.TopAbs import TopAbs_SHELL, TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer

    from recon.brep._step_read import read_step

    shape, _ = read_step(path)
    found = TopExp_Explorer(shape, TopAbs_SHELL if shell else TopAbs_SOLID)
    return found.More() and BRepCheck_Analyzer(shape).IsValid()
