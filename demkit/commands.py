"""``demkit run`` and ``demkit info``: run a TOML scene file, or say what it holds and costs.

    demkit run scene.toml [--duration T] [--out DIR] [--set key.path=value ...] [--progress|--no-progress]
    demkit info scene.toml [--set key.path=value ...] [--measure]

``run`` builds the scene (:func:`demkit.load_scene`), runs it for the file's ``[run] duration`` (or
``--duration``) and writes every output of ``[outputs]`` (paths relative to the scene file, or to
``--out``); with a checkpoint in ``[outputs]`` a rerun resumes from it. ``--set`` changes any key of
the file before it is checked (the value is read as TOML: ``--set integrator.dt=0.005``,
``--set integrator.method=RK4``, ``--set box.periodic=[true,true,false]``).

``info`` prints the spheres, box, interactions and integrator, the time step against the largest
safe one (and whether the checks before a run pass), the memory of the arrays, neighbour lists and
recorded frames, and the cost: steps times a rough cost per pair and step (:data:`PAIR_SECONDS`,
measured on this project's 2-core machine) or, with ``--measure``, a timing run (at least 50 steps and 0.2 s).
"""
from __future__ import annotations

import math
import sys
import time
import tomllib

import numpy as np

from .scenefile import load_scene

from .threads import PAIR_SECONDS, SPHERE_SECONDS  # noqa: E402 (the cost model of one force evaluation)


#: printed by `demkit run` before running a file without outputs (it still runs: a check of the
#: scene, a timing, a stop on max_energy_growth are worth a run that saves nothing)
NO_OUTPUTS = ('no outputs requested: this run saves nothing. Add to the file [outputs] trajectory = "traj.npz" '
              '(and/or [outputs.vtk], docs/scene_files.md), or pass --set outputs.trajectory=traj.npz')


def add_commands(commands):
    """Register ``run`` and ``info`` on an argparse sub-parser collection."""
    import argparse
    doc = __doc__
    run = commands.add_parser("run", help="run a TOML scene file and write its outputs", description=doc,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_argument("scene", help="a TOML scene file (docs/scene_files.md)")
    run.add_argument("--duration", type=float, help="simulated time (overrides [run] duration)")
    run.add_argument("--out", help="folder for the outputs (default: the scene file's folder)")
    run.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE",
                     help="change a key of the file, e.g. --set interactions.dipole.prefactor=0.5 (repeatable)")
    run.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                     help="show a progress bar (default: when the output is a terminal)")
    run.set_defaults(handler=run_command)
    info = commands.add_parser("info", help="what a TOML scene file holds, its time step, memory and cost",
                               description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    info.add_argument("scene", help="a TOML scene file (docs/scene_files.md)")
    info.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE", help="change a key of the file")
    info.add_argument("--duration", type=float, help="simulated time (overrides [run] duration)")
    info.add_argument("--measure", action="store_true", help="time a short run (>= 50 steps, >= 0.2 s) instead of the rough estimate")
    info.set_defaults(handler=info_command)


def parse_sets(items):
    """{key path: value} from ``key.path=value`` strings; values are read as TOML (bare words as strings)."""
    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"--set needs key.path=value, got {item!r}")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        out[key.strip()] = value
    return out


def _load(args):
    overrides = parse_sets(args.set)
    if getattr(args, "duration", None) is not None:
        overrides["run.duration"] = args.duration
    return load_scene(args.scene, overrides=overrides)


