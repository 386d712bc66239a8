"""The time loops' templates: plain Python functions whose source is pasted into the generated kernel
modules (:mod:`demkit.engine.kernels`, tier 2; :mod:`demkit.engine.generic`, tier 1) and compiled there,
so that many steps run in compiled code between Python-level events. A template has the signature

    template(nsteps, first_step, stride, dt, forces_ready, s, record) -> int

where ``s`` is the scene's named state (:mod:`demkit.engine.state`: ``s.position``, ``s.velocity``,
``s.angular_velocity``, ``s.dipole``, ``s.mass``, ``s.inertia``, ``s.force``, ``s.torque``,
``s.accum`` (accum[0]: dissipated work), ``s.clock`` (clock[0]: the time the next forces are evaluated
at; moving walls read it), ...). In scenes whose walls move (``timed``: the program's H_CLOCK on tier 1,
a constant written into a fused module) it sets ``s.clock[0]`` before every call of a force function,
to (global step + fraction of the step its positions have reached) * dt (the global step count of the
chunk's start is s.counters[RUN_START] + first_step), and leaves it at the time of the state it
returns; elsewhere the clock costs nothing (a store a step cost the two magnets' steps 20 %). It may
call ``forces_of(s, commit)`` (fills
``s.force``/``s.torque`` and keeps neighbour lists up to date; returns the dissipated power),
``end_step(step, countdown, stride, s, record, timed)`` (list upkeep, servo-controlled walls, finiteness
check and recording;
returns the steps left until the next frame, or -1 when the run must stop) and the helpers of
:mod:`demkit.engine.motion`. Pass fields straight into calls (``kick(s.velocity, s.force, s.mass, h)``);
binding them to local names makes numba count references at every use. It records frame
``step // stride`` after every step that is a multiple of ``stride`` (global count
``first_step + n + 1``) and returns -1, or the index n of the step after which the run stopped.
Per-particle arrays may be re-ordered or wrapped only in ``end_step``, between steps.

The integrator classes that name them (``template``) are in :mod:`demkit.integrators`.
"""
from __future__ import annotations

import inspect
import re
import textwrap

from .motion import (advance_spin, copy_vectors, drift, kick, kick_all, rk_finish, rk_save,  # noqa: F401
                     rk_stage, total_forces)
from .program import H_CLOCK  # noqa: F401 (used by templates)
from .state import INNER_STEPS, RUN_START  # noqa: F401 (used by templates)


def euler_cromer_template(nsteps, first_step, stride, dt, forces_ready, s, record):
    start = s.counters[RUN_START] + first_step  # the global step count at the start of the chunk
    timed = s.program[0, H_CLOCK] != 0  # walls that move read the clock (tier 2: True or False, as written)
    countdown = stride - first_step % stride  # steps until the next recorded frame
    for n in range(nsteps):
        if timed:
            s.clock[0] = (start + n) * dt
        s.accum[0] += dt * forces_of(s, True)  # noqa: F821 (defined in the generated module)
        kick(s.velocity, s.force, s.mass, dt)
        drift(s.position, s.velocity, dt)
        advance_spin(s.angular_velocity, s.dipole, s.torque, s.inertia, dt, dt)
        if timed:
            s.clock[0] = (start + n + 1) * dt
        countdown = end_step(first_step + n + 1, countdown, stride, s, record, timed)  # noqa: F821
        if countdown < 0:
            return n
    return -1


def velocity_verlet_template(nsteps, first_step, stride, dt, forces_ready, s, record):
    start = s.counters[RUN_START] + first_step  # the global step count at the start of the chunk
    timed = s.program[0, H_CLOCK] != 0  # walls that move read the clock (tier 2: True or False, as written)
    half = 0.5 * dt
    countdown = stride - first_step % stride  # steps until the next recorded frame
    # one call of forces_of in the source (n = -1: the forces of the start): numba inlines each call
    # site whole, so a second one would double the time spent compiling the scene's forces
    n = 0 if forces_ready else -1
    while n < nsteps:
        if n >= 0:
            kick_all(s.velocity, s.angular_velocity, s.dipole, s.force, s.torque, s.mass, s.inertia, half, dt)
            drift(s.position, s.velocity, dt)
        if timed:
            s.clock[0] = (start + n + 1) * dt
        power = forces_of(s, n >= 0)  # noqa: F821
        if n >= 0:
            s.accum[0] += dt * power
            kick_all(s.velocity, s.angular_velocity, s.dipole, s.force, s.torque, s.mass, s.inertia, half, 0.0)
            countdown = end_step(first_step + n + 1, countdown, stride, s, record, timed)  # noqa: F821
            if countdown < 0:
                return n
        n += 1
    return -1


