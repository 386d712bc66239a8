"""The scene-file format: the schema of every table and key (:data:`SCHEMA`), and the reference page
generated from it (:func:`reference`, docs/scene_files.md)."""
from __future__ import annotations

from ..schema import Key, REQUIRED, Table, Tables, Variant


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

_WALL_MOTION = {"amplitude": Key("vector", [0.0, 0.0, 0.0], "vibration: the wall moves by amplitude (1 - cos 2 pi f t)",
                                 dim="length"),
                "frequency": _n("f of the vibration, cycles per time (0: none)", default=0.0, check="non_negative",
                                dim="frequency")}
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
        "velocity": Key("vector", [0.0, 0.0, 0.0], "velocity of the wall: in its plane it slides, along the normal a "
                        "piston", dim="velocity"), **_WALL_MOTION,
        "servo": Table({
            "force": Key("series", doc="the normal force the spheres are to push the wall with (or stress); a list: "
                         "its values at `times`, the target the line through them", check="positive", dim="force"),
            "stress": Key("series", doc="the normal stress instead: force per area of the wall in a box periodic "
                          "along its plane; a list: its values at `times`", check="positive", dim="pressure"),
            "times": Key("series", doc="with a list of targets: the times of its values, increasing (the target the line "
                         "through them, held before the first and after the last)", check="non_negative", dim="time"),
            "max_speed": _n("the fastest the wall moves", default=REQUIRED, check="positive", dim="velocity"),
            "gain": _n("fraction of the force error corrected in a step, in (0, 1]", default=0.2, check="positive")},
            "a servo moving the wall along its normal to hold a force on it (dk.Servo): oedometric tests, a "
            "packing under a set pressure")},
        "a plane wall with the scene's contact law (dk.Wall)"), "plane walls, [[interactions.wall]], any number"),
    "cylinder": Tables(Table({
        "point": Key("vector", REQUIRED, "a point of the axis", dim="length"),
        "axis": Key("vector", REQUIRED, "direction of the axis"),
        "radius": _n("radius of the cylinder", default=REQUIRED, check="positive", dim="length"),
        "inside": Key("bool", True, "the spheres are inside (a tube, drum) or outside (a post)"),
        "angular_velocity": _n("rate of turning about the axis (right-handed): a rotating drum", default=0.0,
                               dim="angular_velocity"),
        "velocity": Key("vector", [0.0, 0.0, 0.0], "velocity of the whole cylinder", dim="velocity"), **_WALL_MOTION,
        "servo": Table({
            "stress": Key("series", REQUIRED, "the normal stress the spheres are to push the side with (force per area "
                          "2 pi R_c L, L the periodic box's length along the axis); a list: its values at `times`",
                          check="positive", dim="pressure"),
            "times": Key("series", doc="with a list of stresses: the times of its values, in order",
                         check="non_negative", dim="time"),
            "max_speed": _n("the fastest the radius moves", default=REQUIRED, check="positive", dim="velocity"),
            "gain": _n("fraction of the force error corrected in a step, in (0, 1]", default=0.2, check="positive")},
            "a servo moving the cylinder's radius to hold a stress on its side (dk.Servo): a confining membrane")},
        "a cylindrical wall with the scene's contact law (dk.Cylinder)"),
        "cylindrical walls, [[interactions.cylinder]], any number"),
    "cone": Tables(Table({
        "apex": Key("vector", REQUIRED, "the cone's tip", dim="length"),
        "axis": Key("vector", REQUIRED, "direction the cone opens along"),
        "half_angle": _n("angle between the axis and the surface, degrees, in (0, 90)", default=REQUIRED,
                         check="positive"),
        "inside": Key("bool", True, "the spheres are inside (a hopper, funnel) or outside (a conical post)"),
        "lower": _n("where the surface starts, distance from the apex along the axis (> 0: an open outlet)",
                    default=0.0, check="non_negative", dim="length"),
        "upper": _n("where the surface ends, distance from the apex along the axis (none: unbounded)",
                    check="positive", dim="length"),
        "angular_velocity": _n("rate of turning about the axis (right-handed)", default=0.0,
                               dim="angular_velocity"),
        "velocity": Key("vector", [0.0, 0.0, 0.0], "velocity of the whole cone", dim="velocity"), **_WALL_MOTION},
        "a conical wall with the scene's contact law (dk.Cone; half_angle in degrees here, radians in Python)"),
        "conical walls, [[interactions.cone]], any number"),
    "mesh": Tables(Table({
        "file": Key("string", REQUIRED, "the mesh file (STL, OBJ, VTK, Gmsh: whatever meshio reads; its triangles), "
                    "relative to the scene file's folder"),
        "scale": _n("factor on the file's coordinates (with units = \"si\": the file is in metres)", default=1.0,
                    check="positive"),
        "point": Key("vector", [0.0, 0.0, 0.0], "a point of the axis the mesh turns about", dim="length"),
        "axis": Key("vector", [0.0, 0.0, 1.0], "the axis it turns about"),
        "angular_velocity": _n("rate of turning about the axis (right-handed; 0: none)", default=0.0,
                               dim="angular_velocity"),
        "velocity": Key("vector", [0.0, 0.0, 0.0], "velocity of the whole mesh", dim="velocity"), **_WALL_MOTION,
        "reach": _n("the largest sphere radius its grid serves (none: the scene's largest)", check="positive",
                    dim="length"),
        "cell": _n("its grid's cell edge (none: chosen from the reach and the triangles)", check="positive",
                   dim="length")},
        "a wall made of a triangle mesh with the scene's contact law (dk.MeshWall)"),
        "triangle-mesh walls, [[interactions.mesh]], any number"),
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
        "periodic": Key("flags", False, "periodic axes: true/false or three of them"),
        "shear": Table({
            "rate": _n("the shear rate gammadot (1/time): the imposed flow gammadot x_b along the flow axis",
                       default=REQUIRED, dim="frequency"),
            "flow": Key("string", "x", "the flow axis a", choices=("x", "y", "z")),
            "gradient": Key("string", "y", "the gradient axis b (the flow grows along it)", choices=("x", "y", "z"))},
            "Lees-Edwards simple shear of the box (dk.Shear; flow and gradient axes periodic)"),
        "deform": Table({
            **{axis: _n(f"the engineering strain rate of {axis} (1/time): L_{axis}(t) = L_{axis}(0) (1 + rate t)",
                        default=0.0, dim="frequency") for axis in "xyz"},
            "servo": Table({
                "pressure": _n("the normal stress each driven axis is brought to (compressive positive)",
                               default=REQUIRED, check="positive", dim="pressure"),
                "max_rate": _n("the largest strain rate it sets (1/time), reached when the stress is off by the "
                               "pressure itself", default=REQUIRED, check="positive", dim="frequency"),
                "every": _n("the time between two changes of the rates", default=REQUIRED, check="positive",
                            dim="time"),
                "axes": Key("string", "xyz", "the axes it drives, e.g. \"xyz\" or \"z\"")},
                "a servo setting the strain rates from the measured stress (dk.PressureServo)")},
            "extension or compression of the box at set strain rates, the positions remapped affinely after each "
            "step (dk.Deform; its axes periodic)")},
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
        "max_energy_growth": _n("stop when total + dissipated energy grows by this fraction", check="positive"),
        "stress_every": _n("measure the stress every this much time during the run (dk.StressSeries): for the "
                           "sweep observables stress and rheology and [outputs] stress", check="positive",
                           dim="time")},
        "how long", required=True),
    "outputs": Table({
        "trajectory": Key("string", doc="write the recorded frames to this .npz file"),
        "stress": Key("string", doc="write the stress series (needs run.stress_every) to this CSV file, a line "
                                    "per sample (dk.StressSeries)"),
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
                     "magnet_field", "wall", "cylinder", "cone", "mesh", "langevin")


_KINDS = {"number": "number", "integer": "integer", "bool": "bool", "string": "string", "vector": "[x, y, z]",
          "size": "number or [x, y, z]", "cells": "integer or 3 integers", "flags": "bool or 3 bools",
          "numbers": "number or list (per sphere)", "series": "number or list (in time)", "vectors": "list of [x, y, z]", "bools": "list of bools",
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
