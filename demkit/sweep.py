"""Parameter sweeps: run a task over a grid or list of points, on local processes or a Dask cluster,
into one tidy, resumable results table.

    rows = dk.sweep(task, {"b_over_R": [1, 2, 3], "speed": [5e-3, 1e-2]}, results="map.csv")

``task(point) -> dict`` takes one point (a dict of parameter values, plus ``seed`` when seeds are
given) and returns its observables (a dict of numbers or strings). It must be picklable: a function
defined at the top level of a module (or a :func:`functools.partial` of one).

The table (CSV) has one row per point: the parameters (and ``seed``), ``status`` ('ok' or 'failed'),
``error`` (empty when fine, else 'Type: message'), ``wall_s`` (seconds the task took) and the
observables. An observable that could not be measured (the task returned an exception for it; scene
sweeps do so for each observable that raises) leaves its cell empty with 'Type: message' in
``<name>_error``, and the point is still 'ok': the others are kept. :func:`summary` counts both.
Rows are appended (and flushed) as points finish, so an interrupted sweep keeps what it finished;
at the end the table is rewritten in the order of the points. Running the same sweep again
skips the points that already have an 'ok' row (same parameter values, compared at 12 significant
digits) and reruns the failed ones. A failing point is recorded with its error; the others go on.
Ctrl-C stops the workers at once and raises KeyboardInterrupt saying how many points are done.
Points run with DEMKIT_QUIET=1 (:func:`quietly`): no progress bars or compile notices of their own.

Where: ``workers`` local processes (default: the machine's cores; 1 runs in this process), or Dask
(``pip install "demkit[dask]"``): ``scheduler="local"`` starts a ``dask.distributed.LocalCluster`` of
``workers`` processes, ``scheduler="tcp://host:8786"`` uses that cluster, and a
``dask.distributed.Client`` is used as it is. Sweep files (TOML) and ``demkit sweep``: :func:`sweep_file`.
See docs/sweeps.md.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import csv
import functools
import importlib
import io
import itertools
import json
import logging
import multiprocessing as mp
import numbers
import os
import signal
import sys
import threading
import time
import tomllib
from pathlib import Path

import numpy as np

from .progress import Progress
from .scene_observables import COLUMNS, OBSERVABLES, observable, observe, run_scene_point  # noqa: F401 (demkit.sweep.observable, ... as before)


#: columns every table has, after the parameters (and seed)
STATUS_COLUMNS = ("status", "error", "wall_s")
#: significant digits at which two numeric parameter values count as the same point
KEY_DIGITS = 12
# cells may hold long JSON (a time series); the csv module's default limit is 128 kB
csv.field_size_limit(min(sys.maxsize, 2 ** 31 - 1))


# ---- points --------------------------------------------------------------------------------------
def expand(parameters, seeds=None):
    """The list of points (dicts): a grid ``{name: [values]}`` gives the Cartesian product (the last
    name varying fastest), a list of dicts is taken as it is; ``seeds`` (a count n -> 0..n-1, or a
    list) repeats every point once per seed with a ``seed`` entry."""
    if isinstance(parameters, dict):
        if not parameters:
            raise ValueError("the grid is empty: give {name: [values, ...]}")
        names = list(parameters)
        values = []
        for name in names:
            v = parameters[name]
            if isinstance(v, (str, bytes)) or not hasattr(v, "__iter__"):
                raise ValueError(f"grid values of {name!r} must be a list, got {v!r}; "
                                 f"write [{v!r}] for a single value")
            v = list(v)
            if not v:
                raise ValueError(f"grid values of {name!r} are an empty list")
            values.append(v)
        points = [dict(zip(names, combo)) for combo in itertools.product(*values)]
    else:
        points = [dict(p) for p in parameters]
        if not points:
            raise ValueError("no points: give a grid {name: [values]} or a non-empty list of dicts")
    if seeds is not None:
        if isinstance(seeds, numbers.Integral) and not isinstance(seeds, bool):
            if seeds < 1:
                raise ValueError(f"seeds must be a positive count or a list, got {seeds}")
            seeds = range(int(seeds))
        seeds = list(seeds)
        if any("seed" in p for p in points):
            raise ValueError("points already have a 'seed' parameter: drop it or do not pass seeds=")
        points = [dict(p, seed=s) for p in points for s in seeds]
    return points


def cell(value):
    """The CSV text of a value: floats in full (repr), integers and strings as they are, None as
    empty, anything else (lists, arrays) as JSON."""
    if value is None:
        return ""
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return repr(float(value))
    if isinstance(value, str):
        return value
    return json.dumps(value, default=_plain)


def _plain(value):
    """JSON of numpy values (arrays as lists; floats stay exact: JSON writes them with repr)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot store a {type(value).__name__} in a table cell")


