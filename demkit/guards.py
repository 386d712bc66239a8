"""Guards: refuse a run that cannot be trusted before its first step, and say when one stops being
trustworthy.

:func:`before_stepping` raises ValueError naming every problem found, each message starting with
what is wrong and giving the numbers (the limit, the value, what to use instead).
:func:`while_stepping` re-checks, cheaply (O(N)), what changes during a run and returns a message,
or None (for :meth:`demkit.Simulation.run` to call at the start of every run and between chunks of
steps).

The checks (thresholds and the measurements behind them: docs/stability.md):

1. the time step against every stiff effect present: contacts and walls (a tenth of the contact
   duration; Hertz at twice the fastest impact speed possible (:func:`fastest_impact`: the speeds
   present, what gravity adds over the drop to the walls below, the walls' own speeds) combined with
   the speed magnets reach snapping together), dipoles at the closest approach possible (omega dt <= SAFE_PHASE = 0.5, omega from
   :meth:`demkit.Dipole.rate_coefficients`: touching spheres when a contact law keeps them apart,
   else the closest pair now), uniform fields, and any interaction's ``max_time_step``;
2. spins: a sphere that feels torques turns by at most :data:`MAX_TURN` = 1 rad per step;
3. geometry (:meth:`demkit.Scene.validate`): overlaps, the box, walls;
4. contacts that hold the magnetic pull: touching head-to-tail magnets must be held by an overlap of
   at most :data:`REFUSED_MAGNETIC_OVERLAP` = 0.5 of the smaller radius (where a run stops), both
   statically and when the energy they release on snapping together is stored in the contact, with
   the attraction as it is at that overlap; the advice keeps them within :data:`MAX_MAGNETIC_OVERLAP`
   = 0.35 (checked for the pairs within
   :data:`MAGNET_REACH` = 2 contact distances: a soft law is accepted while its magnets stay apart).

During a run the limits that depend on the state (Hertz at the speeds now, dipoles at the closest
pair now, spins) are allowed :data:`RUN_SLACK` = 2 times more: a run admitted at a limit is not
stopped by a small change, and one that reaches twice a limit can no longer be trusted.
"""
from __future__ import annotations

import itertools
import math
import weakref

import numpy as np

from .interactions.base import SAFE_PHASE, inverse_inertia
from .interactions.contact import KelvinVoigt
from .interactions.dipole import Dipole
from .interactions.fields import Gravity
from .interactions.hertz import Hertz
from .interactions.wall import Wall
from .engine.state import DEEP_OVERLAP_FRACTION

#: largest rotation per step (rad) of a sphere that feels torques (dipoles, fields, friction)
MAX_TURN = 1.0
#: a contact law is refused when touching head-to-tail magnets snapping together from rest would
#: overlap by more than this fraction of the smaller radius, with the attraction as it is there (it
#: grows as they overlap): the run would be stopped there (demkit.engine.state.DEEP_OVERLAP_FRACTION)
REFUSED_MAGNETIC_OVERLAP = DEEP_OVERLAP_FRACTION
#: the overlap the advised stiffness keeps such a snap within (a margin below the refusal; measured,
#: docs/stability.md: judged at this overlap with the attraction there, the advice is met)
MAX_MAGNETIC_OVERLAP = 0.35
#: during a run, the state-dependent limits are allowed this many times more
RUN_SLACK = 2.0
#: the magnets a contact law must hold are checked among the pairs closer than this many times their
#: contact distance R_i + R_j (within one contact distance of touching)
MAGNET_REACH = 2.0
#: scenes with at most this many kinds of sphere have every pair of kinds checked; more kinds (a
#: polydisperse scene) are checked each against the extreme ones (largest moment, smallest radius,
#: mass, inertia)
KINDS_MAX = 64
#: scenes with up to this many plane walls find the lowest place a sphere can fall to by enumeration
#: (lowest_place), more by scipy's linear programming
ENUMERATED_WALLS = 8
#: without a contact law, the dipoles are checked at the closest pair now, but at most this many
#: largest diameters apart
DIPOLE_REACH = 2.0


