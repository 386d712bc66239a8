"""The ``demkit`` command.

    demkit accuracy scene.toml|scene.py [--duration T] [--dts 0.01,0.005] [--methods VelocityVerlet,RK4]
                             [--plot wp.png] [--csv wp.csv] [--no-progress]
    demkit sweep sweep.toml [--scheduler tcp://host:8786] [--workers N]   (docs/sweeps.md)

    demkit render SERIES.pvd -o run.mp4 [--fps 20] [--max-frames 200] [--color-by speed] ...

``render`` draws a written series to an animation or a picture (:mod:`demkit.viz.command`);
``accuracy`` runs a work-precision study (:data:`ACCURACY_HELP`)."""
from __future__ import annotations

import argparse
import runpy
import sys
from pathlib import Path

from . import accuracy
from .integrators import parse_method  # noqa: F401 (demkit.cli.parse_method, as before)
from .scene import Scene

#: the description of `demkit accuracy --help`
ACCURACY_HELP = """\
Run demkit.accuracy.work_precision on a scene and print the table (method, dt, errors, wall time,
force evaluations, stable?) and write the figure.

The scene is a TOML scene file (docs/scene_files.md; its run.duration is the default --duration, its
integrator and outputs are not used) or a Python file that defines `scene` (a demkit.Scene) or
`make_scene()` returning one, and may define `duration`, `dts`, `methods` (as for work_precision),
`times` and `observable`; options on the command line win. Method names:
EulerCromer, VelocityVerlet, ForestRuth, RK4, MultipleTimeStep (MultipleTimeStep:8 for 8 inner steps;
4 by default), and :resolve after VelocityVerlet or MultipleTimeStep to resolve contact events
(VelocityVerlet:resolve, MultipleTimeStep:8:resolve).
"""

def parse_dts(text):
    try:
        dts = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--dts must be comma-separated numbers, got {text!r}") from None
    if not dts or any(not dt > 0 for dt in dts):
        raise ValueError(f"--dts must be positive time steps, got {text!r}")
    return dts


