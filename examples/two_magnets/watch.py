"""Watch one collision of the seed paper's two magnets: a VTK series for ParaView and an animation.

    python examples/two_magnets/watch.py [--out DIR] [--movie gif|mp4]

Writes DIR/vtk/particles.pvd (+ one .vtu per frame and particles_trails.vtp) and DIR/collision.gif.
Open the .pvd in ParaView, or set it up with ``pvpython $(python -m demkit.io --paraview-script)
DIR/vtk/particles.pvd``. Re-running replaces this example's own series (overwrite=True).
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

import demkit as dk

HERE = Path(__file__).resolve().parent
R = dk.two_magnets.PAPER_RADIUS


def main(argv=None):
    """Run, write and animate; ``argv`` are command-line options (None: the defaults). Returns the
    paths written: {"pvd", "trails", "movie"} (movie None when nothing can render here)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "output", help="output folder")
    parser.add_argument("--movie", choices=["gif", "mp4"], default="gif")
    parser.add_argument("--duration", type=float, default=45000.0, help="simulated time (t_c)")
    parser.add_argument("--every", type=float, default=100.0, help="time between VTK frames (t_c)")
    parser.add_argument("--frames", type=int, default=120, help="frames in the animation")
    args = parser.parse_args([] if argv is None else argv)
    args.out.mkdir(parents=True, exist_ok=True)

    frames = int(args.duration // args.every) + 1
    print(f"simulating t = 0 .. {args.duration:g} with a VTK frame every {args.every:g} ({frames} frames, "
          f"about 1 s)...", flush=True)
    start = time.perf_counter()
    writer = dk.VTKWriter(args.out / "vtk", every=args.every, overwrite=True)
    scene = dk.two_magnets.TwoMagnets(b_over_R=4.0).scene()  # the paper's collision at b = 4R
    sim = dk.Simulation(scene, dk.EulerCromer(dt=0.01), writers=[writer])
    traj = sim.run(args.duration, record_every=1.0)  # fine recording to find the first contact
    sim.close()  # writes the trails file
    touch = np.flatnonzero(np.linalg.norm(traj.position[:, 1] - traj.position[:, 0], axis=1) <= 2 * R)
    t_touch = traj.time[touch[0]] if len(touch) else None
    print(f"simulated t = 0 .. {args.duration:g} ({writer.frames_written} VTK frames) in "
          f"{time.perf_counter() - start:.1f} s; first contact at t ~ {t_touch:g}" if t_touch is not None
          else "the spheres did not touch")
    print(f"VTK series:  {writer.pvd}")
    print(f"trails:      {writer.series.trails}")

    # the animation: from shortly before the contact to the end (the approach, the hit, the spin)
    begin = max(0.0, t_touch - 8000.0) if t_touch is not None else 0.0
    movie = args.out / f"collision.{args.movie}"
    print(f"rendering {args.frames} frames of t = {begin:g} .. {args.duration:g} to {movie.name} off-screen "
          f"(about {max(1, round(args.frames / 15))} s; a progress bar on a terminal)...", flush=True)
    start = time.perf_counter()
    try:
        dk.viz.animate(writer.pvd, movie, time_range=(begin, None), max_frames=args.frames,
                       fps=20, window_size=(640, 480), trail=3000.0)
    except dk.viz.RenderingUnavailable as err:
        print(f"no animation: {err}")
        return {"pvd": writer.pvd, "trails": writer.series.trails, "movie": None}
    print(f"animation:   {movie} ({args.frames} frames, {time.perf_counter() - start:.1f} s)")
    print(f"ParaView:    pvpython {dk.io.paraview_script()} {writer.pvd}")
    return {"pvd": writer.pvd, "trails": writer.series.trails, "movie": movie}


if __name__ == "__main__":
    main(sys.argv[1:])
