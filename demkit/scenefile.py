"""Scene files: a whole simulation (spheres, box, interactions, integrator, run, outputs) in TOML.

    loaded = dk.load_scene("collision.toml")                        # or dk.parse_scene(text)
    loaded = dk.load_scene("collision.toml", overrides={"particles.build.b_over_R": 3.0})
    trajectory = loaded.run()                                       # writes what [outputs] asks for

The format is :data:`SCHEMA` (reference: docs/scene_files.md, generated from it by
:func:`reference`). Reading a file executes nothing from it. Every problem is one
:class:`SceneFileError` naming the file, the line and the key path (``interactions.dipole.prefactor``);
the line comes from a scan of the text (:func:`demkit.schema.key_lines`, tomllib gives none).

``units = "si"`` reads every dimensional number in SI and converts it to the seed paper's
dimensionless units (:mod:`demkit.units`) with the scales of the ``[scales]`` table (mass, radius,
stiffness or Young's modulus, dipole moment or magnetisation of the reference sphere): lengths in
x_c, times in t_c, moments in the reference moment, and the dipole prefactor mu0/4pi (SI) becomes
1/3. The run and its outputs are then in those units (``LoadedScene.units`` converts back).
"""
from __future__ import annotations

import csv
import math
import re
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .integrators import parse_method
from .schema import (REQUIRED, Key, SchemaError, SchemaErrors, Table, Tables, Variant, dotted, key_lines, line_of,
                     validate)

#: scene files larger than this are refused before parsing (bytes)
MAX_FILE_BYTES = 64 * 2**20


class SceneFileError(ValueError):
    """A scene file that cannot be used: one message with the file, line and key path (several, one
    a line, when the file's keys hold several problems: ``errors`` lists them)."""

    def __init__(self, message, source=None, path=(), line=None):
        where = str(source) if source is not None else "<scene>"
        if line is not None:
            where += f":{line}"
        super().__init__(f"{where}: {dotted(path)}: {message}" if path else f"{where}: {message}")
        self.source, self.path, self.line = source, tuple(path), line
        self.errors = [self]

    @classmethod
    def several(cls, errors):
        """One error saying all of ``errors`` (SceneFileErrors), a line each, in the file's order."""
        errors = sorted(errors, key=lambda e: (e.line is None, e.line or 0))
        first = errors[0]
        combined = cls.__new__(cls)
        ValueError.__init__(combined, "\n".join(str(e) for e in errors))
        combined.source, combined.path, combined.line, combined.errors = first.source, first.path, first.line, errors
        return combined


# ---- the format -----------------------------------------------------------------------------------
def _n(doc, **kw):
    return Key("number", doc=doc, **kw)


_SPHERES = {  # shared by the builders that make equal spheres
    "mass": _n("mass of each sphere", default=1.0, check="positive", dim="mass"),
    "inertia_factor": _n("I = inertia_factor m R^2 (2/5: solid sphere)", default=0.4, check="positive"),
}
_RANDOM = {  # states drawn from one generator seeded by `seed`, in this order
    "seed": Key("integer", doc="seed of the one random generator (positions, then directions, velocities, spins)"),
    "moment": _n("dipole moment of each sphere (none: no dipoles)", dim="dipole"),
    "directions": Key("direction", default="random", choices=("random", "random_xy"),
                      doc='moment directions: "random" (uniform on the sphere), "random_xy" (uniform in the '
                          'xy plane) or one vector for all'),
    "kT": _n("thermal velocities at this temperature, zero total momentum (none: at rest)", check="non_negative",
             dim="energy"),
    "spin_kT": _n("thermal spins at this temperature (none: no spin)", check="non_negative", dim="energy"),
    "flat": Key("bool", default=False, doc="a monolayer: no velocity along z"),
}
BUILDERS = {
    "random_packing": Table({
        "n": Key("integer", REQUIRED, "number of spheres", check="at_least_one"),
        "radius": _n("sphere radius", default=REQUIRED, check="positive", dim="length"),
        "volume_fraction": _n("fill a cube at this volume fraction; the cube is the scene's box", check="positive"),
        "periodic": Key("flags", default=True, doc="with volume_fraction: the cube's periodic axes"),
        "region": Key("size", doc="place the spheres in the open box [0, size] (only for placing them)",
                      check="positive", dim="length"),
        **_SPHERES, **_RANDOM}, "random non-overlapping spheres (dk.build.random_packing) in [box], in region, or "
                                "in a cube at volume_fraction", one_of=((("volume_fraction", "region"), False),),
        excludes=(("region", ("periodic",)),)),
    "lattice": Table({
        "lattice": Key("string", REQUIRED, "crystal", choices=("sc", "bcc", "fcc", "hcp")),
        "cells": Key("cells", REQUIRED, "unit cells along x, y, z (one integer or three)", check="at_least_one"),
        "radius": _n("sphere radius", default=REQUIRED, check="positive", dim="length"),
        "spacing": _n("nearest-neighbour distance (default 2 radius: touching)", check="positive", dim="length"),
        "periodic": Key("flags", default=True, doc="periodic axes of the lattice's box, the scene's box"),
        **_SPHERES, **_RANDOM}, "spheres on a lattice (dk.build.lattice); its box is the scene's box"),
    "chain": Table({
        "n": Key("integer", REQUIRED, "number of spheres", check="at_least_one"),
        "radius": _n("sphere radius", default=REQUIRED, check="positive", dim="length"),
        "start": Key("vector", [0.0, 0.0, 0.0], "centre of the first sphere", dim="length"),
        "direction": Key("vector", [1.0, 0.0, 0.0], "direction of the chain and of its moments"),
        "gap": _n("gap between neighbouring surfaces", default=0.0, check="non_negative", dim="length"),
        "moment": _n("dipole moment of each sphere", default=1.0, dim="dipole"),
        **_SPHERES}, "a straight head-to-tail chain of dipoles (dk.build.chain), at rest"),
    "ring": Table({
        "n": Key("integer", REQUIRED, "number of spheres (at least 3)", check="at_least_one"),
        "radius": _n("sphere radius", default=REQUIRED, check="positive", dim="length"),
        "centre": Key("vector", [0.0, 0.0, 0.0], "centre of the ring", dim="length"),
        "normal": Key("vector", [0.0, 0.0, 1.0], "normal of the ring's plane"),
        "gap": _n("gap between neighbouring surfaces", default=0.0, check="non_negative", dim="length"),
        "moment": _n("dipole moment of each sphere", default=1.0, dim="dipole"),
        **_SPHERES}, "a flux-closure ring of dipoles (dk.build.ring), at rest"),
    "two_magnets": Table({
        "b_over_R": _n("impact parameter b / R", default=REQUIRED, check="non_negative"),
        "speed": _n("speed of each sphere (paper: 5.78e-3)", default=5.78e-3, check="positive", dim="velocity"),
        "radius": _n("sphere radius (paper: 6.94)", default=6.94, check="positive", dim="length"),
        "x0": _n("starting |x| of each centre", default=150.0, check="positive", dim="length"),
        "mass": _n("mass of each sphere", default=1.0, check="positive", dim="mass"),
        "dipoles": Key("string", "aligned", "moments along the line of centres: head to tail or head to head",
                       choices=("aligned", "anti-aligned")),
    }, "the seed paper's two spheres (dk.two_magnets.TwoMagnets(...).particles()); its interactions are "
       "written in [interactions]"),
}

PARTICLES = Table({
    "position": Key("vectors", doc="centres, one [x, y, z] per sphere", dim="length"),
    "velocity": Key("vectors", doc="velocities (default: at rest)", dim="velocity"),
    "radius": Key("numbers", 1.0, "radius: one for all or one per sphere", check="positive", dim="length"),
    "mass": Key("numbers", 1.0, "mass: one for all or one per sphere", check="positive", dim="mass"),
    "inertia_factor": Key("numbers", 0.4, "I = inertia_factor m R^2", check="positive"),
    "dipole": Key("vectors", doc="magnetic moments (default: none)", dim="dipole"),
    "angular_velocity": Key("vectors", doc="spins, rad per time (default: none)", dim="angular_velocity"),
    "fixed": Key("bools", doc="spheres held in place (they must start at rest)"),
    "susceptibility": Key("numbers", doc="magnetic susceptibility chi = mu_r - 1 >= 0, one for all or one per "
                                         "sphere: spheres with chi > 0 are magnetisable, their moments induced "
                                         "(needs [interactions.dipole]; also with file and build)",
                          check="non_negative"),
    "ids": Key("integers", doc="unique ids (default 0 .. N-1)"),
    "file": Key("string", doc="a .csv or .npz file of the spheres, relative to the scene file (see the docs)"),
    "build": Variant("kind", BUILDERS, "a builder: kind = random_packing, lattice, chain, ring or two_magnets"),
}, "the spheres: inline arrays, a file, or a [particles.build] table", required=True,
    one_of=((("position", "file", "build"), True),),
    excludes=(("build", ("velocity", "radius", "mass", "inertia_factor", "dipole", "angular_velocity", "fixed",
                         "ids")),
              ("file", ("velocity", "dipole", "angular_velocity", "fixed", "ids"))))