def key_part(text):
    """One parameter's part of a point's key, from its CSV text: numbers at :data:`KEY_DIGITS`
    significant digits (so 1, 1.0 and 0.30000000000000004 / 0.3 match), other text as it is."""
    try:
        return format(float(text), f".{KEY_DIGITS}g")
    except ValueError:
        return text


def point_key(point, names):
    return tuple(key_part(cell(point.get(n))) for n in names)


def parse(text):
    """A table cell back to a value: int, float, True/False, None (empty) or the text."""
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def read_table(path):
    """The rows of a results table as dicts of values (numbers parsed, empty cells None)."""
    with open(path, newline="") as fh:
        return [{k: parse(v) for k, v in row.items()} for row in csv.DictReader(fh)]


# ---- running one point ----------------------------------------------------------------------------
_QUIET = {"lock": threading.Lock(), "depth": 0, "saved": None}


@contextlib.contextmanager
def quietly():
    """Points run with ``DEMKIT_QUIET=1``: no automatic progress bars or compile notices of their
    own (a worker's would be drawn over the user's terminal; the sweep's bar is the progress).
    Thread-safe (a Dask worker may run several points in threads); the old value comes back after."""
    q = _QUIET
    with q["lock"]:
        if q["depth"] == 0:
            q["saved"] = os.environ.get("DEMKIT_QUIET")
            os.environ["DEMKIT_QUIET"] = "1"
        q["depth"] += 1
    try:
        yield
    finally:
        with q["lock"]:
            q["depth"] -= 1
            if q["depth"] == 0:
                if q["saved"] is None:
                    os.environ.pop("DEMKIT_QUIET", None)
                else:
                    os.environ["DEMKIT_QUIET"] = q["saved"]


def run_point(task, point, names=()):
    """``task(point)`` -> the point's row (dict of cells); an exception becomes a 'failed' row.
    The task runs :func:`quietly`.

    Entries of the task's result named like the point's parameters are dropped (echoes); named like
    another parameter of the sweep (``names``) they fail the point (they would spoil its key).
    An entry whose value is an exception is an observable that could not be measured: its cell
    stays empty and ``<name>_error`` holds 'Type: message' (the point is still 'ok')."""
    start = time.perf_counter()
    try:
        with quietly():
            out = task(dict(point))
        if not isinstance(out, dict):
            raise TypeError(f"the task must return a dict of observables, got {type(out).__name__}")
        clash = sorted(set(out) & set(STATUS_COLUMNS))
        if clash:
            raise ValueError(f"the task returned reserved column(s) {clash}: rename them")
        clash = sorted((set(out) & set(names)) - set(point))
        if clash:
            raise ValueError(f"the task returned {clash}, parameter name(s) of this sweep: rename them")
        row = {}
        for name, value in out.items():
            if name in point:
                continue
            if isinstance(value, BaseException):
                if error_column(name) in out:
                    raise ValueError(f"the task returned {error_column(name)!r} and an error for "
                                     f"{name!r}, whose message goes there: rename it")
                row[name], row[error_column(name)] = "", _error_text(value)
            else:
                row[name] = cell(value)
        row.update(status="ok", error="")
    except Exception as exc:  # noqa: BLE001 (recorded in the table; the sweep goes on)
        row = {"status": "failed", "error": _error_text(exc)}
    row["wall_s"] = cell(time.perf_counter() - start)
    row.update({k: cell(v) for k, v in point.items()})
    return row