def forest_ruth_template(nsteps, first_step, stride, dt, forces_ready, s, record):
    start = s.counters[RUN_START] + first_step  # the global step count at the start of the chunk
    timed = s.program[0, H_CLOCK] != 0  # walls that move read the clock (tier 2: True or False, as written)
    w1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
    w0 = 1.0 - 2.0 * w1
    countdown = stride - first_step % stride  # steps until the next recorded frame
    # sub-step m of step m // 3; one call of forces_of in the source (see velocity_verlet_template)
    m = 0 if forces_ready else -1
    h = 0.0
    while m < 3 * nsteps:
        if m >= 0:
            h = w0 * dt if m % 3 == 1 else w1 * dt
            kick_all(s.velocity, s.angular_velocity, s.dipole, s.force, s.torque, s.mass, s.inertia, 0.5 * h, h)
            drift(s.position, s.velocity, h)
        # the positions have reached w1, w1 + w0, 1 of step m // 3 (m = -1: the end of the step before)
        if timed:
            s.clock[0] = (start + m // 3 + (w1 if m % 3 == 0 else (w1 + w0 if m % 3 == 1 else 1.0))) * dt
        power = forces_of(s, False)  # noqa: F821
        if m >= 0:
            s.accum[0] += h * power
            kick_all(s.velocity, s.angular_velocity, s.dipole, s.force, s.torque, s.mass, s.inertia, 0.5 * h, 0.0)
            if m % 3 == 2:
                n = m // 3
                countdown = end_step(first_step + n + 1, countdown, stride, s, record, timed)  # noqa: F821
                if countdown < 0:
                    return n
        m += 1
    return -1


def rk4_template(nsteps, first_step, stride, dt, forces_ready, s, record):
    start = s.counters[RUN_START] + first_step  # the global step count at the start of the chunk
    timed = s.program[0, H_CLOCK] != 0  # walls that move read the clock (tier 2: True or False, as written)
    countdown = stride - first_step % stride  # steps until the next recorded frame
    # one call of forces_of in the source (see velocity_verlet_template): stage k = 0..3 of step n,
    # k = 4: the forces of the state reached (for writers and diagnostics), then return
    result = -1
    n = 0
    k = 4
    total = 0.0
    if nsteps > 0:
        k = 0
        rk_save(s.stage, s.position, s.velocity, s.angular_velocity, s.dipole)
    while True:
        # stage k of step n is at 0, 1/2, 1/2, 1 of the step; k = 4, the state reached: the end of step n
        # if it stopped the run, else n steps done
        if timed:
            s.clock[0] = (start + n + (0.0 if k == 0 else (0.5 if k < 3 else (1.0 if k == 3 or result >= 0 else 0.0)))) * dt
        power = forces_of(s, False)  # noqa: F821
        if k == 4:
            return result
        outer = k == 0 or k == 3
        total += power if outer else 2.0 * power  # Simpson-like quadrature of the power
        c = 0.5 * dt if k < 2 else (dt if k == 2 else 0.0)
        rk_stage(s.stage, s.position, s.velocity, s.angular_velocity, s.dipole, s.force, s.torque, s.mass,
                 s.inertia, 1.0 / 6.0 if outer else 1.0 / 3.0, c)
        k += 1
        if k == 4:
            rk_finish(s.stage, s.position, s.velocity, s.angular_velocity, s.dipole, dt)
            s.accum[0] += dt * total / 6.0
            countdown = end_step(first_step + n + 1, countdown, stride, s, record, timed)  # noqa: F821
            if countdown < 0:
                result = n
            else:
                n += 1
                if n < nsteps:
                    k = 0
                    total = 0.0
                    rk_save(s.stage, s.position, s.velocity, s.angular_velocity, s.dipole)


def multiple_time_step_template(nsteps, first_step, stride, dt, forces_ready, s, record):
    start = s.counters[RUN_START] + first_step  # the global step count at the start of the chunk
    timed = s.program[0, H_CLOCK] != 0  # walls that move read the clock (tier 2: True or False, as written)
    # s.stage[0], [1]: slow force and torque; [2], [3]: fast force and torque (kept between chunks).
    # One call of each force function in the source (see velocity_verlet_template); n = -1: the
    # forces of the start, one evaluation of each
    inner = s.counters[INNER_STEPS]  # noqa: F821
    h = dt / inner
    countdown = stride - first_step % stride  # steps until the next recorded frame
    n = 0 if forces_ready else -1
    while n < nsteps:
        if n >= 0:
            kick_all(s.velocity, s.angular_velocity, s.dipole, s.stage[0], s.stage[1],
                     s.mass, s.inertia, 0.5 * dt, 0.0)
        m = 0 if n >= 0 else inner - 1
        while m < inner:
            if n >= 0:
                kick_all(s.velocity, s.angular_velocity, s.dipole, s.stage[2], s.stage[3],
                         s.mass, s.inertia, 0.5 * h, h)
                drift(s.position, s.velocity, h)
            if timed:
                s.clock[0] = (start + n) * dt + (m + 1) * h
            power = fast_forces_of(s, s.stage[2], s.stage[3], n >= 0)  # noqa: F821
            if n >= 0:
                s.accum[0] += h * power
                kick_all(s.velocity, s.angular_velocity, s.dipole, s.stage[2], s.stage[3],
                         s.mass, s.inertia, 0.5 * h, 0.0)
            m += 1
        if timed:
            s.clock[0] = (start + n + 1) * dt
        power = slow_forces_of(s, s.stage[0], s.stage[1], n >= 0)  # noqa: F821
        if n >= 0:
            s.accum[0] += dt * power
            kick_all(s.velocity, s.angular_velocity, s.dipole, s.stage[0], s.stage[1],
                     s.mass, s.inertia, 0.5 * dt, 0.0)
            countdown = end_step(first_step + n + 1, countdown, stride, s, record, timed)  # noqa: F821
            if countdown < 0:
                total_forces(s.force, s.torque, s.stage)
                return n
        n += 1
    # the total force and torque, for writers and diagnostics
    total_forces(s.force, s.torque, s.stage)
    return -1


def velocity_verlet_events_template(nsteps, first_step, stride, dt, forces_ready, s, record):
    start = s.counters[RUN_START] + first_step  # the global step count at the start of the chunk
    timed = s.program[0, H_CLOCK] != 0  # walls that move read the clock (tier 2: True or False, as written)
    # s.stage[0], [1]: half-step velocities and spins; s.stage[2, 0, 0]: the dissipated power at the
    # last force evaluation (the trapezoidal rule sums the dissipated work). One call of forces_of
    # in the source (see velocity_verlet_template); n = -1: the forces of the start
    tiny = 1e-6 * dt  # a crossing is stepped over in a sub-step this long
    countdown = stride - first_step % stride  # steps until the next recorded frame
    n = 0 if forces_ready else -1
    while n < nsteps:
        left = dt
        events = 0
        while True:
            h = left
            if n >= 0:
                if events < 8:  # at most 8 contact events per step are located; then plain sub-steps
                    tau = next_contact_event(s, s.force, left)  # noqa: F821
                    if tau < left:
                        events += 1
                        h = tau - 0.5 * tiny if tau > tiny else min(tau + 0.5 * tiny, left)
                kick_all(s.velocity, s.angular_velocity, s.dipole, s.force, s.torque, s.mass, s.inertia, 0.5 * h, h)
                drift(s.position, s.velocity, h)
                # the forces see velocities predicted to the end of the sub-step (second order for
                # dashpots), then the half-step ones are restored for the closing kick
                copy_vectors(s.stage[0], s.velocity)
                copy_vectors(s.stage[1], s.angular_velocity)
                kick_all(s.velocity, s.angular_velocity, s.dipole, s.force, s.torque, s.mass, s.inertia, 0.5 * h, 0.0)
            if timed:
                s.clock[0] = (start + n + 1) * dt - (left - h)
            power = forces_of(s, False)  # noqa: F821
            if n < 0:
                s.stage[2, 0, 0] = power
                break
            s.accum[0] += 0.5 * h * (s.stage[2, 0, 0] + power)
            s.stage[2, 0, 0] = power
            copy_vectors(s.velocity, s.stage[0])
            copy_vectors(s.angular_velocity, s.stage[1])
            kick_all(s.velocity, s.angular_velocity, s.dipole, s.force, s.torque, s.mass, s.inertia, 0.5 * h, 0.0)
            left -= h
            if not left > 0.0:
                break
        if n >= 0:
            countdown = end_step(first_step + n + 1, countdown, stride, s, record, timed)  # noqa: F821
            if countdown < 0:
                return n
        n += 1
    return -1


def multiple_time_step_events_template(nsteps, first_step, stride, dt, forces_ready, s, record):
    start = s.counters[RUN_START] + first_step  # the global step count at the start of the chunk
    timed = s.program[0, H_CLOCK] != 0  # walls that move read the clock (tier 2: True or False, as written)
    # s.stage[0], [1]: slow force and torque; [2], [3]: fast force and torque; [4], [5]: half-step
    # velocities and spins; [6, 0, 0]: the fast dissipated power at the last evaluation. One call of
    # each force function in the source (see velocity_verlet_template); n = -1: the forces of the start
    inner = s.counters[INNER_STEPS]  # noqa: F821
    tiny = 1e-6 * dt / inner  # a crossing is stepped over in a sub-step this long
    countdown = stride - first_step % stride  # steps until the next recorded frame
    n = 0 if forces_ready else -1
    while n < nsteps:
        if n >= 0:
            kick_all(s.velocity, s.angular_velocity, s.dipole, s.stage[0], s.stage[1],
                     s.mass, s.inertia, 0.5 * dt, 0.0)
        m = 0 if n >= 0 else inner - 1
        while m < inner:
            left = dt / inner
            events = 0
            while True:
                h = left
                if n >= 0:
                    if events < 8:
                        tau = next_contact_event(s, s.stage[2], left)  # noqa: F821
                        if tau < left:
                            events += 1
                            h = tau - 0.5 * tiny if tau > tiny else min(tau + 0.5 * tiny, left)
                    kick_all(s.velocity, s.angular_velocity, s.dipole, s.stage[2], s.stage[3],
                             s.mass, s.inertia, 0.5 * h, h)
                    drift(s.position, s.velocity, h)
                    copy_vectors(s.stage[4], s.velocity)
                    copy_vectors(s.stage[5], s.angular_velocity)
                    kick_all(s.velocity, s.angular_velocity, s.dipole, s.stage[2], s.stage[3],
                             s.mass, s.inertia, 0.5 * h, 0.0)
                if timed:
                    s.clock[0] = (start + n) * dt + (m + 1) * (dt / inner) - (left - h)
                power = fast_forces_of(s, s.stage[2], s.stage[3], False)  # noqa: F821
                if n < 0:
                    s.stage[6, 0, 0] = power
                    break
                s.accum[0] += 0.5 * h * (s.stage[6, 0, 0] + power)
                s.stage[6, 0, 0] = power
                copy_vectors(s.velocity, s.stage[4])
                copy_vectors(s.angular_velocity, s.stage[5])
                kick_all(s.velocity, s.angular_velocity, s.dipole, s.stage[2], s.stage[3],
                         s.mass, s.inertia, 0.5 * h, 0.0)
                left -= h
                if not left > 0.0:
                    break
            m += 1
        if timed:
            s.clock[0] = (start + n + 1) * dt
        power = slow_forces_of(s, s.stage[0], s.stage[1], n >= 0)  # noqa: F821
        if n >= 0:
            s.accum[0] += dt * power
            kick_all(s.velocity, s.angular_velocity, s.dipole, s.stage[0], s.stage[1],
                     s.mass, s.inertia, 0.5 * dt, 0.0)
            countdown = end_step(first_step + n + 1, countdown, stride, s, record, timed)  # noqa: F821
            if countdown < 0:
                total_forces(s.force, s.torque, s.stage)
                return n
        n += 1
    total_forces(s.force, s.torque, s.stage)
    return -1


#: every loop template, compiled lazily into each scene's kernel module
TEMPLATES = {
    "euler_cromer": euler_cromer_template,
    "velocity_verlet": velocity_verlet_template,
    "forest_ruth": forest_ruth_template,
    "rk4": rk4_template,
    "multiple_time_step": multiple_time_step_template,
    "velocity_verlet_events": velocity_verlet_events_template,
    "multiple_time_step_events": multiple_time_step_events_template,
}


def fused_loop(name, template, timed):
    """The source lines of a fused module's time loop ``<name>_steps`` from ``template``: the clock
    a constant (``timed``: walls that move; pruned where none does)."""
    src = textwrap.dedent(inspect.getsource(template))
    src = src.replace(f"def {template.__name__}(", f"def {name}_steps(", 1)
    src = re.sub(r"timed = s\.program\[0, H_CLOCK\] != 0.*", f"timed = {timed}", src)
    return src.rstrip().splitlines()