_PLACE = {  # where a magpylib source is and how it is turned; magpylib's SI units, whatever `units` says
    "position": Key("vector", [0.0, 0.0, 0.0], "centre, m"),
    "rotation_vector": Key("vector", doc="orientation: rotation axis times angle in radians "
                                         "(scipy Rotation.from_rotvec); none: unrotated"),
    "axis": Key("vector", doc="or orientation as an axis ..."),
    "angle": _n("... and an angle in degrees about it (needs axis)"),
}
_MAGNET = {
    "polarization": Key("vector", doc="magnetic polarization J = mu0 M, T (e.g. [0, 0, 1.2])"),
    "magnetization": Key("vector", doc="or magnetization M, A/m"),
}
_ONE_MAGNETISATION = ((("polarization", "magnetization"), True), (("rotation_vector", "axis"), False))
_ANGLE = (("rotation_vector", ("angle",)),)
MAGNET_SOURCES = {
    "cuboid": Table({"dimension": Key("vector", REQUIRED, "side lengths [a, b, c], m", check="positive"),
                     **_MAGNET, **_PLACE}, "a block magnet (magpylib.magnet.Cuboid)", one_of=_ONE_MAGNETISATION,
                    excludes=_ANGLE),
    "cylinder": Table({"dimension": Key("row", REQUIRED, "[diameter, height], m", check="positive", length=2),
                       **_MAGNET, **_PLACE}, "a cylinder magnet, axis along z before rotation "
                                             "(magpylib.magnet.Cylinder)", one_of=_ONE_MAGNETISATION,
                      excludes=_ANGLE),
    "sphere": Table({"diameter": _n("diameter, m", default=REQUIRED, check="positive"), **_MAGNET, **_PLACE},
                    "a ball magnet (magpylib.magnet.Sphere)", one_of=_ONE_MAGNETISATION, excludes=_ANGLE),
    "circle": Table({"diameter": _n("loop diameter, m", default=REQUIRED, check="positive"),
                     "current": _n("current, A", default=REQUIRED), **_PLACE},
                    "a circular current loop in the xy plane before rotation (magpylib.current.Circle)",
                    one_of=(_ONE_MAGNETISATION[1],), excludes=_ANGLE),
    "dipole": Table({"moment": Key("vector", REQUIRED, "magnetic moment, A m^2"), **_PLACE},
                    "a point dipole (magpylib.misc.Dipole)", one_of=(_ONE_MAGNETISATION[1],), excludes=_ANGLE),
}

_CUTOFF = {"cutoff": _n("centre distance beyond which pairs are ignored (none: never)", check="positive",
                        dim="length"),
           "switch_width": _n("smooth switch-off over [cutoff - width, cutoff] (none: plain cut)", check="positive",
                              dim="length")}
INTERACTIONS = Table({
    "dipole": Table({"prefactor": _n("A = mu0/4pi in SI (the default there); required in plain units, where "
                                     "1/3 with unit moments is the paper's units",
                                     default=1e-7, check="positive", dim="dipole_prefactor"), **_CUTOFF,
                     "ewald": Table({
                         "accuracy": _n("relative RMS force error the sum is tuned to", default=1e-6,
                                        check="positive"),
                         "surface": Key("string", "metallic", "surroundings: metallic or vacuum",
                                        choices=("metallic", "vacuum")),
                         "alpha": _n("splitting parameter (none: tuned)", check="positive", dim="inverse_length")},
                         "every image of a periodic box: a dipolar Ewald sum (dk.Ewald); cutoff is then the "
                         "real-space cutoff (none: tuned); in a box periodic along two axes, a slab sum (surface "
                         "left out)"),
                     "p3m": Table({
                         "accuracy": _n("relative RMS force error the sum is tuned to", default=1e-4,
                                        check="positive"),
                         "surface": Key("string", "metallic", "surroundings: metallic or vacuum",
                                        choices=("metallic", "vacuum")),
                         "alpha": _n("splitting parameter (none: tuned)", check="positive", dim="inverse_length"),
                         "order": Key("integer", 6, "B-spline order, 4 to 7"),
                         "mesh": Key("integer", None, "mesh points per axis (none: tuned)")},
                         "every image of a big periodic box: a dipolar particle-mesh sum (dk.P3M); cutoff is "
                         "then the real-space cutoff (none: tuned); in a box periodic along two axes, a slab sum "
                         "(surface left out)"),
                     "fmm": Table({
                         "accuracy": _n("FMM3D's precision eps", default=1e-9, check="positive"),
                         "exact_below": Key("number_or_auto", "auto", 'fewer spheres keep the exact sum: "auto" '
                                            '(the crossover) or a number (0: always the FMM)')},
                         "every pair of a big open cluster by a fast multipole sum (dk.FMM; needs "
                         "pip install \"demkit[fmm]\")"),
                     "induction": Table({
                         "tolerance": _n("relative residual at which the solve of induced moments stops",
                                         default=1e-6, check="positive"),
                         "max_iterations": Key("integer", 100, "iterations allowed per solve")},
                         "the solve of the magnetisable spheres' moments (dk.Induction; particles.susceptibility)")},
                    "full dipole-dipole force and torque (dk.Dipole)",
                    one_of=((("ewald", "p3m", "fmm"), False),),
                    excludes=(("ewald", ("switch_width",)), ("p3m", ("switch_width",)),
                              ("fmm", ("cutoff", "switch_width")))),
    "power_law_dipole": Table({"prefactor": _n("A, as for dipole (required in plain units)", default=1e-7, check="positive",
                                               dim="dipole_prefactor"), **_CUTOFF},
                              "the paper's central head-to-tail force, no torque (dk.PowerLawDipole)"),
    "kelvin_voigt": Table({
        "stiffness": _n("k, force per overlap", default=REQUIRED, check="positive", dim="stiffness"),
        "damping": _n("c, force per overlap rate", default=0.0, check="non_negative", dim="damping"),
        "no_tension": Key("bool", False, "forbid the attractive end of the contact")},
        "linear spring-dashpot contact (dk.KelvinVoigt)"),
    "hertz": Table({
        "young": _n("Young's modulus", default=REQUIRED, check="positive", dim="pressure"),
        "poisson": _n("Poisson ratio in (-1, 0.5)", default=REQUIRED),
        "restitution": _n("normal restitution in (0, 1]", default=1.0)}, "Hertz contact (dk.Hertz)"),
    "friction": Table({
        "coefficient": _n("Coulomb coefficient mu", default=REQUIRED, check="non_negative"),
        "stiffness": _n("tangential spring (default: from the contact law)", check="positive", dim="stiffness"),
        "damping": _n("tangential dashpot (default: the normal damping ratio)", check="non_negative",
                      dim="damping"),
        "slip_radius": Key("string", "contact", "lever arms: contact or full", choices=("contact", "full")),
        "sliding": Key("string", "coulomb", "sliding rule: coulomb or lammps", choices=("coulomb", "lammps"))},
        "Coulomb friction of the contact law (dk.Friction)"),
    "rolling_resistance": Table({
        "coefficient": _n("mu_r", default=REQUIRED, check="non_negative"),
        "stiffness": _n("rolling spring (default 2.25 mu_r^2 k)", check="positive", dim="stiffness"),
        "damping": _n("rolling dashpot (default: the normal damping ratio)", check="non_negative", dim="damping")},
        "rolling resistance of the contact law, needs friction (dk.RollingResistance)"),
    "twisting_resistance": Table({
        "stiffness": _n("twist spring, torque per radian (default Marshall's k_t a^2/2)", check="positive",
                        dim="energy"),
        "damping": _n("twist dashpot, torque per spin rate (default eta_t a^2/2)", check="non_negative",
                      dim="angular_momentum"),
        "lever": _n("the largest twisting torque is lever times the normal force (default (2/3) mu a)",
                    check="non_negative", dim="length")},
        "twisting resistance of the contact law, needs friction; an empty table: Marshall's coefficients "
        "(dk.TwistingResistance)"),
    "gravity": Table({"acceleration": Key("vector", REQUIRED, "g, e.g. [0, 0, -9.81]", dim="acceleration")},
                     "uniform gravity (dk.Gravity)"),
    "uniform_field": Table({"field": Key("vector", REQUIRED, "B (energy = -m . B)", dim="field")},
                           "a uniform magnetic field (dk.UniformField)"),
    "langevin": Table({
        "temperature": _n("k_B T of the bath (energy)", default=REQUIRED, check="non_negative", dim="energy"),
        "drag": _n("gamma, force per velocity", default=REQUIRED, check="positive", dim="damping"),
        "rotational_drag": _n("gamma_r, torque per angular velocity (default: (4/3) R^2 gamma, the Stokes ratio)",
                              check="positive", dim="angular_momentum"),
        "seed": Key("integer", 0, "seed of the thermostat's random kicks")},
        "Langevin thermostat: drag and random kicks, velocity Verlet only (dk.Langevin)"),
    "magnet_field": Tables(Table({
        "region": Key("vectors", REQUIRED, "two corners [[x0, y0, z0], [x1, y1, z1]] of the box the spheres stay "
                                           "in (scene lengths); no magnet or wire inside it", dim="length"),
        "spacing": _n("largest grid spacing of the table (scene length)", default=REQUIRED, check="positive",
                      dim="length"),
        "length_unit": _n("metres per scene length (units = \"si\": from [scales])", check="positive"),
        "field_unit": _n("tesla per scene field unit (units = \"si\": from [scales])", check="positive"),
        "source": Tables(Variant("kind", MAGNET_SOURCES, "a magpylib source: kind = cuboid, cylinder, sphere, "
                                                         "circle (a current loop) or dipole",
                                 aliases={"coil": "circle", "loop": "circle", "current": "circle", "ring": "circle",
                                          "block": "cuboid", "box": "cuboid", "cube": "cuboid", "ball": "sphere",
                                          "disc": "cylinder", "disk": "cylinder", "rod": "cylinder"}),
                         "the sources, [[interactions.magnet_field.source]], at least one")},
        "the field of magpylib magnets and coils, tabulated over region (dk.MagnetField); needs magpylib: "
        "pip install \"demkit[magnets]\""), "fields of real magnets, [[interactions.magnet_field]], any number"),
    "wall": Tables(Table({
        "point": Key("vector", REQUIRED, "a point of the plane", dim="length"),
        "normal": Key("vector", REQUIRED, "normal pointing to the spheres' side"),
        "velocity": Key("vector", [0.0, 0.0, 0.0], "in-plane velocity of the wall", dim="velocity")},
        "a plane wall with the scene's contact law (dk.Wall)"), "plane walls, [[interactions.wall]], any number"),
}, "the interactions, each a named table", one_of=((("dipole", "power_law_dipole"), False),
                                                   (("kelvin_voigt", "hertz"), False)))

