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


def test_cli_module_loads_no_numpy_before_its_signal_handlers():
    """The `recon` command installs its handlers and thread limits before numpy/OpenCascade load: importing the
    package and the CLI loads none of them (a Ctrl-C during those imports used to give a traceback)."""
    code = "import sys, os, recon.cli; assert not {'numpy', 'scipy', 'trimesh', 'OCP'} & set(sys.modules); " \
           "print(os.environ['OPENBLAS_NUM_THREADS'], os.environ['OMP_NUM_THREADS'])"
    env = {k: v for k, v in __import__("os").environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert proc.returncode == 0 and proc.stdout.split() == ["1", "1"], proc.stderr
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**env, "OPENBLAS_NUM_THREADS": "4", "OMP_NUM_THREADS": "3"})
    assert proc.stdout.split() == ["4", "3"], proc.stderr  # the user's choice stands


def test_lazy_package_keeps_functions_over_submodules():
    import recon
    import recon.decompose
    import recon.deviation

    assert recon.deviation.__name__ == "deviation" and callable(recon.deviation)
    assert recon.decompose.__name__ == "decompose" and callable(recon.decompose)
    assert all(getattr(recon, name) is not None for name in recon.__all__)
