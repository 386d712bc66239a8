"""Export a demkit scene to LAMMPS: a data file and an input deck that run the same physics.

    files = dk.export_lammps(scene, dk.VelocityVerlet(dt=1e-3), "out", duration=0.1, record_every=0.01)
    # lmp -in out/in.scene      (or: mpirun -np 2 lmp -in out/in.scene; run it from the folder "out")

Written for LAMMPS 29 Sep 2021 with the GRANULAR and DIPOLE packages (units lj). What maps to what
(details and the measured agreement in docs/lammps_export.md):

* spheres: ``atom_style hybrid sphere dipole``, diameter 2R, density m / (4/3 pi R^3) (LAMMPS makes
  the mass from it, to the last bit or one off), velocities, angular velocities, image counts;
  fixed spheres are atom type 2, frozen (``fix freeze``) and not integrated;
* ``Box``: ``p`` on periodic axes (box [0, L)), ``s`` (shrink-wrapped) on open ones;
* ``Dipole(prefactor=A, cutoff=r_c)``: ``lj/cut/dipole/cut`` with epsilon 0 (dipole terms only);
  LAMMPS' energy is mu_i.mu_j/r^3 - 3 (mu_i.n)(mu_j.n)/r^3 (qqr2e = 1), so the data file holds the
  moments times sqrt(A) and the dump divides them back. Without a cutoff (open space) the export
  uses ``dipole_cutoff`` (default: 10 times the diagonal of the spheres' initial extent);
* ``KelvinVoigt(k, c)``: ``granular hooke k c ... damping velocity`` (force c * rate, not scaled by
  the mass), ``no_tension`` -> ``limit_damping``; ``Friction`` -> ``tangential linear_history k_t
  eta_t/c mu``; ``RollingResistance`` -> ``rolling sds k_r eta_r mu_r``; ``TwistingResistance()``
  (Marshall's coefficients) -> ``twisting marshall``, ``TwistingResistance(k_tw, eta_tw, l_tw)`` ->
  ``twisting sds k_tw eta_tw l_tw`` (only some of the three given: refused);
* ``Hertz(E, nu, e)`` -> ``hertz/material E alpha nu ... damping tsuji limit_damping``: LAMMPS turns
  its coefficient into the Tsuji constant with a fitted polynomial, so the export writes the
  coefficient whose polynomial value is demkit's gamma sqrt(3/2) (exact to round-off); Mindlin
  friction -> ``tangential mindlin NULL sqrt(4 G*/E*) mu``;
* ``Wall`` (axis-aligned) -> ``fix wall/gran granular hooke ... xplane lo NULL`` (Hertz: the modulus
  2 E/(1 + nu) that LAMMPS' wall formula turns into demkit's E/(1 - nu^2)), an
  in-plane velocity -> ``shear``, a vibration along its normal -> ``wiggle``; an oblique wall at
  rest -> ``region plane`` + ``fix wall/gran/region`` (the same sphere-wall contact code); a
  ``Cylinder`` along x, y or z -> ``region cylinder ... INF INF side in|out``, turned by ``rotate``
  through omega t when it turns, + ``fix wall/gran/region``; a ``Cone`` along +-x, y or z with an upper
  end -> ``region cone ... side in|out open 1 open 2`` (no caps), turned the same way;
  a ``MeshWall`` is refused (LAMMPS has no triangle-mesh walls);
  ``Gravity`` -> ``fix gravity``; ``UniformField(B)`` -> ``fix efield`` with E = B / sqrt(A) (torque
  mu x E);
* a sheared box (``dk.Shear``, flow a, gradient b with ab = xy, xz or yz) -> a triclinic box whose tilt
  ab is the sliding offset, under ``fix deform 1 ab erate gammadot remap v``. fix deform sets the tilt
  at the end of each step, so the forces of step n + 1 would see the tilt of t_n; the exported box is
  led by one step (tilt delta(t + dt)), so that those of every step after the first see the tilt of
  their own time, as demkit's do. The starting forces (the first half kick) then see the box slid by
  gammadot L_b dt more: a one-time difference for pairs across the sliding boundary at the start (none
  when nothing reaches across it: the paths agree to round-off, benchmarks/lammps/in.sheared). LAMMPS'
  unwrapped coordinate along the flow (image_b times the tilt) is ahead by image_b gammadot L_b dt;
  the image counts along the flow are shifted by the whole turns of the offset.
* ``VelocityVerlet`` -> ``fix nve/sphere update dipole/dlm`` (velocity Verlet; the dipoles turn by
  a second-order splitting instead of demkit's exact rotation; ``dipole_update="euler"`` gives
  LAMMPS' default first-order step).

Refused with a ValueError naming the part and why: PowerLawDipole, switched dipole cutoffs,
MagnetField, custom pair or sphere interactions, inertia factors other than 2/5, oblique walls that
slide, walls with a normal component along a periodic axis, Hertz friction or rolling whose stiffness or damping LAMMPS
cannot scale like demkit. With ``strict=True`` (default) also what would run but not reproduce
demkit exactly: friction with demkit's own sliding rule or contact-point slip radius (use
``Friction(..., slip_radius="full", sliding="lammps")``, which also gives walls LAMMPS' lever arm R),
integrators other than plain VelocityVerlet, stored contact history;
``strict=False`` exports those with a note in the deck.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .box import Box
from .integrators import VelocityVerlet
from .interactions import (Cone, Cylinder, Dipole, Gravity, Hertz, KelvinVoigt, MagnetField, MeshWall, PowerLawDipole,
                           UniformField, Wall)

#: tested LAMMPS version
LAMMPS_VERSION = "29 Sep 2021"
DATA_NAME = "scene.data"
DECK_NAME = "in.scene"
DUMP_COLUMNS = "id xu yu zu vx vy vz omegax omegay omegaz v_mux v_muy v_muz"


class Tilt(NamedTuple):
    """A sheared box as LAMMPS' triclinic box: the tilt's name (xy, xz or yz), its value led by one step
    (the offset at the scene's time + dt, folded into [-L_a/2, L_a/2)), the rate, and the whole turns
    of the offset that the folding took away (added to the image counts along the flow, times those
    along the gradient)."""

    name: str
    value: float
    rate: float
    turns: int


def tilt_of(box, time, dt):
    """The :class:`Tilt` of a sheared ``box`` at ``time`` and led by ``dt`` (module docstring)."""
    shear = box.shear
    name = shear.flow + shear.gradient
    if name not in ("xy", "xz", "yz"):
        raise ValueError(f"LAMMPS tilts a box only as xy, xz or yz (the flow along the first axis, the gradient along "
                         f"the second): a box sheared along {shear.flow} with gradient {shear.gradient} cannot be "
                         f"exported; swap the scene's axes")
    a, _ = shear.axes
    total = shear.jump(box.size) * (float(time) + dt)  # gammadot L_b (t + dt), not folded
    turns = math.floor(total / box.size[a] + 0.5)
    return Tilt(name, total - turns * box.size[a], shear.rate, turns)


class LammpsFiles(NamedTuple):
    """What :func:`export_lammps` wrote: the data file, the input deck and the notes (differences
    from demkit that the export accepted, also written into the deck)."""

    data: Path
    deck: Path
    notes: tuple


def g17(x):
    """A float written so that it reads back to the same double."""
    return f"{float(x):.17g}"


def tsuji_polynomial(c):
    """LAMMPS 29 Sep 2021's conversion of a restitution coefficient into the Tsuji damping constant
    (pair granular ``damping tsuji``), evaluated in the same order of operations."""
    c2 = c * c
    c4 = c2 * c2
    return (1.2728 - 4.2783 * c + 11.087 * c2 - 22.348 * (c * c * c) + 27.467 * c4 - 18.022 * (c * c4)
            + 4.8218 * (c2 * c4))


def tsuji_coefficient(alpha):
    """The coefficient c in [0, 1] with tsuji_polynomial(c) = alpha (decreasing on [0, 1]; bisection
    to the last bit; near c = 1 the polynomial's own round-off, ~1e-15 absolute, is the limit), or
    ValueError when alpha is outside the polynomial's range."""
    if not 0.0 <= alpha <= tsuji_polynomial(0.0):
        raise ValueError(f"Hertz damping gamma sqrt(3/2) = {alpha:.6g} is outside the range [0, 1.2728] that "
                         f"LAMMPS' Tsuji damping can express: it cannot be exported")
    lo, hi = 0.0, 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if tsuji_polynomial(mid) > alpha:
            lo = mid
        else:
            hi = mid
    best = min((lo, hi), key=lambda c: abs(tsuji_polynomial(c) - alpha))
    if abs(tsuji_polynomial(best) - alpha) > 1e-14 + 1e-13 * alpha:  # terms up to 27: ~1e-15 absolute
        raise ValueError(f"no LAMMPS Tsuji coefficient reproduces the Hertz damping {alpha:.17g} "
                         f"(closest {tsuji_polynomial(best):.17g})")
    return best


def twisting_words(law):
    """The ``twisting`` words of a contact law's LAMMPS model (none without twisting resistance)."""
    t = getattr(law, "twisting", None)
    if t is None:
        return []
    if t.marshall:  # LAMMPS derives k_t a^2/2, eta_t a^2/2, (2/3) mu a from the tangential words, as demkit
        return ["twisting", "marshall"]
    if None in (t.stiffness, t.damping, t.lever):
        raise ValueError(f"{law!r}: LAMMPS' twisting is either marshall (stiffness, damping and lever all from the "
                         f"friction law) or sds (all three given); give TwistingResistance all three or none")
    return ["twisting", "sds", g17(t.stiffness), g17(t.damping), g17(t.lever)]


def springs(law):
    """History columns of a contact law that hold spring displacements (friction, rolling, twist)."""
    columns = [0, 1, 2]
    if law.rolling is not None:
        columns += [4, 5, 6]
    if getattr(law, "twisting", None) is not None:
        columns.append(8 if law.rolling is not None else 4)
    return columns


class _Export:
    """Collects the deck's lines, the notes and the checks for one scene."""

    def __init__(self, scene, integrator, strict, dipole_update, dipole_cutoff):
        self.scene, self.integrator, self.strict = scene, integrator, strict
        self.p = scene.particles
        self.notes = []
        if dipole_update not in ("dlm", "euler"):
            raise ValueError(f"dipole_update must be 'dlm' (dipole/dlm, second order) or 'euler' (LAMMPS' "
                             f"renormalised Euler step), got {dipole_update!r}")
        self.update = "dipole/dlm" if dipole_update == "dlm" else "dipole"
        self.dipole_cutoff = dipole_cutoff
        self.dipole = None
        self.contact = None
        self.scale = 1.0  # LAMMPS moment = scale * demkit moment

    def differs(self, what, how):
        """A difference from demkit: refused when strict, else noted."""
        if self.strict:
            raise ValueError(f"{what}: {how}. export_lammps(..., strict=False) exports it anyway with a note")
        self.notes.append(f"{what}: {how}")

    # ---- checks -------------------------------------------------------------------------------
    def check(self):
        p, scene = self.p, self.scene
        if not np.allclose(p.inertia_factor, 0.4, rtol=0, atol=0):
            raise ValueError("Particles inertia_factor must be 2/5 (solid spheres) for LAMMPS: fix nve/sphere "
                             "integrates spins with I = 2/5 m R^2")
        if scene.induction is not None:
            raise ValueError("magnetisable spheres (Particles susceptibility > 0) cannot be exported: LAMMPS has no "
                             "induced dipoles (its dipoles are permanent moments)")
        if not isinstance(self.integrator, VelocityVerlet):
            self.differs(f"integrator {self.integrator!r}", "LAMMPS' fix nve/sphere is velocity Verlet; "
                         "export the scene with dk.VelocityVerlet(dt) to compare runs")
        elif self.integrator.resolve_contacts:
            self.differs(f"integrator {self.integrator!r}", "LAMMPS does not locate contact events within a "
                         "step; use VelocityVerlet(dt) without resolve_contacts")
        for inter in scene.interactions:
            kind = type(inter)
            if kind is PowerLawDipole:
                raise ValueError("PowerLawDipole (the paper's central force without torques) has no LAMMPS pair "
                                 "style: only the full Dipole can be exported")
            if kind is Dipole:
                if inter.long_range is not None:
                    raise ValueError(f"{inter!r}: the export knows LAMMPS' cut-off dipoles (lj/cut/dipole/cut) only, "
                                     f"not its ewald/dipole k-space style; export the scene with a cut-off Dipole")
                if inter.switch_width is not None:
                    raise ValueError(f"{inter!r}: LAMMPS' lj/cut/dipole/cut truncates plainly and lj/sf/dipole/sf "
                                     f"shifts differently; export Dipole without switch_width")
                self.dipole = inter
            elif kind in (KelvinVoigt, Hertz):
                self.contact = inter
            else:
                raise ValueError(f"{inter!r} ({kind.__name__}) has no LAMMPS equivalent the export knows: only "
                                 f"Dipole, KelvinVoigt and Hertz pair interactions can be exported")
        for effect in scene.effects:
            kind = type(effect)
            if kind is MagnetField:
                raise ValueError("MagnetField (a tabulated field of real magnets) has no LAMMPS fix: it cannot be "
                                 "exported")
            if kind is MeshWall:
                raise ValueError(f"{effect!r}: LAMMPS has no triangle-mesh walls (its walls are planes and "
                                 f"regions), so a scene with a MeshWall cannot be exported")
            if kind not in (Wall, Cylinder, Cone, Gravity, UniformField):
                raise ValueError(f"{effect!r} ({kind.__name__}) has no LAMMPS equivalent the export knows: only "
                                 f"Wall, Cylinder, Cone, Gravity and UniformField can be exported")
        if self.dipole is not None:
            self.scale = math.sqrt(self.dipole.prefactor)
        for law in [self.contact] + [w.law for w in scene.effects if type(w) in (Wall, Cylinder, Cone)]:
            if law is not None and law.friction is not None:
                f = law.friction
                if f.sliding != "lammps" or f.slip_radius != "full":
                    self.differs(f"{f!r}", "LAMMPS' friction uses the full radii in the slip velocity and, while "
                                 "sliding, keeps the spring at the Coulomb force minus the dashpot's part; use "
                                 "Friction(..., slip_radius='full', sliding='lammps') for the same physics (in a "
                                 "scene file: slip_radius = \"full\" and sliding = \"lammps\" in "
                                 "[interactions.friction]; on the command line: --set interactions.friction."
                                 "slip_radius=full --set interactions.friction.sliding=lammps)")
        self.check_history()

    def check_history(self):
        scene = self.scene
        stored = False
        if self.contact is not None and self.contact.history_size:
            stored = bool(np.any(scene.history(self.contact)[1][:, springs(self.contact)] != 0.0))
        for w in scene.effects:
            if type(w) is Wall and w.history_size:
                stored |= bool(np.any(scene.sphere_history(w)[:, springs(w.law)] != 0.0))
        if stored:
            self.differs("contact history", "the scene holds stretched friction, rolling or twist springs, which a "
                         "LAMMPS data file cannot carry: LAMMPS starts every contact with none")

    # ---- deck parts ---------------------------------------------------------------------------
    def granular_model(self, law, wall=False):
        """The LAMMPS granular model words of a contact law (pair_coeff or fix wall/gran)."""
        if isinstance(law, KelvinVoigt):
            words = ["hooke", g17(law.stiffness), g17(law.damping)]
            eta_n = law.damping
            damping = "velocity"
            limit = law.no_tension
        else:
            # LAMMPS 29 Sep 2021's fix wall/gran hertz/material makes the sphere-wall modulus 4/3 E/(2 (1 - nu));
            # demkit's (a rigid wall) is 4/3 E/(1 - nu^2): the wall gets the modulus 2 E/(1 + nu) that gives it
            young = 2.0 * law.young / (1.0 + law.poisson) if wall else law.young
            alpha = law.gamma * math.sqrt(1.5)
            if law.gamma == 0.0:
                words, damping = ["hertz/material", g17(young), "0.0", g17(law.poisson)], "velocity"
            else:
                words = ["hertz/material", g17(young), g17(tsuji_coefficient(alpha)), g17(law.poisson)]
                damping = "tsuji"
            eta_n = None
            limit = True
        f, r = law.friction, law.rolling
        if f is None:
            words += ["tangential", "linear_nohistory", "0.0", "0.0"]
        elif isinstance(law, KelvinVoigt):
            if eta_n == 0.0 and law.eta_t != 0.0:
                raise ValueError(f"{law!r}: LAMMPS' tangential damping is a multiple of the normal one, which is "
                                 f"0 here while demkit's is {law.eta_t}")
            ratio = law.eta_t / eta_n if eta_n > 0.0 else 0.0
            words += ["tangential", "linear_history", g17(law.kt), g17(ratio), g17(law.mu)]
        else:
            if law.kt_fixed != 0.0 or law.eta_t_fixed >= 0.0:
                raise ValueError(f"{law!r}: LAMMPS' Mindlin spring is k a with a fixed k and its tangential damping "
                                 f"a fixed multiple of the normal one; export Hertz friction with the default "
                                 f"(Mindlin) stiffness and damping")
            # Mindlin k_t = 8 G* a: LAMMPS computes 8 G* itself for pairs (NULL); a rigid wall doubles G*
            stiffness = g17(16.0 * law.shear_eff) if wall else "NULL"
            words += ["tangential", "mindlin", stiffness, g17(math.sqrt(4.0 * law.shear_eff / law.young_eff)),
                      g17(law.mu)]
        if r is not None:
            kr, eta_r = (law.kr, law.eta_r) if isinstance(law, KelvinVoigt) else (law.kr_fixed, law.eta_r_fixed)
            if kr <= 0.0 or eta_r < 0.0:
                raise ValueError(f"{law!r}: LAMMPS' rolling sds has a fixed stiffness and damping; give the Hertz "
                                 f"RollingResistance a stiffness and a damping")
            words += ["rolling", "sds", g17(kr), g17(eta_r), g17(law.mu_r)]
        words += twisting_words(law)
        words += ["damping", damping]
        if limit:
            words.append("limit_damping")
        return " ".join(words)

    def binning(self):
        """"nsq" (all pairs) when the reach of the pair styles is long beside the spheres' extent (LAMMPS'
        bins then fail: open space with an uncut dipole), else "bin"."""
        reach = self.reach if self.dipole is not None else 2.0 * float(self.p.radius.max())
        x = self.p.position
        extent = np.max(x, axis=0) - np.min(x, axis=0) + 2.0 * float(self.p.radius.max())
        if self.scene.box is not None:
            extent = np.where(self.scene.periodic, self.scene.box.size, extent)
        return "nsq" if reach > 0.5 * float(extent.min()) else "bin"

    def dipole_reach(self):
        if self.dipole.cutoff_distance is not None:
            return self.dipole.cutoff_distance
        if self.dipole_cutoff is not None:
            return float(self.dipole_cutoff)
        x = self.p.position
        extent = float(np.linalg.norm(x.max(axis=0) - x.min(axis=0))) + 2.0 * float(self.p.radius.max())
        reach = 10.0 * extent
        self.notes.append(f"the Dipole has no cutoff: LAMMPS skips pairs farther apart than {reach:.6g} (10 times "
                          f"the diagonal of the spheres' initial extent; dipole_cutoff=... sets it)")
        return reach

    def pair_lines(self):
        contact = None if self.contact is None else self.granular_model(self.contact)
        if self.dipole is not None:
            rc = self.reach = self.dipole_reach()
            lj = g17(min(rc, float(self.p.radius.min())))  # epsilon 0: the LJ part is zero anyway
            dip = f"0.0 1.0 {lj} {g17(rc)}"
        if contact is not None and self.dipole is not None:
            return [f"pair_style  hybrid/overlay granular lj/cut/dipole/cut {g17(rc)}",
                    f"pair_coeff  * * granular {contact}",
                    f"pair_coeff  * * lj/cut/dipole/cut {dip}"]
        if contact is not None:
            return ["pair_style  granular", f"pair_coeff  * * {contact}"]
        if self.dipole is not None:
            return [f"pair_style  lj/cut/dipole/cut {g17(rc)}", f"pair_coeff  * * {dip}"]
        return ["pair_style  none"]

    def effect_lines(self):
        lines = []
        periodic = self.scene.periodic
        for k, effect in enumerate(self.scene.effects):
            if type(effect) is Gravity:
                g = effect.acceleration
                size = float(np.linalg.norm(g))
                if size > 0.0:
                    lines.append(f"fix         gravity mobile gravity {g17(size)} vector {g17(g[0])} {g17(g[1])} "
                                 f"{g17(g[2])}")
            elif type(effect) is UniformField:
                e = effect.field / self.scale
                lines.append(f"fix         field mobile efield {g17(e[0])} {g17(e[1])} {g17(e[2])}"
                             + ("   # E = B / sqrt(A): the moments are scaled by sqrt(A)" if self.scale != 1 else ""))
            elif type(effect) is Wall:
                lines.append(self.wall_line(k, effect, periodic))
            elif type(effect) is Cylinder:
                lines.append(self.cylinder_lines(k, effect))
            elif type(effect) is Cone:
                lines.append(self.cone_lines(k, effect))
        return lines

    def wall_friction_note(self, wall):
        """LAMMPS' wall friction takes the lever arm R in the slip and the torque: demkit's with
        ``slip_radius="full"``; with the contact point's R - delta a note (strict=True: refused)."""
        friction = wall.law.friction
        if friction is not None and friction.slip_radius != "full":
            self.differs(f"{wall!r} with friction", "LAMMPS' wall friction has the lever arm R, demkit's with "
                         "slip_radius='contact' R - delta (the contact point on the wall): spins differ by O(delta/R) "
                         "of the friction torque; Friction(slip_radius='full') takes R, as LAMMPS")

    def turning_note(self, wall):
        """LAMMPS' region walls roll and twist against the sphere's own spin (fix_wall_gran: relrot = omega,
        "TODO: incorporate wall angular velocity"); demkit's against its spin relative to a turning wall's."""
        law = wall.law
        if wall.angular_velocity != 0.0 and (getattr(law, "rolling", None) is not None
                                             or getattr(law, "twisting", None) is not None):
            self.differs(f"{wall!r} with rolling or twisting resistance", "LAMMPS' wall rolling and twisting act on "
                         "the sphere's spin alone, demkit's on its spin relative to the turning wall's (a sphere "
                         "turning with the wall feels none in demkit)")

    def cylinder_lines(self, k, cylinder):
        """The deck lines of a cylinder along x, y or z: an infinite ``region cylinder`` (side in for a
        tube, out for a post), turned by ``rotate`` through the angle omega t about its axis, and ``fix
        wall/gran/region`` on it (LAMMPS takes the wall's velocity at a contact from the region's motion)."""
        axes = np.flatnonzero(cylinder.axis != 0.0)
        if len(axes) != 1:
            raise ValueError(f"{cylinder!r}: LAMMPS' cylinder region runs along x, y or z; this axis cannot be exported")
        if cylinder.travels:
            raise ValueError(f"{cylinder!r}: a cylinder carried by a velocity or a vibration cannot be exported (only "
                             f"a cylinder at rest or turning about its axis)")
        if cylinder.servo is not None:
            raise ValueError(f"{cylinder!r}: LAMMPS' regions have no servo (a radius moved to hold a stress): it cannot "
                             f"be exported")
        self.wall_friction_note(cylinder)
        self.turning_note(cylinder)
        a = int(axes[0])
        across = [i for i in range(3) if i != a]
        centre = " ".join(g17(cylinder.point[i]) for i in across)
        side = "in" if cylinder.inside else "out"
        lines, turn = self.turning(k, cylinder)
        lines.append(f"region      drum{k} cylinder {'xyz'[a]} {centre} {g17(cylinder.radius)} INF INF side {side} "
                     f"units box{turn}")
        lines.append(f"fix         wall{k} mobile wall/gran/region granular {self.granular_model(cylinder.law, wall=True)} "
                     f"region drum{k}")
        return "\n".join(lines)

    def turning(self, k, wall):
        """(lines, words): a turning wall's angle variable and the region's ``rotate`` words (none at rest)."""
        if wall.angular_velocity == 0.0:
            return [], ""
        point, axis = " ".join(map(g17, wall.point)), " ".join(map(g17, wall.axis))
        return [f"variable    turn{k} equal {g17(wall.angular_velocity)}*time"], f" rotate v_turn{k} {point} {axis}"

    def cone_lines(self, k, cone):
        """The deck lines of a cone along +-x, y or z with an upper end: ``region cone`` between the planes
        lower and upper from the apex (radii lower tan(alpha), upper tan(alpha)), side in for a hopper, out
        for a post, its end caps open (``open 1 open 2``), turned by ``rotate`` like a cylinder, and ``fix
        wall/gran/region`` on it. LAMMPS' cone finds the same nearest point (the generator's, its ends the
        rims); inside it touches only centres inside the cone between its ends and none on the axis."""
        axes = np.flatnonzero(cone.axis != 0.0)
        if len(axes) != 1:
            raise ValueError(f"{cone!r}: LAMMPS' cone region runs along x, y or z; this axis cannot be exported")
        if cone.travels:
            raise ValueError(f"{cone!r}: a cone carried by a velocity or a vibration cannot be exported (only a cone "
                             f"at rest or turning about its axis)")
        if cone.upper is None:
            raise ValueError(f"{cone!r}: LAMMPS' cone region has two ends; give the Cone an upper end (upper=...) "
                             f"to export it")
        self.wall_friction_note(cone)
        self.turning_note(cone)
        if isinstance(cone.law, Hertz):
            self.differs(f"{cone!r} with Hertz contacts", "LAMMPS' cone puts the curvature 1/r of its circle into the "
                         "contact radius (r the contact point's distance from the axis), demkit the surface's, "
                         "cos(alpha)/r")
        a = int(axes[0])
        across = [i for i in range(3) if i != a]
        centre = " ".join(g17(cone.apex[i]) for i in across)
        tan = math.tan(cone.half_angle)
        ends = (cone.lower, cone.upper) if cone.axis[a] > 0 else (-cone.upper, -cone.lower)
        radii = [abs(h) * tan for h in ends]
        lines, turn = self.turning(k, cone)
        lines.append(f"region      cone{k} cone {'xyz'[a]} {centre} {g17(radii[0])} {g17(radii[1])} "
                     f"{g17(cone.apex[a] + ends[0])} {g17(cone.apex[a] + ends[1])} side "
                     f"{'in' if cone.inside else 'out'} open 1 open 2 units box{turn}")
        lines.append(f"fix         wall{k} mobile wall/gran/region granular {self.granular_model(cone.law, wall=True)} "
                     f"region cone{k}")
        return "\n".join(lines)

    def wall_line(self, k, wall, periodic):
        """The deck line(s) of a wall: ``fix wall/gran ... xplane`` for one normal to an axis, else a
        ``region plane`` (the half-space (x - p).n >= 0, side in) and ``fix wall/gran/region``, which
        LAMMPS runs through the same sphere-wall contact code with a flat wall (R* = R)."""
        axes = np.flatnonzero(wall.normal != 0.0)
        for a in axes:
            if periodic[a]:
                raise ValueError(f"{wall!r}: a wall across the periodic axis {'xyz'[a]} cannot be exported (LAMMPS "
                                 f"refuses walls in periodic dimensions); make that axis open")
        self.wall_friction_note(wall)
        model = self.granular_model(wall.law, wall=True)
        moving = np.flatnonzero(wall.velocity != 0.0)
        if wall.servo is not None:
            raise ValueError(f"{wall!r}: LAMMPS' fix wall/gran has no servo (a wall moved to hold a force): it cannot "
                             f"be exported")
        if wall.travels:  # LAMMPS moves a plane wall only by wiggle: A (1 - cos 2 pi t / period) along its normal
            shaken = np.flatnonzero(wall.amplitude != 0.0)
            if len(axes) > 1 or len(moving) or list(shaken) != [int(axes[0])]:
                raise ValueError(f"{wall!r}: LAMMPS moves a wall only by 'wiggle' (a vibration along the normal of a "
                                 f"wall normal to x, y or z, without a velocity); this motion cannot be exported")
        if len(axes) > 1:
            if len(moving):
                raise ValueError(f"{wall!r}: an oblique wall that slides in its plane cannot be exported (LAMMPS' "
                                 f"region walls take their velocity from moving the region itself); export it at "
                                 f"rest or make its normal lie along x, y or z")
            point, normal = " ".join(map(g17, wall.point)), " ".join(map(g17, wall.normal))
            return (f"region      wallplane{k} plane {point} {normal} side in units box\n"
                    f"fix         wall{k} mobile wall/gran/region granular {model} region wallplane{k}")
        a = int(axes[0])
        where = g17(wall.point[a])
        bounds = f"{where} NULL" if wall.normal[a] > 0 else f"NULL {where}"
        line = f"fix         wall{k} mobile wall/gran granular {model} {'xyz'[a]}plane {bounds}"
        if len(moving) > 1:
            raise ValueError(f"{wall!r}: LAMMPS' shear moves a wall along one axis; this one slides along "
                             f"{len(moving)}")
        if len(moving) == 1:
            line += f" shear {'xyz'[int(moving[0])]} {g17(wall.velocity[moving[0]])}"
        if wall.travels:
            line += f" wiggle {'xyz'[a]} {g17(wall.amplitude[a])} {g17(1.0 / wall.frequency)}"
        return line


def _steps(value, dt, what):
    steps = int(round(value / dt))
    if steps < 1 or abs(steps * dt - value) > 1e-9 * value:
        raise ValueError(f"{what} = {value} must be a whole number of time steps dt = {dt}")
    return steps


def write_data(path, particles, box, periodic, scale, comment, tilt=None):
    """LAMMPS data file (atom_style hybrid sphere dipole, 1 atom type, 2 for fixed spheres); with a
    :class:`Tilt`, a triclinic box (LAMMPS remaps the spheres into it as it reads them)."""
    p = particles
    n = p.n
    x = p.position.astype(float).copy()
    image = np.zeros((n, 3), dtype=np.int64) if p.image is None else p.image.astype(np.int64).copy()
    if box is not None and box.any_periodic:
        x, shift = box.wrap(x)
        image += shift
    image[:, ~np.asarray(periodic)] = 0
    if tilt is not None:  # LAMMPS' xu = x + ix L_a + iy tilt: the turns folded out of the tilt go to ix
        a, b = box.shear.axes
        image[:, a] += tilt.turns * image[:, b]
    lo = x.min(axis=0) - p.radius.max()
    hi = x.max(axis=0) + p.radius.max()
    if box is not None:
        lo, hi = np.minimum(lo, 0.0), np.maximum(hi, box.size)
    for a in range(3):
        if periodic[a]:
            lo[a], hi[a] = 0.0, box.size[a]
    fixed = p.fixed if p.fixed is not None else np.zeros(n, dtype=bool)
    types = np.where(fixed, 2, 1)
    mu = (p.dipole if p.dipole is not None else np.zeros((n, 3))) * scale
    w = p.angular_velocity if p.angular_velocity is not None else np.zeros((n, 3))
    density = p.mass / (4.0 / 3.0 * math.pi * p.radius ** 3)
    lines = [comment, "", f"{n} atoms", "2 atom types", ""]
    lines += [f"{g17(lo[a])} {g17(hi[a])} {c}lo {c}hi" for a, c in enumerate("xyz")]
    if tilt is not None:
        lines.append(" ".join(g17(tilt.value if name == tilt.name else 0.0) for name in ("xy", "xz", "yz"))
                     + " xy xz yz")
    lines += ["", "Masses", "", "1 1.0", "2 1.0", "", "Atoms # hybrid", ""]
    # hybrid sphere dipole: id type x y z | diameter density | q mux muy muz | ix iy iz
    for i in range(n):
        lines.append(f"{i + 1} {types[i]} {g17(x[i, 0])} {g17(x[i, 1])} {g17(x[i, 2])} {g17(2 * p.radius[i])} "
                     f"{g17(density[i])} 0 {g17(mu[i, 0])} {g17(mu[i, 1])} {g17(mu[i, 2])} "
                     f"{image[i, 0]} {image[i, 1]} {image[i, 2]}")
    lines += ["", "Velocities", ""]
    v = p.velocity
    for i in range(n):
        lines.append(f"{i + 1} {g17(v[i, 0])} {g17(v[i, 1])} {g17(v[i, 2])} {g17(w[i, 0])} {g17(w[i, 1])} "
                     f"{g17(w[i, 2])}")
    Path(path).write_text("\n".join(lines) + "\n")


def export_lammps(scene, integrator, directory, duration=None, record_every=None, *, strict=True,
                  dipole_update="dlm", dipole_cutoff=None):
    """Write ``scene.data`` and ``in.scene`` into ``directory`` (created if needed) so that
    ``lmp -in in.scene`` (run in that folder) runs ``scene`` with ``integrator``'s time step.

    duration : simulated time (a whole number of steps); None: pass ``-var nsteps N`` to lmp.
    record_every : time between dumped frames (``state.dump``: id, unwrapped x, v, omega, moments
        in demkit's units, all at full precision; step 0 included); None: the first and last step.
    strict : refuse what LAMMPS would run differently from demkit (see the module docstring);
        False exports it and lists the differences in the returned notes and the deck.
    dipole_update : "dlm" (``update dipole/dlm``, second order) or "euler" (``update dipole``).
    dipole_cutoff : the dipole cutoff to use when the scene's Dipole has none (open space).

    Returns :class:`LammpsFiles` (data, deck, notes). Raises ValueError naming what LAMMPS cannot
    represent.
    """
    sheared = scene.box is not None and scene.box.shear is not None
    tilt = tilt_of(scene.box, scene.time, integrator.dt) if sheared else None
    deform = getattr(scene.box, "deform", None) if scene.box is not None else None
    box = scene.box  # a deforming box as it is now, LAMMPS' erate taken from there (L_0 (1 + r t) = L(t0) (1 + r' (t - t0)))
    if deform is not None:
        box = Box(scene.box.size_at(scene.time), periodic=scene.box.periodic)
        now = deform.strain_rate(scene.box.size, scene.time)  # the rates now (a servo's last), from the box now
        rates = {"xyz"[a]: float(now[a]) for a in deform.axes if now[a] != 0.0}
    job = _Export(scene, integrator, strict, dipole_update, dipole_cutoff)
    job.check()
    if deform is not None and deform.servo is not None:
        job.differs("pressure servo", f"{deform.servo!r} has no LAMMPS counterpart in the export (fix press/berendsen "
                    f"and fix nph scale the box by other laws); the deck deforms the box at the rates set now")
    dt = integrator.dt
    nsteps = None if duration is None else _steps(float(duration), dt, "duration")
    if record_every is None:
        every = nsteps
    else:
        every = _steps(float(record_every), dt, "record_every")
    pair = job.pair_lines()
    effects = job.effect_lines()
    periodic = scene.periodic
    folder = Path(directory)
    folder.mkdir(parents=True, exist_ok=True)
    data, deck = folder / DATA_NAME, folder / DECK_NAME
    p = scene.particles
    write_data(data, p, box, periodic, job.scale,
               f"demkit scene: {p.n} spheres, exported by demkit.export_lammps", tilt)
    fixed = p.fixed is not None and bool(p.fixed.any())
    boundary = " ".join("p" if f else "s" for f in periodic)
    skin = scene.skin
    head = [f"# demkit scene exported by demkit.export_lammps for LAMMPS {LAMMPS_VERSION} (packages GRANULAR, "
            f"DIPOLE).", "#   lmp -in in.scene            (one rank; run in this folder)",
            "#   mpirun -np 2 lmp -in in.scene   (MPI; Open MPI as root: --allow-run-as-root)",
            f"# Scene: {p.n} spheres; box {scene.box!r}; interactions: "
            + ", ".join(repr(i) for i in scene.interactions + scene.effects) + ".",
            f"# Integrator: {integrator!r} -> fix nve/sphere update {job.update}.",
            f"# Dipole moments in {DATA_NAME} are demkit's times sqrt(A) = {g17(job.scale)} (LAMMPS' dipole energy "
            f"has no prefactor); the dump divides them back."]
    if tilt is not None:
        head.append(f"# Shear: the box tilts as {tilt.name} = {g17(tilt.rate)} L t (fix deform, remap v), led by one "
                    f"step (fix deform sets the tilt at the end of a step; demkit's forces take the sliding at the "
                    f"step's own time): the starting forces see it one step ahead.")
    if deform is not None:
        head.append("# Deformation: fix deform erate remap x (the box about its centre, demkit's about the origin: LAMMPS' "
                    "coordinates are demkit's plus its box's lower corner, -(L(t) - L(0)) / 2 along a deforming axis).")
    head += [f"# NOTE: {note}" for note in job.notes]
    lines = head + [""]
    if nsteps is not None:
        lines.append(f"variable    nsteps index {nsteps}")
    else:
        lines.append("# nsteps: the scene has no duration; give it: lmp -in in.scene -var nsteps N")
    lines += [f"variable    dumpevery index {every if every is not None else '${nsteps}'}",
              "variable    dump index state.dump", "",
              "units       lj", "dimension   3", "atom_style  hybrid sphere dipole", f"boundary    {boundary}",
              "newton      on", "comm_modify vel yes                 # contacts need the ghosts' velocities",
              f"read_data   {DATA_NAME}", "group       mobile type 1", "group       fixed type 2", ""]
    lines += pair
    lines += [f"neighbor    {g17(skin)} {job.binning()}", "neigh_modify every 1 delay 0 check yes", ""]
    lines += effects
    if fixed:
        lines.append("fix         hold fixed freeze")
    lines += [f"fix         integrate mobile nve/sphere update {job.update}"]
    if tilt is not None:  # after the integration, as in benchmarks/lammps/in.sheared; led by one step (docstring)
        lines.append(f"fix         shear all deform 1 {tilt.name} erate {g17(tilt.rate)} remap v flip yes")
    if deform is not None and rates:  # after the integration: the box and the positions remapped at each step's end
        lines.append("fix         strain all deform 1 " + " ".join(f"{c} erate {g17(r)}" for c, r in rates.items())
                     + " remap x")
    lines += [f"timestep    {g17(dt)}", "",
              "compute     erot all erotate/sphere", "thermo_style custom step time ke c_erot pe",
              "thermo_modify norm no", "thermo      ${dumpevery}",
              "compute     moment all property/atom mux muy muz"]
    lines += [f"variable    mu{c} atom c_moment[{k + 1}]/{g17(job.scale)}" for k, c in enumerate("xyz")]
    lines += [f"dump        state all custom ${{dumpevery}} ${{dump}} {DUMP_COLUMNS}",
              "dump_modify state sort id format float %.17g", "run         ${nsteps}"]
    deck.write_text("\n".join(lines) + "\n")
    return LammpsFiles(data, deck, tuple(job.notes))


def read_dump(path):
    """{step: (N, columns) array sorted by id} from a LAMMPS custom dump with id in the first column,
    e.g. the dump of an exported deck (columns of :data:`DUMP_COLUMNS`: id, unwrapped x (3), v (3),
    omega (3), moment in demkit's units (3))."""
    frames, lines = {}, Path(path).read_text().splitlines()
    k = 0
    while k < len(lines):
        step = int(lines[k + 1])
        n = int(lines[k + 3])
        rows = np.array(" ".join(lines[k + 9:k + 9 + n]).split(), dtype=float).reshape(n, -1)
        frames[step] = rows[np.argsort(rows[:, 0])]
        k += 9 + n
    return frames


__all__ = ["export_lammps", "read_dump", "LammpsFiles"]