SCHEMA = Table({
    "title": Key("string", doc="a line saying what the scene is"),
    "units": Key("string", "plain", 'plain (numbers used as given) or si (converted to the paper\'s units with '
                                    '[scales])', choices=("plain", "si")),
    "scales": Table({
        "mass": _n("mass of the reference sphere, kg", default=REQUIRED, check="positive"),
        "radius": _n("its radius, m", default=REQUIRED, check="positive"),
        "stiffness": _n("contact stiffness, N/m", check="positive"),
        "young_modulus": _n("or Young's modulus, Pa (k = pi Y R / 2)", check="positive"),
        "dipole_moment": _n("its dipole moment, A m^2", check="positive"),
        "magnetisation": _n("or its magnetisation, A/m", check="positive"),
        "field": _n("or, for magnetisable spheres, a field B (T) that induces its moment 4 pi R^3 chi/(chi + 3) B / "
                    "mu0 (with susceptibility)", check="positive"),
        "susceptibility": _n("its susceptibility chi (with field)", check="positive")},
        'with units = "si": the reference sphere that sets the scales (dk.units.PaperUnits.from_si)',
        one_of=((("stiffness", "young_modulus"), True), (("dipole_moment", "magnetisation", "field"), True))),
    "particles": PARTICLES,
    "box": Table({
        "size": Key("size", REQUIRED, "side lengths [Lx, Ly, Lz] (or one for a cube); corner at the origin",
                    check="positive", dim="length"),
        "periodic": Key("flags", False, "periodic axes: true/false or three of them")},
        "the simulation box (none: open space)"),
    "interactions": INTERACTIONS,
    "scene": Table({
        "skin": _n("extra reach of the neighbour lists (default 0.3 mean diameters); lists are rebuilt when a "
                   "sphere has moved skin/2", check="positive", dim="length"),
        "parallel": Key("bool_or_auto", "auto", 'threads for the pair loops: "auto" (from 2000 spheres), true or '
                                                'false'),
        "sort_every": Key("integer", doc="re-order the spheres by cell every this many steps, 0: never (default: "
                                         "every 1000 steps from 1000 spheres with neighbour lists)",
                          check="non_negative")},
        "how the compiled loops work (the keywords skin, parallel, sort_every of dk.Scene); none of it changes "
        "the physics"),
    "integrator": Table({
        "method": Key("string", "VelocityVerlet", "EulerCromer, VelocityVerlet, ForestRuth, RK4, MultipleTimeStep "
                                                  "(or a name as `demkit accuracy --methods` takes)"),
        "dt": Key("number_or_auto", REQUIRED, 'time step, or "auto": chosen for the accuracy below '
                                             '(dk.choose_time_step: stability, dashpots, a pilot run)',
                  check="positive", dim="time"),
        "accuracy": _n('with dt = "auto": the energy balance the run keeps, a fraction of its energy scale (default '
                       '0.01, the end-of-run note\'s limit)', check="positive"),
        "inner": Key("integer", doc="MultipleTimeStep: inner steps per step (default 4)", check="at_least_one"),
        "resolve_contacts": Key("bool", False, "VelocityVerlet, MultipleTimeStep: resolve contact events")},
        "how to step", required=True),
    "run": Table({
        "duration": _n("simulated time", default=REQUIRED, check="positive", dim="time"),
        "record_every": _n("time between recorded frames (none: start and end)", check="positive", dim="time"),
        "max_energy_growth": _n("stop when total + dissipated energy grows by this fraction", check="positive")},
        "how long", required=True),
    "outputs": Table({
        "trajectory": Key("string", doc="write the recorded frames to this .npz file"),
        "vtk": Table({
            "folder": Key("string", "vtk", "folder of the ParaView series"),
            "every": _n("time between frames", default=REQUIRED, check="positive", dim="time"),
            "trails": Key("bool", True, "also write the paths as poly-lines"),
            "compress": Key("bool", False, "zlib-compress the frames"),
            "contacts": Key("bool", False, "also write the contact network"),
            "measures": Key("strings", [], "per-sphere measurements in every frame (dk.measure)",
                            choices=("pressure", "coordination", "field"))}, "a VTK series (dk.VTKWriter)"),
        "animation": Table({
            "path": Key("string", REQUIRED, "a .gif or .mp4 file, made from the VTK series"),
            "max_frames": Key("integer", 200, "at most this many frames", check="at_least_one"),
            "fps": Key("integer", 20, "frames per second", check="at_least_one"),
            "color_by": Key("string", doc="colour the spheres by this (see dk.viz.animate)"),
            "trail": _n("trail length in time (none: dk.viz's default)", check="non_negative", dim="time")},
            "an animation (dk.viz.animate), needs [outputs.vtk]"),
        "checkpoint": Table({
            "path": Key("string", REQUIRED, "checkpoint file (.npz); a rerun resumes from it"),
            "every": _n("simulated time between saves", check="positive", dim="time"),
            "seconds": _n("wall-clock seconds between saves", check="positive")}, "checkpoints (dk.Checkpoint)"),
    }, "what to write; paths relative to the scene file's folder (or to --out)"),
}, "the keys outside any table")

#: order in which the interactions enter the scene (the file's order does not matter)
INTERACTION_ORDER = ("dipole", "power_law_dipole", "kelvin_voigt", "hertz", "gravity", "uniform_field",
                     "magnet_field", "wall", "langevin")


# ---- reading --------------------------------------------------------------------------------------
class _Source:
    """The text of a scene file, for messages with lines."""

    def __init__(self, text, name, overrides):
        self.text, self.name = text, name
        self.overridden = [tuple(_split(k)) for k in (overrides or {})]
        self.units_note = ""  # units = "si": constructors' messages quote converted numbers; this says so
        self._lines = None

    def error(self, path, message):
        path = tuple(path)
        for key in self.overridden:
            if path[:len(key)] == key or key[:len(path)] == path and path:
                return SceneFileError(f"{message} (set by override {dotted(key)})", self.name, path)
        if self._lines is None:
            self._lines = key_lines(self.text)
        return SceneFileError(message, self.name, path, line_of(self._lines, path))


def _split(key):
    parts = []
    for part in str(key).split("."):
        parts.append(int(part) if part.isdigit() else part)
    return parts


def apply_overrides(data, overrides, source=None):
    """Set each dotted key path of ``overrides`` in the raw dict ``data`` (tables are created as needed;
    a number selects an item of an array of tables: ``interactions.wall.0.point``)."""
    for key, value in (overrides or {}).items():
        parts = _split(key)
        if not parts or any(p == "" for p in parts):
            raise SceneFileError(f"override key {key!r} is not a dotted key path", source)
        node = data
        for k, part in enumerate(parts[:-1]):
            where = parts[:k + 1]
            if isinstance(node, list):
                if not isinstance(part, int) or part >= len(node):
                    raise SceneFileError(f"override {key!r}: no item {part} in {dotted(where[:-1])}", source)
                node = node[part]
            elif isinstance(node, dict):
                if isinstance(part, int):
                    raise SceneFileError(f"override {key!r}: {dotted(where[:-1])} is not an array of tables", source)
                node = node.setdefault(part, {})
            else:
                raise SceneFileError(f"override {key!r}: {dotted(where[:-1])} is a value, not a table", source)
        if not isinstance(node, dict) or isinstance(parts[-1], int):
            raise SceneFileError(f"override {key!r}: {dotted(parts[:-1])} is not a table", source)
        node[parts[-1]] = value
    return data


