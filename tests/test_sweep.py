"""dk.sweep: grids, seeds, one tidy table, resuming, failing points, local processes vs Dask, sweep files."""
import csv
import functools
import importlib
import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import demkit as dk

sweep_module = importlib.import_module("demkit.sweep")  # dk.sweep is the function
from demkit.sweep import expand, point_key, read_sweep_file, read_table

CALLS = []


def square(point):
    """Tiny task: x^2 + seed, fails for x < 0."""
    x = point["x"]
    if x < 0:
        raise ValueError(f"negative x = {x}")
    return {"y": x * x + point.get("seed", 0), "label": f"x={x}"}


def dies(point):
    """Tiny task whose process dies at x = 2 (not an exception: the worker is gone)."""
    if point["x"] == 2:
        os._exit(3)
    return {"y": point["x"]}


def counted(point):
    CALLS.append(dict(point))
    return square(point)


def rows_without_wall(path):
    with open(path, newline="") as fh:
        return [{k: v for k, v in r.items() if k != "wall_s"} for r in csv.DictReader(fh)]


def test_grid_is_the_cartesian_product_with_seeds():
    points = expand({"a": [1, 2], "b": ["u", "v", "w"]}, seeds=2)
    assert len(points) == 12
    assert points[0] == {"a": 1, "b": "u", "seed": 0} and points[1] == {"a": 1, "b": "u", "seed": 1}
    assert points[-1] == {"a": 2, "b": "w", "seed": 1}
    assert expand([{"a": 1}, {"a": 5}], seeds=[7]) == [{"a": 1, "seed": 7}, {"a": 5, "seed": 7}]
    with pytest.raises(ValueError, match="must be a list"):
        expand({"a": 3})
    with pytest.raises(ValueError, match="empty list"):
        expand({"a": []})


def test_keys_match_the_same_number_written_differently():
    names = ["x", "s"]
    assert point_key({"x": 1, "s": "a"}, names) == point_key({"x": 1.0, "s": "a"}, names)
    assert point_key({"x": 0.1 + 0.2, "s": "a"}, names) == point_key({"x": 0.3, "s": "a"}, names)
    assert point_key({"x": 0.3, "s": "a"}, names) != point_key({"x": 0.3000001, "s": "a"}, names)
    # read back from the table's text
    assert point_key({"x": "0.30000000000000004", "s": "a"}, names) == point_key({"x": 0.3, "s": "a"}, names)


def test_table_has_one_row_per_point_and_failures_are_recorded(tmp_path):
    out = tmp_path / "t.csv"
    rows = dk.sweep(square, {"x": [-1.0, 0.5, 2]}, results=out, seeds=[0, 10], workers=1, progress=False)
    assert [(r["x"], r["seed"]) for r in rows] == [(-1.0, 0), (-1.0, 10), (0.5, 0), (0.5, 10), (2, 0), (2, 10)]
    header = next(csv.reader(open(out)))
    assert header[:5] == ["x", "seed", "status", "error", "wall_s"] and set(header[5:]) == {"y", "label"}
    failed = [r for r in rows if r["status"] == "failed"]
    assert len(failed) == 2 and all(r["error"] == "ValueError: negative x = -1.0" and r["y"] is None
                                    for r in failed)
    ok = [r for r in rows if r["status"] == "ok"]
    assert [r["y"] for r in ok] == [0.25, 10.25, 4, 14] and all(r["error"] is None for r in ok)
    assert all(r["wall_s"] >= 0 for r in rows)


def test_the_default_workers_are_the_cpus_this_process_may_use(tmp_path, monkeypatch):
    """Under a one-CPU affinity (taskset, a batch system) the default is one worker, not the machine's
    cores."""
    sweep_module = importlib.import_module("demkit.sweep")
    used = []
    real = sweep_module._local_rows
    monkeypatch.setattr(sweep_module, "_local_rows", lambda task, todo, names, w: used.append(w) or real(task, todo, names, 1))
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    dk.sweep(square, {"x": [1.0, 2.0, 3.0]}, results=tmp_path / "a.csv", progress=False)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2}, raising=False)
    dk.sweep(square, {"x": [1.0, 2.0, 3.0, 4.0]}, results=tmp_path / "b.csv", progress=False)
    assert used == [1, 3] and sweep_module.usable_cpus() == 3


