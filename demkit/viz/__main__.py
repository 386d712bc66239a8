"""``python -m demkit.viz``: check off-screen rendering, or draw a series.

    python -m demkit.viz --check
    python -m demkit.viz snapshot out/particles.pvd frame.png [--time T]
    python -m demkit.viz animate out/particles.pvd run.gif [--fps 20] [--max-frames 200]
    options for both: --color-by FIELD --cmap NAME --frame {auto,all,cluster,box} --zoom Z
"""
import argparse
import sys

from . import RenderingUnavailable, animate, rendering_info, snapshot


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m demkit.viz", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--check", action="store_true", help="report the OpenGL path used off-screen")
    parser.add_argument("action", nargs="?", choices=["snapshot", "animate"])
    parser.add_argument("source", nargs="?", help="a .pvd series, its folder, or a .vtu frame")
    parser.add_argument("output", nargs="?", help="image (.png) or animation (.gif, .mp4)")
    parser.add_argument("--time", type=float, help="snapshot: the frame nearest this time")
    parser.add_argument("--fps", type=float, default=20.0)
    parser.add_argument("--max-frames", type=int, default=200)
    parser.add_argument("--color-by", help="id, speed, contacts, cluster, dipole, radius or a point field")
    parser.add_argument("--cmap", help="a matplotlib colour map (default viridis)")
    parser.add_argument("--frame", default="auto", choices=["auto", "all", "cluster", "box"])
    parser.add_argument("--zoom", type=float, default=1.0)
    args = parser.parse_args(argv)
    style = dict(color_by=args.color_by, cmap=args.cmap, frame=args.frame, zoom=args.zoom)
    try:
        if args.check:
            info = rendering_info()
            print(f"off-screen rendering works: {info['window']} ({info['renderer']})")
        if args.action:
            if not (args.source and args.output):
                parser.error(f"{args.action} needs a source and an output path")
            if args.action == "snapshot":
                print(snapshot(args.source, args.output, time=args.time, **style))
            else:
                print(animate(args.source, args.output, fps=args.fps, max_frames=args.max_frames, **style))
        elif not args.check:
            parser.print_help()
    except (RenderingUnavailable, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