def load_scene(path, overrides=None):
    """Read, validate and build the scene file ``path``: a :class:`LoadedScene`.

    overrides : {dotted key path: value}, set in the file's data before validation, e.g.
        ``{"interactions.dipole.prefactor": 0.5, "particles.build.b_over_R": 3.0}``; a key the format
        does not know is an error like an unknown key in the file.
    Raises :class:`SceneFileError` (a ValueError) for anything wrong, with file, line and key path.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        if not path.is_file():
            raise SceneFileError("is not a file", path)
        if size > MAX_FILE_BYTES:
            raise SceneFileError(f"is {size / 2**20:.0f} MB: scene files are at most {MAX_FILE_BYTES // 2**20} MB "
                                 f"(put large particle sets in a .npz file: particles.file)", path)
        raw = path.read_bytes()
    except OSError as err:
        raise SceneFileError(f"cannot be read: {err.strerror or err}", path) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        line = raw[:err.start].count(b"\n") + 1
        raise SceneFileError(f"is not UTF-8 text (byte {err.start}: {raw[err.start:err.start + 1]!r})",
                             path, line=line) from None
    return parse_scene(text, source=path, overrides=overrides)


def parse_scene(text, source="<string>", overrides=None):
    """Like :func:`load_scene` for the TOML ``text``; relative paths are taken from the folder of
    ``source`` (the current folder for "<string>")."""
    name = source
    base = Path(".") if str(source) == "<string>" else Path(source).resolve().parent
    src = _Source(text, name, overrides)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        message = str(err)
        line = getattr(err, "lineno", None)
        if line is None and "(at line " in message:
            try:
                line = int(message.rsplit("(at line ", 1)[1].split(",")[0])
            except ValueError:
                line = None
        raise SceneFileError(f"not valid TOML: {message.split(' (at ')[0]}", name, line=line) from None
    except RecursionError:
        raise SceneFileError("not readable: arrays or tables nested too deeply", name) from None
    try:
        raw = apply_overrides(raw, overrides, name)
        data = validate(SCHEMA, raw)
        _check_rules(data)
        _check_prefactors(raw, data)
    except SchemaErrors as err:  # every problem of the keys, found in one pass
        raise SceneFileError.several([src.error(e.path, e.problem) for e in err.errors]) from None
    except SchemaError as err:
        raise src.error(err.path, err.problem) from None
    except RecursionError:
        raise SceneFileError("nested too deeply", name) from None
    return _build(data, src, base)


def _check_prefactors(raw, data):
    """In plain units a dipole's prefactor is given: its default, mu0/4pi = 1e-7, is SI's constant."""
    if data["units"] == "si":
        return
    for name in ("dipole", "power_law_dipole"):
        table = (raw.get("interactions") or {}).get(name)
        if isinstance(table, dict) and "prefactor" not in table:
            raise SchemaError(("interactions", name, "prefactor"),
                              "is required in plain units (A in F = A (...) m m / r^4: 1/3 with unit moments in "
                              "the seed paper's units; mu0/4pi = 1e-7 only in SI, with units = \"si\")")


def _check_rules(data):
    """What the schema cannot say: rules between tables."""
    if data["units"] == "si" and data["scales"] is None:
        raise SchemaError(("units",), 'units = "si" needs a [scales] table (the reference sphere)')
    if data["units"] != "si" and data["scales"] is not None:
        raise SchemaError(("scales",), 'is used only with units = "si"')
    scales = data["scales"] or {}
    if scales.get("field") is not None and scales.get("susceptibility") is None:
        raise SchemaError(("scales", "field"), "needs susceptibility: the reference sphere's moment is the one the "
                                               "field induces in it")
    if scales.get("susceptibility") is not None and scales.get("field") is None:
        raise SchemaError(("scales", "susceptibility"), "goes with field (the field that induces the reference "
                                                        "moment)")
    inter = data["interactions"] or {}
    contact = inter.get("kelvin_voigt") or inter.get("hertz")
    for name in ("friction", "rolling_resistance", "twisting_resistance"):
        if inter.get(name) is not None and contact is None:
            raise SchemaError(("interactions", name), "needs a contact law: [interactions.kelvin_voigt] or "
                                                      "[interactions.hertz]")
    for name in ("rolling_resistance", "twisting_resistance"):
        if inter.get(name) is not None and inter.get("friction") is None:
            raise SchemaError(("interactions", name), "needs [interactions.friction]")
    if inter.get("wall") and contact is None:
        raise SchemaError(("interactions", "wall", 0), "walls use the scene's contact law: add "
                                                       "[interactions.kelvin_voigt] or [interactions.hertz]")
    build = (data["particles"] or {}).get("build")
    if build is not None and data["box"] is not None and (
            build["kind"] == "lattice" or (build["kind"] == "random_packing" and build["volume_fraction"])):
        raise SchemaError(("box",), f"the {build['kind']} builder makes the box"
                                    f"{' (volume_fraction)' if build['kind'] == 'random_packing' else ''}: "
                                    f"leave out [box]")
    out = data["outputs"] or {}
    if out.get("animation") is not None and out.get("vtk") is None:
        raise SchemaError(("outputs", "animation"), "is made from the VTK series: add [outputs.vtk]")
    integ = data["integrator"]
    if ":" in integ["method"] and (integ["inner"] is not None or integ["resolve_contacts"]):
        raise SchemaError(("integrator", "method"), "give inner and resolve_contacts either in the name "
                                                    "(MultipleTimeStep:8:resolve) or as keys, not both")


# ---- SI input -------------------------------------------------------------------------------------
def si_scales(scales):
    """(PaperUnits, {dimension: SI value of one dimensionless unit}) for a validated [scales] table."""
    from .units import PaperUnits, dipole_from_magnetisation, induced_dipole
    moment = scales["dipole_moment"]
    if scales["field"] is not None:
        moment = induced_dipole(scales["susceptibility"], scales["radius"], scales["field"])
    units = PaperUnits.from_si(mass=scales["mass"], radius=scales["radius"], stiffness=scales["stiffness"],
                               young_modulus=scales["young_modulus"], dipole_moment=moment,
                               magnetisation=scales["magnetisation"])
    mu = moment or dipole_from_magnetisation(scales["magnetisation"], scales["radius"])
    m, length, t = units.mass, units.length, units.time
    k = m / t**2
    return units, {"length": length, "time": t, "mass": m, "velocity": length / t, "angular_velocity": 1 / t,
                   "acceleration": length / t**2, "stiffness": k, "damping": m / t, "energy": k * length**2,
                   "angular_momentum": m * length**2 / t,
                   "pressure": k / length, "dipole": mu, "dipole_prefactor": k * length**5 / mu**2,
                   "field": k * length**2 / mu, "inverse_length": 1 / length}


def _convert(schema, data, scale):
    """Divide every dimensional value of ``data`` by its unit's SI value (in place)."""
    if data is None:
        return
    if isinstance(schema, Variant):
        schema = schema.variants[data[schema.key]]
    for name, entry in schema.keys.items():
        value = data.get(name)
        if isinstance(entry, Key):
            if entry.dim is not None and value is not None and not isinstance(value, str):
                data[name] = (np.asarray(value, dtype=np.float64) / scale[entry.dim]).tolist()
        elif isinstance(entry, Tables):
            for item in value or []:
                _convert(entry.table, item, scale)
        else:
            _convert(entry, value, scale)


# ---- building -------------------------------------------------------------------------------------
class _At:
    """Turn a ValueError or TypeError of a constructor into a SceneFileError at ``path``; with
    ``keys`` (the table's keys), at the first of them the message names (as a whole word), in the
    table ``keyed`` (default: ``path``)."""

    def __init__(self, src, *path, keys=(), keyed=None):
        self.src, self.path, self.keys = src, path, keys
        self.keyed = path if keyed is None else keyed  # where the keys are (default: in ``path``)

    def __enter__(self):
        return self

    def __exit__(self, kind, err, tb):
        if kind is not None and issubclass(kind, (ValueError, TypeError, OverflowError, MemoryError)) \
                and not isinstance(err, SceneFileError):
            message = str(err)
            named = [(m.start(), key) for key in self.keys
                     for m in [re.search(rf"(?<![\w.]){re.escape(key)}(?!\w)", message)] if m]
            path = self.keyed + (min(named)[1],) if named else self.path
            raise self.src.error(path, message + self.src.units_note) from None
        return False


CSV_COLUMNS = {"x": ("position", 0), "y": ("position", 1), "z": ("position", 2),
               "vx": ("velocity", 0), "vy": ("velocity", 1), "vz": ("velocity", 2),
               "wx": ("angular_velocity", 0), "wy": ("angular_velocity", 1), "wz": ("angular_velocity", 2),
               "mx": ("dipole", 0), "my": ("dipole", 1), "mz": ("dipole", 2),
               "radius": ("radius", None), "mass": ("mass", None), "inertia_factor": ("inertia_factor", None),
               "fixed": ("fixed", None), "id": ("ids", None)}
NPZ_ARRAYS = ("position", "velocity", "radius", "mass", "inertia_factor", "dipole", "angular_velocity", "fixed", "ids")


def read_particle_file(path):
    """{Particles keyword: array} from a .csv (a header row naming the columns of CSV_COLUMNS) or a
    .npz (arrays named as Particles' keywords; read without pickle). Raises ValueError."""
    import difflib
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"particle file {path} does not exist")
    if path.suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {name: z[name] for name in z.files}
        except Exception as err:  # zip or npy damage: one message
            raise ValueError(f"cannot read {path} as .npz: {err}") from None
        for name in arrays:
            if name not in NPZ_ARRAYS:
                near = difflib.get_close_matches(name, NPZ_ARRAYS, n=1)
                raise ValueError(f"{path}: unknown array {name!r}" + (f"; did you mean {near[0]!r}?" if near else
                                                                      f"; known: {', '.join(NPZ_ARRAYS)}"))
        if arrays.get("fixed") is not None:
            arrays["fixed"] = arrays["fixed"].astype(bool)
        return arrays
    if path.suffix != ".csv":
        raise ValueError(f"particle file {path} must end in .csv or .npz")
    with open(path, newline="", encoding="utf-8") as fh:
        rows = [row for row in csv.reader(fh) if row and not row[0].lstrip().startswith("#")]
    if len(rows) < 2:
        raise ValueError(f"{path} needs a header row naming the columns and one row per sphere")
    header = [h.strip() for h in rows[0]]
    for h in header:
        if h not in CSV_COLUMNS:
            near = difflib.get_close_matches(h, list(CSV_COLUMNS), n=1)
            raise ValueError(f"{path}: unknown column {h!r}" + (f"; did you mean {near[0]!r}?" if near else
                                                                f"; known: {', '.join(CSV_COLUMNS)}"))
    try:
        table = np.array([[float(v) for v in row] for row in rows[1:]], dtype=np.float64)
    except ValueError as err:
        raise ValueError(f"{path}: every value must be a number ({err})") from None
    if table.shape[1] != len(header):
        raise ValueError(f"{path}: every row must have {len(header)} values")
    arrays = {}
    for k, h in enumerate(header):
        field, axis = CSV_COLUMNS[h]
        if axis is None:
            arrays[field] = table[:, k]
        else:
            arrays.setdefault(field, np.zeros((len(table), 3)))[:, axis] = table[:, k]
    for field in ("position", "velocity", "angular_velocity", "dipole"):
        given = [h for h in header if CSV_COLUMNS[h][0] == field]
        if given and len(given) != 3:
            raise ValueError(f"{path}: {field} needs all three columns, got {', '.join(given)}")
    if "fixed" in arrays:
        arrays["fixed"] = arrays["fixed"] != 0
    if "ids" in arrays:
        arrays["ids"] = arrays["ids"].astype(np.int64)
    return arrays


