"""recon batch / recon.convert_many on real Dask clusters (a LocalCluster, and a scheduler and workers started as
their own processes): good parts converted, bad ones isolated as error rows, reruns skip, fsspec URLs work."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from recon.batch import BatchRow, convert_many, find_parts, name_parts
from recon.batch._inputs import OUTPUT_FORMATS
from recon.batch._summary import write_html
from recon.cli import main
from recon.verdict import schema

DATA = Path(__file__).resolve().parents[1] / "fixtures" / "data"
#: The smallest fixture (the 8-face prism, a CAD export of a few hundred triangles): seconds per conversion.
GOOD = DATA / "prism_coarse.stl"
#: Statuses and faces of the parts of `_folder`, whichever cluster runs them.
EXPECTED = {"prism.stl": ("ok", "8"), "sub/prism.stl": ("ok", "8"), "truncated.stl": ("error", ""),
            "boom.stl": ("error", "")}


def _expected(holed_faces: str) -> dict[str, tuple[str, str]]:
    """EXPECTED with the open part's row: not good, with as many faces as its report says."""
    return dict(EXPECTED, **{"holed.stl": ("invalid", holed_faces)})


def _folder(root: Path) -> Path:
    """Two good parts with the same name in different folders, a truncated STL, one that aborts its process and
    an open one (the prism without half its top: its faces span the hole, so the result is written but not good)."""
    src = root / "parts"
    (src / "sub").mkdir(parents=True)
    shutil.copy(GOOD, src / "prism.stl")
    shutil.copy(GOOD, src / "sub" / "prism.stl")
    data = GOOD.read_bytes()
    (src / "truncated.stl").write_bytes(data[: len(data) // 2])  # the header counts twice the triangles that follow
    shutil.copy(GOOD, src / "boom.stl")
    n = struct.unpack("<I", data[80:84])[0]  # binary STL: 80-byte header, count, 50 bytes per triangle
    (src / "holed.stl").write_bytes(_without_half_the_top(data, n))
    return src


def _without_half_the_top(data: bytes, n: int) -> bytes:
    """The prism's STL without the top's triangles nearest its centre, 8 % of the area: more than a scan's occlusion
    hole (recon closes those over, as it did the one-triangle hole this test once used), so the mesh stays open."""
    recs = [data[84 + 50 * i: 84 + 50 * (i + 1)] for i in range(n)]
    tri = np.array([struct.unpack("<12f", r[:48])[3:] for r in recs]).reshape(-1, 3, 3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(normal, axis=1)
    top = np.flatnonzero(normal[:, 2] > 0.99 * 2 * area)
    centre = tri[top].mean(axis=1)
    order = top[np.argsort(np.linalg.norm(centre - centre.mean(axis=0), axis=1), kind="stable")]
    drop = set(order[: int(np.searchsorted(np.cumsum(area[order]), 0.08 * area.sum())) + 1].tolist())
    keep = [r for i, r in enumerate(recs) if i not in drop]
    return data[:80] + struct.pack("<I", len(keep)) + b"".join(keep)


def _rows(out: Path) -> dict[str, dict]:
    with open(out / "summary.csv", newline="") as fh:
        return {Path(r["input"]).relative_to(out.parent / "parts").as_posix(): r for r in csv.DictReader(fh)}


def _outcomes(rows: dict[str, dict]) -> dict[str, tuple[str, str]]:
    return {k: (r["status"], r["faces"]) for k, r in rows.items()}


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    """One CLI run on a 2-worker LocalCluster, the abort hook aimed at boom.stl."""
    root = tmp_path_factory.mktemp("batch")
    src = _folder(root)
    os.environ["RECON_TEST_ABORT"] = "boom.stl"
    try:
        code = main(["batch", str(src), "--out", str(root / "out"), "--workers", "2"])
    finally:
        del os.environ["RECON_TEST_ABORT"]
    return root, code, _rows(root / "out")


@pytest.fixture(scope="module")
def external(tmp_path_factory):
    """A scheduler and two workers started as their own processes (`dask scheduler`, `dask worker`, each worker
    under its nanny), as on a cluster; the abort hook aimed at boom.stl, the hang hook at hang.stl. Yields the
    scheduler's address and the workers' scratch folder."""
    root = tmp_path_factory.mktemp("cluster")
    sched_file, scratch = root / "scheduler.json", root / "scratch"
    env = dict(os.environ, RECON_TEST_ABORT="boom.stl", RECON_TEST_HANG="hang.stl",
               PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    dask = [sys.executable, "-m", "dask"]  # the `dask` command of this environment
    procs = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address",
                               "127.0.0.1:0", "--scheduler-file", str(sched_file)], env=env, stderr=subprocess.DEVNULL)]
    try:
        for _ in range(600):
            if sched_file.exists() and sched_file.stat().st_size:
                break
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        procs += [subprocess.Popen([*dask, "worker", address, "--nthreads", "1", "--host", "127.0.0.1",
                                    "--no-dashboard", "--local-directory", str(scratch)],
                                   env=env, stderr=subprocess.DEVNULL) for _ in range(2)]
        from distributed import Client

        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
        yield address, scratch
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            p.wait(timeout=60)


def test_good_parts_converted_bad_ones_error_rows(local_run):
    root, code, rows = local_run
    out = root / "out"
    assert code == 1
    assert _outcomes(rows) == _expected(str(json.loads((out / "holed.report.json").read_text())["n_faces"]))
    # Same-named inputs: the first by sorted path keeps the name, the other gets ~2 and the row says so.
    assert rows["prism.stl"]["output"] == str(out / "prism.step")
    assert rows["sub/prism.stl"]["output"] == str(out / "prism~2.step")
    assert "prism~2" in rows["sub/prism.stl"]["message"] and rows["prism.stl"]["message"] == ""
    for key, stem in (("prism.stl", "prism"), ("sub/prism.stl", "prism~2")):
        row = rows[key]
        report = json.loads((out / f"{stem}.report.json").read_text())
        jsonschema.validate(report, schema())  # written in the runner process, unseen by conftest's check
        assert row["status"] == "ok" and row["valid"] == "True"
        assert int(row["faces"]) == report["n_faces"] == 8  # the prism's 8 true faces
        assert float(row["mesh_to_shape_p95_pct"]) == report["deviation"]["mesh_to_shape"]["p95_pct"]
        assert (out / f"{stem}.step").stat().st_size > 0 and (out / f"{stem}.preview.png").stat().st_size > 0
        assert report["batch"]["input"] == str(root / "parts" / key)
    # Written but not good: the row says which rule failed, as `recon convert` exits 1 for it.
    holed = json.loads((out / "holed.report.json").read_text())
    assert not holed["verdict"]["ok"] and rows["holed.stl"]["message"].startswith("not good: ")
    failed = [r["rule"] for r in holed["verdict"]["rules"] if r["ok"] is False]
    assert failed and all(rule in rows["holed.stl"]["message"] for rule in failed)
    assert (out / "holed.step").exists() and rows["holed.stl"]["output"] == str(out / "holed.step")
    assert rows["truncated.stl"]["status"] == "error" and rows["truncated.stl"]["output"] == ""
    assert rows["boom.stl"]["status"] == "error" and "SIGABRT" in rows["boom.stl"]["message"]
    assert not list(out.glob("boom*")) and not list(out.glob("truncated*")) and not list(out.glob(".*"))
    with open(out / "summary.csv", newline="") as fh:
        assert next(csv.reader(fh)) == ["input", "output", "status", "faces", "valid", "mesh_to_shape_p95_pct",
                                        "seconds", "message"]
    page = (out / "summary.html").read_text()
    assert page.count("<tr class=") == 5 and "5 parts: 2 error, 1 invalid, 2 ok, 0 skipped" in page
    assert page.index('class="error"') < page.index('class="invalid"') < page.index('class="ok"')  # failures first
    assert page.count('<img src="') == 3  # a picture per written part


def test_separate_scheduler_and_workers_same_results(local_run, external, tmp_path):
    from distributed import Client

    address, _ = external
    src = _folder(tmp_path)
    with Client(address, timeout=60) as client:
        convert_many([str(src)], tmp_path / "out", client=client, preview=False)
    assert _outcomes(_rows(tmp_path / "out")) == _outcomes(local_run[2]) == _expected(local_run[2]["holed.stl"]["faces"])


def test_rerun_skips_finished_parts_redoes_the_rest(local_run, external):
    """Resume on the external cluster through the CLI: what finished good is skipped (not rewritten), what failed
    or is not good is converted again; --force, another tolerance or --no-deviation redo a finished part."""
    root, _, _ = local_run
    address, _ = external
    out, prism = root / "out", str(root / "parts" / "prism.stl")
    before = (out / "prism.step").stat().st_mtime_ns

    def run(*args):
        return main(["batch", *args, "--out", str(out), "--scheduler", address, "--no-preview"])

    assert run(str(root / "parts")) == 1
    rows = _rows(out)
    assert rows["prism.stl"]["status"] == rows["sub/prism.stl"]["status"] == "skipped"
    assert rows["prism.stl"]["faces"] == "8" and rows["prism.stl"]["seconds"] == "0.0"
    assert "prism~2" in rows["sub/prism.stl"]["message"]  # the renaming is said again
    assert (out / "prism.step").stat().st_mtime_ns == before  # not rewritten
    assert rows["boom.stl"]["status"] == "error" and "SIGABRT" in rows["boom.stl"]["message"]  # run again
    assert rows["holed.stl"]["status"] == "invalid" and rows["truncated.stl"]["status"] == "error"
    assert run(prism) == 0 and _rows(out)["prism.stl"]["status"] == "skipped"  # exit 0: every part ok or skipped
    assert run(prism, "--force") == 0 and _rows(out)["prism.stl"]["status"] == "ok"
    forced = (out / "prism.step").stat().st_mtime_ns
    assert forced != before
    # Another tolerance is another result: not skipped.
    assert run(prism, "--tolerance", "0.01") == 0 and _rows(out)["prism.stl"]["status"] == "ok"
    assert (out / "prism.step").stat().st_mtime_ns != forced
    # Without the deviation the result is not verified: converted again, and the row says so.
    assert run(prism, "--tolerance", "0.01", "--no-deviation") == 0
    row = _rows(out)["prism.stl"]
    assert row["status"] == "ok" and row["mesh_to_shape_p95_pct"] == "" and "NOT verified" in row["message"]
    report = json.loads((out / "prism.report.json").read_text())
    assert "deviation" not in report and report["verdict"]["within_tolerance"] is None
    assert report["batch"]["deviation"] is False
    # Another format is another result; IGES (for importers without STEP) reads back as the prism's 8 faces.
    assert run(prism, "--format", "iges") == 0 and _rows(out)["prism.stl"]["status"] == "ok"
    from recon.brep._step_read import read_back_shape

    assert len(read_back_shape(out / "prism.igs")[1]) == 8  # a name per face read back


def test_killed_worker_stage_purged_rows_written_as_they_arrive(external, tmp_path):
    """A worker SIGKILLed while its part runs: its runner ends, its staging folder is purged when the nanny starts
    the next worker, Dask runs the part again; the other part's row is in summary.csv while that one still runs."""
    import threading

    import psutil
    from distributed import Client

    address, scratch = external
    src = tmp_path / "parts"
    src.mkdir()
    shutil.copy(GOOD, src / "prism.stl")
    shutil.copy(GOOD, src / "hang.stl")  # hangs (the test hook) until hang.stl.release exists
    out = tmp_path / "out"
    with Client(address, timeout=60) as client:
        result = {}
        thread = threading.Thread(target=lambda: result.update(rows=convert_many([str(src)], out, client=client,
                                                                                 preview=False)))
        thread.start()
        dirs = {a: Path(d).resolve() for a, d in client.run(lambda dask_worker: dask_worker.local_directory).items()}

        def hung_stage():
            # The worker running hang.stl, once its stage exists.
            for addr, keys in client.processing().items():
                if any(str(k).startswith("recon-part-hang-") for k in keys):
                    return [(addr, s) for s in dirs[addr].glob("recon-batch-*")]
            return []

        ((addr, hung),) = _until(hung_stage, thread)
        pid = client.run(os.getpid, workers=[addr])[addr]
        runner = [c for c in psutil.Process(pid).children() if "recon.batch._runner" in " ".join(c.cmdline())]
        os.kill(pid, signal.SIGKILL)
        # hang.stl cannot finish before its release: the prism's row is in the file alone, while the run goes on.
        assert [r["input"] for r in _until(lambda: _csv(out), thread)] == [str(src / "prism.stl")]
        assert thread.is_alive()
        (src / "hang.stl.release").touch()
        thread.join(300)
    rows = result["rows"].to_dict("records") if hasattr(result["rows"], "to_dict") else list(map(vars, result["rows"]))
    assert {Path(r["input"]).name: r["status"] for r in rows} == {"prism.stl": "ok", "hang.stl": "ok"}
    # The nanny's next worker purges the dead one's folder; the runner noticed its worker gone (within a second).
    _until(lambda: not hung.exists() and not list(scratch.glob("*/worker-*/recon-batch-*")))
    assert len(runner) == 1
    _until(lambda: _gone(runner[0]))


def test_ctrl_c_keeps_what_finished(external, tmp_path):
    """`recon batch` interrupted (SIGINT) while one part runs: exit 130, the finished part's row in summary.csv and
    summary.html, its files in place; the rerun skips it."""
    address, _ = external
    src = tmp_path / "parts"
    src.mkdir()
    shutil.copy(GOOD, src / "prism.stl")
    shutil.copy(GOOD, src / "hang.stl")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "recon", "batch", str(src), "--out", str(out), "--scheduler", address, "--no-preview"]
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    proc = subprocess.Popen(cmd, env=env, stderr=subprocess.PIPE, text=True)
    try:
        _until(lambda: _csv(out) or proc.poll() is not None)
        assert proc.poll() is None  # hang.stl holds the run open
        proc.send_signal(signal.SIGINT)
        err = proc.communicate(timeout=120)[1]
        assert proc.returncode == 130 and not list(out.glob("hang*"))
    finally:
        proc.kill()
        (src / "hang.stl.release").touch()  # the part left running on its worker ends (and writes its files)
    assert f"[1/2] ok {src / 'prism.stl'}: 8 faces" in err  # a line per finished part when not on a terminal
    assert [(r["input"], r["status"]) for r in _csv(out)] == [(str(src / "prism.stl"), "ok")]
    assert "1 parts: 0 error, 0 invalid, 1 ok, 0 skipped" in (out / "summary.html").read_text()
    assert (out / "prism.step").exists() and (out / "prism.report.json").exists()
    assert main(["batch", str(src / "prism.stl"), "--out", str(out), "--scheduler", address]) == 0
    assert _csv(out)[0]["status"] == "skipped"


