"""The reference solution: scipy's DOP853 (8th order, adaptive) on the scene's own compiled forces,
restarting exactly at every point where a force law is not smooth (:mod:`demkit.accuracy.switches`), so
that no step straddles a jump. The truth that fixed-step runs are measured against."""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass

import numpy as np

from ..diagnostics import energy_dict
from ..scene import Scene
from ..trajectory import Trajectory
from .equations import _Borrowed
from .switches import _Switches, _grazing, _negative


#: the reference refuses scenes with more spheres (it integrates every coordinate in Python)
MAX_PARTICLES = 200
#: an event is moved across its switching surface until its function is this far (relative to the
#: function's scale) on the new side, so that the compiled law sees the new regime despite round-off
CROSSING_MARGIN = 1e-12
#: approach attempts of one event before the reference gives up
MAX_APPROACHES = 40
#: points at which the dense output of a flagged step is sampled to find the first sign change
SAMPLES = 16


@dataclass
class _Crossing:
    t0: float  # start of the step in which it was found (a clean state)
    y0: np.ndarray
    time: float  # located event time
    key: tuple
    step: float  # the natural step size there


class _Reference:
    def __init__(self, eq, switches, rtol, atol, times):
        from scipy.integrate import DOP853
        self.DOP853 = DOP853
        self.eq, self.switches = eq, switches
        self.rtol, self.atol = rtol, atol
        self.times = times
        self.next_out = 0
        self.out = []
        self.steps = 0
        self.restarts = 0
        self.segments = 0
        self.events = []

    # outputs ------------------------------------------------------------------------------------
    def emit(self, t0, t1, y1, dense):
        """Record the requested times in (t0, t1] (dense: a callable for interior times)."""
        while self.next_out < len(self.times) and self.times[self.next_out] <= t1:
            t = self.times[self.next_out]
            y = y1 if t == t1 else dense()(t)
            self.out.append((t, np.array(y, dtype=np.float64)))
            self.next_out += 1

    # one stretch of smooth integration ----------------------------------------------------------
    def segment(self, t0, y0, bound, first_step):
        """Integrate from (t0, y0) towards ``bound``; return (t, y, step) at the bound or a _Crossing
        for the first step in which a switching function changed sign (that step is discarded)."""
        sw = self.switches
        sw.build(y0)
        keys = None
        g0, _, d0 = sw.values(y0, rates=True)
        self.segments += 1
        if bound - t0 <= 0.0:
            return t0, y0, first_step
        if first_step is not None:
            first_step = min(first_step, bound - t0)
        solver = self.DOP853(self.eq, t0, y0, bound, rtol=self.rtol, atol=self.atol, first_step=first_step)
        last = first_step
        while solver.status == "running":
            tp, yp = solver.t, solver.y.copy()
            message = solver.step()
            if solver.status == "failed":
                raise RuntimeError(f"the reference solver failed at t = {tp:.9g}: {message}")
            tn, yn = solver.t, solver.y
            h = tn - tp
            widened = sw.moved_too_far(yn)
            if widened:  # a sphere went beyond the items' skin: redo the step's check with all the
                # pairs it can have brought to a switch (chosen at the step's start)
                sw.build(yp, sw.step_reach(yp, yn, h))
                keys = None
                g0, _, d0 = sw.values(yp, rates=True)
            g1, _, d1 = sw.values(yn, rates=True)
            grazes, extrema = _grazing(g0, g1, d0, d1, h)
            flagged = (_negative(g0) != _negative(g1)) | grazes
            dense = None
            if flagged.any():
                dense = solver.dense_output()
                items = np.flatnonzero(flagged)
                hit = self.first_root(dense, tp, tn, g0, items, extrema[items])
                if hit is not None:
                    when, k = hit
                    if keys is None:
                        keys = sw.keys()
                    return _Crossing(tp, yp, when, keys[k], h)
            self.steps += 1
            cache = {}
            def interpolant():
                if "d" not in cache:
                    cache["d"] = dense if dense is not None else solver.dense_output()
                return cache["d"]
            self.emit(tp, tn, yn, interpolant)
            last = getattr(solver, "h_abs", h)
            if widened or sw.moved_too_far(yn):
                sw.build(yn)
                keys = None
                g1, _, d1 = sw.values(yn, rates=True)
            g0, d0 = g1, d1
        return solver.t, solver.y.copy(), last

    def first_root(self, dense, tp, tn, g0, items, extrema):
        """(time, item) of the earliest sign change of the flagged items inside [tp, tn] on the
        step's dense output, or None (a graze that the accurate interpolant does not confirm). The
        output is sampled at SAMPLES + 1 times and, for a graze, at the extremum of g near where its
        Hermite cubic has one (``extrema``: fractions of the step), so a narrow dip is not missed."""
        from scipy.optimize import brentq, minimize_scalar
        sw = self.switches
        h = tn - tp
        ts = np.linspace(tp, tn, SAMPLES + 1)
        states = dense(ts)
        values = np.array([sw.values(states[:, s])[0][items] for s in range(SAMPLES + 1)])
        values[0] = g0[items]
        best = None
        for col, k in enumerate(items):
            def f(t, k=k):
                return sw.value(dense(t), k)
            old = _negative(g0[k])
            times, gs = list(ts), list(values[:, col])
            for fraction in extrema[col]:
                if not math.isfinite(fraction):
                    continue
                centre = tp + fraction * h
                lo, hi = max(tp, centre - 0.1 * h), min(tn, centre + 0.1 * h)
                towards = 1.0 if not old else -1.0  # push g towards the other side
                found = minimize_scalar(lambda t: towards * f(t), bounds=(lo, hi), method="bounded",
                                        options={"xatol": 1e-13 * max(h, abs(tp))})
                times.append(float(found.x))
                gs.append(f(found.x))
            order = np.argsort(times, kind="stable")
            times, gs = np.array(times)[order], np.array(gs)[order]
            change = np.flatnonzero(_negative(gs) != old)
            if not len(change):
                continue
            s = int(change[0])
            a, b = times[s - 1], times[s]
            if best is not None and a >= best[0]:
                continue
            root = a if gs[s - 1] == 0.0 else brentq(f, a, b, xtol=4 * np.spacing(max(abs(a), abs(b))), rtol=8.9e-16)
            if best is None or root < best[0]:
                best = (root, k)
        return best

    # crossing an event -----------------------------------------------------------------------------
    def distance(self, t, y, k, step):
        """Newton estimate of the time left until item k changes sign (backward difference of g)."""
        sw = self.switches
        f = self.eq(t, y)
        g = sw.value(y, k)
        tau = 1e-6 * step
        rate = (g - sw.value(y - tau * f, k)) / tau
        if rate == 0.0 or not math.isfinite(rate):
            return math.inf, f, rate
        return -g / rate, f, rate

    def cross(self, t, y, k, step, newton):
        """Move from (t, y), just before item k's switching surface, to just beyond it: first order
        with the old law up to the surface (``newton``: the :meth:`distance` there), then a tiny
        interval with the new law, so that the next solver starts inside the new regime (error
        O(interval^2))."""
        sw = self.switches
        remaining, f_old, rate = newton
        remaining = max(remaining, 0.0) if math.isfinite(remaining) else 0.0
        y1 = y + remaining * f_old
        g1, scale, _ = sw.values(y1)
        old = _negative(sw.value(y, k))
        margin = CROSSING_MARGIN * scale[k]
        eps = margin / abs(rate) if rate and math.isfinite(rate) else 1e-12 * step
        eps = max(eps, 4 * np.spacing(t + remaining + step))
        for _ in range(80):
            probe = y1 + eps * f_old
            if _negative(sw.value(probe, k)) != old:
                f_new = self.eq(t, probe)
                yc = y1 + eps * f_new
                gc = sw.value(yc, k)
                if _negative(gc) != old and abs(gc) >= 0.5 * margin:
                    return t + remaining + eps, yc, t + remaining
            eps *= 2.0
        raise RuntimeError(f"the reference could not cross the {sw.describe(k)[0]} event at t = {t:.9g}")

    def run(self, duration):
        eq = self.eq
        t, y = 0.0, eq.initial()
        self.emit(-math.inf, 0.0, y, None)
        step = None
        while t < duration:
            result = self.segment(t, y, duration, step)
            if not isinstance(result, _Crossing):
                t, y, step = result
                continue
            natural = result.step
            crossing = result
            for _ in range(MAX_APPROACHES):  # redo the straddling step in clean pieces up to the event
                tp, yp, key = crossing.t0, crossing.y0, crossing.key
                tiny = 64 * np.spacing(max(abs(tp), natural))
                # stop a hair before the located root, so that the clean pieces end on the old side
                bound = crossing.time - 1e-9 * (crossing.time - tp) - tiny
                close = bound - tp <= tiny
                if not close:
                    result = self.segment(tp, yp, bound, min(natural, bound - tp))
                    if isinstance(result, _Crossing):
                        crossing = result  # the same (or an earlier) event, from a shorter straddle
                        continue
                    t, y, _ = result
                else:
                    t, y = tp, yp
                    self.switches.build(y)
                k = self.switches.index(key)
                if k is None:  # no longer a candidate: nothing to cross
                    step = natural
                    break
                newton = self.distance(t, y, k, natural)
                remaining = newton[0]
                if close or 0.0 <= remaining <= 1e-2 * math.sqrt(self.rtol) * natural:
                    sw = self.switches
                    before = _negative(sw.values(y)[0])
                    t_old = t
                    t, y, when = self.cross(t, y, k, natural, newton)
                    self.emit(t_old, t, y, lambda: (lambda s: y))
                    self.restarts += 1
                    # this switch, and any other that switched at the same instant (a clamp only
                    # counts while its pair still touches: beyond, its function means nothing)
                    touching = sw.touching(y)
                    changed = (before != _negative(sw.values(y)[0])) & touching
                    changed[k] |= touching[k]
                    for item in np.flatnonzero(changed) if changed.any() else [k]:
                        what, ids, wall = sw.describe(item)
                        self.events.append({"time": when, "kind": what, "particles": ids, "wall": wall})
                    step = None  # the law changed: let the solver choose its first step afresh
                    break
                if 0.0 < remaining < math.inf:  # still some way off: Newton's estimate is the new bound
                    crossing = _Crossing(t, y, t + remaining, key, natural)
                    continue
                step = natural  # moving away (a graze the clean trajectory does not make): carry on
                break
            else:
                raise RuntimeError(f"the reference could not locate an event near t = {crossing.time:.12g}")
        return self.out


