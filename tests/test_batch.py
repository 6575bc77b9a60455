"""recon batch / recon.convert_many on real Dask clusters (a LocalCluster, and a scheduler and workers started as
their own processes): good parts converted, bad ones isolated as error rows, reruns skip, fsspec URLs work."""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import jsonschema
import pytest

from recon.batch import BatchRow, convert_many, find_parts, name_parts
from recon.batch._summary import write_html
from recon.cli import main
from recon.verdict import schema

DATA = Path(__file__).resolve().parents[1] / "fixtures" / "data"
#: The smallest fixture (the 8-face prism, a CAD export of a few hundred triangles): seconds per conversion.
GOOD = DATA / "prism_coarse.stl"


def _folder(root: Path) -> Path:
    """Two good parts with the same name in different folders, a truncated STL, and one that aborts its process."""
    src = root / "parts"
    (src / "sub").mkdir(parents=True)
    shutil.copy(GOOD, src / "prism.stl")
    shutil.copy(GOOD, src / "sub" / "prism.stl")
    data = GOOD.read_bytes()
    (src / "truncated.stl").write_bytes(data[: len(data) // 2])  # the header counts twice the triangles that follow
    shutil.copy(GOOD, src / "boom.stl")
    return src


def _rows(out: Path) -> dict[str, dict]:
    with open(out / "summary.csv", newline="") as fh:
        return {Path(r["input"]).relative_to(out.parent / "parts").as_posix(): r for r in csv.DictReader(fh)}


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


def test_good_parts_converted_bad_ones_error_rows(local_run):
    root, code, rows = local_run
    out = root / "out"
    assert code == 1
    assert set(rows) == {"prism.stl", "sub/prism.stl", "truncated.stl", "boom.stl"}
    # Same-named inputs: the first by sorted path keeps the name, the other gets ~2 and the row says so.
    assert rows["prism.stl"]["output"] == str(out / "prism.step")
    assert rows["sub/prism.stl"]["output"] == str(out / "prism~2.step")
    assert "prism~2" in rows["sub/prism.stl"]["message"]
    for key, stem in (("prism.stl", "prism"), ("sub/prism.stl", "prism~2")):
        row = rows[key]
        report = json.loads((out / f"{stem}.report.json").read_text())
        jsonschema.validate(report, schema())  # written in the runner process, unseen by conftest's check
        assert row["status"] == "ok" and row["valid"] == "True"
        assert int(row["faces"]) == report["n_faces"] == 8  # the prism's 8 true faces
        assert float(row["mesh_to_shape_p95_pct"]) == report["deviation"]["mesh_to_shape"]["p95_pct"]
        assert (out / f"{stem}.step").stat().st_size > 0 and (out / f"{stem}.preview.png").stat().st_size > 0
        assert report["batch"]["input"] == str(root / "parts" / key)
    assert rows["truncated.stl"]["status"] == "error" and rows["truncated.stl"]["output"] == ""
    assert rows["boom.stl"]["status"] == "error" and "SIGABRT" in rows["boom.stl"]["message"]
    assert not list(out.glob("boom*")) and not list(out.glob("truncated*")) and not list(out.glob(".*"))
    page = (out / "summary.html").read_text()
    assert page.count("<tr class=") == 4
    assert page.index('class="error"') < page.index('class="ok"')  # failures first


def test_rerun_skips_finished_parts_and_force_redoes(local_run, capsys):
    root, _, _ = local_run
    out = root / "out"
    before = (out / "prism.step").stat().st_mtime_ns
    code = main(["batch", str(root / "parts"), "--out", str(out), "--workers", "2", "--no-preview"])
    rows = _rows(out)
    assert code == 1  # truncated.stl still fails
    assert rows["prism.stl"]["status"] == rows["sub/prism.stl"]["status"] == "skipped"
    assert rows["prism.stl"]["faces"] == "8"
    assert (out / "prism.step").stat().st_mtime_ns == before  # not rewritten
    assert rows["boom.stl"]["status"] == "ok"  # without the hook it converts: it failed, so it was not skipped
    assert rows["truncated.stl"]["status"] == "error"
    # A different tolerance is a different result: nothing is skipped.
    code = main(["batch", str(root / "parts" / "prism.stl"), "--out", str(out), "--workers", "1",
                 "--tolerance", "0.01", "--no-preview"])
    assert code == 0 and _rows(out)["prism.stl"]["status"] == "ok"
    assert (out / "prism.step").stat().st_mtime_ns != before


def test_separate_scheduler_and_workers_same_results(local_run, tmp_path):
    _, _, reference = local_run
    src = _folder(tmp_path)
    sched_file = tmp_path / "scheduler.json"
    env = dict(os.environ, RECON_TEST_ABORT="boom.stl", PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    dask = [sys.executable, "-m", "dask"]  # the `dask` command of this environment
    procs = [subprocess.Popen([*dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address",
                               "127.0.0.1:0", "--scheduler-file", str(sched_file)], env=env, stderr=subprocess.DEVNULL)]
    try:
        for _ in range(600):
            if sched_file.exists() and sched_file.stat().st_size:
                break
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        procs += [subprocess.Popen([*dask, "worker", address, "--nthreads", "1",
                                    "--host", "127.0.0.1", "--no-dashboard"], env=env, stderr=subprocess.DEVNULL)
                  for _ in range(2)]
        from distributed import Client

        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
            convert_many([str(src)], tmp_path / "out", client=client, preview=False)
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            p.wait(timeout=60)
    rows = _rows(tmp_path / "out")
    assert {k: (r["status"], r["faces"]) for k, r in rows.items()} == \
        {k: (r["status"], r["faces"]) for k, r in reference.items()}


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
    assert [r["status"] for r in starved] == ["error"] and "used more than 64 MiB" in starved[0]["message"]
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
