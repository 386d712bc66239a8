"""The catalogue of tier 1: every shipped pair law and single-sphere effect with its integer *kind* (its
position in :data:`PAIR_LAWS` or :data:`EFFECTS`), and how a scene's interaction is matched to one
(:meth:`Law.fits`). Registering a shipped law is one line here (docs/architecture.md)."""
from __future__ import annotations

import importlib
import inspect

import numpy as np


#: the kind of a pair law or effect not in the catalogue (your own functions): the program describes the
#: scene, but only the scene's own pieces (tier 2) can run it
OWN = -1

#: the shipped pair laws: (module, force function, energy function, torque, dissipative, branch_free[, the
#: force and energy functions of a law run as this kind]). A frictional contact law without twisting is run
#: as the twisting one (which, with lever 0, skips its twisting part: the same bits), and a frictional wall
#: likewise: tier 1 compiles one kind for both (the full family's pieces 21.9 -> 18.7 CPU-s, measured)
PAIR_LAWS = (
    ("demkit.interactions.dipole", "dipole_force", "dipole_energy", True, False, True),
    ("demkit.interactions.dipole", "switched_dipole_force", "switched_dipole_energy", True, False, True),
    ("demkit.interactions.dipole", "power_law_force", "power_law_energy", False, False, True),
    ("demkit.interactions.dipole", "switched_power_law_force", "switched_power_law_energy", False, False, True),
    ("demkit.interactions.ewald", "ewald_real_force", "ewald_real_energy", True, False, True),
    ("demkit.interactions.contact", "kelvin_voigt_force", "kelvin_voigt_energy", False, True, False),
    ("demkit.interactions.contact", "kelvin_voigt_twisting_force", "kelvin_voigt_twisting_energy", True, True, False,
     ("kelvin_voigt_friction_force", "kelvin_voigt_friction_energy")),
    ("demkit.interactions.hertz", "hertz_force", "hertz_energy", False, True, False),
    ("demkit.interactions.hertz", "hertz_twisting_force", "hertz_twisting_energy", True, True, False,
     ("hertz_friction_force", "hertz_friction_energy")),
)
#: the shipped single-sphere effects: (module, force function, energy function, torque, dissipative,
#: plane_contact[, functions run as this kind])
EFFECTS = (
    ("demkit.interactions.fields", "gravity_force", "gravity_energy", False, False, False),
    ("demkit.interactions.fields", "field_torque", "field_energy", True, False, False),
    ("demkit.interactions.langevin", "langevin_force", "langevin_energy", True, False, False),
    ("demkit.interactions.magnets", "magnet_force", "magnet_energy", True, False, False),
    ("demkit.interactions.wall", "wall_kelvin_voigt_force", "wall_kelvin_voigt_energy", False, True, True),
    ("demkit.interactions.wall", "wall_kelvin_voigt_twisting_force", "wall_kelvin_voigt_twisting_energy",
     True, True, True, ("wall_kelvin_voigt_friction_force", "wall_kelvin_voigt_friction_energy")),
    ("demkit.interactions.wall", "wall_hertz_force", "wall_hertz_energy", False, True, True),
    ("demkit.interactions.wall", "wall_hertz_twisting_force", "wall_hertz_twisting_energy", True, True, True,
     ("wall_hertz_friction_force", "wall_hertz_friction_energy")),
)
#: the long-range sums over all spheres: (module, function), called as
#: f(position, dipole, box, params, slot, force, torque, with_forces) -> energy
SUMS = (("demkit.interactions.ewald", "reciprocal_sum"), ("demkit.interactions.p3m", "p3m_sum"),
        ("demkit.interactions.fmm", "fmm_sum"))
MAX_SUMS = 2
FIELD_NAMES = ("velocity", "angular_velocity", "dipole", "radius", "mass")


class Law:
    """One catalogue entry: its functions and the shape of their calls (read from their signature)."""

    def __init__(self, kind, module, force, energy, torque, dissipative, special, also=None, *, pair):
        self.kind, self.module, self.force_name, self.energy_name = kind, module, force, energy
        self.torque, self.dissipative = torque, dissipative
        self.branch_free = special if pair else False
        self.plane_contact = special if not pair else False
        self.pair = pair
        fn = getattr(importlib.import_module(module), force)
        names = [n for n in inspect.signature(fn.py_func).parameters if n != "vshift"][6 if pair else 4:]
        #: the law takes the velocity shift of a sliding image (demkit.engine.shear) as its last argument
        self.shifted = "vshift" in inspect.signature(fn.py_func).parameters
        self.reads = []
        while names and names[0] in FIELD_NAMES:
            self.reads.append(names.pop(0))
        self.reads = tuple(self.reads)
        self.history = bool(names) and names[0] == "history"
        if self.history:
            names = names[4:]
        self.table = bool(names) and names[0] == "params"
        if self.table:
            names = names[2:]
        self.parameters = len(names)
        self.functions = (fn, getattr(importlib.import_module(module), energy))
        #: the function pairs this kind runs: its own, and those of a law whose bits it gives with a part off
        self.runs = (self.functions,) + ((tuple(getattr(importlib.import_module(module), name) for name in also),)
                                         if also else ())

    def fits(self, inter):
        """Is ``inter`` (a scene's interaction or effect) this law, called the way the law is?"""
        table = np.size(inter.table_values()) > 0 if not self.pair else False
        return (tuple(inter.pair_functions()) in self.runs and bool(inter.torque) == self.torque
                and bool(inter.dissipative) == self.dissipative and tuple(inter.reads) == self.reads
                and bool(inter.history_size) == self.history and len(inter.parameters) == self.parameters
                and table == self.table and (self.pair or bool(getattr(inter, "plane_contact", False))
                                             == self.plane_contact))


_CATALOGUE = None
#: the pair laws of the small family, "plain": the paper's magnets (dipoles, Kelvin-Voigt contacts)
#: and power-law dipoles, no cutoff switch, no effects (a new install's first scene waits for its
#: pieces alone: 9 CPU-s, against 45 for the full family's)
PLAIN_LAWS = ("dipole_force", "power_law_force", "kelvin_voigt_force")
#: the families of pieces modules, each holding the laws and effects it accepts (with their catalogue
#: kind numbers), from the smallest: a scene runs on the first family holding its laws. Two, not
#: more: every family is compiled once per install (a third, for scenes without contact history, cost
#: 21 CPU-s more in all and ran no faster: 440-504 against 448-487 steps/s, a 600-sphere Hertz gas)
FAMILIES = {"plain": lambda law: law.pair and law.force_name in PLAIN_LAWS, "full": lambda law: True}
#: the pieces module of the blocked pair loop, shared by the families: it holds the branch-free laws
#: (dipoles) alone, which every family holds
BLOCKED = "blocked"
#: the families whose pair loops take a sheared box's sliding images (demkit.engine.shear); a sheared
#: scene runs on the first of them. The plain family's do not: the paper's scene, a new install's
#: first, does not compile them (2.2 CPU-s of its first step, measured)
SLIDING = ("full", BLOCKED)


def catalogue():
    """(pair laws, effects): the :class:`Law` entries, in the order of their kind numbers."""
    global _CATALOGUE
    if _CATALOGUE is None:
        _CATALOGUE = ([Law(k, *entry, pair=True) for k, entry in enumerate(PAIR_LAWS)],
                      [Law(k, *entry, pair=False) for k, entry in enumerate(EFFECTS)])
    return _CATALOGUE


def _law_of(inter, laws):
    for law in laws:
        if law.fits(inter):
            return law
    return None