def _default_atol(eq, y, rtol, duration):
    """rtol times a scale per kind of component (lengths: the smallest radius; speeds: the fastest
    sphere or the speed its share of the energy gives; ...)."""
    radius = float(np.min(eq.scene.arrays["radius"]))
    movable = np.isfinite(eq.mass)
    mass = float(np.min(eq.mass[movable])) if movable.any() else 1.0
    e = eq.energies(y)
    energy = float(np.sum(np.abs(e)))
    v = eq.part(y, "velocity")
    speed = max(float(np.max(np.linalg.norm(v, axis=1))) if len(v) else 0.0, math.sqrt(2.0 * energy / mass),
                radius / duration)
    scales = {"position": radius, "velocity": speed, "angular_velocity": speed / radius,
              "dissipated": max(energy, mass * speed * speed)}
    if "dipole" in eq.slices:
        m = np.linalg.norm(eq.part(y, "dipole"), axis=1)
        scales["dipole"] = float(np.max(m)) if m.size and np.max(m) > 0 else 1.0
    if "angular_velocity" in eq.slices:
        w = np.linalg.norm(eq.part(y, "angular_velocity"), axis=1)
        scales["angular_velocity"] = max(scales["angular_velocity"], float(np.max(w)) if w.size else 0.0)
    return scales