def before_stepping(scene, integrator):
    """Raise ValueError if ``integrator`` cannot be trusted on ``scene`` (see the module docstring);
    the message names every problem, one after the other ("... Also: ...")."""
    scene.validate()
    problems = _contact_problems(scene) + _step_problems(scene, integrator)
    spin = _spin_problem(scene, integrator, 1.0)
    problems += [spin] if spin else []
    dipoles = _dipole_problem(scene, integrator, 1.0)
    problems += [dipoles] if dipoles else []
    if problems:
        raise ValueError(" Also: ".join(problems))


def largest_safe_step(scene):
    """(limit, why): the largest time step the contact and field checks of :func:`before_stepping`
    accept, and what sets it (Hertz contacts at twice the fastest impact speed possible,
    :func:`fastest_impact`, combined with the speed of touching magnets snapping together);
    (math.inf, why) when nothing limits it yet."""
    limits = _limits(scene)
    if not limits:
        return math.inf, "no contact law, field or plug-in interaction sets a largest time step"
    limit, what, why, _ = min(limits, key=lambda item: item[0])
    if not math.isfinite(limit):
        return math.inf, (f"{what} has no limit yet: every sphere is at rest, nothing pulls them onto a wall "
                          f"(gravity with a wall below) or drags them (a moving wall) and no touching magnets "
                          f"snap together, so the impact speed it must resolve is unknown")
    return limit, f"{what}: {why}"


def fastest_impact(scene):
    """(speed, why): an upper bound of the speed (length/time) any moving sphere can hit a wall or
    another sphere with, before it has been stepped:

        v_i = sqrt(|v0_i|^2 + 2 |g| h_i) + u,   speed = max_i v_i,

    with v0_i the speed now, g the scene's gravity, h_i the distance the sphere's centre can fall
    along g before the walls stop it (:func:`fall_heights`; energy conservation: the drop's
    potential energy g h per unit mass becomes kinetic at most) and u the fastest wall's speed
    (a moving wall drags spheres up to its speed and hits them at its speed plus theirs); in a sheared
    box half the speed gammadot L_b of the sliding images is added (a sphere meets an image at up to
    2 v + gammadot L_b: :meth:`demkit.Scene.max_time_step` counts the same). Gravity
    with no wall below (a fall the walls do not bound) adds nothing here: ``why`` says so, and the
    speeds are re-checked while stepping. Magnets snapping together are added by the guards."""
    p = scene.particles
    moving = ~p.fixed if p.fixed is not None else np.ones(len(p), dtype=bool)
    if not moving.any():
        return 0.0, "every sphere is fixed"
    v0 = np.linalg.norm(p.velocity, axis=1)
    walls = [e for e in scene.effects if isinstance(e, Wall)]
    drag = max((w.surface_speed() for w in walls), default=0.0)
    heights, g, note = fall_heights(scene)
    k = int(np.argmax(np.where(moving, v0, -1.0)))
    why = f"the fastest speed present, {v0[k]:.4g}"
    speed = float(v0[k])
    if heights is not None:
        reach = np.where(moving, np.sqrt(v0**2 + 2.0 * g * heights), -1.0)
        k = int(np.argmax(reach))
        speed = float(reach[k])
        why = (f"particle {p.ids[k]} falling from speed {v0[k]:.4g} through h = {heights[k]:.4g} under g = {g:.4g} "
               f"to the walls below: sqrt(v0^2 + 2 g h) = {speed:.4g}")
    elif note:
        why = f"{why}; {note}"
    if drag > 0.0:
        speed += drag
        why = f"{why}, plus {drag:.4g} of the fastest moving wall"
    shear = getattr(getattr(scene, "box", None), "shear", None)
    slide = abs(shear.jump(scene.box.size)) if shear is not None else 0.0
    if slide > 0.0:  # a sphere and an image approach at up to 2 v + gammadot L_b: an impact at v + slide / 2
        speed += 0.5 * slide
        why = (f"{why}, plus half the {slide:.4g} at which the sheared box's images slide by (a sphere meets an "
               f"image at up to 2 v + gammadot L_b)")
    return speed, why