def _builder(b, box, src):
    """(Particles keywords, box made by the builder or None) from a [particles.build] table."""
    from . import build as B
    from .box import Box
    where = ("particles", "build")
    kind = b["kind"]
    keys = [k for k in b if k != "kind"]
    if kind == "two_magnets":
        from .two_magnets import TwoMagnets
        with _At(src, *where, keys=keys):
            p = TwoMagnets(b_over_R=b["b_over_R"], speed=b["speed"], radius=b["radius"], x0=b["x0"], mass=b["mass"],
                           dipoles=b["dipoles"]).particles()
        return {"particles": p}, None
    if kind in ("chain", "ring"):
        with _At(src, *where, keys=keys):
            if kind == "chain":
                x, m = B.chain(b["n"], b["radius"], start=b["start"], direction=b["direction"], gap=b["gap"],
                               moment=b["moment"])
            else:
                x, m = B.ring(b["n"], b["radius"], centre=b["centre"], normal=b["normal"], gap=b["gap"],
                              moment=b["moment"])
        return dict(position=x, radius=b["radius"], mass=b["mass"], inertia_factor=b["inertia_factor"], dipole=m), None
    rng = np.random.default_rng(b["seed"])
    made = None
    with _At(src, *where, keys=keys):
        if kind == "lattice":
            x, made = B.lattice(b["lattice"], b["cells"], spacing=b["spacing"],
                                radius=None if b["spacing"] is not None else b["radius"], periodic=b["periodic"])
        else:
            if b["volume_fraction"] is not None:
                made = place = B.box_for(b["n"], b["radius"], b["volume_fraction"], periodic=b["periodic"])
            elif b["region"] is not None:
                place = Box(b["region"])
            elif box is not None:
                place = box
            else:
                raise ValueError("random_packing needs a box to fill: a [box] table, region or volume_fraction")
            x = B.random_packing(b["n"], b["radius"], place, seed=rng)
    n = len(x)
    out = dict(position=x, radius=b["radius"], mass=b["mass"], inertia_factor=b["inertia_factor"])
    with _At(src, *where, keys=keys):
        if b["moment"] is not None:
            if b["directions"] == "random":
                u = B.random_directions(n, seed=rng)
            elif b["directions"] == "random_xy":
                angle = rng.uniform(0.0, 2 * math.pi, n)
                u = np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=1)
            else:
                d = np.asarray(b["directions"], dtype=np.float64)
                if not np.linalg.norm(d) > 0:
                    raise ValueError("directions must be a non-zero vector")
                u = np.tile(d / np.linalg.norm(d), (n, 1))
            out["dipole"] = b["moment"] * u
        if b["kT"] is not None:
            v = B.thermal_velocities(n, kT=b["kT"], mass=b["mass"], seed=rng)
            if b["flat"]:
                v[:, 2] = 0.0
            out["velocity"] = v
        if b["spin_kT"] is not None:
            out["angular_velocity"] = B.thermal_spins(n, kT=b["spin_kT"], inertia=b["inertia_factor"] * b["mass"]
                                                      * b["radius"] ** 2, seed=rng)
    return out, made


def _check_memory(data, box, interactions, src):
    """Refuse a [particles.build] table whose spheres, with the file's interactions and record, would
    not fit in the memory available (:func:`demkit.memory.estimate`), before anything is built: a
    SceneFileError at its ``cells`` (lattice) or ``n`` key with the estimate and what the machine
    has. Other particles are checked by dk.Scene (:meth:`demkit.Scene.memory_estimate`)."""
    from types import SimpleNamespace

    import numba

    from . import build as B
    from . import memory
    from .interactions.base import PairInteraction
    from .scene import DEFAULT_SKIN, PARALLEL_MIN, SORT_MIN
    b = data["particles"]["build"] if data["particles"] else None
    if b is None or b["kind"] == "two_magnets":
        return
    kind, radius = b["kind"], float(b["radius"])
    volume, periodic = None, box is not None and box.any_periodic
    if kind == "lattice":
        key = "cells"
        cells = [int(c) for c in np.broadcast_to(np.asarray(b["cells"], dtype=object), (3,))]
        edges, basis, _ = B._LATTICES[b["lattice"]]
        n = math.prod(cells) * len(basis)
        spacing = b["spacing"] if b["spacing"] is not None else 2.0 * radius
        volume = math.prod(cells) * math.prod(edges) * spacing**3
        periodic = bool(np.any(b["periodic"]))
        subject = f"{n:,} spheres ({' x '.join(map(str, cells))} cells of {len(basis)}, {b['lattice']}) need"
    else:
        key, n = "n", int(b["n"])
        if kind == "random_packing":
            if b["volume_fraction"] is not None:
                volume = n * 4.0 / 3.0 * math.pi * radius**3 / b["volume_fraction"]
                periodic = bool(np.any(b["periodic"]))
            elif b["region"] is not None:
                volume = float(np.prod(np.broadcast_to(b["region"], (3,))))
            elif box is not None:
                volume = box.volume
        subject = f"{n:,} spheres need"
    proxy = SimpleNamespace(radius=np.array([radius]), mass=np.array([float(b["mass"])]))
    reaches = {}
    for inter in interactions:
        if isinstance(inter, PairInteraction):
            try:
                reach = float(inter.cutoff(proxy))
            except Exception:  # a plug-in that needs more of the particles: a contact's reach  # noqa: BLE001
                reach = 2.0 * radius
            reaches[reach] = reaches.get(reach, 0) + inter.history_size
    options = data["scene"] or {}
    skin = options.get("skin") or DEFAULT_SKIN * 2.0 * radius
    lists = [(min(memory.pairs_per_sphere(n, r + skin, radius, volume), memory.pairs_per_sphere(n, r + skin, radius)),
              width) for r, width in reaches.items() if math.isfinite(r)]
    run = data["run"]
    frames = run["duration"] / run["record_every"] + 2 if run["record_every"] else 2
    frames = int(min(frames, 2.0**62))  # (for the estimate: more than any machine holds)
    torques = any(inter.torque or "angular_velocity" in inter.reads for inter in interactions)
    threads = int(numba.config.NUMBA_NUM_THREADS) if n >= PARALLEL_MIN and options.get("parallel") is not False else 1
    # (an upper bound: with parallel unset, only scenes whose force evaluation is estimated at 0.5 ms or
    # more are cut into chunks for threads, demkit.engine.threads.THREADS_FROM_SECONDS)
    try:
        stages = parse_method(data["integrator"]["method"])(1.0).stage_arrays
    except Exception:  # the method is checked, with its own message, once the scene is built  # noqa: BLE001
        stages = 0
    parts = memory.estimate(n, dipoles=kind in ("chain", "ring") or b.get("moment") is not None,
                            spins=torques or b.get("spin_kT") is not None, periodic=periodic,
                            sorted_copies=n >= SORT_MIN and bool(lists) and options.get("sort_every") != 0,
                            threads=threads, stages=stages, lists=lists,
                            all_pairs_history=sum(w for r, w in reaches.items() if not math.isfinite(r)),
                            frames=frames)
    advice = f"fewer spheres ({'fewer cells' if key == 'cells' else 'a smaller n'})"
    if parts["record"] > parts["arrays"] + parts["lists"]:
        advice += ", or fewer frames in memory (a larger run.record_every; the record is the largest part)"
    try:
        memory.refuse_above(parts["total"], subject, advice, parts=memory.describe(parts, frames))
    except ValueError as err:
        raise src.error(("particles", "build", key), str(err)) from None


def _particles(d, box, src, base, scale):
    from .particles import Particles
    p = d["particles"]
    made = None
    if p["build"] is not None:
        kw, made = _builder(p["build"], box, src)
        if "particles" in kw:
            if p["susceptibility"] is not None:
                raise src.error(("particles", "susceptibility"), "the two_magnets builder makes permanent magnets: "
                                "no susceptibility")
            return kw["particles"], made
        where = ("particles", "build")
    elif p["file"] is not None:
        where = ("particles", "file")
        file = Path(p["file"]) if Path(p["file"]).is_absolute() else base / p["file"]
        with _At(src, *where):
            kw = read_particle_file(file)
            if scale is not None:
                for name, value in kw.items():
                    dim = PARTICLES.keys[name].dim
                    if dim is not None:
                        kw[name] = value / scale[dim]
        for name in ("radius", "mass", "inertia_factor"):
            kw.setdefault(name, p[name])
    else:
        where = ("particles",)
        kw = {name: p[name] for name in ("position", "velocity", "radius", "mass", "inertia_factor", "dipole",
                                         "angular_velocity", "ids")}
        if p["fixed"] is not None:
            kw["fixed"] = np.array(p["fixed"], dtype=bool)
    for name in ("position", "velocity", "dipole", "angular_velocity"):
        if kw.get(name) is not None and len(kw[name]) == 0:
            raise src.error(where + ((name,) if where == ("particles",) else ()), "needs at least one sphere")
    if p["susceptibility"] is not None:
        kw["susceptibility"] = p["susceptibility"]
    with _At(src, *where, keys=[k for k in kw if where == ("particles",) and p.get(k) is not None]):
        return Particles(**kw), made