def load_scene_file(path):
    """The namespace of a scene file (a Python file defining ``scene`` or ``make_scene()``)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"scene file {path} does not exist")
    namespace = runpy.run_path(str(path), run_name="demkit_scene")
    scene = namespace.get("scene")
    if scene is None and callable(namespace.get("make_scene")):
        scene = namespace["make_scene"]()
    if not isinstance(scene, Scene):
        raise ValueError(f"{path} must define `scene` (a demkit.Scene) or `make_scene()` returning one")
    namespace["scene"] = scene
    return namespace


def scene_namespace(path, overrides=None):
    """What a scene file defines, as a dict: a Python file's names (:func:`load_scene_file`), or for a
    TOML scene file (:func:`demkit.load_scene`, with ``overrides`` {key path: value}) its ``scene``,
    ``integrator``, ``duration``, ``record_every`` and ``time_unit`` (seconds per time unit with
    units = "si", else 1)."""
    if Path(path).suffix == ".py":
        if overrides:
            raise ValueError(f"--set changes keys of TOML scene files; {path} is a Python file: change it there")
        return load_scene_file(path)
    from .scenefile import load_scene
    loaded = load_scene(path, overrides=overrides)
    return {"scene": loaded.scene, "integrator": loaded.integrator, "duration": loaded.duration,
            "record_every": loaded.record_every,
            "time_unit": loaded.units.time if loaded.units is not None else 1.0}


def accuracy_command(args):
    namespace = scene_namespace(args.scene)
    time_unit = namespace.get("time_unit", 1.0)  # units = "si": --duration and --dts in seconds, like the file
    duration = args.duration / time_unit if args.duration is not None else namespace.get("duration")
    if duration is None:
        raise ValueError(f"give --duration or define `duration` in {args.scene}")
    methods = ({m: parse_method(m) for m in args.methods.split(",") if m.strip()} if args.methods
               else namespace.get("methods"))
    dts = [dt / time_unit for dt in parse_dts(args.dts)] if args.dts else namespace.get("dts")
    report = accuracy.work_precision(namespace["scene"], float(duration), methods=methods, dts=dts,
                                     times=namespace.get("times"), observable=namespace.get("observable"),
                                     repeats=args.repeats, progress=False if args.no_progress else None)
    print(report.table())
    plot = Path(args.plot) if args.plot else Path(f"{Path(args.scene).stem}_accuracy.png")
    report.plot(plot)
    print(f"wrote {plot}")
    if args.csv:
        report.to_csv(args.csv)
        print(f"wrote {args.csv}")
    return 0


def load_run(path, overrides=None):
    """(scene, integrator, duration, record_every) of a scene file for export-lammps: a TOML scene
    file (:func:`demkit.load_scene`, with ``overrides``), or a Python file (``.py``) that defines
    ``scene`` (or ``make_scene()``) and ``integrator``, and may define ``duration`` and ``record_every``."""
    namespace = scene_namespace(path, overrides)
    integrator = namespace.get("integrator")
    if integrator is None:
        raise ValueError(f"{path} must define `integrator` (e.g. demkit.VelocityVerlet(dt=1e-3))")
    return namespace["scene"], integrator, namespace.get("duration"), namespace.get("record_every")


def export_lammps_command(args):
    from .commands import parse_sets
    from .lammps import export_lammps
    scene, integrator, duration, record_every = load_run(args.scene, parse_sets(args.set))
    try:
        files = export_lammps(scene, integrator, args.out_dir, duration=duration, record_every=record_every,
                              strict=not args.allow_differences)
    except ValueError as err:
        if "strict=False" not in str(err):
            raise
        raise ValueError(f"{err} (on the command line: --allow-differences)") from None
    print(f"wrote {files.data} and {files.deck}; run: cd {args.out_dir} && lmp -in {files.deck.name}")
    for note in files.notes:
        print(f"note: {note}")
    return 0


def sweep_command(args):
    from .sweep import read_sweep_file, summary, sweep_file
    try:
        rows = sweep_file(args.file, workers=args.workers, scheduler=args.scheduler)
    except KeyboardInterrupt as stop:  # Ctrl-C: finished points are in the table; a rerun resumes
        print(f"demkit {stop or 'sweep interrupted'}", file=sys.stderr)
        return 130
    print(summary(rows, read_sweep_file(args.file)["results"]))
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(prog="demkit", description="demkit: spinning magnetic spheres.")
    commands = parser.add_subparsers(dest="command", required=True)
    study = commands.add_parser("accuracy", help="what accuracy costs in time: a work-precision table and figure",
                                description=ACCURACY_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    study.add_argument("scene", help="a TOML scene file, or a Python file defining `scene` or `make_scene()`")
    study.add_argument("--duration", type=float, help="simulated time of every run (in the scene file's units)")
    study.add_argument("--dts", help="comma-separated time steps (default: the safe step and 4 halvings)")
    study.add_argument("--methods", help="comma-separated methods (default: EulerCromer,VelocityVerlet)")
    study.add_argument("--plot", help="figure path (default: <scene>_accuracy.png here)")
    study.add_argument("--csv", help="also write the table as CSV")
    study.add_argument("--no-progress", action="store_true", help="no progress bar over the runs")
    study.add_argument("--repeats", type=int, help="time each run this many times (default: runs shorter than "
                                                   "0.2 s again until they add up to 0.2 s, at least 5 times)")
    from . import commands as scene_commands  # demkit run / demkit info (TOML scene files)
    scene_commands.add_commands(commands)
    export = commands.add_parser("export-lammps", help="write a LAMMPS data file and input deck of a scene",
                                 description="Write scene.data and in.scene (LAMMPS 29 Sep 2021, units lj) that "
                                             "run the scene in LAMMPS; see docs/lammps_export.md.")
    export.add_argument("scene", help="a TOML scene file (docs/scene_files.md), or a Python file defining `scene` "
                                      "and `integrator` (and optionally `duration`, `record_every`)")
    export.add_argument("out_dir", help="folder for scene.data, in.scene (created if needed)")
    export.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE",
                        help="change a key of a TOML scene file, e.g. --set interactions.friction.sliding=lammps "
                             "(repeatable)")
    export.add_argument("--allow-differences", action="store_true",
                        help="export what LAMMPS runs differently from demkit (listed as notes) instead of refusing")
    export.set_defaults(handler=export_lammps_command)
    study.set_defaults(handler=accuracy_command)
    sweeping = commands.add_parser("sweep", help="run a parameter sweep file (TOML) into a results table",
                                   description="Run the sweep a TOML file describes (docs/sweeps.md); "
                                               "finished points are not rerun.")
    sweeping.add_argument("file", help="the sweep file (TOML)")
    sweeping.add_argument("--scheduler", help="Dask: 'local' (a LocalCluster) or an address tcp://host:8786 "
                                              "(default: local processes)")
    sweeping.add_argument("--workers", type=int, help="processes, or Dask workers of a LocalCluster")
    sweeping.set_defaults(handler=sweep_command)
    from .viz import command as render
    drawing = commands.add_parser("render", help="draw a series (.pvd) to an animation (.mp4, .gif) or a picture",
                                  description=render.__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    render.add_arguments(drawing)
    drawing.set_defaults(handler=render.render)
    args = parser.parse_args(argv)
    return scene_commands.main_errors(parser, args)


if __name__ == "__main__":
    sys.exit(main())
