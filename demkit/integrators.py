"""Time integrators. They see only force and torque arrays, never which interactions exist.

Each integrator names a *loop template* (:mod:`demkit.engine.templates`, where their signature and what
they may call are written): a plain Python function whose source is pasted into the scene's generated
kernel modules and compiled there, so that many steps run in compiled code between Python-level events.

Methods: :class:`EulerCromer` (order 1), :class:`VelocityVerlet` (2), :class:`ForestRuth` (4,
symplectic composition of velocity-Verlet sub-steps) and :class:`RK4` (4, not symplectic; its
stages work on copies of the state in ``s.stage``). The adaptive reference solver used as the truth
is in :mod:`demkit.accuracy`.
"""
from __future__ import annotations

import numpy as np

from . import checks
from .engine.templates import TEMPLATES  # noqa: F401 (the integrators name their templates)

class Integrator:
    """Base class: a fixed time step ``dt`` and the name of a loop template in :data:`TEMPLATES`.

    Class attributes: ``order`` (of the trajectory, for smooth forces), ``evaluations_per_step``
    (force evaluations per step), ``symplectic``, ``stage_arrays`` ((N,3) working arrays the scene
    must hold, :meth:`demkit.Scene.reserve_stages`) and ``history`` (whether it integrates
    per-contact history: friction and rolling springs advance by one step at each force evaluation,
    which only fits methods that evaluate forces once per step at increasing times).
    """

    template = None
    order = None
    evaluations_per_step = 1
    symplectic = True
    stage_arrays = 0
    history = True

    #: inner steps per step (only multiple time stepping has more than one)
    inner = 1
    #: contact onsets and releases located (VelocityVerlet and MultipleTimeStep can)
    resolve_contacts = False

    def __init__(self, dt):
        self.dt = checks.positive("time step dt", dt)

    @property
    def contact_step(self):
        """The step the stiff forces are integrated with (and contact history advances by)."""
        return self.dt / self.inner

    def check(self, scene):
        """Raise ValueError if this method cannot integrate ``scene``."""
        baths = scene.heat_baths
        if baths and not (type(self) is VelocityVerlet and not self.resolve_contacts):
            raise ValueError(
                f"{baths[0]!r} runs with VelocityVerlet(dt) only (without resolve_contacts): with it the "
                f"random kicks keep the bath's temperature exactly for free spheres; {self!r} would not")
        if self.resolve_contacts:
            if scene.box is not None and scene.box.shear is not None:
                raise ValueError(f"{self!r} locates contacts with the plain minimum image, not the sliding images of "
                                 f"a sheared box: use {type(self).__name__}(dt) without resolve_contacts")
            if scene.box is not None and getattr(scene.box, "deform", None) is not None:
                raise ValueError(f"{self!r} locates contacts in a fixed box, not one the steps remap: use "
                                 f"{type(self).__name__}(dt) without resolve_contacts in a deforming box")
            curved = [e for e in scene.effects if not getattr(e, "flat", True)]
            if curved:
                raise ValueError(f"{self!r} locates contacts with plane walls that stand still only, and this scene has "
                                 f"{curved[0]!r}: use {type(self).__name__}(dt) without resolve_contacts")
        if not self.history:
            kept = scene.history_keepers()
            if kept:
                raise ValueError(
                    f"{type(self).__name__} cannot integrate per-contact history, which {kept[0]!r} keeps "
                    f"(friction or rolling springs advance one step per force evaluation): use VelocityVerlet "
                    f"(without resolve_contacts) or EulerCromer for this scene")

    def _resolving(self, resolve_contacts, template, stage_arrays):
        """Switch to the contact-event template ``template`` (see VelocityVerlet) when asked."""
        if resolve_contacts not in (True, False):
            raise ValueError(f"resolve_contacts must be True or False, got {resolve_contacts!r}")
        self.resolve_contacts = bool(resolve_contacts)
        if self.resolve_contacts:
            self.template, self.stage_arrays, self.history = template, stage_arrays, False

    def __repr__(self):
        extra = ", resolve_contacts=True" if self.resolve_contacts else ""
        return f"{type(self).__name__}(dt={self.dt!r}{extra})"


class EulerCromer(Integrator):
    """Semi-implicit (symplectic) Euler, the seed paper's method; first order.

    v += F(x)/m dt; x += v dt; w += tau/I dt; dipoles rotate about the new w by |w| dt.
    """

    template = "euler_cromer"
    order = 1


class VelocityVerlet(Integrator):
    """Kick-drift-kick velocity Verlet with exact free rotation of the dipoles; second order.

    v += F/m dt/2, w += tau/I dt/2; x += v dt, dipoles rotate by |w| dt; new F, tau; v, w += dt/2.
    Velocity-dependent forces (dashpots) see the half-step velocities.

    resolve_contacts : locate every contact onset and release within a step (:mod:`demkit.engine.events`)
        and end a sub-step there, stepping over the crossing itself in a sub-step of 1e-6 dt; the
        forces see velocities predicted to the end of each sub-step (v + F/m h, so a dashpot is
        second order too) and the dissipated work is summed by the trapezoidal rule. With it, the
        state and the energy balance of colliding spheres converge at second order instead of
        first, for one extra O(N) pass and an event search per step (all pairs in scenes without
        neighbour lists, the contact list otherwise, and every sphere against every wall).
        Contact history is refused (sub-steps of varying length).
    """

    template = "velocity_verlet"
    order = 2

    def __init__(self, dt, resolve_contacts=False):
        super().__init__(dt)
        self._resolving(resolve_contacts, "velocity_verlet_events", 3)