def error_column(name):
    """The column holding the error of observable ``name`` when it could not be measured."""
    return f"{name}_error"


def observable_errors(rows):
    """{observable: [error text of each row where it failed]} over ``rows`` (from :func:`read_table`
    or :func:`sweep`): rows whose ``<name>`` is empty and ``<name>_error`` holds text (a numeric
    ``<name>_error`` of a task's own, an uncertainty say, is not an error)."""
    columns = dict.fromkeys(c for r in rows for c in r)
    errors = {}
    for name in columns:
        if error_column(name) in columns:
            texts = [r[error_column(name)] for r in rows
                     if r.get(name) in (None, "") and isinstance(r.get(error_column(name)), str)
                     and r[error_column(name)]]
            if texts:
                errors[name] = texts
    return errors


def summary(rows, results=None):
    """The terminal's account of a sweep's rows: points done and failed, then each observable that
    could not be measured and each cause of failure, with how often and the first message."""
    failed = [r for r in rows if r.get("status") != "ok"]
    errors = observable_errors(rows)
    partly = sum(any(r.get(name) in (None, "") and isinstance(r.get(error_column(name)), str)
                     and r[error_column(name)] for name in errors) for r in rows if r.get("status") == "ok")
    head = f"{len(rows)} points, {len(failed)} failed" + (f", {partly} with observables not measured" if partly else "")
    lines = [head + (f": {results}" if results is not None else "")]
    if failed:
        lines.append(_counted("failed", [str(r.get("error") or "no message") for r in failed]))
    for name, texts in errors.items():
        lines.append(_counted(f"{name} not measured", texts, f"; see column {error_column(name)}"))
    return "\n".join(lines)


def _counted(what, texts, tail=""):
    """'  what in n points: first message (k different messages)...' for :func:`summary`."""
    n, kinds = len(texts), len(set(texts))
    more = f" ({kinds} different messages)" if kinds > 1 else ""
    return f"  {what} in {n} point{'s' if n != 1 else ''}{more}{tail}; first: {texts[0]}"


# ---- the table -----------------------------------------------------------------------------------
class _Table:
    """A CSV table appended row by row (flushed and synced each time); rewritten atomically (a
    temporary file renamed over it) when a new column appears and at the end. A row cut short by a
    crash while it was appended is dropped when the table is read again (the point runs again)."""

    def __init__(self, path, names):
        from .outputs import check_writable
        self.path = Path(path)
        self.names = list(names)
        self.rows, self.columns = [], self.names + list(STATUS_COLUMNS)
        check_writable(self.path, "sweep table")
        if self.path.exists() and self.path.stat().st_size > 0:
            with open(self.path, newline="") as fh:
                text = fh.read()
            reader = csv.DictReader(io.StringIO(text))
            old = list(reader.fieldnames or [])
            self.rows = list(reader)
            if self.rows and (not text.endswith("\n") or None in self.rows[-1].values()):
                cut = self.rows.pop()  # the row being appended when the last sweep stopped
                print(f"{self.path}: its last row was cut short (the sweep stopped while writing it) and is "
                      f"dropped: {', '.join(f'{k}={v}' for k, v in cut.items() if v)[:200]}; that point runs "
                      f"again", file=sys.stderr)
            missing = [n for n in self.names if n not in old]
            if missing:
                raise ValueError(f"{self.path} has no column(s) {missing} for this sweep's parameters "
                                 f"(it was written by another sweep): choose another results file")
            self.columns = old + [c for c in self.columns if c not in old]
        self._rewrite()

    def done(self):
        return {point_key(r, self.names) for r in self.rows if r.get("status") == "ok"}

    def _rewrite(self):
        from .outputs import write_atomically
        self.path.parent.mkdir(parents=True, exist_ok=True)

        def write(tmp):
            with open(tmp, "w", newline="") as fh:
                w = csv.DictWriter(fh, self.columns, restval="")
                w.writeheader()
                w.writerows(self.rows)
        try:
            write_atomically(self.path, write)
        except OSError as err:
            raise OSError(f"could not rewrite the sweep table {self.path} ({err.strerror or err}): it holds the "
                          f"rows written before; run the sweep again to finish the rest") from err

    def add(self, row):
        self.rows.append(row)
        new = [c for c in row if c not in self.columns]
        if new:
            self.columns += new
            self._rewrite()
            return
        try:
            with open(self.path, "a", newline="") as fh:
                csv.DictWriter(fh, self.columns, restval="").writerow(row)
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as err:
            raise OSError(f"could not add a row to the sweep table {self.path} ({err.strerror or err}): the "
                          f"{len(self.rows) - 1} rows before it are kept; run the sweep again to finish the "
                          f"rest") from err

    def finish(self, points):
        """Rewrite in the points' order: one row per point (its latest), then rows of other sweeps."""
        latest = {}
        for r in self.rows:
            k = point_key(r, self.names)
            if k not in latest or latest[k].get("status") != "ok" or r.get("status") == "ok":
                latest[k] = r
        order = []
        for p in points:
            k = point_key(p, self.names)
            if k in latest:
                order.append(latest.pop(k))
        self.rows = order + [r for r in latest.values()]
        # observables' columns in order of first appearance in this order (not of completion)
        fixed = self.names + list(STATUS_COLUMNS)
        seen = dict.fromkeys(c for r in self.rows for c in r if c not in fixed)
        self.columns = fixed + list(seen) + [c for c in self.columns if c not in fixed and c not in seen]
        self._rewrite()


