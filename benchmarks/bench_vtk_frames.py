"""Cost of one VTK frame as a series grows: does writing frame k cost more when k is large?

1. ``write_state``: a two-sphere series of 25,000 frames written through
   ``VTKWriter.write_state`` (frame file + .pvd entry), every frame timed.
2. ``simulation``: the two-magnet scene of docs/visualisation.md run by a Simulation with a
   VTKWriter every time step (default options: force evaluation, trails kept in memory),
   25,000 frames, timed in blocks of 100 steps (time per step, i.e. per frame, stepping
   included).
3. ``former_full_rewrite``: the way used before, the same frame write followed by a rewrite of
   the whole .pvd (``write_pvd``: temporary file + rename) at 0..100 frames and at ~25,000 frames
   (the entry list filled up to that length first).

Uses only the public API, so it also runs on older demkit versions (``--out`` another file);
the JSON records which demkit it ran. Writes benchmarks/results/vtk_frames.json.

    python benchmarks/bench_vtk_frames.py [--frames 25000] [--out results/vtk_frames.json]
"""
import argparse
import json
import os
import platform
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import demkit as dk
from demkit.io.frames import FrameWriter
from demkit.io.pvd import write_pvd

HERE = Path(__file__).resolve().parent
WINDOW = 101  # frames timed at the start (0..100) and at the end of the series


def two_spheres():
    return dk.Particles([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]], velocity=[[1e-3, 0, 0], [-1e-3, 0, 0]],
                        radius=1.0, dipole=[[1.0, 0, 0], [1.0, 0, 0]])


def summary(ms):
    ms = np.asarray(ms)
    return {"median_ms": round(float(np.median(ms)), 3), "mean_ms": round(float(ms.mean()), 3),
            "p95_ms": round(float(np.percentile(ms, 95)), 3), "frames_timed": int(len(ms))}


def grow(folder, frames):
    """Per-frame milliseconds of VTKWriter.write_state over a series of ``frames`` frames."""
    p = two_spheres()
    force = np.zeros((2, 3))
    writer = dk.VTKWriter(folder, every=1.0, trails=False)
    writer.begin(p, has_force=True)
    ms = np.empty(frames)
    for k in range(frames):
        p.position += p.velocity
        start = time.perf_counter()
        writer.write_state(float(k), p, force)
        ms[k] = 1e3 * (time.perf_counter() - start)
    writer.close()
    assert len(dk.io.read_pvd(writer.pvd)) == frames
    return ms


def two_magnets():
    R, v, b = 6.94, 5.78e-3, 4 * 6.94
    pos = np.array([[-40.0, b / 2, 0], [40.0, -b / 2, 0]])
    n = (pos[1] - pos[0]) / np.linalg.norm(pos[1] - pos[0])
    p = dk.Particles(pos, velocity=[[v, 0, 0], [-v, 0, 0]], radius=R, mass=1.0, dipole=[n, n])
    return dk.Scene(p, [dk.Dipole(prefactor=1 / 3), dk.KelvinVoigt(stiffness=1.0, damping=0.1)])


def simulate(folder, frames, block=100, dt=0.01):
    """{first frame of a block: ms per step} of a Simulation writing a frame every step."""
    writer = dk.VTKWriter(folder, every=dt)
    sim = dk.Simulation(two_magnets(), dk.EulerCromer(dt=dt), writers=[writer])
    sim.run(dt)  # compiles, opens the series: frames 0 and 1
    ms = {}
    while writer.frames_written + block <= frames:
        first = writer.frames_written
        start = time.perf_counter()
        sim.run(block * dt)
        ms[first] = 1e3 * (time.perf_counter() - start) / block
    sim.close()
    return ms


def rewrite(folder, first, count):
    """Per-frame milliseconds of the former way (frame file, then the whole .pvd rewritten) for
    frames first .. first+count-1 (entries before ``first`` are listed but not written)."""
    p = two_spheres()
    data = {"id": p.ids, "radius": p.radius, "mass": p.mass, "velocity": p.velocity,
            "dipole": p.dipole, "force": np.zeros((2, 3))}
    frames = FrameWriter()
    entries = [(float(k), f"particles_{k:06d}.vtu") for k in range(first)]
    pvd = Path(folder) / "particles.pvd"
    ms = []
    for k in range(first, first + count):
        start = time.perf_counter()
        path = Path(folder) / f"particles_{k:06d}.vtu"
        frames.write(path, p.position, data)
        entries.append((float(k), path.name))
        write_pvd(pvd, entries)
        ms.append(1e3 * (time.perf_counter() - start))
    return ms


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=25000)
    parser.add_argument("--out", default=str(HERE / "results" / "vtk_frames.json"))
    parser.add_argument("--note", default=None, help="stored in the JSON (e.g. which demkit version ran)")
    args = parser.parse_args()
    n = args.frames
    checkpoints = [k for k in (1000, 5000, 10000, 20000) if k + WINDOW <= n]
    with tempfile.TemporaryDirectory() as tmp:
        clock = time.perf_counter()
        ms = grow(Path(tmp) / "grow", n)
        total = time.perf_counter() - clock
        now = {"frames_0_100": summary(ms[:WINDOW]),
               **{f"frames_{k}_{k + WINDOW - 1}": summary(ms[k:k + WINDOW]) for k in checkpoints},
               f"last_{WINDOW}_frames": summary(ms[-WINDOW:]),
               "total_seconds": round(total, 2)}
        clock = time.perf_counter()
        blocks = simulate(Path(tmp) / "sim", n)
        firsts = sorted(blocks)
        simulation = {"ms_per_frame_in_blocks_of_100_from_frame": {
                          str(k): round(blocks[k], 3) for k in firsts
                          if k in (firsts[0], firsts[-1]) or any(0 <= k - c < 100 for c in checkpoints)},
                      "total_seconds": round(time.perf_counter() - clock, 2)}
        os.makedirs(Path(tmp) / "old0")
        os.makedirs(Path(tmp) / "oldN")
        before = {"frames_0_100": summary(rewrite(Path(tmp) / "old0", 0, WINDOW)),
                  f"last_{WINDOW}_frames": summary(rewrite(Path(tmp) / "oldN", n - WINDOW, WINDOW))}
    result = {
        "what": "milliseconds per frame of a two-sphere series (id, radius, mass, velocity, dipole, force; "
                "float64, uncompressed), as the series grows",
        "frames": n,
        "demkit": {"path": str(Path(dk.__file__).parent), "commit": commit(), "note": args.note},
        "write_state": now,
        "simulation": simulation,
        "former_full_rewrite": before,
        "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform(),
                    "python": platform.python_version()},
    }
    out = Path(args.out)
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


def commit():
    """The git commit of the demkit that runs (+ '-dirty' with local changes), or None."""
    here = Path(dk.__file__).parent
    try:
        head = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(here), "status", "--porcelain", "--", "."], capture_output=True,
                               text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ("-dirty" if dirty else "")


if __name__ == "__main__":
    main()