def test_resume_skips_finished_points_and_reruns_failed_ones(tmp_path):
    out = tmp_path / "t.csv"
    CALLS.clear()
    dk.sweep(counted, {"x": [-1, 1, 2]}, results=out, workers=1, progress=False)
    assert len(CALLS) == 3
    CALLS.clear()
    # same points written as floats, one new point: only the new and the failed point run
    rows = dk.sweep(counted, {"x": [-1.0, 1.0, 2.0, 3.0]}, results=out, workers=1, progress=False)
    assert sorted(c["x"] for c in CALLS) == [-1.0, 3.0]
    assert [r["x"] for r in rows] == [-1, 1, 2, 3.0] and len(read_table(out)) == 4
    # an interrupted sweep: finished rows are in the file as soon as they finish
    CALLS.clear()
    dk.sweep(counted, {"x": [1, 2, 3]}, results=out, workers=1, progress=False)
    assert CALLS == []


def test_arrays_and_long_cells_round_trip(tmp_path):
    import numpy as np

    def series(point):
        return {"s": np.linspace(0, 1, 30001) * point["x"], "n": np.int64(3), "f": np.float64(1 / 3)}
    rows = dk.sweep(series, {"x": [0.1]}, results=tmp_path / "s.csv", workers=1, progress=False)
    assert rows[0]["n"] == 3 and rows[0]["f"] == 1 / 3
    assert np.array_equal(json.loads(rows[0]["s"]), np.linspace(0, 1, 30001) * 0.1)  # exact


def test_rows_are_appended_as_points_finish(tmp_path):
    out = tmp_path / "t.csv"

    seen = []
    table = sweep_module._Table(out, ["x"])
    table.add(sweep_module.run_point(square, {"x": 2}))
    seen.append(len(read_table(out)))
    table.add(sweep_module.run_point(square, {"x": -2}))
    seen.append(len(read_table(out)))
    assert seen == [1, 2]
    assert read_table(out)[1]["error"].startswith("ValueError")


def test_bad_tasks_and_arguments(tmp_path):
    def returns_a_number(point):
        return 3.0
    rows = dk.sweep(returns_a_number, {"x": [1]}, results=tmp_path / "a.csv", workers=1, progress=False)
    assert rows[0]["status"] == "failed" and "must return a dict" in rows[0]["error"]
    def echoes(point):
        # x: an echo (dropped); z: another point's parameter (fails the first point)
        return {"x": point["x"], "z": 1.0} if "x" in point else {"z": 5.0, "w": 1}
    rows = dk.sweep(echoes, [{"x": 1}, {"z": 2}], results=tmp_path / "e.csv", workers=1, progress=False)
    assert rows[0]["status"] == "failed" and "parameter name" in rows[0]["error"]
    assert rows[1]["status"] == "ok" and rows[1]["z"] == 2 and rows[1]["x"] is None and rows[1]["w"] == 1
    with pytest.raises(ValueError, match="repeat"):
        dk.sweep(square, [{"x": 1}, {"x": 1.0}], results=tmp_path / "b.csv", workers=1)
    with pytest.raises(ValueError, match="another sweep"):
        dk.sweep(square, {"z": [1]}, results=tmp_path / "a.csv", workers=1)
    with pytest.raises(ValueError, match="scheduler must be"):
        dk.sweep(square, {"x": [1]}, results=tmp_path / "c.csv", scheduler="nowhere")


def test_local_processes_and_dask_local_cluster_give_the_same_table(tmp_path):
    pytest.importorskip("dask.distributed")
    grid = {"x": [-1.0, 0.0, 0.5, 1.5, 3.0], "k": ["a", "b"]}
    serial = tmp_path / "serial.csv"
    local = tmp_path / "local.csv"
    dask = tmp_path / "dask.csv"
    dk.sweep(square, grid, results=serial, seeds=2, workers=1, progress=False)
    dk.sweep(square, grid, results=local, seeds=2, workers=2, progress=False)
    dk.sweep(square, grid, results=dask, seeds=2, workers=2, scheduler="local", progress=False)
    assert rows_without_wall(local) == rows_without_wall(serial)
    assert rows_without_wall(dask) == rows_without_wall(serial)
    assert len(rows_without_wall(dask)) == 20


SWEEP_FILE = textwrap.dedent("""
    scene = "collision.toml"
    observables = ["outcome", "final_spin", "sim_time"]
    seeds = 2
    seed_key = "build.seed"
    results = "out/map.csv"
    workers = 3

    [grid]
    particles.speed = [0.01, 0.02]
    "interactions.0.prefactor" = [0.5]
    b = {start = 0, stop = 1, num = 5}
    v = {start = 1e-3, stop = 1e-1, num = 3, log = true}
""")