def run_command(args):
    from .simulation import SimulationError
    loaded = _load(args)
    n = len(loaded.scene.particles)
    steps = round(loaded.duration / loaded.integrator.dt)
    print(f"{loaded.path}: {n} spheres, {loaded.integrator!r}, t = 0 .. {loaded.duration:g} ({steps:,} steps)")
    outputs = dict(_outputs(loaded, args.out))
    if not outputs:
        print(NO_OUTPUTS)
    checkpoint = outputs.get("checkpoint")
    clock = time.perf_counter()
    try:  # the checkpoint is checked against the scene before it is announced
        trajectory = loaded.run(progress=args.progress, out_dir=args.out,
                                on_resume=lambda path: print(f"resuming from {path} (delete it to start over)",
                                                             flush=True))
    except SimulationError as err:
        print(f"demkit run: stopped: {err}")
        return 1
    except (KeyboardInterrupt, OSError) as err:  # Ctrl-C, or a file that failed while running (a full disk)
        kept = [f"{name} {where}" for name, where in outputs.items() if where.exists()]
        again = ("run the same command to resume" if checkpoint is not None else
                 "no [outputs.checkpoint]: a rerun starts over")
        what = "interrupted" if isinstance(err, KeyboardInterrupt) else f"error: {err}"
        print(f"demkit run: {what}; kept: {', '.join(kept) or 'nothing'}; {again}", file=sys.stderr)
        return 130 if isinstance(err, KeyboardInterrupt) else 1
    seconds = time.perf_counter() - clock
    frames = len(trajectory) if trajectory is not None else 0
    print(f"done in {seconds:.1f} s (compilation included): {frames} frames recorded")
    for name, where in outputs.items():
        rescued = loaded.rescued.get(name)
        print(f"wrote {name}: {where}" if rescued is None else f"wrote {name}: {rescued} (could not write {where})")
    return 0


def _outputs(loaded, out_dir):
    out = loaded.outputs
    if out.get("trajectory"):
        yield "trajectory", loaded.output_path(out["trajectory"], out_dir)
    if out.get("vtk"):
        yield "VTK series", loaded.output_path(out["vtk"]["folder"], out_dir) / "particles.pvd"
    if out.get("animation"):
        yield "animation", loaded.output_path(out["animation"]["path"], out_dir)
    if out.get("checkpoint"):
        yield "checkpoint", loaded.output_path(out["checkpoint"]["path"], out_dir)