def gravity(scene):
    """The scene's gravitational acceleration (3,): its Gravity effects summed (zeros without any)."""
    field = [e for e in scene.effects + scene.interactions if isinstance(e, Gravity)]
    return np.sum([e.acceleration for e in field], axis=0) if field else np.zeros(3)


def fall_heights(scene):
    """(h (N,), |g|, note): how far each sphere's centre can fall along the scene's gravity before
    the walls stop it (length; 0 for a sphere already at its lowest place), or (None, |g|, note)
    when the scene has no gravity or the walls do not bound the fall (``note`` says which).

    The lowest place is that of the smallest sphere (radius R_min, so that the bound holds for all)
    in the region the walls leave it, {x : (x - p_w).n_w >= R_min for every wall w}: the largest
    x.g/|g| there, a linear programme (:func:`lowest_place`; a flat floor under a walled box
    gives its height + R_min, a V-shaped trough the bottom of the V). h_i = max(0, lowest - x_i.g/|g|).
    An open box does not stop spheres (docs/stability.md), so only walls count."""
    p = scene.particles
    g = gravity(scene)
    size = float(np.linalg.norm(g))
    if size == 0.0 or not len(p):
        return None, size, ""
    down = g / size
    walls = [e for e in scene.effects if isinstance(e, Wall) and e.flat]  # (a cylinder's floor: not counted)
    normals = np.array([w.normal for w in walls]).reshape(-1, 3)
    curved = " (curved and mesh walls are not counted)" if any(isinstance(e, Wall) and not e.flat
                                                                for e in scene.effects) else ""
    unbounded = (f"gravity ({size:.4g}) has no plane wall below the spheres to stop their fall{curved}, so it does "
                 f"not bound the impact speed (checked while stepping)")
    if not len(walls) or not np.any(normals @ down < 0.0):
        return None, size, unbounded
    lowest = lowest_place(normals, np.array([w.plane for w in walls]) + float(np.min(p.radius)), down)
    if lowest is None:  # unbounded: a tilted floor with nothing at its foot
        return None, size, unbounded
    return np.maximum(lowest - p.position @ down, 0.0), size, ""


def lowest_place(normals, planes, down):
    """The largest x.down over {x : n_w.x >= b_w for every w} (``normals`` (m, 3), ``planes`` b (m,)),
    or None when it has none (the walls do not stop a fall along ``down``). By linear programming
    duality in three unknowns: the least -b.y over the ways of writing -down = sum_w y_w n_w, y >= 0,
    with one, two or three walls (the dual's basic solutions; no way at all: unbounded). Exact where
    the region has room; where it has none (walls closer than the smallest sphere's diameter, refused
    by the overlap checks) an upper bound. Up to ENUMERATED_WALLS walls (at most 92 small solves)
    without scipy.optimize, whose import cost the first step of every walled scene 0.3 CPU s."""
    n, b, v = (np.asarray(x, dtype=float) for x in (normals, planes, -np.asarray(down, dtype=float)))
    if len(n) > ENUMERATED_WALLS:
        from scipy.optimize import linprog
        found = linprog(v, A_ub=-n, b_ub=-b, bounds=[(None, None)] * 3, method="highs")
        return float(-v @ found.x) if found.status == 0 else None
    best = None
    for k in (1, 2, 3):
        for rows in itertools.combinations(range(len(n)), k):
            a = n[list(rows)]
            y = np.linalg.lstsq(a.T, v, rcond=None)[0]
            if np.linalg.norm(a.T @ y - v) <= 1e-9 and (y >= -1e-12).all():
                value = -float(b[list(rows)] @ y)
                best = value if best is None else min(best, value)
    return best


def while_stepping(scene, integrator):
    """A message saying why the run can no longer be trusted, or None. O(N) and cheap: the fastest
    speed and spin, and a cell list only in scenes whose dipoles no contact law keeps apart or a
    contact law too soft for them would have to."""
    law = _hertz_problem(scene, integrator, RUN_SLACK)
    if law:
        return law
    spin = _spin_problem(scene, integrator, RUN_SLACK)
    if spin:
        return spin
    soft = _contact_problems(scene)
    if soft:
        return f"{soft[0]} They came close during the run."
    if not _contact_laws(scene):
        return _dipole_problem(scene, integrator, RUN_SLACK)
    return None


