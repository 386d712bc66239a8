"""Work-precision studies: runs of several integrators and time steps from the same state, their errors
against a reference and what they cost; the cheapest run meeting a target; a time step from a pilot."""
from __future__ import annotations

import csv
import json
import math
import time as _time
from dataclasses import dataclass

import numpy as np

from ..guards import largest_safe_step
from ..integrators import EulerCromer, Integrator, VelocityVerlet
from ..progress import Progress, check_progress
from ..scene import Scene
from ..simulation import Simulation, SimulationError
from ..trajectory import Trajectory
from .solver import MAX_PARTICLES, _adaptive, reference


#: work-precision timing (repeats=None): a run shorter than this (wall seconds) is repeated until
#: its timed runs add up to it, keeping the least time of a run ...
TIMING_SECONDS = 0.2
#: ... at least this many times, and as long as its repeats (set-up included) take less than
REPEAT_RUNS = 5
REPEAT_BUDGET = 0.5
#: timings are not trusted when the repeats of a run differ by more than this fraction
#: ((median - least) / least) ...
TIMING_SPREAD = 0.25
#: ... or when its wall time exceeds its CPU time by more than this factor (it waited for a processor)
TIMING_WAIT = 1.5


#: error measures of a report row: (key, heading, what it is)
MEASURES = {
    "position": ("position_error", "pos err", "max over the check times and spheres of |x - x_ref| (length)"),
    "velocity": ("velocity_error", "vel err", "max over the check times and spheres of |v - v_ref| (speed)"),
    "energy": ("energy_error", "energy err",
               "max over frames of |(E + W)(t) - (E + W)(0)| / energy_scale (E total energy, W dissipated work)"),
    "angular_momentum": ("angular_momentum_drift", "L drift", "max over frames of |L(t) - L(0)| (angular momentum)"),
    "observable": ("observable_error", "obs err", "|observable(run) - observable(reference)|"),
}


def copy_scene(scene, particles=None):
    """A fresh scene with the same interactions, effects, box, skin and threading as ``scene``, on a
    copy of its particles (or on ``particles``): no contact history, no dissipated work. It shares
    the compiled kernels (nothing is compiled again)."""
    scene.pull()
    p = scene.particles.copy() if particles is None else particles
    return Scene(p, list(scene.interactions) + list(scene.effects), box=scene.box, skin=scene.skin,
                 parallel=scene.parallel, sort_every=scene.sort_every)


def _makers(methods):
    """[(label, f(dt) -> Integrator)] from classes, callables or a dict {label: either}."""
    if methods is None:
        methods = [EulerCromer, VelocityVerlet]
    if isinstance(methods, dict):
        pairs = list(methods.items())
    else:
        if isinstance(methods, type) or callable(methods):
            methods = [methods]
        pairs = [(None, m) for m in methods]
    out = []
    for label, method in pairs:
        if not callable(method):
            raise TypeError(f"methods must be Integrator classes or callables f(dt) -> Integrator, got {method!r}")
        if label is None:
            if isinstance(method, type):
                label = method.__name__
            else:
                label = getattr(method, "label", None) or getattr(method, "__name__", "method")
                if label == "<lambda>":
                    label = None
        out.append([label, method])
    return out


def _integrator(make, dt):
    integrator = make(dt)
    if not isinstance(integrator, Integrator):
        raise TypeError(f"a method must give a demkit Integrator for dt = {dt}, got {integrator!r}")
    return integrator


def _checkpoints(times, dt):
    """Whole step counts reaching the check times with time step dt (0 excluded, sorted, unique)."""
    steps = np.unique(np.round(np.asarray(times) / dt).astype(np.int64))
    return steps[steps > 0]


def _run(scene, make, dt, duration, times, record_every, particles=None, fresh=None):
    """One run from the scene's initial state: (trajectory, seconds, cpu_seconds, steps, integrator,
    error message). The wall and CPU (process) times are those of the ``Simulation.run`` calls; making
    the scene's copy (or taking ``fresh``, a copy ready to run) and the Simulation is not timed."""
    fresh = copy_scene(scene, particles) if fresh is None else fresh
    integrator = _integrator(make, dt)
    try:
        sim = Simulation(fresh, integrator, notes=False)  # coarse steps on purpose: the study measures the error
    except ValueError as error:
        return None, math.nan, math.nan, 0, integrator, str(error)
    total = int(round(duration / integrator.dt))
    if total < 1:
        return (None, math.nan, math.nan, 0, integrator,
                f"duration {duration:.6g} is shorter than the time step {dt:.6g}")
    stops = list(_checkpoints(times, integrator.dt)) + [total]
    stops = sorted({s for s in stops if 0 < s <= total})
    stride = max(1, int(round(record_every / integrator.dt)))
    parts, seconds, cpu, done = [], 0.0, 0.0, 0
    try:
        for stop in stops:
            piece = stop - done
            if piece <= 0:
                continue
            wall0, cpu0 = _time.perf_counter(), _time.process_time()
            parts.append(sim.run(piece * integrator.dt, record_every=min(piece, stride) * integrator.dt,
                                 progress=False))
            seconds += _time.perf_counter() - wall0
            cpu += _time.process_time() - cpu0
            done = stop
    except SimulationError as error:
        if error.trajectory is not None and len(error.trajectory):
            parts.append(error.trajectory)
        return _joined(parts), math.nan, math.nan, sim.step, integrator, str(error)
    except (ValueError, FloatingPointError) as error:
        return _joined(parts), math.nan, math.nan, sim.step, integrator, str(error)
    return _joined(parts), seconds, cpu, total, integrator, ""


