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
recorded frames, and the cost: a model of the run's steps and outputs (:mod:`demkit.cost`, measured
on this project's 2-core machine) or, with ``--measure``, a timing run (at least 50 steps and 0.2 s).
"""
from __future__ import annotations

import math
import sys
import time
import tomllib

import numpy as np

from .scenefile import load_scene



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
    if loaded.step_choice is not None:
        choice = loaded.step_choice
        print(f'dt = "auto" for a balance within {choice.accuracy:g}: {choice.why} ({choice.seconds:.1f} s)')
    outputs = dict(_outputs(loaded, args.out))
    if not outputs:
        print(NO_OUTPUTS)
    checkpoint = outputs.get("checkpoint")
    earlier = [str(where) for where in outputs.values() if where.exists()] if checkpoint is None else []
    if earlier:  # nothing to resume from: the run starts over and replaces them
        print(f"replacing the outputs of an earlier run: {', '.join(earlier)} (without [outputs.checkpoint] a "
              f"rerun starts over; --out DIR writes elsewhere)")
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
        from .engine.threads import finish_compiling
        finish_compiling()  # a compilation in the background ends first (said on stderr): this line stays the last
        print(f"demkit run: {what}; kept: {', '.join(kept) or 'nothing'}; {again}", file=sys.stderr)
        return 130 if isinstance(err, KeyboardInterrupt) else 1
    seconds = time.perf_counter() - clock
    frames = len(trajectory) if trajectory is not None else 0
    if loaded.complete:  # a rerun of a finished run: nothing ran, nothing was written
        print(f"already complete: {checkpoint} holds the end of the run (t = {loaded.duration:g}); nothing ran "
              f"and the outputs are as they were (delete the checkpoint to run again)")
        for name, where in outputs.items():
            if loaded.made is not None and where == loaded.made:  # (interrupted while it was being made)
                print(f"wrote {name} (the finished run's, not made before): {where}")
            elif name != "checkpoint" and where.exists():
                print(f"kept {name}: {where}")
        return 0
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
    if out.get("stress"):
        yield "stress series", loaded.output_path(out["stress"], out_dir)
    if out.get("checkpoint"):
        yield "checkpoint", loaded.output_path(out["checkpoint"]["path"], out_dir)


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
    shear = scene.box.shear if scene.box is not None else None
    if shear is not None:  # Lees-Edwards: what the run will do to the sample
        stress = (f"the stress measured every {loaded.stress_every:g} (run.stress_every)" if loaded.stress_every
                  else "the stress not measured during the run (run.stress_every gives the rheology)")
        print(f"shear         rate {shear.rate:g} along {shear.flow}, gradient {shear.gradient}: the images slide at "
              f"{shear.jump(scene.box.size):.4g}, a strain of {shear.rate * loaded.duration:.4g} by t = "
              f"{loaded.duration:g}; {stress}")
    deform = getattr(scene.box, "deform", None) if scene.box is not None else None
    if deform is not None and deform.servo is not None:  # what the run will do to the box
        servo = deform.servo
        fixed = [f"{'xyz'[a]} at {deform.rates[a]:g}" for a in range(3) if deform.rates[a] and a not in servo.axes]
        print(f"deform        a servo drives {', '.join('xyz'[a] for a in servo.axes)} to the normal stress "
              f"{servo.pressure:g}: strain rates up to {servo.max_rate:g}, set every {servo.every:g} from the stress "
              "measured then" + "".join(", " + rate for rate in fixed))
    elif deform is not None:
        end = scene.box.size_at(loaded.duration)
        print("deform        " + ", ".join(f"{'xyz'[a]} at {deform.rates[a]:g}" for a in deform.axes) + ": the box "
              f"{' x '.join(f'{x:.4g}' for x in scene.box.size)} becomes {' x '.join(f'{x:.4g}' for x in end)} by t = "
              f"{loaded.duration:g} (volume x {np.prod(end) / np.prod(scene.box.size):.4g}), the positions remapped "
              "affinely after each step")
    for inter in scene.interactions + scene.effects:
        print(f"interaction   {inter!r}")
    for wall in scene.effects:
        if hasattr(wall, "listed"):  # a mesh wall: its grid and what a sphere's query visits now
            _, side, counts, _, _ = wall.grid()
            listed = wall.listed(p.position, scene.time)
            print(f"mesh          {wall.triangle_count:,} triangles, a grid of {' x '.join(map(str, counts))} cells of "
                  f"{side:.4g} ({wall.geometry_values().nbytes / 1e6:.3g} MB in the scene's parameters); the "
                  f"spheres' cells list {listed.mean():.3g} triangles on average now, {int(listed.max())} at most")
    for tuned in scene.long_range:
        print(f"long range    {tuned!r}")
    for inter in scene.interactions:  # a long-range setting the scene did not need (an FMM below its crossover)
        note = getattr(inter, "long_range_note", None)
        if note and inter.tuned is None:
            print(f"long range    {note}")
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
    choice = loaded.step_choice
    if choice is not None:
        runs = sum(p["added"] == p["steps"] for p in choice.pilots)  # (a pilot that found no impact ran on)
        pilots = (f"{runs} pilot run{'s' if runs != 1 else ''} of {sum(p['added'] for p in choice.pilots):,} steps "
                  f"in all" if choice.pilots else "no pilot run")
        print(f'chosen        dt = "auto" for an energy balance within {choice.accuracy:.3g} of the energy scale '
              f"(integrator.accuracy): {choice.why}; {pilots}, {choice.seconds:.2f} s")
    else:
        print('              (a step chosen for an accuracy: dt = "auto" with integrator.accuracy, dk.choose_time_step; '
              'errors against a reference: `demkit accuracy`)')
    # memory
    from . import cost, memory
    tree = cost.centres_tree(scene)  # for the pairs counted here and in the cost estimate
    pairs = cost.pair_counts(scene, tree)
    frames = (steps // max(1, round(loaded.record_every / integ.dt)) + 2) if loaded.record_every else 2
    parts = scene.memory_estimate(frames=frames, stages=integ.stage_arrays)
    listed = [(count / max(n, 1), group.width) for group, _, count in pairs if group.kind == "list"]
    parts["lists"] = memory.estimate(n, lists=listed)["lists"]  # the pairs counted now
    parts["total"] = parts["arrays"] + parts["lists"] + parts["record"]
    available, total = memory.machine_memory()
    print(f"memory        ~{memory.describe(parts, frames)}: ~{parts['total'] / memory.GB:.3g} GB in all "
          f"({available / memory.GB:.3g} GB free of {total / memory.GB:.3g} GB; dk.Scene.memory_estimate)")
    # cost
    for group, reach, count in pairs:
        kind = "all pairs" if group.kind == "all" else f"neighbour list within {reach:.4g} + skin {scene.skin:.3g}"
        names = ", ".join(type(inter).__name__ for _, inter in group.members)
        print(f"pairs         {count:,} ({kind}: {names})")
    out = loaded.outputs
    est = cost.estimate(scene, integ, loaded.duration, record_every=loaded.record_every,
                        vtk_every=(out.get("vtk") or {}).get("every"),
                        animation_frames=(out.get("animation") or {}).get("max_frames") or 0, tree=tree)
    if args.measure:
        from .simulation import Simulation
        sim = Simulation(scene, integ, notes=False)
        sim.run(duration=5 * integ.dt, progress=False)  # compiles (or loads the cache) and warms up
        per_step, count = _timed_steps(sim, integ)
        how = f"measured over {count:,} steps now"
        tiers = sim._tiers
        switched = tiers.switch_step is not None  # during the timing (earlier runs of the combination count)
        if switched or tiers.worth_switching(per_step * round(loaded.duration / integ.dt)):
            # the run goes over to the scene's own code (tier 2): time that, compiled or loaded now
            tiers.hurry()
            deadline = time.perf_counter() + 300.0
            while tiers.tier == 1 and tiers.switchable and time.perf_counter() < deadline:
                sim.run(duration=count * integ.dt, progress=False)
            if tiers.tier == 2:
                sim.run(duration=5 * integ.dt, progress=False)  # its first chunk warms up, as above
                per_step, count = _timed_steps(sim, integ)
                how = f"measured over {count:,} steps now on tier 2, the scene's own code a run this long switches to"
            else:
                how += f" on tier 1 ({tiers.reason})"
        per_step += est.later
        if est.later > 0.0:
            how += f", + {_short(est.later)} for {est.later_what} of the model ({est.note})"
    else:
        per_step = est.per_step
        biggest = sorted(est.parts.items(), key=lambda kv: -kv[1])[:3]
        how = "model: " + ", ".join(f"{name} {_short(seconds)}" for name, seconds in biggest if seconds > 0)
        if integ.evaluations_per_step > 1:
            how += f", x {integ.evaluations_per_step} force evaluations"
        if est.note:
            how += f"; {est.touching[0]:,} touching now, ~{est.touching[1]:,.0f} on average ({est.note})"
        how += "; --measure times it"
    stepping = per_step * steps
    print(f"cost          {_short(per_step)} per step ({how})")
    print(f"              -> ~{_duration(stepping + est.outputs)} for the run: stepping {_duration(stepping)}"
          + (f", outputs {_duration(est.outputs)}" if est.outputs >= 0.05 else "")
          + " (one thread, compilation not included; dk.cost)")
    from .engine.threads import ThreadChoice
    from .engine.tiers import TierChoice
    print(f"threads       {ThreadChoice(scene, integ.template).describe()}")
    print(f"compiled code {TierChoice(scene, f'{integ.template}_steps').describe()}")
    return 0


def _timed_steps(sim, integ):
    """(seconds per step, steps timed) of ``sim`` going on: at least 50 steps and 0.2 s of wall
    time, so that tiny scenes are timed too. Each try aims at 0.3 s from the last one's rate (at
    most 8 times as many steps), so that no timing run is long enough to count as a long run (one
    of 2 s or more loads the scene's own code, tier 2, when it is cached)."""
    count = 50
    while True:
        clock = time.perf_counter()
        sim.run(duration=count * integ.dt, progress=False)
        seconds = time.perf_counter() - clock
        if seconds >= 0.2 or count >= 10**7:
            return seconds / count, count
        count = int(count * min(8.0, max(2.0, 0.3 / max(seconds, 1e-9))))


def _short(seconds):
    """A short time: '1.6 ms', '883 us', '0.157 us'."""
    return f"{seconds * 1e3:.3g} ms" if seconds >= 1e-3 else f"{seconds * 1e6:.3g} us"


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