# ---- what the scene holds --------------------------------------------------------------------
def _contact_laws(scene):
    return [inter for inter in scene.interactions if isinstance(inter, (KelvinVoigt, Hertz))]


def _dipoles(scene):
    return [inter for inter in scene.interactions if isinstance(inter, Dipole)]


#: per scene, values computed from the particles' constant properties (kinds of sphere, ...)
_CACHE = weakref.WeakKeyDictionary()


def _key(p):
    """What the cached values depend on: the spheres' count, sizes, masses, inertias and moments."""
    # moments rotate during a run: their sizes count, to 9 digits (rotation changes their last bits)
    moments = f"{float(np.einsum('ij,ij->', p.dipole, p.dipole)):.9e}" if p.dipole is not None else 0.0
    fixed = int(p.fixed.sum()) if p.fixed is not None else 0
    return len(p), float(p.radius.sum()), float(p.mass.sum()), float(p.inertia.sum()), moments, fixed


def _cached_kinds(scene):
    """:func:`_kinds` of the scene's particles, computed again only when they change."""
    p = scene.particles
    known = _CACHE.get(scene, {}).get("kinds")
    if known is not None and known[0] == _key(p):
        return known[1]
    kinds = _kinds(p)
    _CACHE.setdefault(scene, {})["kinds"] = (_key(p), kinds)
    return kinds