class _Spare:
    """Copies of a scene at its initial state for repeated runs: one copy put back to the initial
    state for each repeat (making a Scene takes tens of milliseconds, more than a small run), or a new
    copy each time for scenes that keep per-contact history or reorder their spheres."""

    FIELDS = ("position", "velocity", "angular_velocity", "dipole", "image")

    def __init__(self, scene):
        self.scene, self.copy, self.initial = scene, None, None
        self.reuse = not scene.history_keepers() and not scene.plan.sorted

    def ready(self):
        if not self.reuse:
            return copy_scene(self.scene)
        if self.copy is None:
            self.copy = copy_scene(self.scene)
            self.initial = {name: getattr(self.copy.particles, name).copy() for name in self.FIELDS
                            if getattr(self.copy.particles, name) is not None}
        else:  # the next Simulation sees the changed arrays, checks them and rebuilds the lists
            for name, value in self.initial.items():
                getattr(self.copy.particles, name)[...] = value
            self.copy.arrays["accum"][...] = 0.0
        return self.copy


def _timed(scene, make, dt, duration, times, record_every, repeats):
    """:func:`_run`, timed robustly: (trajectory, steps, integrator, message, timing), timing a dict of
    seconds (the least wall time of a run), cpu_seconds (the least CPU time), repeats (runs timed) and
    timing_spread ((median - least) / least of the wall times; NaN under 3 runs).

    ``repeats``: a number of runs, or None: a run shorter than :data:`TIMING_SECONDS` is repeated
    until its runs add up to that (at least :data:`REPEAT_RUNS` runs, and no more once the repeats
    took :data:`REPEAT_BUDGET` seconds with their set-up). Repeats start from the same state and do
    the same work (the first run's trajectory is kept)."""
    began = _time.perf_counter()
    traj, seconds, cpu, steps, integrator, message = _run(scene, make, dt, duration, times, record_every)
    walls, cpus = [seconds], [cpu]
    spare = _Spare(scene)

    def more():
        if repeats is not None:
            return len(walls) < repeats
        if walls[0] >= TIMING_SECONDS:
            return False
        return len(walls) < REPEAT_RUNS or (sum(walls) < TIMING_SECONDS
                                            and _time.perf_counter() - began < REPEAT_BUDGET)
    while not message and more():
        _, seconds, cpu, _, _, again = _run(scene, make, dt, duration, times, record_every, fresh=spare.ready())
        if again:  # the same run failed this time: keep the timings so far
            break
        walls.append(seconds)
        cpus.append(cpu)
    if message:
        return traj, steps, integrator, message, {"seconds": math.nan, "cpu_seconds": math.nan, "repeats": 1,
                                                  "timing_spread": math.nan}
    least = min(walls)
    spread = (float(np.median(walls)) - least) / least if len(walls) >= 3 and least > 0 else math.nan
    return traj, steps, integrator, "", {"seconds": least, "cpu_seconds": min(cpus), "repeats": len(walls),
                                         "timing_spread": spread}


def _joined(parts):
    parts = [p for p in parts if p is not None and len(p)]
    if not parts:
        return None
    # runs of one Simulation are consecutive: rebase the times on whole steps to join them exactly
    return Trajectory.concatenate(parts) if len(parts) > 1 else parts[0]


def _balance(traj):
    e = traj.energy
    s = np.asarray(e["total"]) + np.asarray(e["dissipated"])
    return np.abs(s - s[0])


def _at(traj, t, what="position"):
    """State of a trajectory at time t: the frame at t or, for a run-based reference whose frames
    miss t by less than half its step, the nearest frame advanced linearly (x + v dt)."""
    k = int(np.argmin(np.abs(traj.time - t)))
    offset = t - traj.time[k]
    position = traj.unwrapped()[k] if traj.image is not None else traj.position[k]
    if what == "velocity":
        return traj.velocity[k], abs(offset)
    return position + offset * traj.velocity[k], abs(offset)