# ---- executors: generators of finished rows -----------------------------------------------------
def _error_text(exc):
    """A failed point's error cell: 'Type: message' on one line."""
    return f"{type(exc).__name__}: {exc}".replace("\n", " ")


def _lost_row(exc, point):
    """The row of a point whose worker died (a broken pool, a killed Dask worker)."""
    return {"status": "failed", "error": _error_text(exc), "wall_s": "",
            **{k: cell(v) for k, v in point.items()}}


def _ignore_interrupt():
    """Pool workers leave Ctrl-C (SIGINT, sent to the whole terminal's process group) to the sweep,
    which stops them; otherwise each would print a traceback."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextlib.contextmanager
def _children_ignore_interrupt():
    """Processes started (spawned) inside this scope inherit an ignored SIGINT, as pool workers do with
    :func:`_ignore_interrupt`: Ctrl-C goes to the sweep, which stops them (Dask's worker processes
    would each print a traceback). Only the main thread can set signal handlers."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _local_rows(task, todo, names, workers):
    """Rows of ``todo`` as they finish: in this process (workers = 1) or a pool of processes.
    Interrupted (Ctrl-C, or the consumer stops), the pool's processes are terminated at once."""
    if workers == 1:
        for point in todo:
            yield run_point(task, point, names)
        return
    # not "fork": once a parallel numba kernel ran, GNU OpenMP makes fork() unsafe; a fork server starts clean
    methods = mp.get_all_start_methods()
    context = mp.get_context("forkserver" if "forkserver" in methods else "spawn")
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_ignore_interrupt)
    try:
        futures = {pool.submit(run_point, task, p, names): p for p in todo}
        for future in cf.as_completed(futures):
            try:
                row = future.result()
            except Exception as exc:  # noqa: BLE001 (the worker died)
                row = _lost_row(exc, futures[future])
            yield row
    except BaseException:  # KeyboardInterrupt, GeneratorExit: stop the running points now
        _terminate(pool)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _terminate(pool):
    """Terminate a ProcessPoolExecutor's worker processes (Python 3.14 has pool.terminate_workers)."""
    if hasattr(pool, "terminate_workers"):
        pool.terminate_workers()
        return
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            process.terminate()
        except (OSError, ValueError, AttributeError):
            pass


