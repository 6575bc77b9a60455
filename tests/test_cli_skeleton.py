"""``recon skeleton``: outputs, option help, and clean failure on bad input."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from recon.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
STAR = ROOT / "fixtures" / "shapes" / "star.json"


def test_readme_quick_start_on_the_star(tmp_path, capsys):
    """The README's command, run from another folder: a five-pointed star."""
    out, png = tmp_path / "star.json", tmp_path / "star.png"
    assert main(["skeleton", str(STAR), "--json", str(out), "--plot", str(png)]) == 0
    doc = json.loads(out.read_text())
    kinds = [p["kind"] for p in doc["parts"]]
    # Five spikes give five terminals; a tree whose inner vertices all have degree 3 and that has 5 leaves
    # has 5 - 2 = 3 junctions (Voronoi vertices have degree <= 3, §3).
    assert kinds.count("terminal") == 5
    assert kinds.count("junction") == 3
    edges = np.asarray(doc["skeleton"]["edges"])
    assert len(edges) == len(doc["skeleton"]["vertices"]) - 1  # a tree: no hole, one component
    assert doc["shape"] == str(STAR)
    assert Image.open(png).format == "PNG"
    out = capsys.readouterr().out  # the result's line on stdout
    assert "3 junction, 5 terminal" in out and out.count("\n") == 1


def test_options_are_passed_through(tmp_path):
    out = tmp_path / "s.json"
    assert main(["skeleton", str(STAR), "--json", str(out), "--omega-min", "7.5", "--spacing", "0.5"]) == 0
    doc = json.loads(out.read_text())
    assert doc["omega_min"] == 7.5 and doc["spacing"] == 0.5


def test_invert_on_an_image(tmp_path):
    mask = np.ones((40, 40), np.uint8) * 255
    mask[10:30, 8:32] = 0  # the shape, drawn black on white
    img = tmp_path / "ink.png"
    Image.fromarray(mask).save(img)
    out = tmp_path / "ink.json"
    assert main(["skeleton", str(img), "--json", str(out), "--invert"]) == 0
    parts = json.loads(out.read_text())["parts"]
    # The parts tile the 24 x 20 block (less the half pixel marching squares cuts off, less resampling).
    area = sum(_ring_area(np.array(p["polygon"])) - sum(_ring_area(np.array(h)) for h in p["holes"]) for p in parts)
    assert area == pytest.approx(24 * 20 - 0.5, rel=0.01)


def _ring_area(r):
    return 0.5 * abs(np.dot(r[:, 0], np.roll(r[:, 1], -1)) - np.dot(r[:, 1], np.roll(r[:, 0], -1)))


def test_every_option_help_states_unit_and_default():
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    parser = sub.choices["skeleton"]
    for action in parser._actions:
        if action.option_strings and action.dest not in ("help", "json"):
            assert "default" in action.help, action.dest
    for dest in ("omega_min", "spacing"):
        action = next(a for a in parser._actions if a.dest == dest)
        assert "shape units" in action.help


@pytest.mark.parametrize(
    "args, message",
    [
        (["missing.json"], "does not exist"),
        (["bad.json"], "not valid JSON"),
        (["cross.json"], "intersects itself"),
        (["shape.txt"], "unknown suffix"),
    ],
)
def test_bad_input_one_line_exit_2_no_output(tmp_path, args, message):
    (tmp_path / "bad.json").write_text("{")
    (tmp_path / "cross.json").write_text(json.dumps({"curves": [[[0, 0], [4, 2], [4, 0], [0, 3]]]}))
    (tmp_path / "shape.txt").write_text("hello")
    out, png = tmp_path / "o.json", tmp_path / "o.png"
    proc = subprocess.run(
        [sys.executable, "-m", "recon", "skeleton", str(tmp_path / args[0]), "--json", str(out), "--plot", str(png)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert message in proc.stderr and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert not out.exists() and not png.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json", "cross.json", "shape.txt"]


def test_missing_output_folder_fails_before_work(tmp_path, capsys):
    assert main(["skeleton", str(STAR), "--json", str(tmp_path / "no" / "o.json")]) == 2
    err = capsys.readouterr().err
    assert "does not exist" in err and err.count("\n") == 1


@pytest.mark.parametrize("value", ["0", "-1", "nan", "abc", "inf"])
def test_non_positive_omega_is_a_usage_error(tmp_path, value, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["skeleton", str(STAR), "--json", str(tmp_path / "o.json"), "--omega-min", value])
    assert exc.value.code == 2
    assert "positive" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
