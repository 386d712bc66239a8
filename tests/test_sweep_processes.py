"""dk.sweep beyond one process: a Dask cluster reached by its address (scheduler and worker started
here as `dask scheduler` / `dask worker`), Parquet tables, Ctrl-C in `demkit sweep`, quiet workers."""
import csv
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import demkit as dk
from demkit.sweep import read_table

import sweep_tasks  # tasks importable by name in other processes (tests/ on their PYTHONPATH)

ROOT = Path(dk.__file__).resolve().parents[1]  # this checkout's demkit, not an installed one
ENV = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]))
GRID = {"x": [-1.0, 0.0, 0.5, 1.5, 3.0], "k": ["a", "b"]}


def rows_without_wall(path):
    with open(path, newline="") as fh:
        return [{k: v for k, v in r.items() if k != "wall_s"} for r in csv.DictReader(fh)]


def session_alive(sid):
    """Processes of session ``sid`` still running (zombies, dead and waiting for init, excluded)."""
    alive = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[3]) == sid and fields[0] != "Z":
                alive.append(int(entry))
    return alive


def stop(process, timeout=10):
    """End a subprocess started in its own session, and everything it started."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            pass
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.wait(timeout)


# ---- a Dask cluster by its address ---------------------------------------------------------------
@pytest.fixture(scope="module")
def dask_address(tmp_path_factory):
    """tcp://127.0.0.1:PORT of a `dask scheduler` (a free port, chosen by the scheduler) with one
    `dask worker` of one thread, both torn down afterwards."""
    distributed = pytest.importorskip("dask.distributed")
    folder = tmp_path_factory.mktemp("dask")
    info = folder / "scheduler.json"
    dask = [sys.executable, "-m", "dask"]
    started = []
    try:
        started.append(subprocess.Popen(
            dask + ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                    "--scheduler-file", str(info)], env=ENV, cwd=folder, start_new_session=True,
            stdout=open(folder / "scheduler.out", "w"), stderr=subprocess.STDOUT))
        deadline = time.monotonic() + 60
        while not (info.exists() and info.stat().st_size > 0):
            assert time.monotonic() < deadline and started[0].poll() is None, \
                (folder / "scheduler.out").read_text()
            time.sleep(0.1)
        time.sleep(0.1)  # the file is written at once, but be sure it is whole
        address = json.loads(info.read_text())["address"]
        assert re.fullmatch(r"tcp://127\.0\.0\.1:\d+", address), address
        started.append(subprocess.Popen(
            dask + ["worker", address, "--nthreads", "1", "--nworkers", "1", "--no-dashboard"],
            env=ENV, cwd=folder, start_new_session=True,
            stdout=open(folder / "worker.out", "w"), stderr=subprocess.STDOUT))
        with distributed.Client(address, timeout=30) as client:
            client.wait_for_workers(1, timeout=60)
        yield address
    finally:
        for process in reversed(started):
            stop(process)


def test_a_dask_cluster_by_address_gives_the_local_table(tmp_path, dask_address):
    serial, api = tmp_path / "serial.csv", tmp_path / "api.csv"
    dk.sweep(sweep_tasks.square, GRID, results=serial, seeds=2, workers=1, progress=False)
    rows = dk.sweep(sweep_tasks.square, GRID, results=api, seeds=2, scheduler=dask_address, progress=False)
    assert len(rows) == 20 and sum(r["status"] == "failed" for r in rows) == 4
    assert all(r["quiet"] for r in rows if r["status"] == "ok")  # points ran with DEMKIT_QUIET
    assert rows_without_wall(api) == rows_without_wall(serial)
    # the same through `demkit sweep --scheduler ADDRESS`
    (tmp_path / "s.toml").write_text('task = "sweep_tasks:square"\nresults = "cli.csv"\nseeds = 2\n'
                                     '[grid]\nx = [-1.0, 0.0, 0.5, 1.5, 3.0]\nk = ["a", "b"]\n')
    done = subprocess.run([sys.executable, "-m", "demkit", "sweep", "s.toml", "--scheduler", dask_address],
                          capture_output=True, text=True, cwd=tmp_path, env=ENV, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "20 points, 4 failed" in done.stdout
    assert rows_without_wall(tmp_path / "cli.csv") == rows_without_wall(serial)


# ---- Parquet -------------------------------------------------------------------------------------
def test_a_parquet_table_equals_the_csv_also_when_resumed(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "t.parquet"
    dk.sweep(sweep_tasks.square, {"x": [-1.0, 2, 0.1]}, results=out, workers=1, progress=False)
    first = read_table(tmp_path / "t.csv")
    assert pq.read_table(out).to_pylist() == first and len(first) == 3
    # resumed with a longer grid: the finished points are kept, the failed and the new ones run
    sweep_tasks.CALLS.clear()
    rows = dk.sweep(sweep_tasks.counted, {"x": [-1.0, 2, 0.1, 7]}, results=out, workers=1, progress=False)
    assert sorted(c["x"] for c in sweep_tasks.CALLS) == [-1.0, 7]
    table = pq.read_table(out)
    assert table.to_pylist() == read_table(tmp_path / "t.csv") == rows and len(rows) == 4
    assert rows[1]["y"] == 4 and rows[2]["y"] == pytest.approx(0.01) and rows[0]["error"].startswith("ValueError")
    types = {f.name: str(f.type) for f in table.schema}
    assert types["x"] == "double" and types["y"] == "double" and types["status"] == "string"
    assert types["quiet"] == "bool" and types["error"] == "string"


def test_parquet_without_pyarrow_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow fails as if not installed
    with pytest.raises(ImportError, match=r"needs pyarrow \(pip install pyarrow\)"):
        dk.sweep(sweep_tasks.square, {"x": [1]}, results=tmp_path / "a.parquet", workers=1)
    assert not (tmp_path / "a.csv").exists()  # refused before anything ran


# ---- quiet points --------------------------------------------------------------------------------
def test_points_run_quietly_and_the_setting_comes_back(tmp_path, monkeypatch):
    monkeypatch.delenv("DEMKIT_QUIET", raising=False)
    for workers in (1, 2):
        rows = dk.sweep(sweep_tasks.square, {"x": [1, 2]}, results=tmp_path / f"q{workers}.csv",
                        workers=workers, progress=False)
        assert [r["quiet"] for r in rows] == [True, True]
    assert "DEMKIT_QUIET" not in os.environ
    monkeypatch.setenv("DEMKIT_QUIET", "0")
    dk.sweep(sweep_tasks.square, {"x": [3]}, results=tmp_path / "q.csv", workers=1, progress=False)
    assert os.environ["DEMKIT_QUIET"] == "0"


# ---- Ctrl-C --------------------------------------------------------------------------------------
NAPS = 'task = "sweep_tasks:nap"\nresults = "nap.csv"\n[grid]\nx = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]\nt = [0.3]\n'


def answer_ctrl_c():
    """In the child before exec: SIGINT back to its default, as in a terminal (a test suite started
    in the background of a shell inherits SIGINT ignored, and Python then never raises KeyboardInterrupt)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def started_points(log):
    return sorted(int(line) for line in log.read_text().split()) if log.exists() else []