class WorkPrecision:
    """What accuracy costs for one scene: one row per (method, dt) run. See :func:`work_precision`.

    rows : list of dicts (method, dt, steps, evaluations, seconds, cpu_seconds, repeats,
        timing_spread, stable, message, errors, observable, is_reference).
    reference : a dict describing the reference (kind, description, evaluations, seconds, restarts,
        energy_error, angular_momentum_drift, observable).
    energy_scale, energy_scale_source : the scale dividing the energy-balance error and where it
        comes from. times : the check times of the position and velocity errors.
    spread : None or a dict (samples, perturbation, observable values and spread, position spread
        per check time): how far references from perturbed starts drift apart, the floor below which
        more accuracy buys nothing.
    """

    def __init__(self, rows, reference, energy_scale, energy_scale_source, times, duration, spread=None,
                 observable_name=None, length_scale=None):
        self.length_scale = length_scale  # the smallest radius: the size at which position errors saturate
        self.rows = rows
        self.reference = reference
        self.energy_scale, self.energy_scale_source = energy_scale, energy_scale_source
        self.times, self.duration = times, duration
        self.spread = spread
        self.observable_name = observable_name

    def measures(self):
        """The error measures present (names of :data:`MEASURES`)."""
        out = ["position", "velocity", "energy"]
        if any(math.isfinite(r["angular_momentum_drift"]) for r in self.rows):
            out.append("angular_momentum")
        if self.observable_name is not None:
            out.append("observable")
        return out

    def floor(self, measure):
        """The chaotic floor of a measure from the spread of perturbed references (None if not measured)."""
        if not self.spread:
            return None
        if measure == "position":
            return self.spread["position_max"]
        if measure == "observable" and self.spread.get("observable_range") is not None:
            return self.spread["observable_range"]
        return None

    def _timed_rows(self):
        return [r for r in self.rows if r["stable"] and math.isfinite(r.get("seconds", math.nan))]

    def timing_notes(self):
        """Why the wall times cannot be trusted, one sentence each (empty when nothing says so): repeats
        of a run that differ by more than :data:`TIMING_SPREAD`, wall time above CPU time by more than
        :data:`TIMING_WAIT` (the process waited for a processor), and a method whose time does not
        grow with its force evaluations (fixed costs of a run, not the integrator, are measured)."""
        notes, rows = [], self._timed_rows()
        spread = [r for r in rows if r.get("timing_spread", math.nan) > TIMING_SPREAD]
        if spread:
            worst = max(spread, key=lambda r: r["timing_spread"])
            notes.append(f"the repeats of {len(spread)} of {len(rows)} runs differ by more than "
                         f"{TIMING_SPREAD:.0%} (up to {worst['timing_spread']:.0%}: {worst['method']} "
                         f"dt = {worst['dt']:.4g}, {worst['repeats']} runs): the machine was busy or the runs "
                         f"are too short to time")
        waited = [r for r in rows if r.get("cpu_seconds", 0) > 0 and r["seconds"] > TIMING_WAIT * r["cpu_seconds"]]
        if waited:
            worst = max(waited, key=lambda r: r["seconds"] / r["cpu_seconds"])
            notes.append(f"{len(waited)} of {len(rows)} runs took more than {TIMING_WAIT:g}x their CPU time in wall "
                         f"time (up to {worst['seconds'] / worst['cpu_seconds']:.1f}x: {worst['method']} "
                         f"dt = {worst['dt']:.4g}): the process waited for a processor (a busy machine); "
                         f"compare CPU times (cpu_seconds) or force evaluations")
        for method in dict.fromkeys(r["method"] for r in rows):
            mine = sorted((r for r in rows if r["method"] == method and not r.get("is_reference")),
                          key=lambda r: r["evaluations"])
            if len(mine) < 2 or mine[0]["evaluations"] == mine[-1]["evaluations"]:
                continue
            slope = float(np.polyfit(np.log([r["evaluations"] for r in mine]), np.log([r["seconds"] for r in mine]),
                                     1)[0])
            faster = [(a, b) for a, b in zip(mine, mine[1:]) if b["seconds"] < a["seconds"]]
            if slope < 0.5 or faster:
                a, b = faster[0] if faster else (mine[0], mine[-1])
                notes.append(f"{method}: the wall time does not follow the work (time ~ evaluations^{slope:.2f}; "
                             f"dt = {b['dt']:.4g} took {b['seconds']:.3g} s for {b['evaluations']} force "
                             f"evaluations, dt = {a['dt']:.4g} {a['seconds']:.3g} s for {a['evaluations']}): "
                             f"fixed costs of each run (Python, recording, the pieces between check times) or "
                             f"noise dominate; compare force evaluations")
        return notes

    def convergence_notes(self):
        """Where position errors stall while energy errors converge, and why, one sentence per method."""
        notes = []
        for method in dict.fromkeys(r["method"] for r in self.rows):
            mine = sorted((r for r in self.rows if r["method"] == method and r["stable"] and not r.get("is_reference")
                           and r["position_error"] > 0 and r["energy_error"] > 0), key=lambda r: -r["dt"])
            if len(mine) < 3:
                continue
            dts = np.log([r["dt"] for r in mine])
            position = float(np.polyfit(dts, np.log([r["position_error"] for r in mine]), 1)[0])
            energy = float(np.polyfit(dts, np.log([r["energy_error"] for r in mine]), 1)[0])
            rises = any(b["position_error"] > 1.2 * a["position_error"] for a, b in zip(mine, mine[1:]))
            if energy < 0.7 or not (position < 0.5 or rises):
                continue
            largest = max(r["position_error"] for r in mine)
            text = (f"{method}: position errors do not converge with dt (fitted order {position:.2f}, "
                    f"{min(r['position_error'] for r in mine):.2e} to {largest:.2e}"
                    f"{', rising at some halvings' if rises else ''}) while energy errors do (order {energy:.2f}). "
                    f"Positions compared at fixed times depend on when each contact begins and ends, which a fixed "
                    f"step finds only to within a step, differently for every dt (first order at best, erratic); "
                    f"the energy balance is an integral over the run and averages these phase errors out")
            if self.length_scale and largest >= 0.1 * self.length_scale:
                text += (f". Errors of {largest:.2e}, a sizeable part of a radius ({self.length_scale:.3g}), mean "
                         f"runs that parted from the reference for good (a chaotic scene, or a contact gained or "
                         f"missed): such errors saturate at the size of the scene instead of shrinking")
            floor = self.floor("position")
            if floor is not None and min(r["position_error"] for r in mine) < 10 * floor:
                text += f". They also reach the spread of perturbed references ({floor:.2e}), the chaotic floor"
            notes.append(text + ". Trust the energy column, or resolve contacts (VelocityVerlet:resolve).")
        return notes

    def table(self):
        """A plain-text table: method, dt, each error, wall time (least of its repeats), CPU time, force
        evaluations, stable; then the reference, the notes on the timings and on convergence."""
        measures = self.measures()
        head = (["method", "dt"] + [MEASURES[m][1] for m in measures]
                + ["seconds", "cpu s", "runs", "evaluations", "stable"])
        lines = []
        for r in self.rows:
            cells = [r["method"], f"{r['dt']:.4g}"]
            for m in measures:
                value = r[MEASURES[m][0]]
                cells.append("ref" if r.get("is_reference") else (f"{value:.3e}" if math.isfinite(value) else "nan"))
            seconds = f"{r['seconds']:.4g}" if math.isfinite(r["seconds"]) else "-"
            cpu = r.get("cpu_seconds", math.nan)
            cells += [seconds, f"{cpu:.4g}" if math.isfinite(cpu) else "-", str(r.get("repeats", 1)),
                      str(r["evaluations"]), "yes" if r["stable"] else "NO"]
            lines.append(cells)
        widths = [max(len(h), *(len(c[k]) for c in lines)) if lines else len(h) for k, h in enumerate(head)]
        fmt = lambda cells: "  ".join(c.rjust(w) if k else c.ljust(w) for k, (c, w) in enumerate(zip(cells, widths)))  # noqa: E731
        out = [fmt(head), fmt(["-" * w for w in widths])] + [fmt(c) for c in lines]
        ref = self.reference
        out.append("")
        out.append(f"reference: {ref['description']}")
        out.append(f"energy err is divided by {self.energy_scale:.6g} ({self.energy_scale_source})")
        if self.spread:
            s = self.spread
            text = (f"spread of {s['samples']} references started {s['perturbation']:.3g} apart: positions "
                    f"{s['position_max']:.3e}")
            if s.get("observable_range") is not None:
                text += f", observable {s['observable_range']:.3e}"
            out.append(text + " (errors below this are not meaningful)")
        for r in self.rows:
            if not r["stable"]:
                out.append(f"{r['method']} dt={r['dt']:.4g}: {r['message']}")
        notes = self.timing_notes()
        runs = [r.get("repeats", 1) for r in self._timed_rows()]
        if runs:
            kept = f"the least wall time of {min(runs)}" + (f"-{max(runs)}" if max(runs) > min(runs) else "") + \
                " runs each"
            if notes:
                out.append(f"timings ({kept}) cannot be trusted:")
                out += [f"  - {note}" for note in notes]
            else:
                checked = (f"repeats within {TIMING_SPREAD:.0%}, " if max(runs) >= 3 else "")
                out.append(f"timings: {kept}; {checked}wall time within {TIMING_WAIT:g}x CPU time, growing with the "
                           f"force evaluations" + ("" if max(runs) >= 3 else
                                                   " (runs timed fewer than 3 times cannot show how much they vary)"))
        notes = self.convergence_notes()
        if notes:
            out.append("convergence:")
            out += [f"  - {note}" for note in notes]
        return "\n".join(out)

    def __str__(self):
        return self.table()

    def __repr__(self):
        return f"WorkPrecision({len(self.rows)} runs, reference: {self.reference['kind']})"

    def suggest(self, target, measure="position"):
        """The cheapest (least wall time) stable run whose ``measure`` error is at most ``target``:
        a :class:`Suggestion` (its ``row`` is None, and its message says why, when none does)."""
        if measure not in MEASURES:
            raise ValueError(f"measure must be one of {sorted(MEASURES)}, got {measure!r}")
        key = MEASURES[measure][0]
        good = [r for r in self.rows if r["stable"] and not r.get("is_reference") and math.isfinite(r[key])
                and r[key] <= target and math.isfinite(r["seconds"])]
        floor = self.floor(measure)
        note = ""
        if floor is not None and target < floor:
            note = (f" Note: the target is below the spread {floor:.3e} of references started "
                    f"{self.spread['perturbation']:.3g} apart: errors that small are not meaningful here.")
        if not good:
            measured = [r[key] for r in self.rows if r["stable"] and math.isfinite(r[key]) and not r.get("is_reference")]
            best = f"the smallest {measure} error measured is {min(measured):.3e}" if measured else "no run was stable"
            return Suggestion(None, f"no run meets {measure} error <= {target:.3e}: {best}; try smaller time steps "
                                    f"or a higher-order method.{note}")
        row = min(good, key=lambda r: r["seconds"])
        return Suggestion(row, f"{row['method']} with dt = {row['dt']:.6g}: {measure} error {row[key]:.3e} <= "
                               f"{target:.3e} in {row['seconds']:.4g} s ({row['evaluations']} force evaluations)"
                               f".{note}")

    # ---- output -------------------------------------------------------------------------------
    COLUMNS = ("method", "dt", "steps", "evaluations", "seconds", "cpu_seconds", "repeats", "timing_spread",
               "stable", "position_error", "velocity_error",
               "energy_error", "angular_momentum_drift", "observable", "observable_error", "is_reference", "message")

    def to_csv(self, path):
        """Write the rows as CSV (one line per run)."""
        with open(path, "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(self.COLUMNS)
            for r in self.rows:
                writer.writerow([r.get(c, "") for c in self.COLUMNS])
        return path

    def as_dict(self):
        def clean(value):
            if isinstance(value, dict):
                return {k: clean(v) for k, v in value.items()}
            if isinstance(value, (list, tuple, np.ndarray)):
                return [clean(v) for v in value]
            if isinstance(value, (np.floating, float)):
                return float(value) if math.isfinite(value) else None
            if isinstance(value, np.integer):
                return int(value)
            if isinstance(value, np.bool_):
                return bool(value)
            return value
        return clean({"duration": self.duration, "times": list(self.times), "energy_scale": self.energy_scale,
                      "energy_scale_source": self.energy_scale_source, "reference": self.reference,
                      "spread": self.spread, "observable": self.observable_name, "rows": self.rows,
                      "timing_notes": self.timing_notes(), "convergence_notes": self.convergence_notes()})

    def to_json(self, path=None):
        """The report as JSON (NaN as null); written to ``path`` if given, else returned as text."""
        text = json.dumps(self.as_dict(), indent=1)
        if path is None:
            return text
        with open(path, "w") as fh:
            fh.write(text)
        return path

    def plot(self, path, x="seconds", title=None):
        """Log-log error against cost (``x``: "seconds", "cpu_seconds" or "evaluations"), one line per method, one
        panel per error measure, dashed: the chaotic floor when a spread was measured. Saved to path."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        if x not in ("seconds", "cpu_seconds", "evaluations"):
            raise ValueError(f"x must be 'seconds', 'cpu_seconds' or 'evaluations', got {x!r}")
        from matplotlib.ticker import NullFormatter
        measures = self.measures()
        ncols = min(3, len(measures))
        nrows = -(-len(measures) // ncols)
        fig, axes = plt.subplots(nrows, ncols, figsize=(4.6 * ncols, 3.7 * nrows), squeeze=False)
        for ax in axes.ravel()[len(measures):]:
            ax.set_visible(False)
        methods = list(dict.fromkeys(r["method"] for r in self.rows))
        for ax, measure in zip(axes.ravel(), measures):
            key = MEASURES[measure][0]
            for method in methods:
                rows = [r for r in self.rows if r["method"] == method and r["stable"] and not r.get("is_reference")
                        and math.isfinite(r[key]) and r[key] > 0 and math.isfinite(float(r.get(x, math.nan)))
                        and r[x] > 0]
                if not rows:
                    continue
                rows.sort(key=lambda r: r[x])
                line, = ax.loglog([r[x] for r in rows], [r[key] for r in rows], "o-", label=method)
                for r in rows:
                    ax.annotate(f"{r['dt']:.2g}", (r[x], r[key]), fontsize=6, color=line.get_color(),
                                xytext=(3, 3), textcoords="offset points")
            floor = self.floor(measure)
            if floor is not None and floor > 0:
                ax.axhline(floor, color="grey", ls="--", lw=1, label="spread of perturbed references")
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.set_xlabel({"seconds": "wall time [s]", "cpu_seconds": "CPU time [s]"}.get(x, "force evaluations"))
            label = {"energy": f"energy balance error / {self.energy_scale:.3g}"}.get(measure, MEASURES[measure][1])
            if measure == "observable":
                label = f"error of {self.observable_name}"
            ax.set_ylabel(label)
            ax.grid(True, which="both", alpha=0.3)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=7)
            else:  # every error is zero (angular momentum kept exactly) or failed
                ax.text(0.5, 0.5, "all zero or not finite", transform=ax.transAxes, ha="center", fontsize=8)
        if x != "evaluations" and self.timing_notes():
            fig.text(0.5, 0.005, "timings cannot be trusted: see report.timing_notes()", ha="center",
                     fontsize=7, color="firebrick")
        fig.suptitle(title or f"work-precision (numbers: dt); reference: {self.reference['kind']}", fontsize=9)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return path


@dataclass
class Suggestion:
    """What :meth:`WorkPrecision.suggest` found: the row (None when no run meets the target) and why."""

    row: dict | None
    message: str

    def __bool__(self):
        return self.row is not None

    def __str__(self):
        return self.message


def _observable_name(observable):
    if observable is None:
        return None
    return getattr(observable, "__name__", None) or type(observable).__name__


def _evaluate_observable(observable, traj):
    """observable(traj), or NaN when it cannot be measured on this run (e.g. final_spin raises
    ValueError on a run that did not settle)."""
    if observable is None or traj is None:
        return math.nan
    try:
        return float(observable(traj))
    except (ValueError, ArithmeticError, IndexError):
        return math.nan


def work_precision(scene, duration, methods=None, dts=None, reference="auto", times=None, energy_scale=None,
                   observable=None, spread=None, record_every=None, repeats=None, rtol=1e-12, progress=None):
    """Run ``scene`` with every method and time step from its current state and compare each run with
    a reference: a :class:`WorkPrecision` report.

    methods : Integrator classes, callables ``f(dt) -> Integrator`` (``lambda dt: MyIntegrator(dt,
        inner=4)``) or a dict {label: either}; default [EulerCromer, VelocityVerlet].
    dts : time steps (default: the scene's largest safe step and 4 halvings of it).
    reference : "auto" (the adaptive :func:`reference` for scenes it accepts, at rtol; otherwise the
        finest run of the highest-order method given), "adaptive", "finest", or a Trajectory (its
        frames should include the check times).
    times : check times of the position and velocity errors (default 5 evenly spaced, ending at
        duration); each run is compared at its own whole-step times nearest to them.
    energy_scale : divides the energy-balance error (default: the largest |potential energy| in the
        reference, or its largest kinetic energy if there is no potential energy).
    observable : f(trajectory) -> float (e.g. a final spin); its error against the reference's value.
    spread : None or dict(samples=5, perturbation=1e-9 * smallest radius (length), seed=0): also
        integrate the reference from ``samples`` starts whose positions are displaced at random by
        ``perturbation`` and report how far apart they end up (positions at the check times, the
        observable): the floor below which more accuracy buys nothing (chaotic scenes).
    record_every : frame interval of every run (energy balance, angular momentum, observable);
        default duration / 200.
    repeats : None (default): time a run shorter than :data:`TIMING_SECONDS` (0.2 s) again until its
        runs add up to that (at least 5 runs, within about :data:`REPEAT_BUDGET` s of repeats a run),
        keeping the least wall time and the least CPU time; a number: time each run that many times.
        ``report.timing_notes()`` says when the timings cannot be trusted anyway.
    progress : one progress bar on stderr over the study's runs (each method and dt, then the
        adaptive reference and the spread's references), the run under way in its postfix: None
        (default) when stderr is a terminal and the study looks like taking more than about 2 s,
        True always, False never (see :mod:`demkit.progress`). The runs themselves draw no bars;
        the results do not depend on it.

    Every run starts from a fresh copy of the scene (no contact history, no dissipated work) after an
    untimed warm-up of each method, so compilation is not timed. A run that fails (SimulationError,
    or the ValueError for a time step above the scene's safe limit) gives a row with stable=False,
    NaN errors and the message.
    """
    check_progress(progress)
    with Progress(0, progress, desc="accuracy study", unit="run") as bar:  # total set once known
        return _work_precision(scene, duration, methods, dts, reference, times, energy_scale, observable, spread,
                               record_every, repeats, rtol, bar)


def _work_precision(scene, duration, methods, dts, reference, times, energy_scale, observable, spread,
                    record_every, repeats, rtol, bar):
    """The body of :func:`work_precision`, updating ``bar`` (a Progress) at every run."""
    duration = float(duration)
    if not math.isfinite(duration) or duration <= 0:
        raise ValueError(f"duration must be a positive finite time, got {duration}")
    makers = _makers(methods)
    if dts is None:
        limit, why = largest_safe_step(scene)
        if not math.isfinite(limit):
            raise ValueError(f"this scene sets no largest safe time step ({why}): pass dts=[...]")
        dts = [limit / 2 ** k for k in range(5)]
    dts = sorted({float(dt) for dt in np.atleast_1d(dts)}, reverse=True)
    if not dts or any(not math.isfinite(dt) or dt <= 0 for dt in dts):
        raise ValueError(f"dts must be positive finite time steps, got {dts}")
    if duration < dts[0]:
        raise ValueError(f"duration {duration:.6g} is shorter than the largest time step {dts[0]:.6g}: give a "
                         f"longer duration or smaller dts")
    if times is None:
        times = duration * np.arange(1, 6) / 5.0
    times = np.unique(np.asarray(times, dtype=np.float64).ravel())
    if len(times) == 0 or times[0] <= 0 or times[-1] > duration * (1 + 1e-12):
        raise ValueError(f"times must lie in (0, duration = {duration:.6g}]")
    record_every = duration / 200.0 if record_every is None else float(record_every)
    if repeats is not None:
        if isinstance(repeats, bool) or not isinstance(repeats, (int, np.integer)) or repeats < 1:
            raise ValueError(f"repeats must be None (repeat short runs, see TIMING_SECONDS) or a whole number "
                             f">= 1, got {repeats!r}")
        repeats = int(repeats)
    # labels and orders of the methods (one integrator made per method to learn them)
    for entry in makers:
        sample = _integrator(entry[1], dts[-1])
        if entry[0] is None:
            entry[0] = type(sample).__name__
        entry.append(sample.order if isinstance(sample.order, (int, float)) else 0)
    labels = [m[0] for m in makers]
    for k, label in enumerate(labels):
        if labels.count(label) > 1:
            makers[k][0] = f"{label}#{labels[:k + 1].count(label)}"
    # choose the reference
    mode = reference
    if isinstance(reference, str):
        if reference not in ("auto", "adaptive", "finest"):
            raise ValueError(f"reference must be 'auto', 'adaptive', 'finest' or a Trajectory, got {reference!r}")
        if reference == "auto":
            mode = "adaptive" if len(scene.particles) <= MAX_PARTICLES and not scene.history_keepers() else "finest"
    elif not isinstance(reference, Trajectory):
        raise TypeError(f"reference must be 'auto', 'adaptive', 'finest' or a Trajectory, got {reference!r}")
    # the bar's units: every (method, dt), the adaptive reference, the spread's references
    adaptive = mode == "adaptive" and not isinstance(reference, Trajectory)
    bar.total = len(makers) * len(dts) + adaptive + (int(dict(spread).get("samples", 5)) if spread else 0)
    # untimed warm-up: compile each method's loop and the recording on this scene's kernels
    for label, make, _ in makers:
        try:
            warm = Simulation(copy_scene(scene), _integrator(make, dts[-1]), notes=False)
            warm.run(2 * dts[-1], record_every=dts[-1], progress=False)
        except (ValueError, SimulationError):
            pass
    best = max(range(len(makers)), key=lambda k: (makers[k][2], k))  # highest order, last given on ties
    # every run stops at its own whole steps nearest to the check times
    all_check = sorted({float(s * _integrator(m[1], dt).dt) for m in makers for dt in dts
                        for s in _checkpoints(times, _integrator(m[1], dt).dt)})
    frame_grid = np.unique(np.concatenate([np.arange(0.0, duration, record_every), [duration]]))
    rows, runs = [], []
    for label, make, _ in makers:
        for dt in dts:
            bar.update(len(rows), f"{label} dt = {dt:.4g}")
            traj, steps, integrator, message, timing = _timed(scene, make, dt, duration, all_check, record_every,
                                                              repeats)
            runs.append(traj)
            per_step = getattr(integrator, "evaluations_per_step", 1)
            rows.append({"method": label, "dt": integrator.dt, "steps": int(steps),
                         "evaluations": int(steps * per_step), **timing,
                         "stable": not message, "message": message, "position_error": math.nan,
                         "velocity_error": math.nan, "energy_error": math.nan,
                         "angular_momentum_drift": math.nan, "observable": math.nan,
                         "observable_error": math.nan, "is_reference": False})
    # the reference
    info = {}
    if isinstance(reference, Trajectory):
        ref = reference
        info = {"kind": "given", "description": f"the trajectory given ({len(ref)} frames)"}
    elif mode == "adaptive":
        # runs end on whole steps, which may lie a little beyond duration
        horizon = max([duration] + all_check)
        bar.update(len(rows), f"reference: adaptive DOP853, rtol = {rtol:g}")
        ref = _adaptive(scene, horizon, times=np.unique(np.concatenate([[0.0], all_check, frame_grid])), rtol=rtol)
        info = {"kind": "adaptive", "description": f"adaptive DOP853, rtol={rtol:g} ({ref.evaluations} force "
                                                   f"evaluations, {ref.restarts} restarts at events, "
                                                   f"{ref.seconds:.3g} s)",
                "evaluations": ref.evaluations, "restarts": ref.restarts, "seconds": ref.seconds, "rtol": rtol}
    else:
        label = makers[best][0]
        stable = [r for r in rows if r["method"] == label and r["stable"]]
        if not stable:
            last = min((r for r in rows if r["method"] == label), key=lambda r: r["dt"])
            raise ValueError(f"no stable run of {label} to serve as the reference; at dt = {last['dt']:.4g}: "
                             f"{last['message']}")
        finest = min(stable, key=lambda r: r["dt"])
        ref = runs[rows.index(finest)]
        finest["is_reference"] = True
        info = {"kind": "finest", "description": f"the finest run, {label} with dt = {finest['dt']:.6g} (highest "
                                                 f"order given; its own error is not measured)",
                "method": label, "dt": finest["dt"], "seconds": finest["seconds"],
                "evaluations": finest["evaluations"]}
    # energy scale
    e = ref.energy
    kinetic = np.asarray(e["kinetic"]) + np.asarray(e["rotational"])
    potential = np.asarray(e["total"]) - kinetic
    if energy_scale is not None:
        scale, source = float(energy_scale), "given"
    elif np.max(np.abs(potential)) > 0:
        scale, source = float(np.max(np.abs(potential))), "the largest |potential energy| in the reference"
    else:
        scale, source = float(np.max(np.abs(kinetic))) or 1.0, "the largest kinetic energy in the reference"
    conserves = (not scene.effects and not scene.has_fixed and not any(scene.periodic))
    info["energy_error"] = float(np.max(_balance(ref))) / scale
    info["angular_momentum_drift"] = (float(np.max(np.linalg.norm(ref.angular_momentum - ref.angular_momentum[0],
                                                                  axis=1))) if conserves else math.nan)
    ref_obs = _evaluate_observable(observable, ref)
    info["observable"] = ref_obs
    # errors
    for row, traj in zip(rows, runs):
        if not row["stable"] or traj is None or row["is_reference"]:
            continue
        pos, vel = [], []
        dt = row["dt"]
        for t in times:
            tk = round(t / dt) * dt
            k = int(np.argmin(np.abs(traj.time - tk)))
            x = traj.unwrapped()[k] if traj.image is not None else traj.position[k]
            xr, _ = _at(ref, traj.time[k])
            vr, _ = _at(ref, traj.time[k], "velocity")
            pos.append(float(np.max(np.linalg.norm(x - xr, axis=1))))
            vel.append(float(np.max(np.linalg.norm(traj.velocity[k] - vr, axis=1))))
        row["position_error"], row["velocity_error"] = max(pos), max(vel)
        row["position_errors"], row["velocity_errors"] = pos, vel  # at each check time
        row["energy_error"] = float(np.max(_balance(traj))) / scale
        if conserves:
            row["angular_momentum_drift"] = float(np.max(np.linalg.norm(
                traj.angular_momentum - traj.angular_momentum[0], axis=1)))
        if observable is not None:
            row["observable"] = _evaluate_observable(observable, traj)
            row["observable_error"] = abs(row["observable"] - ref_obs)
    spread_info = None
    if spread:
        spread_info = _spread(scene, duration, spread, mode if not isinstance(reference, Trajectory) else "finest",
                              ref, times, all_check, frame_grid, observable, ref_obs, rtol, makers[best],
                              info.get("dt", dts[-1]), record_every, bar)
    bar.update(bar.total, "done")
    return WorkPrecision(rows, info, scale, source, list(times), duration, spread_info, _observable_name(observable),
                         length_scale=float(np.min(scene.particles.radius)))


def _spread(scene, duration, spread, mode, ref, times, all_check, frame_grid, observable, ref_obs, rtol, best, dt,
            record_every, bar):
    """References from randomly displaced starts: how far apart they drift (the chaotic floor)."""
    options = dict(spread)
    unknown = set(options) - {"samples", "perturbation", "seed"}
    if unknown:
        raise ValueError(f"spread takes samples, perturbation and seed, not {sorted(unknown)}")
    samples = int(options.get("samples", 5))
    size = float(options.get("perturbation", 1e-9 * float(np.min(scene.particles.radius))))
    rng = np.random.default_rng(options.get("seed", 0))
    values, apart = [], np.zeros(len(times))
    for sample in range(samples):
        bar.update(bar.total - samples + sample, f"spread: perturbed reference {sample + 1}/{samples}")
        scene.pull()
        p = scene.particles.copy()
        step = rng.normal(size=p.position.shape)
        step *= size / np.linalg.norm(step, axis=1, keepdims=True)
        if p.fixed is not None:
            step[p.fixed] = 0.0
        p.position = p.position + step
        fresh = copy_scene(scene, p)
        if mode == "adaptive":
            other = reference(fresh, max([duration] + list(all_check)),
                              times=np.unique(np.concatenate([[0.0], all_check, frame_grid])), rtol=rtol)
        else:
            other, _, _, _, _, message = _run(fresh, best[1], dt, duration, all_check, record_every)
            if message:
                raise RuntimeError(f"a perturbed reference run failed: {message}")
        for m, t in enumerate(times):
            k = int(np.argmin(np.abs(ref.time - t)))
            x0, _ = _at(ref, ref.time[k])
            x1, _ = _at(other, ref.time[k])
            apart[m] = max(apart[m], float(np.max(np.linalg.norm(x1 - x0, axis=1))))
        values.append(_evaluate_observable(observable, other))
    out = {"samples": samples, "perturbation": size, "position": apart.tolist(),
           "position_max": float(np.max(apart)), "times": list(times)}
    if observable is not None:
        finite = [v for v in values + [ref_obs] if math.isfinite(v)]
        out["observable_values"] = values
        out["observable_range"] = float(np.ptp(finite)) if len(finite) > 1 else None
        out["observable_std"] = float(np.std(finite, ddof=1)) if len(finite) > 1 else None
    return out


@dataclass
class DtSuggestion:
    """What :func:`suggest_dt` found: the time step (None when the pilot showed no convergence), the
    fitted error model error = constant * dt^order * (duration / pilot)^growth, the pilot report
    and an explanation."""

    dt: float | None
    order: float
    constant: float
    growth: float
    predicted: float
    report: WorkPrecision
    message: str

    def __str__(self):
        return self.message


def suggest_dt(scene, target, pilot, method=VelocityVerlet, measure="position", dt=None, duration=None,
               reference="auto", progress=None):
    """A time step for ``method`` to reach an error ``target`` in ``measure`` ("position",
    "velocity", "energy" or "angular_momentum"), from a short pilot.

    The pilot is a :func:`work_precision` run of ``pilot`` time units with dt, dt/2 and dt/4 (dt:
    default half the scene's largest safe step). It fits error = C dt^p over the stable runs; for a
    ``duration`` longer than the pilot, position and velocity errors are scaled by
    (duration/pilot)^q, q fitted to how the finest pilot run's error grew over the pilot's check
    times (clipped to [0, 3]). The suggestion is capped at the scene's largest safe step. This is
    an extrapolation: errors that grow exponentially (chaotic scenes, many-body collisions) or jump
    at events the pilot did not reach are not predicted; check with a work_precision run at the
    suggested dt. ``progress``: the pilot study's bar (see :func:`work_precision`). Returns a
    :class:`DtSuggestion`.
    """
    if measure not in MEASURES or measure == "observable":
        raise ValueError(f"measure must be one of position, velocity, energy, angular_momentum; got {measure!r}")
    pilot = float(pilot)
    limit, why = largest_safe_step(scene)
    if dt is None:
        if not math.isfinite(limit):
            raise ValueError(f"this scene sets no largest safe time step ({why}): pass dt=...")
        dt = 0.5 * limit
    dts = [dt, dt / 2, dt / 4]
    times = pilot * np.array([0.25, 0.5, 0.75, 1.0])
    report = work_precision(scene, pilot, methods=[method], dts=dts, reference=reference, times=times,
                            repeats=1, progress=progress)  # its errors are used, not its timings
    key = MEASURES[measure][0]
    rows = [r for r in report.rows if r["stable"] and not r["is_reference"] and math.isfinite(r[key]) and r[key] > 0]
    if len(rows) < 2:
        return DtSuggestion(None, math.nan, math.nan, math.nan, math.nan, report,
                            f"the pilot gave fewer than two usable runs (stable, error > 0): {report.table()}")
    x = np.log([r["dt"] for r in rows])
    y = np.log([r[key] for r in rows])
    order, log_c = np.polyfit(x, y, 1)
    growth, factor = 0.0, 1.0
    if duration is not None and float(duration) > pilot and measure in ("position", "velocity"):
        finest = min(rows, key=lambda r: r["dt"])
        per_time = np.array(finest[f"{measure}_errors"])
        ok = per_time > 0
        if ok.sum() >= 2:
            growth = float(np.clip(np.polyfit(np.log(times[ok]), np.log(per_time[ok]), 1)[0], 0.0, 3.0))
        factor = (float(duration) / pilot) ** growth
    if order < 0.5:
        return DtSuggestion(None, float(order), math.exp(log_c), growth, math.nan, report,
                            f"the pilot's {measure} errors do not converge with dt (fitted order {order:.2f}): they "
                            f"may be at round-off, chaotic or dominated by events; see the pilot report:\n"
                            f"{report.table()}")
    constant = math.exp(log_c)
    suggested = (target / (constant * factor)) ** (1.0 / order)
    capped = min(suggested, limit)
    predicted = constant * capped ** order * factor
    span = f" over {float(duration):.6g} (error growth ~ t^{growth:.2f} from the pilot)" if factor != 1.0 else ""
    message = (f"{report.rows[0]['method']}: dt = {capped:.4g} for a {measure} error of about {predicted:.3g}{span} "
               f"(pilot of {pilot:.6g}: error = {constant:.3g} dt^{order:.2f})")
    if capped < suggested:
        message += f"; capped at the scene's largest safe step {limit:.4g}"
    return DtSuggestion(float(capped), float(order), constant, growth, predicted, report, message)
