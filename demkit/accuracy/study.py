"""Work-precision studies: runs of several integrators and time steps from the same state, their errors
against a reference and what they cost; the cheapest run meeting a target; a time step from a pilot."""
from __future__ import annotations

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
from .report import MEASURES, WorkPrecision
from .solver import MAX_PARTICLES, _adaptive, reference


#: work-precision timing (repeats=None): a run shorter than this (wall seconds) is repeated until
#: its timed runs add up to it, keeping the least time of a run ...
TIMING_SECONDS = 0.2
#: ... at least this many times, and as long as its repeats (set-up included) take less than
REPEAT_RUNS = 5
REPEAT_BUDGET = 0.5


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
