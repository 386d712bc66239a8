"""A time step chosen for an accuracy: what ``dt = "auto"`` means.

:func:`choose_time_step` picks the step of a run so that its energy balance (kinetic + rotational +
potential + dissipated, the figure the end-of-run notes check, :mod:`demkit.notes`) stays within
``accuracy`` of the run's energy scale (default :data:`ACCURACY`, the notes' own limit). It aims
at :data:`MARGIN` of it, in three stages:

1. **stability**: half the largest step the guards accept (:func:`demkit.guards.largest_safe_step`);
2. **a pilot**, measured: the scene's start is run (on a copy: nothing of the scene changes) for
   :data:`PILOT_FRACTION` of the run (at least :data:`PILOT_STEPS` steps) at that step; in a scene
   with dashpots, a pilot that dissipates less than :data:`DISSIPATING` of the energy scale runs
   on to :data:`GROWTH` times its window, and again, until it has dissipated :data:`ENOUGH` of it
   or reached the run's end (its impacts come later: the seed paper's pair meets 37 % into its run;
   a pour's first impacts are not its bulk; a pilot at this longest step costs at most what a run
   at it does). Its balance
   is read: the largest departure, plus, when the pilot dissipates, the departure per energy
   dissipated at its end times the energy the run would dissipate beyond the pilot's at the
   pilot's rate (at most the whole scale: the part that accumulates; the whole scale when it began
   dissipating only after its first window: the bulk of a pour's impacts is still to come). When this prediction
   exceeds :data:`ACCEPT` of the accuracy, the step shrinks to aim at MARGIN of it (at first order
   when the pilot dissipates: dashpots; else at the method's order); a pilot of the first window
   runs again at the new step (at most :data:`PILOTS` in all), a longer one is trusted (running it
   again would cost more than the run).
3. **dashpots**, a law, only with ``pilot=False`` (the worst case, no run): a fixed step applies a
   dashpot's force with the velocity half a step old, which strengthens its damping by
   c dt / 2 m* (docs/accuracy.md: measured on a Kelvin-Voigt impact, 0.27 % of the dissipated
   energy at 80 steps per contact for the predicted 0.26 %): a run that dissipates its energy
   scale ends rate * dt of it off, rate = c / 2 m* of the fastest dashpot (Kelvin-Voigt: its
   damping over the lightest pair; Hertz: eta_n = gamma sqrt(m* S_n) at the deepest overlap of the
   fastest impact the guards foresee; a wall: the lightest sphere). On the way, each contact's
   onset takes c dt / m* = 2 rate dt of the impact's kinetic energy before the dashpot's work is
   booked (:data:`ONSET`; measured: 1.00 % at c dt / m* = 0.01, the largest departure of a
   head-on impact's balance). So dt <= MARGIN accuracy / ((ONSET + 1) rate): right for a pair
   (the seed paper's: 0.22 % at the aim 0.5 %), 10-20 times too strict for scenes of many spheres,
   whose impacts each carry a sliver of the scale and which dissipate a part of it (60 steel balls
   chaining in a field: 0.13 % at half the largest safe step, where the law says 2.7 %). Skipped by
   resolved contacts (``resolve_contacts=True``: their dashpots are second order).

The balance is not checked in scenes with a heat bath or a moving wall (their work is not booked,
:mod:`demkit.notes`): they take stage 1 alone. Overlaps depend on the contact law's
stiffness, not on the step: no step choice removes their note.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from . import checks
from .guards import _approach_speed, largest_safe_step
from .interactions.contact import KelvinVoigt
from .interactions.hertz import Hertz, hertz_impact
from .interactions.wall import Wall
from .notes import ENERGY_DRIFT

#: the energy balance a run with dt = "auto" keeps by default (fraction of its energy scale): the
#: end-of-run note's limit
ACCURACY = ENERGY_DRIFT
#: the step aims at this fraction of the accuracy asked: a margin for what a pilot extrapolates
#: (its predictions were 1.2-2.4 times the drift of the runs, benchmarks/results/auto_step.json)
MARGIN = 0.6
#: a pilot runs this fraction of the run ...
PILOT_FRACTION = 0.02
#: ... and at least this many steps (or the whole run when it is shorter)
PILOT_STEPS = 300
#: a pilot whose impacts began after its first window runs on until it has dissipated this much of
#: the energy scale (or to the run's end): a pour's first impacts are not its bulk
ENOUGH = 0.1
#: a step this many times shorter than half the safe step says so in its reason
COSTLY = 20.0
#: a pilot records frames at every step, or as often as this many sphere-frames allow (~100 MB)
SPHERE_FRAMES = 1_000_000
#: a contact's onset departs the balance by ONSET rate dt of the impact's kinetic energy (stage 3)
ONSET = 2.0
#: a pilot that dissipated nothing runs on to this many times its window (up to the whole run)
GROWTH = 4.0
#: at most this many pilots at shorter steps (each over the first pilot's window)
PILOTS = 3
#: a pilot's prediction is accepted up to this fraction of the accuracy (it aims at MARGIN when it
#: shrinks the step: a prediction within 25 % of the aim is not worth another pilot)
ACCEPT = 0.75
#: a pilot that dissipates more than this fraction of the energy scale measures the dashpots' drift
DISSIPATING = 0.01


@dataclass
class StepChoice:
    """The step chosen (``dt``, the method's whole step) and why: ``accuracy`` asked, ``stable`` half
    the largest safe step, ``dashpot`` the worst-case bound of stage 3 (inf: none), ``pilots``
    one dict per pilot reading (dt, steps from its start, of which ``added`` new: a pilot that found no
    impact runs on; drift and dissipated energy as fractions of the energy scale, predicted drift of
    the run), ``seconds`` what choosing cost (wall), ``why`` one line."""

    dt: float
    accuracy: float
    stable: float
    dashpot: float
    why: str
    pilots: list = field(default_factory=list)
    seconds: float = 0.0

    def __str__(self):
        return f"dt = {self.dt:.4g}: {self.why}"


def dashpot_rate(scene):
    """(rate, what): the largest c / 2 m* of the scene's contact dashpots (1/time; 0.0 when none), and
    which law sets it. A Hertz law's at the deepest overlap of the fastest impact the guards foresee
    (0.0 while nothing moves: no impact speed is known yet)."""
    p = scene.particles
    if not len(p):
        return 0.0, "no spheres"
    m = np.sort(np.asarray(p.mass, dtype=float))
    pair_mass = m[0] * m[1] / (m[0] + m[1]) if len(m) > 1 else 0.5 * m[0]
    speed = None
    best, what = 0.0, "no contact dashpot"
    for inter in scene.interactions + scene.effects:
        wall = isinstance(inter, Wall)
        law = inter.law if wall else inter
        mass = m[0] if wall else pair_mass
        if isinstance(law, KelvinVoigt):
            rate = law.damping / (2.0 * mass)
        elif isinstance(law, Hertz):
            if speed is None:
                speed = _approach_speed(scene)[0]
            if not speed > 0.0:
                continue
            r = np.sort(np.asarray(p.radius, dtype=float))
            other = r[min(1, len(r) - 1)]
            radius = r[0] if wall else r[0] * other / (r[0] + other)
            young = 2.0 * law.young_eff if wall else law.young_eff  # a rigid plane: E/(1 - nu^2)
            depth = hertz_impact(young, radius, mass, speed)[0]
            stiffness = 2.0 * young * math.sqrt(radius * depth)
            rate = 0.5 * law.gamma * math.sqrt(stiffness / mass)
        else:
            continue
        if rate > best:
            best, what = rate, f"{'a wall of ' if wall else ''}{law!r}"
    return best, what


def choose_time_step(scene, method, duration, accuracy=ACCURACY, pilot=True):
    """A step for ``method`` (an Integrator class or a callable dt -> Integrator, e.g. ``lambda dt:
    dk.MultipleTimeStep(dt, inner=4)``) to run ``scene`` for ``duration`` with its energy balance
    within ``accuracy`` of its energy scale (see the module docstring). ``pilot=False``: stages 1
    and 3 only (no run). Returns a :class:`StepChoice`; raises ValueError when no stability limit
    is known yet (nothing moves or pulls) or a pilot fails."""
    from .accuracy import copy_scene
    from .notes import RunNotes
    clock = time.perf_counter()
    duration = checks.positive("duration", duration)
    accuracy = checks.positive("accuracy", accuracy)
    if accuracy >= 1.0:
        raise ValueError(f"accuracy is a fraction of the energy scale, below 1; got {accuracy!r}")
    probe = method(1.0)
    probe.check(scene)  # what the method refuses in this scene (e.g. a heat bath without velocity Verlet)
    inner = probe.dt / probe.contact_step  # the contact step is dt / inner
    limit, why = largest_safe_step(scene)
    if not math.isfinite(limit):
        raise ValueError(f'dt = "auto" found no largest safe step ({why}); give dt as a number (for an impact '
                         f'at speed v: a tenth of the contact time at v, docs/contacts.md)')
    stable = 0.5 * limit * inner
    aim = MARGIN * accuracy
    rate, what = dashpot_rate(scene)
    resolved = bool(getattr(probe, "resolve_contacts", False))
    dashpot = aim / ((ONSET + 1.0) * rate) * inner if rate > 0.0 and not resolved else math.inf
    dt, reason, pilots = stable, f"half the largest safe step ({why})", []
    if pilot and RunNotes(scene).balance:
        first = min(max(PILOT_STEPS * dt, PILOT_FRACTION * duration), duration)
        window, run = first, _Pilot(copy_scene(scene), method(dt))
        while True:  # until it dissipates (impacts later in the run: the seed paper's pair meets at 37 %)
            figures = run.extend(window, duration, late=window > first)
            if figures is None:  # no energy at all: nothing to measure
                break
            pilots.append(figures)
            if window >= duration or rate == 0.0:  # (no dashpot: nothing to wait for)
                break
            if figures["dissipated"] > (DISSIPATING if window == first else ENOUGH):  # (a late start: its bulk)
                break
            window = min(GROWTH * window, duration)
        tries = 1
        while figures is not None and figures["predicted"] > ACCEPT * accuracy:
            dissipating = figures["dissipated"] > DISSIPATING
            order = 1.0 if dissipating else float(probe.order or 1)
            dt *= 0.9 * (aim / figures["predicted"]) ** (1.0 / order)
            reason = (f"a pilot of {figures['steps']:,} steps at dt = {figures['dt']:.4g} "
                      f"({figures['steps'] * figures['dt'] / duration:.0%} of the run) predicted a drift of "
                      f"{figures['predicted']:.3g} of the energy scale ("
                      f"{'its dissipation extrapolated to the run' if dissipating else 'as measured'}); shrunk at "
                      f"order {order:g} to aim at {aim:.3g}")
            if window > first:  # a long pilot is not run again (it would cost more than the run saves)
                break
            if tries == PILOTS:
                reason += f" (after {PILOTS} pilots)"
                break
            tries += 1
            figures = _Pilot(copy_scene(scene), method(dt)).extend(window, duration, late=window > first)
            if figures is not None:
                pilots.append(figures)
    elif pilot:
        reason += "; no pilot: a heat bath or a moving wall does work the balance does not book"
    elif dashpot < dt:  # no pilot asked for: the dashpots' law, the worst case
        dt = dashpot
        reason = (f"the dashpots of {what} (rate c/2m* = {rate:.4g}) in the worst case keep the balance within "
                  f"{aim:.3g}: {rate * dt / inner:.3g} of the energy dissipated, {ONSET * rate * dt / inner:.3g} "
                  f"of an impact's at its onset")
    if dt < stable / COSTLY:  # a careless accuracy: say what it costs
        reason += (f"; {stable / dt:.0f} times the steps of half the safe step (the accuracy asked costs that; "
                   f"a looser one costs less)")
    return StepChoice(dt, accuracy, stable, dashpot, reason, pilots, time.perf_counter() - clock)


class _Pilot:
    """A pilot run of a copy of the scene at one step, extended window by window (a continued run is
    the same as one run: the steps already made are not made again)."""

    def __init__(self, scene, integrator):
        from .simulation import Simulation
        self.sim, self.dt, self.steps, self.energies = Simulation(scene, integrator, notes=False), integrator.dt, 0, []

    def extend(self, window, duration, late=False):
        """Run on to ``window`` and return the figures over it: its largest departure of the balance
        (``drift``) and energy dissipated (fractions of the energy scale), and the drift it predicts
        for the run (the departure per energy dissipated at its end, times the energy the run would
        dissipate beyond the pilot's at the pilot's rate, at most the scale; the whole scale when the
        dissipation started ``late``: its bulk is still to come); None without energy."""
        from .simulation import SimulationError
        more = max(0, math.ceil(window / self.dt) - self.steps)
        if more > 0:
            # frames at every step up to SPHERE_FRAMES (the balance departs most for a step or two as
            # a contact begins: sparse frames would miss what a run recording often shows)
            stride = max(1, math.ceil(more * len(self.sim.scene.particles) / SPHERE_FRAMES))
            try:
                traj = self.sim.run(duration=more * self.dt, record_every=stride * self.dt, progress=False)
            except SimulationError as error:
                raise ValueError(f'dt = "auto": a pilot run at dt = {self.dt:.4g} failed ({error}); give dt as '
                                 f'a number') from error
            self.energies.append((np.column_stack([v for k, v in traj.energy.items()
                                                   if k not in ("total", "dissipated")]), traj.energy["dissipated"]))
            self.steps += more
        parts = np.concatenate([e for e, _ in self.energies])
        lost = np.concatenate([d for _, d in self.energies])
        total = parts.sum(axis=1) + lost
        scale = float(np.max(np.abs(parts).sum(axis=1)))  # as the notes' (demkit.notes)
        if not scale > 0.0:
            return None
        drift = float(np.max(np.abs(total - total[0]))) / scale
        dissipated = float(lost[-1] - lost[0]) / scale
        predicted = drift
        if dissipated > DISSIPATING:
            expected = min(1.0, dissipated * duration / (self.steps * self.dt))  # of the scale, by the run's end
            if late and self.steps * self.dt < duration:
                expected = 1.0
            predicted += abs(total[-1] - total[0]) / scale / dissipated * max(0.0, expected - dissipated)
        return {"dt": self.dt, "steps": self.steps, "added": more, "drift": drift, "dissipated": dissipated,
                "predicted": predicted}