def _until(ready, thread=None, seconds: float = 300.0):
    """Poll ``ready()`` until it is truthy (and return it); fail past ``seconds`` or when ``thread`` ended."""
    deadline = time.monotonic() + seconds
    while not (value := ready()):
        assert time.monotonic() < deadline and (thread is None or thread.is_alive())
        time.sleep(0.05)
    return value


def _gone(proc) -> bool:
    import psutil

    try:
        return proc.status() == psutil.STATUS_ZOMBIE  # ended, not yet reaped by its new parent
    except psutil.NoSuchProcess:
        return True


def _csv(out: Path) -> list[dict]:
    try:
        with open(out / "summary.csv", newline="") as fh:
            return list(csv.DictReader(fh))
    except FileNotFoundError:
        return []


def test_memory_limit_is_the_workers(tmp_path, capsys):
    """--memory-limit sets the local cluster's Dask worker limit (the job carries none: the task reads the
    worker's); the task holds the part's process to it. 250 MB leaves a bare worker below Dask's pause at 80 %
    and is below the ~360 MiB a runner holds once recon and OpenCascade are imported: the part is stopped, and its
    row says by what."""
    out = tmp_path / "out"
    code = main(["batch", str(GOOD), "--out", str(out), "--workers", "1", "--memory-limit", "250MB", "--no-preview"])
    assert code == 1
    (row,) = _csv(out)
    assert row["status"] == "error" and row["message"] == (
        f"killed by the memory limit: the part's process passed {250e6 / 2**20:,.0f} MiB")
    assert not (out / "prism_coarse.step").exists()