@pytest.mark.parametrize("where", [["--workers", "2"], ["--workers", "1"], ["--scheduler", "local", "--workers", "2"]],
                         ids=["processes", "in-process", "dask-local"])
def test_ctrl_c_stops_demkit_sweep_keeps_finished_points_and_a_rerun_finishes_the_rest(tmp_path, where):
    if where[0] == "--scheduler":
        pytest.importorskip("dask.distributed")
    (tmp_path / "nap.toml").write_text(NAPS)
    table = tmp_path / "nap.csv"
    command = [sys.executable, "-m", "demkit", "sweep", "nap.toml", *where]
    # its own session, as a terminal's foreground job: Ctrl-C sends SIGINT to every process of the group
    process = subprocess.Popen(command, cwd=tmp_path, env=dict(ENV, SWEEP_TASKS_LOG=str(tmp_path / "first.log")),
                               start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=answer_ctrl_c)
    try:
        deadline = time.monotonic() + 60
        while not (table.exists() and len(read_table(table)) >= 1):
            assert time.monotonic() < deadline and process.poll() is None, process.communicate()
            time.sleep(0.05)
        os.killpg(process.pid, signal.SIGINT)
        out, err = process.communicate(timeout=30)
    finally:
        stop(process)
    assert process.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    match = re.fullmatch(r"demkit sweep interrupted: (\d+) of 12 points done in nap\.csv; "
                         r"run it again to finish the rest", lines[0])
    assert match, err
    kept = read_table(table)
    assert all(r["status"] == "ok" and r["y"] == 2 * r["x"] for r in kept)
    assert 1 <= len(kept) == int(match[1]) < 12
    deadline = time.monotonic() + 10
    while session_alive(process.pid):  # the workers are gone (a fork server exits once it sees EOF)
        assert time.monotonic() < deadline, f"processes left: {session_alive(process.pid)}"
        time.sleep(0.1)
    if where[0] != "--workers" or where[1] != "2":
        return
    # the rerun runs exactly the points not in the table
    done = subprocess.run(command, cwd=tmp_path, env=dict(ENV, SWEEP_TASKS_LOG=str(tmp_path / "rerun.log")),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert started_points(tmp_path / "rerun.log") == sorted(set(range(12)) - {r["x"] for r in kept})
    assert [(r["x"], r["status"]) for r in read_table(table)] == [(x, "ok") for x in range(12)]
