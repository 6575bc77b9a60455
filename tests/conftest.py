"""Fixtures the test files share, and the check that every report follows its schema.

Data from outside the repository: the real meshes and silhouettes sit in ``../shared/`` beside the repository (CI's
layout). A test that needs them skips where they are absent, saying so; ``.ci/run`` sets ``RECON_REQUIRE_SHARED=1``
(and ``RECON_REQUIRE_FREECAD=1``), so there a missing folder (or FreeCAD) fails instead.

Every convert report the test-suite makes in this process is validated against ``recon/report.schema.json``.

``recon.pipeline._report`` (every :func:`recon.convert`) and ``recon._io.write_json`` (every report written, after
:func:`recon.verdict.write_checked` judged the written file) are looked up by name when called, so wrapping them here
sees every report, whichever way a test reaches them. Reports of CLI runs in a subprocess are not seen here.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import pytest
import trimesh

#: ../shared beside the repository: the real meshes (meshes/) and the MPEG-7 silhouettes (shapes/mpeg7/)
SHARED = Path(__file__).resolve().parents[2] / "shared"


def shared_data(*parts: str) -> Path:
    """``../shared/<parts>``; skips the calling test where it is absent, and fails where CI requires it."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        reason = f"needs {path} (../shared beside the repository, not part of it): absent here"
        if os.environ.get("RECON_REQUIRE_SHARED") == "1":
            pytest.fail(reason + ", and RECON_REQUIRE_SHARED=1 (.ci/run) requires it")
        pytest.skip(reason)
    return path


def pytest_runtest_setup(item: pytest.Item) -> None:
    """``@pytest.mark.freecad``: the test opens files in FreeCAD; skipped where ``freecadcmd`` is absent, failed there
    where ``RECON_REQUIRE_FREECAD=1`` (.ci/run installs FreeCAD and sets it)."""
    if item.get_closest_marker("freecad") is None:
        return
    from recon._freecad import freecadcmd

    if freecadcmd() is None:
        if os.environ.get("RECON_REQUIRE_FREECAD") == "1":
            pytest.fail("needs FreeCAD (freecadcmd), which RECON_REQUIRE_FREECAD=1 (.ci/run) requires: not installed")
        pytest.skip("needs FreeCAD (freecadcmd): not installed (RECON_REQUIRE_FREECAD=1 makes this a failure)")


@pytest.fixture
def shared():
    """:func:`shared_data`, for a test that needs another folder of ../shared."""
    return shared_data


@pytest.fixture
def shared_meshes() -> Path:
    """../shared/meshes: real meshes nobody here made (shared/meshes/README.md)."""
    return shared_data("meshes")


@pytest.fixture(scope="session")
def box_mesh() -> trimesh.Trimesh:
    """A 30 x 20 x 10 box of ~1 mm triangles: 6 true faces, all planes, volume 6000. Shared by the whole session, so
    read-only: a test that changes it fails (``mesh.copy()`` to have one to change)."""
    mesh = trimesh.creation.box(extents=(30, 20, 10)).subdivide_to_size(1.0)
    mesh.vertices.flags.writeable = False
    mesh.faces.flags.writeable = False
    return mesh


@pytest.fixture(autouse=True, scope="session")
def _reports_follow_the_schema():
    import jsonschema

    import recon._io
    import recon.pipeline
    from recon.verdict import schema

    validator = jsonschema.Draft202012Validator(schema())
    made, wrote = recon.pipeline._report, recon._io.write_json

    @functools.wraps(made)
    def checked_report(*args, **kwargs):
        report = made(*args, **kwargs)
        validator.validate(report)
        return report

    @functools.wraps(wrote)
    def checked_write(path, data, *args, **kwargs):
        if isinstance(data, dict) and "verdict" in data and "faces_by_type" in data:
            validator.validate(data)
        return wrote(path, data, *args, **kwargs)

    recon.pipeline._report, recon._io.write_json = checked_report, checked_write
    yield
    recon.pipeline._report, recon._io.write_json = made, wrote