def test_sweep_file_parsing(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SWEEP_FILE)
    spec = read_sweep_file(path)
    assert spec["parameters"] == {"particles.speed": [0.01, 0.02], "interactions.0.prefactor": [0.5],
                                  "b": [0.0, 0.25, 0.5, 0.75, 1.0], "v": [0.001, 0.01, 0.1]}
    assert spec["seeds"] == 2 and spec["workers"] == 3 and spec["scheduler"] is None
    assert spec["results"] == tmp_path / "out" / "map.csv"
    task = spec["task"]
    assert isinstance(task, functools.partial) and task.func is sweep_module.run_scene_point
    assert task.keywords == {"scene": str((tmp_path / "collision.toml").resolve()),
                             "observables": ("outcome", "final_spin", "sim_time"), "seed_key": "build.seed"}
    path.write_text('task = "tests_absent:nothing"\n[[points]]\na.b = 1\n[[points]]\na.b = 2\n')
    with pytest.raises(ValueError, match="cannot import task"):
        read_sweep_file(path)
    path.write_text('task = "math:hypot"\n[[points]]\na.b = 1\nc = [1, 2]\n[[points]]\na.b = 2\n')
    spec = read_sweep_file(path)
    assert spec["task"] is math.hypot and spec["parameters"] == [{"a.b": 1, "c": [1, 2]}, {"a.b": 2}]
    assert spec["results"] == tmp_path / "s.csv"
    for text, message in [('scene = "a.toml"\n', "grid"), ('[grid]\nx = [1]\n', "exactly one of scene"),
                          ('task = "math:hypot"\n[grid]\nx = 1\n', "must be a list"),
                          ('scene = "a.toml"\nobservables = ["colour"]\n[grid]\nx = [1]\n', "unknown observable"),
                          ('scene = "a.toml"\nsteps = 3\n[grid]\nx = [1]\n', "unknown setting"),
                          ('scene = "a.toml"\nworkers = 0\n[grid]\nx = [1]\n', "workers"),
                          ('task = "math:hypot"\n[grid]\nx = {start = 0, stop = 1}\n', "a range needs"),
                          ('scene = \n', "not valid TOML")]:
        path.write_text(text)
        with pytest.raises(ValueError, match=message):
            read_sweep_file(path)


def test_observables_of_a_trajectory():
    setup = dk.two_magnets.TwoMagnets(2.0, speed=2e-2, x0=16.0)
    fate, trajectory = setup.fate()
    out = sweep_module.observe(["outcome", "sim_time", "contacts", "energy_drift", "kinetic_energy"],
                               None, trajectory)
    assert out["outcome"] == fate and out["sim_time"] == trajectory.time[-1]
    r = math.dist(trajectory.position[-1, 1], trajectory.position[-1, 0])
    assert out["contacts"] == int(r <= 2 * setup.radius)
    assert abs(out["energy_drift"]) < 1e-2
    e = trajectory.energy
    assert out["kinetic_energy"] == pytest.approx(e["kinetic"][-1] + e["rotational"][-1])


def test_contacts_are_counted_across_periodic_faces():
    """Two spheres touching through the x faces of a periodic box (and a third apart): one contact."""
    box = dk.Box([10.0, 10.0, 10.0], periodic=[True, False, False])
    p = dk.Particles(position=[[0.3, 5, 5], [9.4, 5, 5], [5, 5, 5]], radius=0.5)
    trajectory = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(100.0)], box=box), dk.VelocityVerlet(1e-3)).run(2e-3)
    assert sweep_module.observe(["contacts"], None, trajectory) == {"contacts": 1}


def test_an_observable_that_cannot_be_measured_keeps_the_others(tmp_path):
    """A task returns an exception for one observable: that cell is empty, its error is in
    <name>_error, the point is 'ok' with its other observables, and the summary counts it."""
    import sweep_tasks
    out = tmp_path / "p.csv"
    rows = dk.sweep(sweep_tasks.partly, {"x": [-2.0, -1.0, 0.0, 4.0]}, results=out, workers=1, progress=False)
    assert [r["status"] for r in rows] == ["failed", "ok", "ok", "ok"]
    assert [r["y"] for r in rows] == [None, -2.0, 0.0, 8.0]
    assert [r["spin"] for r in rows] == [None, None, None, 2.0]
    assert [r["spin_error"] for r in rows] == [None, "ValueError: no spin at x = -1.0",
                                               "ValueError: no spin at x = 0.0", None]
    text = sweep_module.summary(rows, out)
    assert text.splitlines() == [
        f"4 points, 1 failed, 2 with observables not measured: {out}",
        "  failed in 1 point; first: ValueError: x = -2.0 is out of range",
        "  spin not measured in 2 points (2 different messages); see column spin_error; "
        "first: ValueError: no spin at x = -1.0"]
    # done points are not rerun: the error is the point's measurement, not a failure
    sweep_tasks.CALLS.clear()
    rows = dk.sweep(sweep_tasks.partly, {"x": [-1.0, 0.0, 4.0]}, results=out, workers=1, progress=False)
    assert sweep_tasks.CALLS == [] and rows[0]["spin_error"] == "ValueError: no spin at x = -1.0"
    # a numeric <name>_error of a task's own (an uncertainty) is not an error
    assert sweep_module.observable_errors([{"w": 1.0, "w_error": 0.1}, {"w": None, "w_error": "E: x"}]) == {
        "w": ["E: x"]}
    row = sweep_module.run_point(lambda p: {"a": ValueError("x"), "a_error": 1}, {"x": 1})
    assert row["status"] == "failed" and "returned 'a_error' and an error for 'a'" in row["error"]


