"""Tasks of the sweep tests that run in other processes (Dask workers, `demkit sweep` subprocesses):
importable as `sweep_tasks` with tests/ on the path."""
import os
import time

from demkit.progress import quiet

CALLS = []


def square(point):
    """x^2 + seed, and whether the point runs quietly (DEMKIT_QUIET); fails for x < 0."""
    x = point["x"]
    if x < 0:
        raise ValueError(f"negative x = {x}")
    return {"y": x * x + point.get("seed", 0), "label": f"x={x}", "quiet": quiet()}


def counted(point):
    """square, noting the point in CALLS (in this process: workers=1)."""
    CALLS.append(dict(point))
    return square(point)


def nap(point):
    """Sleeps point['t'] seconds; notes the point's x in the file $SWEEP_TASKS_LOG (a line per start)."""
    log = os.environ.get("SWEEP_TASKS_LOG")
    if log:
        with open(log, "a") as fh:
            fh.write(f"{point['x']}\n")
    time.sleep(point["t"])
    return {"y": 2 * point["x"]}


def partly(point):
    """y = 2x, and 'spin' measured only for x > 0 (else the exception that measuring raised); fails
    for x < -1; notes the point in CALLS."""
    CALLS.append(dict(point))
    if point["x"] < -1:
        raise ValueError(f"x = {point['x']} is out of range")
    spin = point["x"] ** 0.5 if point["x"] > 0 else ValueError(f"no spin at x = {point['x']}")
    return {"y": 2 * point["x"], "spin": spin}
