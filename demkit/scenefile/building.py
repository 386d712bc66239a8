"""Building from checked data: the spheres (builders, CSV and NPZ files), the interactions, the
magnets' fields, the integrator, the scene."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from ..integrators import parse_method
from .errors import _At
from .format import INTERACTION_ORDER, PARTICLES, SCHEMA
from .running import LoadedScene
from .si import _convert, si_scales


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
    from .. import build as B
    from ..box import Box
    where = ("particles", "build")
    kind = b["kind"]
    keys = [k for k in b if k != "kind"]
    if kind == "two_magnets":
        from ..two_magnets import TwoMagnets
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

    from .. import build as B
    from .. import memory
    from ..interactions.base import PairInteraction
    from ..scene import DEFAULT_SKIN, PARALLEL_MIN, SORT_MIN
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
    from ..particles import Particles
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


def _interactions(d, src, scale=None, base="."):
    from .. import interactions as I
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
        if name == "cone":
            for k, cone in enumerate(value):
                with _At(src, "interactions", name, k, keys=cone):
                    out.append(I.Cone(**{**cone, "half_angle": math.radians(cone["half_angle"])}))
        if name == "mesh":
            for k, mesh in enumerate(value):
                with _At(src, "interactions", name, k, keys=mesh):
                    file = Path(mesh["file"]) if Path(mesh["file"]).is_absolute() else Path(base) / mesh["file"]
                    factor = mesh["scale"] / (scale["length"] if scale is not None else 1.0)
                    out.append(I.MeshWall(**{**mesh, "file": file, "scale": factor}))
        if name in ("wall", "cylinder"):
            for k, wall in enumerate(value):
                with _At(src, "interactions", name, k, keys=wall):
                    if wall.get("servo") is not None:
                        wall = {**wall, "servo": I.Servo(**_servo_targets(wall["servo"]))}
                    elif "servo" in wall:
                        wall = {key: value for key, value in wall.items() if key != "servo"}
                    out.append((I.Wall if name == "wall" else I.Cylinder)(**wall))
    return out


def _servo_targets(servo):
    """A validated servo table as dk.Servo's arguments: a list of forces or stresses with ``times`` as
    (time, value) points."""
    servo = dict(servo)
    times = servo.pop("times", None)
    for name in ("force", "stress"):
        value = servo.get(name)
        if isinstance(value, list):
            if not isinstance(times, list) or len(times) != len(value):
                raise ValueError(f"servo {name} is a list of {len(value)} values: give times = [...], one time for "
                                 f"each, got {times!r}")
            servo[name] = list(zip(times, value))
            times = None
    if times is not None:
        raise ValueError(f"servo times = {times!r} go with a list of forces or stresses (force = [...] or "
                         f"stress = [...]), not one value")
    return servo


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
    from ..interactions.magnets import MagnetField
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
        from ..step_choice import ACCURACY, choose_time_step
        accuracy = ACCURACY if integ["accuracy"] is None else integ["accuracy"]
        with _At(src, "integrator", keys=("dt", "accuracy")):  # at the key its message names first
            choice = choose_time_step(scene, make, d["run"]["duration"], accuracy)
        dt = choice.dt
    with _At(src, "integrator"):
        return make(dt), choice


def _build(data, src, base):
    from ..box import Box, Deform, Shear
    from ..box_servo import PressureServo
    from ..scene import Scene
    units = scale = None
    if data["units"] == "si":
        with _At(src, "scales"):
            units, scale = si_scales(data["scales"])
        _convert(SCHEMA, data, scale)
        src.units_note = (f" [numbers in the paper's units, converted from SI: length {units.length:.4g} m, "
                          f"time {units.time:.4g} s, mass {units.mass:.4g} kg]")
    box = None
    if data["box"] is not None:
        with _At(src, "box", keys=("size", "periodic", "shear", "deform")):
            shear, deform = data["box"].get("shear"), data["box"].get("deform")
            if deform and deform.get("servo"):  # a box driven to a set pressure
                deform = dict(deform, servo=PressureServo(**deform["servo"]))
            box = Box(data["box"]["size"], data["box"]["periodic"], shear=Shear(**shear) if shear else None,
                      deform=Deform(**deform) if deform else None)
    interactions = _interactions(data, src, scale, base)
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
        from ..guards import before_stepping
        before_stepping(scene, integrator)
        integrator.check(scene)
    outputs = data["outputs"] or {"trajectory": None, "vtk": None, "animation": None, "checkpoint": None}
    return LoadedScene(scene=scene, integrator=integrator, duration=run["duration"], record_every=run["record_every"],
                       outputs=outputs, path=None if str(src.name) == "<string>" else Path(src.name), data=data,
                       units=units, max_energy_growth=run["max_energy_growth"], base=base, source=src,
                       step_choice=step_choice, stress_every=run["stress_every"])