def _interactions(d, src, scale=None):
    from . import interactions as I
    inter = d["interactions"] or {}
    friction = rolling = twisting = None
    with _At(src, "interactions", "friction", keys=inter.get("friction") or ()):
        if inter.get("friction") is not None:
            friction = I.Friction(**inter["friction"])
    with _At(src, "interactions", "rolling_resistance", keys=inter.get("rolling_resistance") or ()):
        if inter.get("rolling_resistance") is not None:
            rolling = I.RollingResistance(**inter["rolling_resistance"])
    with _At(src, "interactions", "twisting_resistance", keys=inter.get("twisting_resistance") or ()):
        if inter.get("twisting_resistance") is not None:
            twisting = I.TwistingResistance(**inter["twisting_resistance"])
    out = []
    for name in INTERACTION_ORDER:
        value = inter.get(name)
        if not value:
            continue
        with _At(src, "interactions", name, keys=value if isinstance(value, dict) else ()):
            if name in ("dipole", "power_law_dipole"):
                cls = I.Dipole if name == "dipole" else I.PowerLawDipole
                method = next((m for m in ("ewald", "p3m", "fmm") if value.get(m) is not None), None)
                options = {}
                if method is not None:
                    with _At(src, "interactions", name, method, keys=value[method]):
                        options["long_range"] = {"ewald": I.Ewald, "p3m": I.P3M, "fmm": I.FMM}[method](**value[method])
                else:
                    options["switch_width"] = value["switch_width"]
                if value.get("induction") is not None:
                    with _At(src, "interactions", name, "induction", keys=value["induction"]):
                        options["induction"] = I.Induction(**value["induction"])
                out.append(cls(prefactor=value["prefactor"], cutoff=value["cutoff"], **options))
            elif name == "kelvin_voigt":
                out.append(I.KelvinVoigt(**value, friction=friction, rolling=rolling, twisting=twisting))
            elif name == "hertz":
                out.append(I.Hertz(**value, friction=friction, rolling=rolling, twisting=twisting))
            elif name == "gravity":
                out.append(I.Gravity(value["acceleration"]))
            elif name == "uniform_field":
                out.append(I.UniformField(value["field"]))
            elif name == "langevin":
                out.append(I.Langevin(**value))
        if name == "magnet_field":
            for k, table in enumerate(value):
                out.append(_magnet_field(table, ("interactions", "magnet_field", k), src, scale))
        if name == "wall":
            for k, wall in enumerate(value):
                with _At(src, "interactions", "wall", k, keys=wall):
                    out.append(I.Wall(**wall))
    return out


def magnet_source(s):
    """A magpylib source from a validated [[interactions.magnet_field.source]] table (SI units)."""
    import magpylib
    from scipy.spatial.transform import Rotation
    kw = {"position": s["position"]}
    if s["rotation_vector"] is not None:
        kw["orientation"] = Rotation.from_rotvec(s["rotation_vector"])
    elif s["axis"] is not None:
        axis = np.asarray(s["axis"], dtype=np.float64)
        if not np.linalg.norm(axis) > 0:
            raise ValueError("axis must be a non-zero vector")
        kw["orientation"] = Rotation.from_rotvec(math.radians(s["angle"]) * axis / np.linalg.norm(axis))
    kind = s["kind"]
    if kind in ("cuboid", "cylinder", "sphere"):
        kw["polarization" if s["polarization"] is not None else "magnetization"] = \
            s["polarization"] if s["polarization"] is not None else s["magnetization"]
        if kind == "sphere":
            return magpylib.magnet.Sphere(diameter=s["diameter"], **kw)
        cls = magpylib.magnet.Cuboid if kind == "cuboid" else magpylib.magnet.Cylinder
        return cls(dimension=s["dimension"], **kw)
    if kind == "circle":
        return magpylib.current.Circle(diameter=s["diameter"], current=s["current"], **kw)
    return magpylib.misc.Dipole(moment=s["moment"], **kw)


def _magnet_field(table, where, src, scale):
    """A dk.MagnetField from a validated [[interactions.magnet_field]] table."""
    from .interactions.magnets import MagnetField
    try:
        import magpylib  # noqa: F401
    except ImportError:
        raise src.error(where, 'needs magpylib, an optional extra: pip install "demkit[magnets]"') from None
    if not table["source"]:
        raise src.error(where, "needs at least one source: add [[interactions.magnet_field.source]] with kind = "
                               "cuboid, cylinder, sphere, circle or dipole")
    if len(table["region"]) != 2:
        raise src.error(where + ("region",), f"must be two corners [[x0, y0, z0], [x1, y1, z1]], got "
                                             f"{len(table['region'])} rows")
    units = {"length_unit": table["length_unit"], "field_unit": table["field_unit"]}
    if scale is not None:  # units = "si": the scene's length and field units are the paper's
        for name in units:
            if units[name] is not None:
                raise src.error(where + (name,), 'is set from [scales] with units = "si": leave it out')
        units = {"length_unit": scale["length"], "field_unit": scale["field"]}
    sources = []
    for k, source in enumerate(table["source"]):
        at = where + ("source", k)
        if (source["axis"] is None) != (source["angle"] is None):
            raise src.error(at + ("axis" if source["axis"] is None else "angle",),
                            "missing: an orientation by axis and angle needs both (or give rotation_vector)")
        with _At(src, *at, keys=[key for key in source if key != "kind"]):
            sources.append(magnet_source(source))
    with _At(src, *where, keys=("region", "spacing", "length_unit", "field_unit")):
        return MagnetField(sources, table["region"], table["spacing"],
                           length_unit=1.0 if units["length_unit"] is None else units["length_unit"],
                           field_unit=1.0 if units["field_unit"] is None else units["field_unit"])


def _integrator(d, scene, src):
    """(the integrator, the StepChoice of dt = "auto" or None)."""
    integ = d["integrator"]
    text = integ["method"]
    if integ["inner"] is not None:
        text += f":{integ['inner']}"
    if integ["resolve_contacts"]:
        text += ":resolve"
    with _At(src, "integrator", "method"):
        make = parse_method(text)
    dt = integ["dt"]
    if integ["accuracy"] is not None and dt != "auto":
        raise src.error(("integrator", "accuracy"), 'accuracy chooses the step of dt = "auto"; with dt given as a '
                                                     'number it has no effect: remove it, or set dt = "auto"')
    choice = None
    if dt == "auto":
        from .step_choice import ACCURACY, choose_time_step
        accuracy = ACCURACY if integ["accuracy"] is None else integ["accuracy"]
        with _At(src, "integrator", keys=("dt", "accuracy")):  # at the key its message names first
            choice = choose_time_step(scene, make, d["run"]["duration"], accuracy)
        dt = choice.dt
    with _At(src, "integrator"):
        return make(dt), choice


def _build(data, src, base):
    from .box import Box
    from .scene import Scene
    units = scale = None
    if data["units"] == "si":
        with _At(src, "scales"):
            units, scale = si_scales(data["scales"])
        _convert(SCHEMA, data, scale)
        src.units_note = (f" [numbers in the paper's units, converted from SI: length {units.length:.4g} m, "
                          f"time {units.time:.4g} s, mass {units.mass:.4g} kg]")
    box = None
    if data["box"] is not None:
        with _At(src, "box", keys=("size", "periodic")):
            box = Box(data["box"]["size"], data["box"]["periodic"])
    interactions = _interactions(data, src, scale)
    _check_memory(data, box, interactions, src)  # before a builder allocates anything
    particles, made = _particles(data, box, src, base, scale)
    box = made if made is not None else box
    options = data["scene"] or {"skin": None, "parallel": "auto", "sort_every": None}
    parallel = None if options["parallel"] == "auto" else options["parallel"]
    given = [k for k in ("skin", "sort_every") if options[k] is not None] + ["parallel"] * (parallel is not None)
    with _At(src, "particles", keys=given, keyed=("scene",)):
        scene = Scene(particles, interactions, box=box, skin=options["skin"], parallel=parallel,
                      sort_every=options["sort_every"])
    integrator, step_choice = _integrator(data, scene, src)
    run = data["run"]
    with _At(src, "integrator"):
        from .guards import before_stepping
        before_stepping(scene, integrator)
        integrator.check(scene)
    outputs = data["outputs"] or {"trajectory": None, "vtk": None, "animation": None, "checkpoint": None}
    return LoadedScene(scene=scene, integrator=integrator, duration=run["duration"], record_every=run["record_every"],
                       outputs=outputs, path=None if str(src.name) == "<string>" else Path(src.name), data=data,
                       units=units, max_energy_growth=run["max_energy_growth"], base=base, source=src,
                       step_choice=step_choice)