def _hog(n: int) -> int:
    data = b"x" * n  # n bytes touched: the worker's own memory
    time.sleep(60)
    return len(data)


def test_worker_killed_by_dask_memory_limit_is_named():
    """A worker that Dask's nanny restarts for passing its memory limit: the part's row says so (the scheduler's
    worker-restart-memory event of that worker), not just that a worker died."""
    import dask
    from distributed import Client, LocalCluster

    from recon.batch._run import task_failure

    # 300 MB: above a bare worker (~100 MiB), below what the task holds (400 MiB); one death ends the task.
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            LocalCluster(n_workers=1, threads_per_worker=1, memory_limit="300MB", host="127.0.0.1") as cluster, \
            Client(cluster) as client:
        with pytest.raises(Exception) as err:
            client.submit(_hog, 400 * 2**20, pure=False).result()
        message = task_failure(client, err.value)
    assert type(err.value).__name__ == "KilledWorker"
    assert message.startswith("killed by the memory limit: its worker's memory (") and "tried on 1 worker;" in message
    used = float(message.split("(")[1].split(" MiB")[0].replace(",", ""))
    assert 0.95 * 300e6 / 2**20 < used < 400 + 300e6 / 2**20  # past the nanny's 95 %; at most the hog and a worker


def test_fsspec_urls_timeout_and_memory_limit(tmp_path):
    """memory:// lives in one process, so the cluster is threads in this process; the worker reads and writes
    through fsspec, not the disk. A file:// input is read in place."""
    import fsspec
    from distributed import Client, LocalCluster

    mem = fsspec.filesystem("memory")
    mem.pipe("/batch-in/a/prism.stl", GOOD.read_bytes())
    # A 5,000-triangle part cannot be decomposed in 50 ms (its conversion takes about a second): it times out.
    slow = DATA / "box_fillet_noisy20.stl"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False) as cluster, Client(cluster) as client:
        rows = convert_many(["memory://batch-in", f"file://{GOOD}"], "memory://batch-out", client=client,
                            preview=False, format="brep")
        timed = convert_many([str(slow)], tmp_path / "t", client=client, timeout=0.05, preview=False)
        # 64 MiB is below what the part's process holds once recon and OpenCascade are imported: stopped at once.
        starved = convert_many([str(GOOD)], tmp_path / "m", client=client, memory_limit=64 * 2**20, preview=False)
    by_input = {r["input"]: r for r in (rows.to_dict("records") if hasattr(rows, "to_dict") else map(vars, rows))}
    assert by_input["memory:///batch-in/a/prism.stl"]["status"] == "ok"  # fsspec's own spelling of the URL
    assert by_input[str(GOOD)]["status"] == "ok"  # file:// is the local disk: a plain path
    assert mem.exists("/batch-out/prism.brep") and mem.exists("/batch-out/prism_coarse.brep")
    report = json.loads(mem.cat("/batch-out/prism.report.json"))
    jsonschema.validate(report, schema())
    assert report["n_faces"] == 8 and report["batch"]["format"] == "brep"
    assert mem.cat("/batch-out/summary.csv").decode().count("\n") == 3
    status = list(timed["status"]) if hasattr(timed, "columns") else [r.status for r in timed]
    message = list(timed["message"]) if hasattr(timed, "columns") else [r.message for r in timed]
    assert status == ["error"] and message == ["timed out after 0.05 s"]
    starved = starved.to_dict("records") if hasattr(starved, "to_dict") else list(map(vars, starved))
    assert [r["status"] for r in starved] == ["error"] and "passed 64 MiB" in starved[0]["message"]
    assert not (tmp_path / "m" / "prism_coarse.step").exists()


