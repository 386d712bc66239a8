"""What interruptibility, re-entry and checkpoints cost.

* chunking: the compiled loop returns to Python every CHUNK_SECONDS (0.2 s) of wall time; steps per
  second of the paper's two magnets and of the N = 8000 reference scene with chunks of 0.2 s
  against one chunk for the whole run (CHUNK_SECONDS = 1e9);
* re-entry: wall time of a run() call of one step at N = 8000, continuing (O(N): fingerprint,
  no validation, no force evaluation) and after the user touched the velocities (validated and
  prepared again);
* checkpoints: time to save and to resume, and file size, at N = 8000.

Writes benchmarks/results/restart.json. Usage: python benchmarks/bench_restart.py
"""
from __future__ import annotations

import json
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import demkit as dk
import demkit.simulation as simulation

sys.path.insert(0, str(Path(__file__).parent))
from reference_scene import make_reference_scene, particles_and_box  # noqa: E402

RESULTS = Path(__file__).parent / "results" / "restart.json"


def reference(n=8000):
    p, box = particles_and_box(make_reference_scene(n))
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=4.0), dk.KelvinVoigt(1000.0, 1.5)], box=box)


def two_magnets():
    return dk.two_magnets.TwoMagnets(b_over_R=4.0).scene()


def rate(make_scene, dt, steps, chunk_seconds, repeats=3):
    best = 0.0
    for _ in range(repeats):
        scene = make_scene()
        sim = dk.Simulation(scene, dk.VelocityVerlet(dt))
        sim.run(dt * 10)  # compile, warm
        simulation.CHUNK_SECONDS = chunk_seconds
        began = time.perf_counter()
        sim.run(dt * steps)
        best = max(best, steps / (time.perf_counter() - began))
        simulation.CHUNK_SECONDS = 0.2
    return best


def main():
    out = {"machine": platform.processor() or platform.machine(), "date": time.strftime("%Y-%m-%d")}
    chunking = {}
    for name, make, dt, steps in (("two_magnets", two_magnets, 0.01, 40_000_000),
                                  ("reference_N8000", reference, 0.001, 400)):
        chunked = rate(make, dt, steps, 0.2)
        whole = rate(make, dt, steps, 1e9)
        chunking[name] = {"steps_per_second_chunked": chunked, "steps_per_second_one_chunk": whole,
                          "overhead_percent": 100 * (whole / chunked - 1)}
        print(name, chunking[name], flush=True)
    out["chunking"] = chunking

    scene = reference()
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.001))
    sim.run(0.001)
    began = time.perf_counter()
    for _ in range(10):
        sim.run(0.001)
    continuing = (time.perf_counter() - began) / 10
    began = time.perf_counter()
    for _ in range(3):
        scene.particles.velocity[0, 0] += 0.0
        scene.particles.velocity = scene.particles.velocity.copy()  # touched: prepared again
        sim.run(0.001)
    touched = (time.perf_counter() - began) / 3
    step_alone = sim.statistics["seconds"]
    out["reentry_N8000"] = {"run_of_one_step_continuing_s": continuing, "run_of_one_step_after_change_s": touched,
                            "one_step_s": step_alone}
    print(out["reentry_N8000"], flush=True)

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.ckpt"
        checkpoint = dk.Checkpoint(path)
        began = time.perf_counter()
        for _ in range(5):
            checkpoint.save(sim)
        save = (time.perf_counter() - began) / 5
        other = dk.Simulation(reference(), dk.VelocityVerlet(0.001))
        began = time.perf_counter()
        other.resume(path)
        resume = time.perf_counter() - began
        out["checkpoint_N8000"] = {"save_s": save, "resume_s": resume, "bytes": path.stat().st_size,
                                   "bytes_per_particle": path.stat().st_size / 8000}
    print(out["checkpoint_N8000"], flush=True)
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    print("wrote", RESULTS)


if __name__ == "__main__":
    main()