def test_demkit_sweep_command_runs_a_sweep_file(tmp_path):
    """`demkit sweep`: failed points and observables not measured are recorded, and the terminal says
    which, how often and why."""
    (tmp_path / "s.toml").write_text('task = "sweep_tasks:partly"\nworkers = 1\n[grid]\nx = [-2.0, 0.0, 1.0]\n')
    root = Path(dk.__file__).resolve().parents[1]  # this checkout's demkit, not an installed one
    done = subprocess.run([sys.executable, "-m", "demkit", "sweep", "s.toml", "--workers", "1"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120,
                          env=dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), str(root / "tests")])))
    assert done.returncode == 0, done.stderr
    rows = read_table(tmp_path / "s.csv")
    assert [r["status"] for r in rows] == ["failed", "ok", "ok"] and rows[1]["y"] == 0.0
    assert done.stdout.splitlines() == [
        "3 points, 1 failed, 1 with observables not measured: s.csv",
        "  failed in 1 point; first: ValueError: x = -2.0 is out of range",
        "  spin not measured in 1 point; see column spin_error; first: ValueError: no spin at x = 0.0"]


def test_a_clear_error_without_dask(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask", None)  # import dask fails as if not installed
    with pytest.raises(ImportError, match=r"demkit\[dask\]"):
        dk.sweep(square, {"x": [1]}, results=tmp_path / "a.csv", scheduler="local", progress=False)


def test_a_worker_that_dies_is_recorded_as_failed(tmp_path):
    # two points so that a process pool runs them (one point would run in this process)
    rows = dk.sweep(dies, {"x": [1, 2]}, results=tmp_path / "d.csv", workers=2, progress=False)
    assert rows[1]["status"] == "failed" and "BrokenProcessPool" in rows[1]["error"]
    assert rows[0]["status"] == "ok" or "BrokenProcessPool" in rows[0]["error"]  # the pool may take it along


def test_a_scene_file_sweep_runs_each_point_with_its_overrides_and_writes_no_scene_outputs(tmp_path):
    """The paper's collision as a scene file, swept over b/R: a grazing impact sticks, a wide one misses
    (the capture boundary at the paper's speed is b/R = 5.5-5.75, docs/outcome_map.md), and a point
    with an impossible value is recorded as failed while the others go on. final_spin cannot be
    measured on a miss: its error is recorded and the miss's outcome kept."""
    scene = Path(__file__).resolve().parents[1] / "examples" / "two_magnets" / "collision.toml"
    (tmp_path / "collision.toml").write_text(scene.read_text())
    (tmp_path / "sweep.toml").write_text(textwrap.dedent("""
        scene = "collision.toml"
        observables = ["outcome", "final_spin", "sim_time"]
        workers = 1
        [grid]
        "particles.build.b_over_R" = [2.0, 12.0, -1.0]
        "run.duration" = [30000.0]
    """))
    rows = dk.sweep_file(tmp_path / "sweep.toml")
    by_b = {float(r["particles.build.b_over_R"]): r for r in rows}
    assert by_b[2.0]["outcome"] == "stick" and by_b[12.0]["outcome"] == "miss"
    assert float(by_b[2.0]["sim_time"]) == pytest.approx(30000.0)
    assert by_b[-1.0]["status"] != "ok" and "b_over_R" in by_b[-1.0]["error"]
    miss = by_b[12.0]
    assert miss["status"] == "ok" and miss["final_spin"] is None and miss["final_spin_sigma"] is None
    assert miss["final_spin_error"].startswith("ValueError: ") and float(miss["sim_time"]) == pytest.approx(30000.0)
    assert "final_spin not measured in" in sweep_module.summary(rows)
    assert not (tmp_path / "output").exists()  # the scene file's [outputs] were not written
