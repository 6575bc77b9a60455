import pytest

from recon._io import atomic_path, write_json
from recon.errors import ExportError


def test_failure_leaves_no_file(tmp_path):
    out = tmp_path / "x.json"
    with pytest.raises(RuntimeError):
        with atomic_path(out) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_write_json_round_trip(tmp_path):
    out = tmp_path / "x.json"
    write_json(out, {"a": [1, 2]})
    assert out.read_text() == '{"a": [1, 2]}'


def test_missing_folder_is_one_clear_error(tmp_path):
    with pytest.raises(ExportError, match="does not exist"):
        with atomic_path(tmp_path / "nope" / "x.json"):
            pass


def test_output_gets_the_default_file_mode(tmp_path):
    import os

    umask = os.umask(0o022)
    try:
        write_json(tmp_path / "x.json", {})
        plain = tmp_path / "plain"
        plain.write_text("")
        assert (tmp_path / "x.json").stat().st_mode & 0o777 == plain.stat().st_mode & 0o777 == 0o644
    finally:
        os.umask(umask)