# ---- running --------------------------------------------------------------------------------------
@dataclass
class LoadedScene:
    """A validated scene file, built: ``scene`` (a fresh dk.Scene), ``integrator``, ``duration``,
    ``record_every``, ``outputs`` (the validated [outputs] table), ``path`` (the file or None),
    ``data`` (the whole validated file as plain values, defaults filled in, in the units simulated)
    and ``units`` (dk.units.PaperUnits for units = "si", else None)."""

    #: set by :meth:`run`: the checkpoint held the run's end already (nothing ran)
    complete = False

    scene: object
    integrator: object
    duration: float
    record_every: float | None
    outputs: dict
    path: Path | None
    data: dict
    units: object = None
    max_energy_growth: float | None = None
    #: with dt = "auto": how the step was chosen (dk.step_choice.StepChoice), else None
    step_choice: object = None
    base: Path = Path(".")
    source: object = None
    #: outputs that could not be written where asked and were saved elsewhere: {name: path}
    rescued: dict = field(default_factory=dict)

    def output_path(self, name, out_dir=None):
        """Where an output path of the file goes: as written when absolute, else in ``out_dir`` or
        the scene file's folder."""
        p = Path(name)
        if p.is_absolute():
            return p
        return (Path(out_dir) if out_dir is not None else self.base) / p

    def check_outputs(self, out_dir=None):
        """Raise SceneFileError (naming the key, the path and the problem) unless every output file
        of ``[outputs]`` can be written: found before the first step, not after the run. The VTK
        series folder is checked by its writer."""
        from .outputs import check_writable
        out = self.outputs
        for key, name, what in (("trajectory", out.get("trajectory"), "trajectory"),
                                ("animation", (out.get("animation") or {}).get("path"), "animation"),
                                ("checkpoint", (out.get("checkpoint") or {}).get("path"), "checkpoint")):
            if name:
                with _At(self.source, "outputs", key):
                    check_writable(self.output_path(name, out_dir), what)

    def simulation(self, out_dir=None):
        """A dk.Simulation of the scene with the file's writers and checkpoint; when the checkpoint
        file exists the simulation is resumed from it (and the VTK series continued)."""
        from .checkpoint import Checkpoint
        from .io import VTKWriter
        from .simulation import Simulation
        out = self.outputs
        self.check_outputs(out_dir)
        checkpoint = None
        resume = False
        if out.get("checkpoint") is not None:
            c = out["checkpoint"]
            target = self.output_path(c["path"], out_dir)
            target.parent.mkdir(parents=True, exist_ok=True)
            with _At(self.source, "outputs", "checkpoint"):
                checkpoint = Checkpoint(target, every=c["every"], seconds=c["seconds"])
            resume = checkpoint.exists()
        writers = []
        if out.get("vtk") is not None:
            v = out["vtk"]
            with _At(self.source, "outputs", "vtk"):
                writers.append(VTKWriter(self.output_path(v["folder"], out_dir), every=v["every"], compress=v["compress"],
                                         trails=v["trails"], contacts=v["contacts"], measures=v["measures"],
                                         overwrite=not resume, resume=resume))
        with _At(self.source, "run"):
            sim = Simulation(self.scene, self.integrator, writers=writers, checkpoint=checkpoint,
                             max_energy_growth=self.max_energy_growth)
        if resume:
            with _At(self.source, "outputs", "checkpoint"):
                sim.resume()
        return sim

    def run(self, progress=None, out_dir=None, on_resume=None):
        """Run to ``duration`` (from a checkpoint when there is one) and write every output the file
        asks for. ``progress``: as for Simulation.run (None: a bar on a terminal for runs longer than
        a moment).

        Every output path is checked writable before the first step (SceneFileError otherwise).
        Frames are taken on the grid of the whole run (steps 0, s, 2s, ... with s = record_every /
        dt, and the last step), also when resuming. The trajectory file is written atomically at
        the end, on Ctrl-C, when the run stops, and, with a checkpoint, just before every
        checkpoint (the frames recorded so far): a run killed at any moment leaves a file that
        holds at least every frame on the grid up to its checkpoint, and the checkpoint a digest of
        them. A resumed run's file holds the whole run: the earlier frames are taken from the file
        when they are the ones the checkpoint's run recorded (checked by that digest, or, for a
        checkpoint without one, against the checkpoint's state in the file's folded convention);
        otherwise the old file is renamed ``<name>.set-aside.npz`` (never overwritten), the new
        one holds the frames from the resume on, and a line says why. When the file cannot be
        written at the end (a full disk), it is saved elsewhere
        (:func:`demkit.outputs.write_or_rescue`) and a line says where. ``on_resume(path)`` is
        called once the checkpoint has been checked and loaded (not when it holds the run's end:
        then nothing runs, ``self.complete`` is True and the files are left as they are). Returns the
        Trajectory written (the whole run), or without a trajectory file the frames of this call
        (from where it started)."""
        from .simulation import SimulationError
        sim = self.simulation(out_dir)
        dt = self.integrator.dt
        end = round(self.duration / dt)
        start = sim.step
        #: the checkpoint already held the end of the run: nothing ran, the outputs are as they were
        self.complete = start >= end
        if getattr(sim, "resumed_meta", None) is not None and on_resume is not None and not self.complete:
            on_resume(sim.checkpoint.path)
        with _At(self.source, "run", "record_every"):
            stride = end if self.record_every is None else sim._steps(self.record_every, "record_every")
        target = self.output_path(self.outputs["trajectory"], out_dir) if self.outputs.get("trajectory") else None
        if target is not None:
            from .outputs import remove_partials
            remove_partials(target)  # left by a process killed while writing the file
        earlier = self._earlier_frames(target, sim, stride) if start > 0 and target is not None else None
        if start >= end:  # a finished run's checkpoint: nothing left to do
            sim.close()
            return earlier if earlier is not None else sim.trajectory
        grid = -(-start // stride) * stride  # the first step of the grid at or after the start
        plan = [] if grid in (start, end) or grid > end else [(grid * dt, None)]
        plan.append((self.duration, self.record_every if grid < end else None))
        parts = []
        written = {"step": None}  # the step the trajectory file was last written at
        if target is not None and sim.checkpoint is not None:
            def before_checkpoint(s):
                so_far = _join(earlier, parts + _current(s), start, stride, end, dt)
                steps = np.rint(so_far.time / dt).astype(np.int64)
                if len(steps) > 1 and steps[-1] <= steps[-2]:  # mid-run: the last frame kept twice
                    so_far = _frames(so_far, np.arange(len(steps) - 1))
                save_trajectory(so_far, target)
                written["step"] = s.step if round(so_far.time[-1] / dt) == s.step else None  # all of it?
                kept = _kept(np.rint(so_far.time / dt).astype(np.int64), stride, s.step)
                return {"trajectory": {"sha256": frames_digest(so_far, kept), "frames": int(kept.sum())}}
            sim.checkpoint.before_save = before_checkpoint
        told = sim.notes
        try:
            for k, (until, every) in enumerate(plan):
                before = sim.trajectory
                sim.notes = told and k == len(plan) - 1  # one set of notes, at the end, for the whole run
                try:
                    parts.append(sim.run(until=until, record_every=every, progress=progress))
                except (KeyboardInterrupt, SimulationError):
                    if sim.trajectory is not before and sim.trajectory is not None:
                        parts.append(sim.trajectory)  # the frames of the run that stopped (last: where)
                    raise
                if k < len(plan) - 1:
                    sim.continue_notes()
        finally:
            sim.notes = told
            if sim.checkpoint is not None:
                sim.checkpoint.before_save = None
            sim.close()
            if parts:
                trajectory = _join(earlier, parts, start, stride, end, dt)
                if target is not None and written["step"] != sim.step:
                    from .outputs import write_or_rescue
                    target.parent.mkdir(parents=True, exist_ok=True)
                    where = write_or_rescue(target, lambda tmp: _savez(trajectory, tmp), "trajectory")
                    if where != target:
                        self.rescued["trajectory"] = where
        self.write_outputs(None, out_dir, sim)
        return trajectory

    def _earlier_frames(self, target, sim, stride):
        """The frames of the earlier runs on the grid up to the resume step, from the trajectory file,
        or None (with a line saying why) when it does not hold them all or ends elsewhere."""
        dt, start = self.integrator.dt, sim.step
        recorded = (getattr(sim, "resumed_meta", None) or {}).get("trajectory")  # digest of its frames
        why = None
        try:
            saved = load_trajectory(target) if target.is_file() else None
        except ValueError as err:
            saved, why = None, f"it cannot be read ({err})"
        if saved is None:
            why = why or "there is none"
        else:
            steps = np.rint(saved.time / dt).astype(np.int64)
            keep = _kept(steps, stride, start)
            first = int(steps[0]) if len(steps) else 0
            grid = np.union1d([first], np.arange(-(-first // stride) * stride, start + 1, stride))
            p = self.scene.particles
            if len(saved.ids) != len(p) or not np.array_equal(saved.ids, p.ids):
                why = "it holds other spheres"
            elif not np.array_equal(steps[keep], grid[grid <= start]):
                why = (f"it ends at t = {steps.max() * dt:.6g}, before the checkpoint's t = {start * dt:.6g} (the "
                       f"earlier run was stopped before writing the frames in between)"
                       if len(steps) and steps.max() < grid[grid <= start].max() else
                       "its frames are not on this run's record_every grid")
            elif recorded is not None and frames_digest(saved, keep) != recorded.get("sha256"):
                why = ("its frames up to the checkpoint are not those the checkpoint's run recorded (another run "
                       "wrote it)")
            elif recorded is None and not _holds_state(saved, steps == start, _state_frame(sim)):
                why = (f"its frame at t = {start * dt:.6g} is not the checkpoint's state (another run wrote it)"
                       if (steps == start).any() else f"it has no frame at the checkpoint's t = {start * dt:.6g}")
            else:
                return _frames(saved, keep)
        aside = ""
        if target.is_file():  # not overwritten: what another run wrote may be all there is of it
            k, kept = 1, target.with_name(f"{target.stem}.set-aside{target.suffix}")
            while kept.exists():
                k += 1
                kept = target.with_name(f"{target.stem}.set-aside-{k}{target.suffix}")
            try:
                target.rename(kept)
                aside = f" (the file is kept as {kept})"
            except OSError as err:
                aside = f" (it could not be set aside: {err.strerror or err}; it will be replaced)"
        print(f"{target}: frames before t = {start * dt:.6g} (the resume) are not kept: {why}{aside}; the file will "
              f"hold t = {start * dt:.6g} .. {self.duration:g}", file=sys.stderr)
        return None

    def write_outputs(self, trajectory, out_dir=None, sim=None):
        """Write the trajectory file (unless ``trajectory`` is None) and the animation (the VTK
        series and checkpoints are written while running). Returns the paths written."""
        out, written = self.outputs, []
        if out.get("trajectory") and trajectory is not None:
            from .outputs import write_or_rescue
            target = self.output_path(out["trajectory"], out_dir)
            target.parent.mkdir(parents=True, exist_ok=True)
            written.append(write_or_rescue(target, lambda tmp: _savez(trajectory, tmp), "trajectory"))
        if out.get("animation") is not None:
            from . import viz
            a = out["animation"]
            target = self.output_path(a["path"], out_dir)
            target.parent.mkdir(parents=True, exist_ok=True)
            options = {"color_by": a["color_by"]} if a["color_by"] else {}
            if a["trail"] is not None:
                options["trail"] = a["trail"]
            try:
                viz.animate(sim.writers[0].pvd, target, max_frames=a["max_frames"], fps=a["fps"], **options)
                written.append(target)
            except viz.RenderingUnavailable as err:
                print(f"no animation: {err}")
        return written


def _kept(steps, stride, upto):
    """Mask of the frames (at ``steps``) of a trajectory file that a resume at step ``upto`` keeps:
    those on the record grid up to it, and the first (a file may start at an earlier resume)."""
    keep = (steps <= upto) & (steps % stride == 0)
    if len(steps):
        keep[0] = steps[0] <= upto
    return keep


def _current(sim):
    """[the frames of ``sim``'s run in progress]: the part of a run not yet returned by
    Simulation.run. At its end or on Ctrl-C the run has recorded the state it stopped at
    (``sim.trajectory``); in the middle, only the frames on its record grid so far are taken (the
    kernels are not asked to record the state now: that would maintain the neighbour lists at a
    moment an uninterrupted run does not, and change its last bits)."""
    record, first, local = sim._recording
    dt = sim.integrator.dt
    t = sim.trajectory
    if t is not None and len(t.time) and round(t.time[0] / dt) == first and round(t.time[-1] / dt) == sim.step:
        return [t]
    n = (sim.step - first) // local + 1
    return [sim._trajectory(record, (first + np.arange(n) * local) * dt)]


def _state_frame(sim):
    """The state of ``sim`` now as a one-frame Trajectory, recorded by the kernels as a run records
    its frames (periodic coordinates folded into the box, image counts moved along). Only where the
    next run records this state anyway (right after a resume)."""
    record = sim._allocate(1)
    sim.scene.kernels.record_frame(0, sim.scene.state, record)
    return sim._trajectory(record, np.array([sim.time]))


def _holds_state(saved, at, state):
    """Does the trajectory ``saved`` hold ``state`` (one frame) at its last frame where ``at``?"""
    at = np.flatnonzero(at)
    if not len(at):
        return False
    k = at[-1]
    same = [np.array_equal(saved.position[k], state.position[0]), np.array_equal(saved.velocity[k], state.velocity[0])]
    if saved.image is not None and state.image is not None:
        same.append(np.array_equal(saved.image[k], state.image[0]))
    return all(same)


def frames_digest(trajectory, keep):
    """sha256 (hex) of the frames ``keep`` (mask or indices) of a Trajectory: every per-frame array
    and energy, bit for bit."""
    import hashlib
    t = _frames(trajectory, keep)
    h = hashlib.sha256(str(len(t.time)).encode())
    fields = [(name, getattr(t, name)) for name in ("position", "velocity", "angular_velocity", "dipole", "image",
                                                   "angular_momentum")]
    fields += [(f"energy_{k}", t.energy[k]) for k in sorted(t.energy)]
    for name, a in fields:
        if a is not None:
            a = np.ascontiguousarray(a)
            h.update(f"{name}:{a.dtype}:{a.shape}".encode())
            h.update(a.tobytes())
    return h.hexdigest()


def _frames(trajectory, keep):
    """The frames ``keep`` (a mask or indices) of a Trajectory, as a new Trajectory."""
    from .simulation import Trajectory
    t = trajectory

    def pick(a):
        return None if a is None else np.asarray(a)[keep]
    return Trajectory(time=pick(t.time), position=pick(t.position), velocity=pick(t.velocity),
                      angular_velocity=pick(t.angular_velocity), dipole=pick(t.dipole),
                      energy={k: pick(v) for k, v in t.energy.items()}, angular_momentum=pick(t.angular_momentum),
                      radius=t.radius, mass=t.mass, inertia=t.inertia, ids=t.ids, image=pick(t.image), box=t.box)


def _join(earlier, parts, start, stride, end, dt):
    """One Trajectory on the whole run's grid (steps that are multiples of ``stride``, and ``end``):
    ``earlier`` (its frames up to step ``start``, or None) followed by the frames of the
    consecutive runs ``parts`` (from ``start`` on) after ``start`` on the grid. Kept besides: the
    last frame of the last part (where a stopped run stopped) and, without ``earlier``, the first
    (the file then starts at the resume)."""
    from .simulation import Trajectory
    pieces = [] if earlier is None else [earlier]
    for k, part in enumerate(parts):
        steps = np.rint(part.time / dt).astype(np.int64)
        keep = ((steps % stride == 0) | (steps == end)) & (steps > start)
        keep[0] = earlier is None and k == 0  # later parts start where the one before ended
        keep[-1] |= k == len(parts) - 1
        pieces.append(_frames(part, keep))
    first = pieces[0]

    def joined(name, get=getattr):
        arrays = [get(p, name) for p in pieces]
        return None if arrays[0] is None else np.concatenate(arrays)
    energy = {key: joined(key, lambda p, k: np.asarray(p.energy[k])) for key in first.energy}
    return Trajectory(energy=energy, radius=first.radius, mass=first.mass, inertia=first.inertia, ids=first.ids,
                      box=first.box, **{name: joined(name) for name in ("time", "position", "velocity",
                                                                        "angular_velocity", "dipole",
                                                                        "angular_momentum", "image")})


def load_trajectory(path):
    """A Trajectory from a .npz written by :func:`save_trajectory` (read without pickle). Raises
    ValueError for a file that is not one."""
    from .box import Box
    from .simulation import Trajectory
    try:
        with np.load(path, allow_pickle=False) as z:
            a = {name: z[name] for name in z.files}
    except Exception as err:  # zip or npy damage: one message
        raise ValueError(f"cannot read {path} as .npz: {err}") from None
    need = ("time", "position", "velocity", "angular_momentum", "radius", "mass", "inertia", "ids")
    missing = [name for name in need if name not in a]
    if missing:
        raise ValueError(f"{path} is not a demkit trajectory (no {', '.join(missing)})")
    box = Box(a["box_size"], a["box_periodic"]) if "box_size" in a else None
    return Trajectory(time=a["time"], position=a["position"], velocity=a["velocity"],
                      angular_velocity=a.get("angular_velocity"), dipole=a.get("dipole"),
                      energy={k[len("energy_"):]: v for k, v in a.items() if k.startswith("energy_")},
                      angular_momentum=a["angular_momentum"], radius=a["radius"], mass=a["mass"],
                      inertia=a["inertia"], ids=a["ids"], image=a.get("image"), box=box)


def save_trajectory(trajectory, path):
    """Write a Trajectory's arrays to a .npz (no pickle): time, position, velocity, angular_velocity,
    dipole, image (when present), angular_momentum, radius, mass, inertia, ids and energy_<kind>.
    Written atomically (:func:`demkit.outputs.write_atomically`): ``path`` holds the previous file
    or the new one whole, never a part. Raises OSError when it cannot be written."""
    from .outputs import write_atomically
    return write_atomically(path, lambda tmp: _savez(trajectory, tmp))


def _savez(trajectory, path):
    arrays = {name: getattr(trajectory, name) for name in ("time", "position", "velocity", "angular_velocity",
                                                           "dipole", "image", "angular_momentum", "radius", "mass",
                                                           "inertia", "ids")}
    arrays.update({f"energy_{k}": v for k, v in trajectory.energy.items()})
    if trajectory.box is not None:
        arrays["box_size"], arrays["box_periodic"] = trajectory.box.size, trajectory.box.periodic
    with open(path, "wb") as fh:
        np.savez(fh, **{k: v for k, v in arrays.items() if v is not None})
    return path


# ---- the format's reference ------------------------------------------------------------------------
_KINDS = {"number": "number", "integer": "integer", "bool": "bool", "string": "string", "vector": "[x, y, z]",
          "size": "number or [x, y, z]", "cells": "integer or 3 integers", "flags": "bool or 3 bools",
          "numbers": "number or list (per sphere)", "vectors": "list of [x, y, z]", "bools": "list of bools",
          "integers": "list of integers", "strings": "list of names", "number_or_auto": 'number or "auto"',
          "bool_or_auto": 'bool or "auto"', "row": "list of numbers", "direction": 'string or [x, y, z]'}


def reference():
    """The key reference of docs/scene_files.md, as Markdown, generated from :data:`SCHEMA`."""
    out = []

    def default(key):
        if key.default is REQUIRED:
            return "**required**"
        if key.default is None:
            return "none"
        return f"`{key.default!r}`".replace("'", '"').replace("True", "true").replace("False", "false")

    def table(name, schema, header):
        keys = [(k, e) for k, e in schema.keys.items() if isinstance(e, Key)]
        out.append(f"### `{header}`\n\n{schema.doc}.\n")
        if keys:
            out.append("| key | type | default | meaning | SI dimension |\n|---|---|---|---|---|")
            for k, e in keys:
                choices = f" ({', '.join(map(repr, e.choices))})".replace("'", '"') if e.choices else ""
                check = f", {e.check.replace('_', ' ')}" if e.check else ""
                out.append(f"| `{k}` | {_KINDS[e.kind]}{check} | {default(e)} | {e.doc}{choices} | {e.dim or ''} |")
            out.append("")
        for group, required in schema.one_of:
            out.append(f"{'Exactly' if required else 'At most'} one of {', '.join(f'`{g}`' for g in group)}.\n")
        for k, e in schema.keys.items():
            path = f"{name}.{k}" if name else k
            if isinstance(e, Table):
                table(path, e, path)
            elif isinstance(e, Tables) and isinstance(e.table, Variant):
                variant(path, e.table, f"[{path}]")
            elif isinstance(e, Tables):
                table(path, e.table, f"[{path}]")
            elif isinstance(e, Variant):
                variant(path, e, path)

    def variant(path, e, header):
        out.append(f"### `{header}`\n\n{e.doc}.\n")
        for kind, sub in e.variants.items():
            table(path, sub, f'{header}, kind = "{kind}"')

    table("", SCHEMA, "top level")
    return "\n".join(out).replace("### `top level`", "### Top level")