class ReferenceTrajectory(Trajectory):
    """A :class:`demkit.Trajectory` computed by :func:`reference`, with what it cost:

    evaluations (force evaluations), steps (accepted DOP853 steps), restarts (events crossed),
    events (list of dicts: time, kind, particles (ids), wall (index of the wall effect or None)),
    seconds (wall time), rtol, atol (dict of absolute tolerances by component).
    """

    evaluations = steps = restarts = 0
    seconds = 0.0
    events = ()
    rtol = atol = None

    def __repr__(self):
        return (f"ReferenceTrajectory({len(self)} frames, {self.position.shape[1]} particles, "
                f"t = {self.time[0]:.6g} .. {self.time[-1]:.6g}; {self.evaluations} force evaluations, "
                f"{self.restarts} restarts)")


def reference(scene, duration, times=None, rtol=1e-12, atol=None):
    """Adaptive reference solution of a small scene (at most :data:`MAX_PARTICLES` spheres) from its
    current state, with scipy's DOP853 on the scene's own compiled forces.

    State: positions, velocities, angular velocities (if the scene has them), dipoles
    (dm/dt = omega x m) and the dissipated work W (dW/dt = the dissipated power the forces report),
    so the result carries the energy balance. Fixed spheres stay put. The integration restarts
    exactly at every switch of a force law (contact onset and release of pairs and walls, the zero
    crossing of a clamped dashpot's force, plain cutoffs): the step in which a switching function
    changed sign is discarded, redone in clean pieces up to the event, and the state carried across
    it (see docs/accuracy.md). Periodic boxes are followed with unwrapped coordinates.

    duration : time to integrate; times : output times in [0, duration] (default: 0 and duration).
    rtol : DOP853's relative tolerance; atol : absolute tolerance: None (rtol times a scale per
        kind of component: the smallest radius, the largest speed, ...), a number, or a dict by
        component ("position", "velocity", "angular_velocity", "dipole", "dissipated").

    Returns a :class:`ReferenceTrajectory`. The scene is left exactly as it was (state, dissipated
    work, neighbour lists rebuilt around it). Refuses (ValueError) scenes of more than
    :data:`MAX_PARTICLES` spheres and scenes whose interactions keep per-contact history
    (friction, rolling resistance), whose springs advance with the integrator's own step.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"reference needs a demkit.Scene, got {type(scene).__name__}")
    n = len(scene.particles)
    if n > MAX_PARTICLES:
        raise ValueError(f"the reference solver handles at most {MAX_PARTICLES} spheres, this scene has {n}: it "
                         f"integrates every coordinate with scipy in Python (cost grows as N^2 per evaluation and "
                         f"the adaptive step shrinks with N); compare against the finest fixed-step run instead "
                         f"(work_precision does so for reference='auto')")
    keepers = scene.history_keepers()
    if keepers:
        raise ValueError(f"the reference solver cannot integrate {', '.join(type(k).__name__ for k in keepers)} with "
                         f"per-contact history (friction or rolling resistance springs): their springs advance with "
                         f"the integrator's own time step, which an adaptive solver cannot reproduce; compare against "
                         f"the finest fixed-step run instead (work_precision does so for reference='auto')")
    duration = float(duration)
    if not math.isfinite(duration) or duration <= 0:
        raise ValueError(f"duration must be a positive finite time, got {duration}")
    rtol = float(rtol)
    if not (0 < rtol < 1e-3):
        raise ValueError(f"rtol must lie in (0, 1e-3), got {rtol}")
    if times is None:
        times = np.array([0.0, duration])
    times = np.unique(np.asarray(times, dtype=np.float64).ravel())
    if len(times) == 0 or times[0] < 0 or times[-1] > duration * (1 + 1e-12) or not np.isfinite(times).all():
        raise ValueError(f"times must lie in [0, duration = {duration:.6g}]")
    times = np.minimum(times, duration)
    clock = _time.perf_counter()
    with _Borrowed(scene) as eq:
        y0 = eq.initial()
        scales = _default_atol(eq, y0, rtol, duration)
        if atol is None:
            atols = {name: rtol * value for name, value in scales.items()}
        elif isinstance(atol, dict):
            unknown = set(atol) - set(eq.slices)
            if unknown:
                raise ValueError(f"atol names unknown components {sorted(unknown)}; known: {list(eq.slices)}")
            atols = {name: float(atol.get(name, rtol * scales[name])) for name in eq.slices}
        else:
            atols = {name: float(atol) for name in eq.slices}
        vector = np.zeros(eq.size_y)
        for name, s in eq.slices.items():
            vector[s] = atols[name]
        switches = _Switches(scene, eq)
        driver = _Reference(eq, switches, rtol, vector, times)
        frames = driver.run(duration)
        records = [eq.frame(y) for _, y in frames]
        evaluations = eq.evaluations
    seconds = _time.perf_counter() - clock
    p = scene.particles
    stack = lambda k: np.array([r[k] for r in records])  # noqa: E731
    energies = stack(5)
    dissipated = np.array([y[eq.slices["dissipated"]][0] for _, y in frames])
    traj = ReferenceTrajectory(
        time=np.array([t for t, _ in frames]), position=stack(0), velocity=stack(2),
        angular_velocity=stack(3) if p.angular_velocity is not None else None,
        dipole=stack(4) if p.dipole is not None else None,
        energy=energy_dict(energies, eq.kinds, dissipated), angular_momentum=stack(6),
        radius=p.radius.copy(), mass=p.mass.copy(), inertia=p.inertia.copy(), ids=p.ids.copy(),
        image=stack(1) if p.image is not None else None, box=scene.box)
    traj.evaluations, traj.steps, traj.restarts = evaluations, driver.steps, driver.restarts
    traj.events, traj.seconds, traj.rtol, traj.atol = list(driver.events), seconds, rtol, atols
    return traj


_adaptive = reference  # work_precision's argument ``reference`` shadows the name