def _dask_rows(task, todo, names, workers, scheduler):
    """Rows of ``todo`` as they finish on a Dask cluster; interrupted, the points are cancelled and a
    LocalCluster is closed."""
    client, close = _dask_client(scheduler, workers)
    futures = {}
    try:
        from dask.distributed import as_completed
        futures = {client.submit(run_point, task, p, names, pure=False): p for p in todo}
        for future in as_completed(list(futures)):
            try:
                row = future.result()
            except Exception as exc:  # noqa: BLE001 (the worker died)
                row = _lost_row(exc, futures[future])
            yield row
    except BaseException:
        try:
            if scheduler != "local":  # a LocalCluster is closed with its running points below
                client.cancel(list(futures))
        except Exception:  # noqa: BLE001 (closing anyway)
            pass
        raise
    finally:
        if close is not None:
            close()


def _dask_client(scheduler, workers):
    try:
        from dask import distributed
    except ImportError:
        raise ImportError('a Dask sweep needs dask.distributed: pip install "demkit[dask]" '
                          '(or leave scheduler=None for local processes)') from None
    if hasattr(scheduler, "submit"):  # a Client already
        return scheduler, None
    if scheduler == "local":
        with _children_ignore_interrupt():
            # no dashboard; its HTTP server (health checks) on a free port, not 8787 that may be taken
            # silence_logs: closed mid-sweep (Ctrl-C), its workers would log their lost scheduler as
            # errors with tracebacks on the user's terminal; a point's own failure comes back in its row
            cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                               silence_logs=logging.CRITICAL,
                                               dashboard_address=None, scheduler_kwargs={"dashboard_address": ":0"})
        client = distributed.Client(cluster)

        def close():
            client.close()
            cluster.close()
        return client, close
    if not isinstance(scheduler, str) or "://" not in scheduler:
        raise ValueError(f"scheduler must be 'local', an address such as 'tcp://host:8786' or a "
                         f"dask.distributed.Client, got {scheduler!r}")
    client = distributed.Client(scheduler)
    return client, client.close


# ---- the sweep -----------------------------------------------------------------------------------

