import subprocess
import sys

from recon.cli import main


def test_help_lists_subcommands(capsys):
    try:
        main(["--help"])
    except SystemExit as exc:
        assert exc.code == 0
    out = capsys.readouterr().out
    assert "skeleton" in out


def test_module_entry_point_runs():
    proc = subprocess.run([sys.executable, "-m", "recon", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and "recon" in proc.stdout