def test_report_ok_is_the_verdict():
    from recon.batch._inputs import report_ok

    # The acceptance verdict (deviation within tolerance, every part a face) decides, not a valid solid alone;
    # a report without one (written by an older recon) is not taken as good.
    valid = {"validity": {"ok": True}}
    assert not report_ok(valid)
    assert not report_ok(dict(valid, verdict={"ok": False}))
    assert report_ok({"validity": {"ok": False}, "verdict": {"ok": True}})


@pytest.mark.parametrize("args, words", [
    (["{src}/nothing.stl"], "no such file"),
    (["{src}", "--workers", "0"], "workers must be at least 1"),
    (["{src}", "--tolerance", "-1"], "tolerance must be"),
    (["{src}", "--tolerance", "nan"], "tolerance must be"),
    (["{src}", "--timeout", "0"], "timeout must be"),
    (["{src}", "--memory-limit", "lots"], "memory limit must be a size"),
    (["{src}", "--memory-limit", "0"], "memory limit must be a positive"),
    (["{src}/empty"], "no mesh files"),
    (["{src}/*.obj"], "no mesh files"),
])
def test_bad_arguments_one_line_exit_2_nothing_made(tmp_path, capsys, args, words):
    src = tmp_path / "src"
    (src / "empty").mkdir(parents=True)
    shutil.copy(GOOD, src / "a.stl")
    out = tmp_path / "out"
    code = main(["batch", *[a.format(src=src) for a in args], "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and words in err
    assert not out.exists()


def test_outputs_never_overwrite_inputs(tmp_path, capsys):
    shutil.copy(GOOD, tmp_path / "a.stl")
    before = (tmp_path / "a.stl").read_bytes()
    code = main(["batch", str(tmp_path / "a.stl"), "--out", str(tmp_path), "--format", "stl"])
    assert code == 2 and "would overwrite an input" in capsys.readouterr().err
    assert (tmp_path / "a.stl").read_bytes() == before and sorted(os.listdir(tmp_path)) == ["a.stl"]
    (tmp_path / "f").write_text("x")
    assert main(["batch", str(tmp_path / "a.stl"), "--out", str(tmp_path / "f")]) == 2


def test_cli_formats_are_the_writers():
    from recon.cli import build_parser

    args = build_parser().parse_args(["batch", "x.stl", "--out", "o", "--format", "iges"])
    assert args.format == "iges"
    for fmt in OUTPUT_FORMATS:  # every format the writer knows is offered, and nothing else
        assert build_parser().parse_args(["batch", "x", "--out", "o", "--format", fmt]).format == fmt
    with pytest.raises(SystemExit):
        build_parser().parse_args(["batch", "x", "--out", "o", "--format", "obj"])


def test_find_and_name_parts(tmp_path):
    for rel in ("b/Part.stl", "a/part.obj", "a/part.STL", "a/.hidden.stl", "a/notes.txt", "out/part.stl"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_bytes(b"x")
    parts = find_parts([str(tmp_path), str(tmp_path / "a" / "*.obj")], exclude=str(tmp_path / "out"))
    # Folders searched recursively, hidden files and other formats left out, the output folder too, no duplicates.
    assert [Path(p.url).relative_to(tmp_path).as_posix() for p in parts] == ["a/part.STL", "a/part.obj", "b/Part.stl"]
    names = name_parts(list(reversed(parts)))  # the input order does not matter: names follow the sorted paths
    assert [(Path(p.url).name, p.name) for p in names] == [("part.STL", "part"), ("part.obj", "part~2"),
                                                           ("Part.stl", "Part~3")]
    assert names[0].note == "" and str(tmp_path / "a" / "part.STL") in names[1].note


def test_html_sorts_failures_first(tmp_path):
    rows = [BatchRow(f"/in/{s}.stl", f"{tmp_path}/{s}.step" if s != "error" else "", s, 8, True, 0.1, 1.0, "")
            for s in ("ok", "skipped", "error", "invalid")]
    write_html(str(tmp_path), rows)
    page = (tmp_path / "summary.html").read_text()
    order = [page.index(f'<tr class="{s}"') for s in ("error", "invalid", "ok", "skipped")]
    assert order == sorted(order) and "<script>" in page and "http" not in page  # nothing fetched from outside