def usable_cpus():
    """The CPUs this process may run on (its affinity, as set by taskset, cgroups or a batch system;
    os.cpu_count() where the platform cannot say)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1

def sweep(task, parameters, results="sweep.csv", seeds=None, workers=None, scheduler=None, progress=None):
    """Run ``task(point)`` for every point not finished in ``results``; returns the table's rows
    (:func:`read_table`) in the points' order.

    parameters : grid {name: [values]} (Cartesian product) or a list of point dicts.
    seeds : a count n (seeds 0..n-1) or a list; adds a ``seed`` parameter.
    results : the CSV table (created, or resumed when it exists). A copy as Parquet is written
        next to it if the name ends in '.parquet' (needs pyarrow; the CSV stays the working table).
    workers : processes (default: the cores this process may use; 1: in this process) or Dask workers of a
        LocalCluster. scheduler : None (local processes), 'local' (Dask LocalCluster), an address
        'tcp://host:8786', or a dask.distributed.Client.
    progress : a bar over the points (:class:`demkit.progress.Progress`): None on a terminal for a
        sweep that looks longer than a moment (not with DEMKIT_QUIET), True always, False never;
        or a Progress of the caller's, over several steps of work: the sweep counts its points on
        from the bar's ``done`` (those already in the table at once) and leaves it open.

    Ctrl-C (KeyboardInterrupt): running points are abandoned (worker processes terminated, a
    LocalCluster closed, queued Dask points cancelled), finished ones stay in the table, and a
    KeyboardInterrupt says how many are done; the same call again finishes the rest.
    """
    if not callable(task):
        raise ValueError(f"task must be a function of one point (a dict), got {task!r}")
    points = expand(parameters, seeds)
    names = list(dict.fromkeys(n for p in points for n in p))
    keys = [point_key(p, names) for p in points]
    if len(set(keys)) != len(keys):
        raise ValueError("some points repeat (same parameter values): each point must be distinct")
    results = Path(results)
    parquet = None
    if results.suffix == ".parquet":
        parquet, results = results, results.with_suffix(".csv")
        _require_pyarrow()
        from .outputs import check_writable
        check_writable(parquet, "sweep table")
    table = _Table(results, names)
    done = table.done()
    todo = [p for p, k in zip(points, keys) if k not in done]
    workers = int(workers) if workers is not None else usable_cpus()
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    rows = (_local_rows(task, todo, names, min(workers, len(todo))) if scheduler is None
            else _dask_rows(task, todo, names, workers, scheduler))
    shared = isinstance(progress, Progress)
    bar = progress if shared else Progress(len(todo), progress, desc="sweep", unit="point")
    before = bar.done + len(points) - len(todo) if shared else 0  # points done before count at once
    if shared and before != bar.done:
        bar.update(before)
    try:
        with contextlib.closing(rows):
            for finished, row in enumerate(rows if todo else (), start=1):
                table.add(row)
                bar.update(before + finished)
    except KeyboardInterrupt:
        bar.close()
        finished = len(table.done() & set(keys))
        raise KeyboardInterrupt(f"sweep interrupted: {finished} of {len(points)} points done in {results}; "
                                f"run it again to finish the rest") from None
    finally:
        if not shared:
            bar.close()
    table.finish(points)
    if parquet is not None:
        _write_parquet(results, parquet)
    return read_table(results)[:len(points)]


def _require_pyarrow():
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        raise ImportError("a .parquet results table needs pyarrow (pip install pyarrow); "
                          "or write results='....csv'") from None


def _write_parquet(csv_path, parquet_path):
    """The CSV table as Parquet, one type per column decided over the whole column (pyarrow's own CSV
    reader guesses from the first block and fails on a column whose text starts later, such as
    ``error``): bool, int64, float64 (ints and floats mixed), else string; empty cells are nulls."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    with open(csv_path, newline="") as fh:
        reader = csv.DictReader(fh)
        columns, rows = list(reader.fieldnames or []), list(reader)
    arrays = {}
    for name in columns:
        texts = [r.get(name) or "" for r in rows]
        values = [parse(t) for t in texts]
        kinds = {type(v) for v in values if v is not None}
        if kinds == {bool}:
            arrays[name] = pa.array(values, pa.bool_())
            continue
        if kinds and kinds <= {int, float}:
            try:
                arrays[name] = (pa.array(values, pa.int64()) if kinds == {int} else
                                pa.array([None if v is None else float(v) for v in values], pa.float64()))
                continue
            except OverflowError:  # an integer beyond int64: kept as text
                pass
        arrays[name] = pa.array([t if t != "" else None for t in texts], pa.string())
    from .outputs import write_atomically
    write_atomically(parquet_path, lambda tmp: pq.write_table(pa.table(arrays), tmp))  # whole or not at all


# ---- sweep files ---------------------------------------------------------------------------------
RANGE_KEYS = {"start", "stop", "num", "log"}


def grid_range(spec, name="a grid entry"):
    """Values of a range entry {start, stop, num[, log]}: num evenly spaced values from start to
    stop inclusive (log = true: evenly spaced in log), rounded to 12 significant digits."""
    missing = {"start", "stop", "num"} - set(spec)
    if missing or set(spec) - RANGE_KEYS:
        raise ValueError(f"{name} = {spec!r}: a range needs start, stop, num (and optionally log)")
    num = spec["num"]
    if not isinstance(num, int) or num < 1:
        raise ValueError(f"{name}: num must be a positive whole number, got {num!r}")
    start, stop = float(spec["start"]), float(spec["stop"])
    if spec.get("log", False):
        if start <= 0 or stop <= 0:
            raise ValueError(f"{name}: a log range needs positive start and stop")
        values = np.geomspace(start, stop, num)
    else:
        values = np.linspace(start, stop, num)
    return [float(f"{v:.12g}") for v in values]


