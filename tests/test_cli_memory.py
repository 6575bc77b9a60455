"""A run that cannot get memory (an address-space limit, ``ulimit -v``) ends with one line and exit 2, in bounded
time: refused up front when the limit cannot even hold the libraries, and "not enough memory" when the mesh
outgrows it mid-run. (Before: a traceback, "failed to map segment", or glibc aborting with exit 127.)"""

from __future__ import annotations

import resource
import sys

import numpy as np
import pytest

from cli_harness import binary_stl, copy_fixture, run_subprocess
from recon.cli import MIN_ADDRESS_SPACE

if not sys.platform.startswith("linux"):
    pytest.skip("RLIMIT_AS is enforced on Linux", allow_module_level=True)


def _limit(nbytes: int):
    def apply():
        resource.setrlimit(resource.RLIMIT_AS, (nbytes, nbytes))

    return apply


def test_limit_below_the_libraries_is_refused_up_front(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    copy_fixture("prism_coarse.stl", work)
    run = run_subprocess(["convert", "prism_coarse.stl", "o.step"], work, timeout=120,
                         preexec_fn=_limit(MIN_ADDRESS_SPACE * 2 // 3))
    run.assert_one_line_error(2, "not enough memory: the address-space limit (ulimit -v)")


@pytest.mark.slow
def test_mesh_that_outgrows_the_limit_fails_with_one_line(tmp_path):
    """327,680 triangles need about 1.3 GiB; under a 1.1 GiB limit an allocation fails mid-run."""
    import trimesh

    work = tmp_path / "work"
    work.mkdir()
    sphere = trimesh.creation.icosphere(subdivisions=7, radius=10.0)
    (work / "sphere.stl").write_bytes(binary_stl(np.asarray(sphere.vertices), np.asarray(sphere.faces)))
    run = run_subprocess(["convert", "sphere.stl", "o.step", "--no-deviation"], work, timeout=300,
                         preexec_fn=_limit(int(1.1 * (1 << 30))))
    run.assert_one_line_error(2, "not enough memory")
