"""``demkit render``: draw a written series to an animation or a picture.

    demkit render out/particles.pvd -o run.mp4 [--fps 20] [--max-frames 200] [--start T] [--stop T]
    demkit render out/particles.pvd -o last.png [--time T]
    options for both: --color-by FIELD --cmap NAME --frame {auto,all,cluster,box} --zoom Z
                      --size WIDTHxHEIGHT --trail T --view {auto,xy,xz,yz,iso}

The output's suffix chooses: .mp4 or .gif an animation (:func:`demkit.viz.animate`, with a progress
bar over the frames on a terminal), .png/.jpg a picture of one frame (:func:`demkit.viz.snapshot`;
the last one, or the one nearest ``--time``). The source is a .pvd series, its folder or a .vtu frame.
"""
from __future__ import annotations

import sys
from pathlib import Path

PICTURES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
MOVIES = (".mp4", ".gif")


def add_arguments(parser):
    """The ``render`` options on an argparse parser."""
    parser.add_argument("source", help="a .pvd series, its folder, or a .vtu frame")
    parser.add_argument("-o", "--output", required=True, help="run.mp4, run.gif, or a picture (.png, .jpg)")
    parser.add_argument("--fps", type=float, default=20.0, help="animation: frames per second (default 20)")
    parser.add_argument("--max-frames", type=int, default=200,
                        help="animation: at most this many frames, evenly chosen (default 200)")
    parser.add_argument("--start", type=float, help="animation: first simulation time shown")
    parser.add_argument("--stop", type=float, help="animation: last simulation time shown")
    parser.add_argument("--time", type=float, help="picture: the frame nearest this time (default: the last)")
    parser.add_argument("--color-by", help="id, speed, contacts, cluster, dipole, radius or a point field")
    parser.add_argument("--cmap", help="a matplotlib colour map (default viridis)")
    parser.add_argument("--frame", default="auto", choices=["auto", "all", "cluster", "box"],
                        help="what the camera fits (default auto)")
    parser.add_argument("--view", default="auto", choices=["auto", "xy", "xz", "yz", "iso"])
    parser.add_argument("--zoom", type=float, default=1.0)
    parser.add_argument("--trail", type=float, help="length of the fading trails in time units (0: none)")
    parser.add_argument("--size", default=None, help="window size WIDTHxHEIGHT in pixels "
                        "(default 800x600 for animations, 1024x768 for pictures)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def window_size(text):
    """(width, height) from 'WIDTHxHEIGHT'; ValueError naming the option otherwise."""
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size must be WIDTHxHEIGHT in pixels, e.g. 800x600, got {text!r}") from None
    if width < 16 or height < 16:
        raise ValueError(f"--size must be at least 16x16 pixels, got {text!r}")
    return width, height


def render(args):
    """Run ``demkit render`` for parsed ``args``; returns the exit status (ValueError for bad input)."""
    from . import RenderingUnavailable, animate, snapshot

    output = Path(args.output)
    suffix = output.suffix.lower()
    if suffix not in MOVIES + PICTURES:
        raise ValueError(f"-o {output}: the suffix chooses what is written: {', '.join(MOVIES)} for an "
                         f"animation, {', '.join(PICTURES)} for a picture")
    if not Path(args.source).exists():
        raise ValueError(f"{args.source} does not exist (give a .pvd series, its folder or a .vtu frame)")
    style = dict(color_by=args.color_by, cmap=args.cmap, frame=args.frame, zoom=args.zoom, view=args.view,
                 trail=args.trail)
    if args.size:
        style["window_size"] = window_size(args.size)
    try:
        if suffix in MOVIES:
            if args.time is not None:
                raise ValueError("--time chooses the frame of a picture; for an animation use --start/--stop")
            span = None if args.start is None and args.stop is None else (args.start, args.stop)
            path = animate(args.source, output, fps=args.fps, max_frames=args.max_frames, time_range=span,
                           progress=False if args.no_progress else None, **style)
        else:
            if args.start is not None or args.stop is not None:
                raise ValueError("--start/--stop choose the frames of an animation; for a picture use --time")
            path = snapshot(args.source, output, time=args.time, **style)
    except RenderingUnavailable as err:
        print(f"demkit render: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as err:  # Ctrl-C: one line, no traceback, the shell's status for SIGINT
        print(f"demkit render: {err or 'interrupted'}", file=sys.stderr)
        return 130
    print(f"wrote {path}")
    return 0