class ForestRuth(Integrator):
    """Fourth-order symplectic composition (Forest & Ruth 1990; Yoshida 1990): three velocity-Verlet
    sub-steps of w1 dt, w0 dt, w1 dt with w1 = 1/(2 - 2^(1/3)) = 1.3512, w0 = 1 - 2 w1 = -1.7024.

    Three force evaluations per step; exact free rotation of the dipoles in every sub-step. Fourth
    order for smooth conservative forces; the jumps of a dashpot at contact onset cap it, as they
    cap every method (docs/accuracy.md). The middle sub-step runs backwards in time, so contact
    history (friction, rolling resistance) is refused.
    """

    template = "forest_ruth"
    order = 4
    evaluations_per_step = 3
    history = False


class RK4(Integrator):
    """Classic fourth-order Runge-Kutta, with the dipoles carried by Runge-Kutta-Munthe-Kaas: each
    stage turns m0 by a rotation vector theta (exp(theta) m0, exact rotations, so |m| is kept to
    round-off), whose rate is dexp^-1_theta(omega). Four force evaluations per step.

    Not symplectic: over long conservative runs its energy error drifts instead of staying bounded
    (kept for comparison). The dissipated work is summed with RK4's weights (b = 1/6, 1/3, 1/3, 1/6),
    so the energy balance is fourth order too between contact events. No contact history.
    """

    template = "rk4"
    order = 4
    evaluations_per_step = 4
    symplectic = False
    stage_arrays = 9
    history = False


class MultipleTimeStep(Integrator):
    """Multiple time stepping (r-RESPA, Tuckerman, Berne & Martyna 1992): the slow forces (dipoles,
    ``Interaction.slow``) kick on the outer step ``dt``, the fast ones (contacts, walls, gravity,
    fields) drive ``inner`` velocity-Verlet sub-steps of dt/inner in between:

        kick_slow(dt/2) [kick_fast(h/2) drift(h) kick_fast(h/2)] x inner  kick_slow(dt/2),  h = dt/inner.

    Symmetric and symplectic, second order. Each step costs ``inner`` fast force evaluations and one
    slow one: where dipoles dominate the cost (dense magnetic scenes), dt can grow to what the
    dipoles need while the contacts keep their short step. Contact history advances by the inner
    step. Slow forces are assumed smooth: with dt much longer than their own time scale, resonances
    of r-RESPA appear (keep dt below a third of the fastest dipolar period).

    resolve_contacts : the inner sub-steps as ``VelocityVerlet(resolve_contacts=True)``'s: contact
        onsets and releases located, dashpots seeing predicted velocities, dissipated work by the
        trapezoidal rule (no contact history then).
    """

    template = "multiple_time_step"
    order = 2
    stage_arrays = 4

    def __init__(self, dt, inner=4, resolve_contacts=False):
        super().__init__(dt)
        if isinstance(inner, bool) or not isinstance(inner, (int, np.integer)) or inner < 1:
            raise ValueError(f"inner must be a whole number of sub-steps >= 1, got {inner!r}")
        self.inner = int(inner)
        self._resolving(resolve_contacts, "multiple_time_step_events", 7)

    @property
    def evaluations_per_step(self):
        """Force evaluations per step: ``inner`` fast ones and a slow one (counted as one each)."""
        return self.inner + 1

    def check(self, scene):
        super().check(scene)
        slow_history = [inter for inter in scene.interactions if inter.slow and inter.history_size]
        if slow_history:
            raise ValueError(f"{slow_history[0]!r} is a slow interaction that keeps history: "
                             f"MultipleTimeStep evaluates slow forces once per outer step and cannot advance it")

    def __repr__(self):
        extra = ", resolve_contacts=True" if self.resolve_contacts else ""
        return f"MultipleTimeStep(dt={self.dt!r}, inner={self.inner}{extra})"


#: integrators named without options in scene files and on the command line
PLAIN = {"EulerCromer": EulerCromer, "VelocityVerlet": VelocityVerlet, "ForestRuth": ForestRuth, "RK4": RK4}


def parse_method(text):
    """An integrator factory f(dt) from a name such as 'RK4', 'MultipleTimeStep:8:resolve' (the
    methods of scene files and of `demkit accuracy --methods`)."""
    name, *options = text.strip().split(":")
    resolve = "resolve" in options
    options = [o for o in options if o != "resolve"]
    if name in PLAIN and not options:
        if resolve and name != "VelocityVerlet":
            raise ValueError(f"{name} cannot resolve contact events (VelocityVerlet and MultipleTimeStep can)")
        cls = PLAIN[name]
        return (lambda dt: cls(dt, resolve_contacts=True)) if resolve else cls
    if name == "MultipleTimeStep" and len(options) <= 1:
        try:
            inner = int(options[0]) if options else 4
        except ValueError:
            raise ValueError(f"MultipleTimeStep:<inner> needs a whole number of inner steps, got {text!r}") from None
        MultipleTimeStep(1.0, inner=inner)  # checks inner now, not in the middle of the study
        return lambda dt: MultipleTimeStep(dt, inner=inner, resolve_contacts=resolve)
    raise ValueError(f"unknown method {text!r}: use {', '.join(PLAIN)}, MultipleTimeStep[:inner], with "
                     f"':resolve' after VelocityVerlet or MultipleTimeStep")
