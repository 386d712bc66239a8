"""``python -m demkit.viz``: check off-screen rendering, or draw a series.

    python -m demkit.viz --check
    python -m demkit.viz snapshot out/particles.pvd frame.png [--time T]
    python -m demkit.viz animate out/particles.pvd run.gif [--fps 20] [--max-frames 200]
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
    args = parser.parse_args(argv)
    try:
        if args.check:
            info = rendering_info()
            print(f"off-screen rendering works: {info['window']} ({info['renderer']})")
        if args.action:
            if not (args.source and args.output):
                parser.error(f"{args.action} needs a source and an output path")
            if args.action == "snapshot":
                print(snapshot(args.source, args.output, time=args.time))
            else:
                print(animate(args.source, args.output, fps=args.fps, max_frames=args.max_frames))
        elif not args.check:
            parser.print_help()
    except (RenderingUnavailable, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