def flatten(table, prefix="", ranges=False):
    """{'a': {'b': 1}} -> {'a.b': 1}: TOML's dotted keys (a.b = 1) become nested tables; key paths
    are joined back with dots. ``ranges``: a table {start, stop, num[, log]} is a range of values
    (:func:`grid_range`)."""
    flat = {}
    for k, v in table.items():
        path = f"{prefix}{k}"
        if ranges and isinstance(v, dict) and v and set(v) <= RANGE_KEYS:
            flat[path] = grid_range(v, path)
        elif isinstance(v, dict):
            flat.update(flatten(v, path + ".", ranges))
        else:
            flat[path] = v
    return flat


SWEEP_KEYS = {"scene", "task", "grid", "points", "seeds", "seed_key", "observables", "results", "workers",
              "scheduler"}


def read_sweep_file(path):
    """The settings of a sweep file (TOML) as a dict: task (a callable), parameters, seeds, results
    (a path), workers, scheduler. See docs/sweeps.md for the format."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"sweep file {path} does not exist")
    try:
        spec = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path} is not valid TOML: {err}") from None
    unknown = sorted(set(spec) - SWEEP_KEYS)
    if unknown:
        raise ValueError(f"{path}: unknown setting(s) {unknown}; known: {sorted(SWEEP_KEYS)}")
    if ("scene" in spec) == ("task" in spec):
        raise ValueError(f"{path} needs exactly one of scene = 'file.toml' (a scene file) or "
                         f"task = 'module:function'")
    if ("grid" in spec) == ("points" in spec):
        raise ValueError(f"{path} needs exactly one of a [grid] table (name = [values]) or [[points]] tables")
    if "grid" in spec:
        parameters = flatten(spec["grid"], ranges=True)
        for name, values in parameters.items():
            if not isinstance(values, list):
                raise ValueError(f"{path}: [grid] {name} = {values!r} must be a list of values")
    else:
        if not isinstance(spec["points"], list) or not all(isinstance(p, dict) for p in spec["points"]):
            raise ValueError(f"{path}: points must be [[points]] tables")
        parameters = [flatten(p) for p in spec["points"]]
    observables = spec.get("observables")
    if observables is not None and (not isinstance(observables, list)
                                    or not all(isinstance(o, str) for o in observables)):
        raise ValueError(f"{path}: observables must be a list of names, got {observables!r}")
    if "scene" in spec:
        scene = (path.parent / spec["scene"]).resolve()
        observables = list(observables or ["sim_time"])
        unknown = [o for o in observables if o not in OBSERVABLES]
        if unknown:
            raise ValueError(f"{path}: unknown observable(s) {unknown}; known: {sorted(OBSERVABLES)}")
        task = functools.partial(run_scene_point, scene=str(scene), observables=tuple(observables),
                                 seed_key=spec.get("seed_key", "seed"))
    else:
        task = import_task(spec["task"])
        if observables is not None:
            raise ValueError(f"{path}: observables are for scene sweeps; task = ... returns its own")
    results = path.parent / spec.get("results", path.stem + ".csv")
    workers = spec.get("workers")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ValueError(f"{path}: workers must be a positive whole number, got {workers!r}")
    return {"task": task, "parameters": parameters, "seeds": spec.get("seeds"), "results": results,
            "workers": workers, "scheduler": spec.get("scheduler")}


def import_task(text):
    """The function named by 'package.module:function'."""
    module, _, name = str(text).partition(":")
    if not module or not name:
        raise ValueError(f"task must be 'module:function' (e.g. 'demkit.two_magnets.outcome_map:"
                         f"two_magnets_point'), got {text!r}")
    try:
        function = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as err:
        raise ValueError(f"cannot import task {text!r}: {err}") from None
    if not callable(function):
        raise ValueError(f"task {text!r} is not a function")
    return function


def sweep_file(path, workers=None, scheduler=None, progress=None):
    """Run the sweep a TOML file describes (``demkit sweep``); arguments given here win over the file's."""
    spec = read_sweep_file(path)
    return sweep(spec["task"], spec["parameters"], results=spec["results"], seeds=spec["seeds"],
                 workers=workers if workers is not None else spec["workers"],
                 scheduler=scheduler if scheduler is not None else spec["scheduler"], progress=progress)