def estimate_pairs(scene):
    """[(group kind, reach, pairs, history width)]: the pairs each pair loop visits per force
    evaluation, all pairs or those within reach + skin now (a k-d tree; periodic only when every
    axis is)."""
    from scipy.spatial import cKDTree
    p = scene.particles
    n = len(p)
    out = []
    for group in scene.plan.groups:
        if group.kind == "all":
            out.append(("all pairs", math.inf, n * (n - 1) // 2, group.width))
            continue
        reach = group.reach + scene.skin
        box = scene.box
        if box is not None and box.periodic.all():
            tree = cKDTree(np.mod(p.position, box.size), boxsize=box.size)
        else:
            tree = cKDTree(p.position)
        # counted, not listed (a set of every pair took ~150 bytes per pair): ordered pairs with i = j
        within = int(tree.count_neighbors(tree, reach))
        out.append(("neighbour list", group.reach, (within - n) // 2, group.width))
    return out


def info_command(args):
    from . import guards
    loaded = _load(args)
    scene, integ = loaded.scene, loaded.integrator
    p = scene.particles
    n = len(p)
    r = p.radius
    print(f"{loaded.path}" + (f": {loaded.data['title']}" if loaded.data.get("title") else ""))
    radius = f"{r[0]:.6g}" if np.all(r == r[0]) else f"{r.min():.6g} to {r.max():.6g}"
    print(f"spheres       {n}, radius {radius}" + (", with dipoles" if p.dipole is not None else "")
          + (f", {int(p.fixed.sum())} fixed" if p.fixed is not None and p.fixed.any() else ""))
    print(f"box           {scene.box!r}" if scene.box is not None else "box           none (open space)")
    for inter in scene.interactions + scene.effects:
        print(f"interaction   {inter!r}")
    if loaded.units is not None:
        u = loaded.units
        print(f"units         the paper's: length {u.length:.4g} m, time {u.time:.4g} s, mass {u.mass:.4g} kg")
    steps = round(loaded.duration / integ.dt)
    print(f"integrator    {integ!r}: {steps:,} steps to t = {loaded.duration:g}")
    limit, why = guards.largest_safe_step(scene)
    if math.isfinite(limit):
        print(f"time step     dt = {integ.dt:.6g}; largest safe step {limit:.6g} (dk.guards.largest_safe_step: "
              f"{why}) -> dt is {integ.contact_step / limit:.2f} of it")
    else:
        print(f"time step     dt = {integ.dt:.6g}; nothing limits it yet ({why}; dipoles are checked at the "
              f"closest approach)")
    try:
        guards.before_stepping(scene, integ)
        print("checks        the checks before a run pass (dk.guards.before_stepping)")
    except ValueError as err:
        print(f"checks        refused: {err}")
    print("              (a time step for a target accuracy: dk.accuracy.suggest_dt, or `demkit accuracy`)")
    # memory
    from . import memory
    pairs = estimate_pairs(scene)
    frames = (steps // max(1, round(loaded.record_every / integ.dt)) + 2) if loaded.record_every else 2
    parts = scene.memory_estimate(frames=frames, stages=integ.stage_arrays)
    listed = [(count / max(n, 1), width) for kind, _, count, width in pairs if kind == "neighbour list"]
    parts["lists"] = memory.estimate(n, lists=listed)["lists"]  # the pairs counted now
    parts["total"] = parts["arrays"] + parts["lists"] + parts["record"]
    available, total = memory.machine_memory()
    print(f"memory        ~{memory.describe(parts, frames)}: ~{parts['total'] / memory.GB:.3g} GB in all "
          f"({available / memory.GB:.3g} GB free of {total / memory.GB:.3g} GB; dk.Scene.memory_estimate)")
    # cost
    total_pairs = sum(count for _, _, count, _ in pairs)
    for kind, reach, count, width in pairs:
        where = "" if math.isinf(reach) else f" within {reach:.4g} + skin {scene.skin:.3g}"
        print(f"pairs         {count:,} ({kind}{where})")
    if args.measure:
        from .simulation import Simulation
        sim = Simulation(scene, integ)
        sim.run(duration=5 * integ.dt)  # compiles (or loads the cache) and warms up
        count = 50
        while True:  # at least 50 steps and 0.2 s of wall time, so that tiny scenes are timed too
            clock = time.perf_counter()
            sim.run(duration=count * integ.dt)
            seconds = time.perf_counter() - clock
            if seconds >= 0.2 or count >= 10**7:
                break
            count *= 8
        per_step = seconds / count
        how = f"measured over {count:,} steps"
    else:
        per_step = integ.evaluations_per_step * (total_pairs * PAIR_SECONDS + n * SPHERE_SECONDS)
        how = (f"rough: {integ.evaluations_per_step} force evaluation(s) per step x ({total_pairs:,} pairs x "
               f"{PAIR_SECONDS:.0e} s + {n} spheres x {SPHERE_SECONDS:.0e} s); --measure times it")
    print(f"cost          {per_step * 1e6:.3g} us per step ({how}) -> ~{_duration(per_step * steps)} for the run "
          f"(one core, compilation not included)")
    from .threads import ThreadChoice
    print(f"threads       {ThreadChoice(scene, integ.template).describe()}")
    return 0


def _duration(seconds):
    if seconds < 120:
        return f"{seconds:.3g} s"
    if seconds < 7200:
        return f"{seconds / 60:.3g} min"
    return f"{seconds / 3600:.3g} h"


def main_errors(parser, args):
    """Run the chosen command's handler; a bad scene file, option, missing extra or output path that
    cannot be written is one line on stderr and exit code 2, a file that fails while it is read or
    written (OSError) one line and exit code 1, Ctrl-C not handled by the command one line and exit
    code 130."""
    try:
        return args.handler(args)
    except (ValueError, ImportError) as err:  # SceneFileError is a ValueError
        parser.exit(2, f"demkit {args.command}: error: {err}\n")
    except KeyboardInterrupt:
        parser.exit(130, f"demkit {args.command}: interrupted\n")
    except OSError as err:  # a file that could not be read or written (a full disk, ...): one line too
        parser.exit(1, f"demkit {args.command}: error: {err}\n")
