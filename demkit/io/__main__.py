"""``python -m demkit.io``: where the ParaView script is, and series summaries."""
import argparse
import sys

from . import paraview_script, read_pvd


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m demkit.io", description=__doc__)
    parser.add_argument("--paraview-script", action="store_true",
                        help="print the path of the pvpython script (pvpython PATH series.pvd)")
    parser.add_argument("pvd", nargs="?", help="a .pvd series to summarise")
    args = parser.parse_args(argv)
    if args.paraview_script:
        print(paraview_script())
    if args.pvd:
        entries = read_pvd(args.pvd)
        times = [t for t, _ in entries]
        span = f", t = {times[0]:.6g} .. {times[-1]:.6g}" if times else ""
        print(f"{args.pvd}: {len(entries)} frames{span}")
    if not (args.paraview_script or args.pvd):
        parser.print_help()
    return 0


if __name__ == "__main__":
    sys.exit(main())