def _kinds(particles):
    """Index pairs (i, j) standing for every pair of kinds of sphere (radius, mass, inertia, moment,
    fixed), two different spheres where a kind has two; pairs of two fixed spheres are left out."""
    p = particles
    moment = np.linalg.norm(p.dipole, axis=1) if p.dipole is not None else np.zeros(len(p))
    fixed = p.fixed if p.fixed is not None else np.zeros(len(p), dtype=bool)
    keys = np.stack([p.radius, p.mass, p.inertia, moment, fixed.astype(float)], axis=1)
    _, first, inverse, counts = np.unique(keys, axis=0, return_index=True, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    second = first.copy()
    if np.any(counts > 1):  # a second member of each kind that has one
        order = np.argsort(inverse, kind="stable")
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        many = counts > 1
        second[many] = order[starts[many] + 1]
    if len(first) <= KINDS_MAX:
        a, b = np.triu_indices(len(first))
        same = a == b
        keep = ~same | (counts[a] > 1)
        i, j = first[a[keep]], np.where(same[keep], second[b[keep]], first[b[keep]])
    else:
        extremes = np.unique([np.argmax(moment), np.argmin(p.radius), np.argmin(p.mass), np.argmin(p.inertia)])
        i = np.repeat(np.arange(len(p)), len(extremes))
        j = np.tile(extremes, len(p))
        keep = i != j
        i, j = i[keep], j[keep]
    moving = ~(fixed[i] & fixed[j])
    return i[moving], j[moving]


def _safe(value, up=False):
    """``value`` to 4 significant digits, rounded towards safety (down for a largest step, up for a
    smallest stiffness), so that the advice given is accepted when followed to the letter."""
    if not math.isfinite(value) or value <= 0.0:
        return f"{value:.4g}"
    scale = 10.0 ** (math.floor(math.log10(value)) - 3)
    return f"{(math.ceil if up else math.floor)(value / scale * (1 + 1e-12 if up else 1 - 1e-12)) * scale:.4g}"


def _summed(pairs):
    """Element-wise sums of the (x, y) pairs of arrays that several interactions give."""
    pairs = list(pairs)
    return sum(x for x, _ in pairs), sum(y for _, y in pairs)


def _pair_name(p, i, j):
    return f"particles {p.ids[i]} and {p.ids[j]} (radii {p.radius[i]:.4g} and {p.radius[j]:.4g})"


# ---- 4: can a contact hold the magnets? --------------------------------------------------------
def _contact_problems(scene):
    """Magnets the contact law cannot hold, among the pairs now closer than MAGNET_REACH times their
    contact distance (a soft law is accepted while its magnets stay apart)."""
    dipoles, laws = _dipoles(scene), _contact_laws(scene)
    p = scene.particles
    if not dipoles or not laws or len(p) < 2 or not _some_too_soft(scene, dipoles, laws):
        return []
    pairs = scene.close_pairs(MAGNET_REACH * 2.0 * float(np.max(p.radius)))
    if not len(pairs):
        return []
    i, j = pairs[:, 0], pairs[:, 1]
    near = np.linalg.norm(scene.separations(pairs), axis=1) < MAGNET_REACH * (p.radius[i] + p.radius[j])
    if p.fixed is not None:
        near &= ~(p.fixed[i] & p.fixed[j])
    return _too_soft(p, dipoles, laws, i[near], j[near])


def _some_too_soft(scene, dipoles, laws):
    """Whether some pair of kinds of sphere is too much for a contact law (cached per scene: the
    answer changes only with the spheres' sizes, masses and moments)."""
    p = scene.particles
    known = _CACHE.get(scene, {}).get("too_soft")
    if known is None or known[0] != _key(p):
        i, j = _cached_kinds(scene)
        known = (_key(p), bool(_too_soft(p, dipoles, laws, i, j)))
        _CACHE.setdefault(scene, {})["too_soft"] = known
    return known[1]


def _too_soft(p, dipoles, laws, i, j):
    """Messages for each contact law that needs an overlap of more than MAX_MAGNETIC_OVERLAP of the
    smaller radius to hold or stop some of the head-to-tail pairs (i, j)."""
    if not len(i):
        return []
    force, energy = _summed(d.touching_attraction(p, i, j) for d in dipoles)
    smaller = np.minimum(p.radius[i], p.radius[j])
    problems = []
    # the attraction grows as the spheres overlap (U ~ 1/r^3, F ~ 1/r^4): a law is judged by whether it
    # holds and stops them at the largest overlap accepted, with the attraction there
    touching = p.radius[i] + p.radius[j]

    def at(overlap):
        grow = touching / (touching - overlap)
        return force * grow**4, energy * grow**3

    for law in laws:  # (several laws act in parallel; each alone is checked: conservative)
        static, stored = law.overlaps(p, i, j, force, energy)
        at_limit = law.overlaps(p, i, j, *at(REFUSED_MAGNETIC_OVERLAP * smaller))
        need = np.maximum(*at_limit) / smaller
        worst = int(np.argmax(need))
        if need[worst] <= REFUSED_MAGNETIC_OVERLAP:
            continue
        name, value = law.stiffer(p, i, j, *at(MAX_MAGNETIC_OVERLAP * smaller), MAX_MAGNETIC_OVERLAP * smaller)
        _, comfortable = law.stiffer(p, i, j, *at(0.1 * smaller), 0.1 * smaller)
        count = int(np.sum(need > REFUSED_MAGNETIC_OVERLAP))
        where = f"closer than {MAGNET_REACH:g} contact distances"
        if count > 1:
            where = f"the worst of {count} pairs {where} that it cannot hold"
        problems.append(
            f"contact {name} = {getattr(law, name):.6g} is too soft for the magnetic attraction: "
            f"{_pair_name(p, i[worst], j[worst])}, {where}, pull each other with {force[worst]:.4g} when touching "
            f"head to tail, which needs an overlap of {static[worst] / smaller[worst]:.3g} of the smaller radius "
            f"to hold, and release {energy[worst]:.4g} when they snap together, which needs "
            f"{stored[worst] / smaller[worst]:.3g} of it to store (more as they overlap and the attraction grows); "
            f"snapping together they would pass {REFUSED_MAGNETIC_OVERLAP:g} of it, where a run stops. Use {name} >= {_safe(value, up=True)} in {law!r} (the snap within "
            f"{MAX_MAGNETIC_OVERLAP:g} of the radius; "
            f"{_safe(comfortable, up=True)} keeps it within 0.1), or weaker moments.")
    return problems


# ---- 1: the time step against contacts, walls, fields, plug-ins -------------------------------
def _approach_speed(scene):
    """(speed, why): the approach speed Hertz contacts must be resolved at: twice the fastest
    impact speed possible (:func:`fastest_impact`: two spheres meeting head on; a sphere hitting a
    wall at v is the same contact time as a pair approaching at 2 v), combined (in energy) with the
    speed touching magnets reach snapping together."""
    p = scene.particles
    impact, how = fastest_impact(scene) if len(p) else (0.0, "no spheres")
    speed = 2.0 * impact
    why = f"twice the fastest impact speed, {impact:.4g}: {how}"
    dipoles = _dipoles(scene)
    if dipoles and len(p) > 1:
        i, j = _cached_kinds(scene)
        if len(i):
            _, energy = _summed(d.touching_attraction(p, i, j) for d in dipoles)
            inv_mass, _ = inverse_inertia(p)
            snap = float(np.sqrt(np.max(2.0 * energy * (inv_mass[i] + inv_mass[j]))))
            if snap > 0.0:
                why = f"{why}, and {snap:.4g} of magnets snapping together"
                speed = math.hypot(speed, snap)
    return speed, f"a tenth of the Hertz contact time at the approach speed {speed:.4g} ({why})"


def _limits(scene, speed=None, why=None):
    """(limit, what, why, hertz) of every interaction and effect that sets a largest time step;
    Hertz contacts at approach ``speed`` (None: :func:`_approach_speed`)."""
    p = scene.particles
    out = []
    for inter in scene.interactions + scene.effects:
        law = inter.law if isinstance(inter, Wall) else inter
        if isinstance(law, Hertz):
            if speed is None:
                speed, why = _approach_speed(scene)
            out.append((law.max_time_step(p, speed), f"the stiffest contact ({law!r})", why, True))
        elif isinstance(law, KelvinVoigt):
            out.append((law.max_time_step(p), f"the stiffest contact ({law!r})",
                        "a tenth of the shortest contact duration", False))
        else:
            limit = inter.max_time_step(p)
            if math.isfinite(limit):
                out.append((limit, f"{inter!r}", "its max_time_step", False))
    return out


def _step_problems(scene, integrator):
    limits = _limits(scene)
    if not limits:
        return []
    limit, what, why, _ = min(limits, key=lambda item: item[0])
    return [_too_large(integrator, limit, what, why)] if integrator.contact_step > limit else []


def _too_large(integrator, limit, what, why, slack=1.0):
    step = integrator.contact_step
    during = f"; during a run up to {slack:g} times it is accepted" if slack > 1 else ""
    if integrator.inner == 1:
        return (f"time step dt = {step:.6g} is too large for {what}: the largest safe value is {limit:.6g} "
                f"({why}{during}). Use dt <= {_safe(limit)}.")
    inner = math.ceil(integrator.dt / limit)
    return (f"inner time step dt/inner = {step:.6g} is too large for {what}: the largest safe value is "
            f"{limit:.6g} ({why}{during}). Use inner >= {inner} (or a smaller dt).")


def _hertz_problem(scene, integrator, slack):
    """The Hertz contacts at the speeds now (twice the fastest), allowed ``slack`` times more."""
    if not any(isinstance(inter.law if isinstance(inter, Wall) else inter, Hertz)
               for inter in scene.interactions + scene.effects):
        return None  # no Hertz law: no speed to find (an O(N) pass)
    p = scene.particles
    speed = 2.0 * float(np.max(np.linalg.norm(p.velocity, axis=1))) if len(p) else 0.0
    if speed == 0.0:
        return None
    why = f"a tenth of the Hertz contact time at twice the fastest speed now, {speed:.4g}"
    limits = [lim for lim in _limits(scene, speed, why) if lim[3]]
    if not limits:
        return None
    limit, what, why, _ = min(limits, key=lambda item: item[0])
    if integrator.contact_step <= slack * limit:
        return None
    return _too_large(integrator, limit, what, why, slack)


# ---- 2: spins -------------------------------------------------------------------------------
def _spin_problem(scene, integrator, slack):
    p = scene.particles
    if p.angular_velocity is None or not len(p):
        return None
    everything = scene.interactions + scene.effects
    any_torque = [inter for inter in everything if inter.torque and "dipole" not in inter.reads]
    dipole_torque = [inter for inter in everything if inter.torque and "dipole" in inter.reads]
    if any_torque:
        coupled = np.ones(len(p), dtype=bool)
    elif dipole_torque:
        coupled = np.linalg.norm(p.dipole, axis=1) > 0.0
    else:
        return None
    if p.fixed is not None:
        coupled &= ~p.fixed
    spin = np.where(coupled, np.linalg.norm(p.angular_velocity, axis=1), 0.0)
    k = int(np.argmax(spin))
    turn = spin[k] * integrator.dt
    if turn <= slack * MAX_TURN:
        return None
    cause = f"{(any_torque or dipole_torque)[0]!r}"
    return (f"time step dt = {integrator.dt:.6g} is too large for the spin of particle {p.ids[k]}: |omega| = "
            f"{spin[k]:.4g} turns it by {turn:.3g} rad per step while torques act on it ({cause}); at most "
            f"{slack * MAX_TURN:g} rad per step is accepted{' during a run' if slack > 1 else ''}. "
            f"Use dt <= {_safe(MAX_TURN / spin[k])}.")


# ---- 1: dipoles -------------------------------------------------------------------------------
def _dipole_problem(scene, integrator, slack):
    """The dipoles at the closest approach possible: touching spheres when a contact law keeps them
    apart, else the closest pair now (at most DIPOLE_REACH largest diameters apart). Checked
    against the whole step dt (multiple time stepping puts dipoles on it)."""
    dipoles = _dipoles(scene)
    p = scene.particles
    if not dipoles or len(p) < 2:
        return None
    dt = integrator.dt
    fastest = slack * SAFE_PHASE / dt  # the largest omega accepted
    if _contact_laws(scene):
        i, j = _cached_kinds(scene)
        r = p.radius[i] + p.radius[j]
        where = "touching"
    else:
        i, j, r = _closest(scene, dipoles, fastest)
        where = "at the closest distance now (no contact law keeps them apart)"
    if not len(i):
        return None
    a, b = _summed(d.rate_coefficients(p, i, j) for d in dipoles)
    rate = np.sqrt(a / r**5 + b / r**3)
    k = int(np.argmax(rate))
    if rate[k] <= fastest:
        return None
    limit = SAFE_PHASE / rate[k]
    return (f"time step dt = {dt:.6g} is too large for the dipole forces: {where}, {_pair_name(p, i[k], j[k])} at "
            f"r = {r[k]:.4g} move with omega = {rate[k]:.4g} (omega^2 = a/r^5 + b/r^3 with a = {a[k]:.4g} from "
            f"the pull, b = {b[k]:.4g} from the torques), so omega dt = {rate[k] * dt:.3g}; at most "
            f"{slack * SAFE_PHASE:.3g} is accepted{' during a run' if slack > 1 else ''}. "
            f"Use dt <= {_safe(limit)}.")


def _closest(scene, dipoles, fastest):
    """(i, j, r) of the pairs now closer than where the dipoles would move faster than ``fastest``,
    looked for within DIPOLE_REACH largest diameters; if none is that close, the kinds of sphere
    at DIPOLE_REACH diameters."""
    p = scene.particles
    ki, kj = _cached_kinds(scene)
    if not len(ki):
        return ki, kj, np.zeros(0)
    a, b = _summed(d.rate_coefficients(p, ki, kj) for d in dipoles)
    # omega(r) <= fastest where both terms are below fastest^2 / 2
    reach = float(np.max(np.maximum((2.0 * a / fastest**2) ** 0.2, (2.0 * b / fastest**2) ** (1.0 / 3.0))))
    cap = DIPOLE_REACH * 2.0 * float(np.max(p.radius))
    if scene.box is not None and any(scene.periodic):
        cap = min(cap, 0.49 * float(np.min(scene.box.size[np.array(scene.periodic)])))
    pairs = scene.close_pairs(min(reach, cap))
    if len(pairs):
        r = np.linalg.norm(scene.separations(pairs), axis=1)
        return pairs[:, 0], pairs[:, 1], r
    if reach > cap:
        return ki, kj, np.full(len(ki), cap)
    return ki[:0], kj[:0], np.zeros(0)
