"""Cost of VTK output: frames of 100,000 particles written by VTKWriter, compressed and not.

Writes benchmarks/results/vtk.json. Each frame carries every field (id, radius, mass, velocity,
angular_velocity, dipole, force, torque) of a granular-like state (random positions in a box,
random velocities, spins, unit dipoles, forces), and includes the .pvd rewrite. Reports, per
setting, milliseconds per frame (median over the frames) and bytes per frame, plus the time to
write the trails (poly-lines) of the frames written.

    python benchmarks/bench_vtk.py [--particles 100000] [--frames 10]
"""
import argparse
import json
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path

import meshio
import numpy as np

import demkit as dk
from demkit.io import write_polylines

HERE = Path(__file__).resolve().parent

SETTINGS = [  # (label, compress, dtype, frames factor)
    ("binary, uncompressed, float64", False, "float64", 1.0),
    ("binary, zlib, float64", "zlib", "float64", 1.0),
    ("binary, lzma, float64", "lzma", "float64", 0.3),
    ("binary, uncompressed, float32", False, "float32", 1.0),
    ("binary, zlib, float32", "zlib", "float32", 1.0),
]


def state(n, rng):
    """A Particles object (no scene needed) and force/torque arrays for n spheres."""
    side = (n ** (1 / 3)) * 2.4
    dipole = rng.normal(size=(n, 3))
    dipole /= np.linalg.norm(dipole, axis=1)[:, None]
    p = dk.Particles(rng.uniform(0, side, size=(n, 3)), velocity=rng.normal(0, 1e-2, size=(n, 3)),
                     radius=1.0, mass=1.0, dipole=dipole, angular_velocity=rng.normal(0, 1e-3, size=(n, 3)))
    return p, rng.normal(0, 1e-2, size=(n, 3)), rng.normal(0, 1e-3, size=(n, 3))


def measure(n, frames, compress, dtype, rng, folder):
    p, force, torque = state(n, rng)
    writer = dk.VTKWriter(folder, every=1.0, compress=compress, dtype=dtype, trails=False)
    writer.begin(p, has_force=True, has_torque=True)
    times, sizes = [], []
    for k in range(frames):
        p.position += p.velocity  # a different state each frame
        start = time.perf_counter()
        path = writer.write_state(float(k), p, force, torque)
        times.append(time.perf_counter() - start)
        sizes.append(path.stat().st_size)
    writer.close()
    start = time.perf_counter()
    series = dk.read_series(writer.pvd)
    read_ms = (time.perf_counter() - start) * 1e3 / frames
    start = time.perf_counter()
    trails = write_polylines(series, Path(folder) / "trails.vtp", compress=bool(compress))
    trails_s = time.perf_counter() - start
    return {"frames": frames, "ms_per_frame": float(np.median(times) * 1e3),
            "ms_per_frame_min": float(np.min(times) * 1e3), "bytes_per_frame": int(np.mean(sizes)),
            "bytes_per_particle": float(np.mean(sizes) / n), "read_ms_per_frame": read_ms,
            "trails_seconds": trails_s, "trails_bytes": trails.stat().st_size}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, default=100_000)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--out", type=Path, default=HERE / "results" / "vtk.json")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(2024)
    rows = []
    for label, compress, dtype, factor in SETTINGS:
        folder = tempfile.mkdtemp(prefix="demkit-bench-vtk-")
        try:
            row = measure(args.particles, max(2, int(args.frames * factor)), compress, dtype, rng, folder)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        row.update(setting=label, compress=compress or None, dtype=dtype)
        rows.append(row)
        print(f"{label:32s} {row['ms_per_frame']:8.1f} ms/frame {row['bytes_per_frame'] / 1e6:8.2f} MB/frame "
              f"({row['bytes_per_particle']:.0f} B/particle), read back {row['read_ms_per_frame']:.0f} ms/frame, "
              f"trails of {row['frames']} frames {row['trails_seconds']:.2f} s")
    result = {
        "benchmark": "VTKWriter frames (meshio .vtu, binary) of N particles with all fields, .pvd rewrite included",
        "particles": args.particles,
        "fields": ["id", "radius", "mass", "velocity", "angular_velocity", "dipole", "force", "torque"],
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
                    "meshio": meshio.__version__, "platform": platform.platform()},
        "results": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
