"""What a triangle-mesh wall (dk.MeshWall) costs per sphere, against the plane wall and the cylinder, and
that scenes without one step as fast as before it existed.

    python3 benchmarks/bench_mesh_wall.py [--seconds S] [--rounds N] [--tiers 1,2] [--main PATH]
                                          [--kinds none,plane,vibrated] [--out mesh_wall_unused.json]

Each scene is N = 4000 fixed spheres (radius 0.5: their forces are computed every step and they stay
where they are; a Kelvin-Voigt law with friction over neighbour lists), spaced 3 radii apart so that no
two touch, as in benchmarks/bench_walls.py:

* on a floor, pressed 1e-3 into it: the plane wall (``plane``), a mesh of the floor in 2 triangles
  (``mesh2``), in 2 048 (a 32 x 32 grid of squares cut in two: triangles 12 radii wide, ``mesh2k``) and
  in 49 928 (158 x 158: 2.4 radii, ``mesh50k``); the 50k floor with the spheres 0.9 radii above it,
  touching nothing (``above50k``: outside the grid, which reaches one radius from the floor: the
  cost of a sphere beside a mesh it cannot touch);
* inside a drum of radius 60 along z, pressed 1e-3 into it: the cylinder (``cylinder``), a mesh of 50 x 20
  facets (2 000 triangles, ``drum2k``) and of 500 x 50 (50 000, ``drum50k``), the spheres pressed into
  the mesh's own facets;
* no wall (``none``): the baseline; (time a step - baseline) / N is the cost of one sphere on one wall.

Each figure is the median of ``rounds`` fresh processes stepping on one thread for about S seconds of
CPU time after warming up (compiling excluded), the scenes taking turns, on the tiers asked for: CPU
time, not wall time, so that other jobs on a shared machine slow the figures less (they still share
its caches and memory). With ``--main PATH`` (a checkout
of the code before mesh walls, e.g. /work/main) the plane and vibrated-plane scenes (``plane``,
``vibrated``) also run on that code, in the same rounds: an unused wall kind must cost nothing.
``--kinds`` runs those scenes only. Results: benchmarks/results/mesh_wall.json (or ``--out``).
"""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "mesh_wall.json"

CHILD = r"""
import json, math, sys, time
import numpy as np
import demkit as dk
kind, tier, seconds = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
n, R, gap, press = 4000, 0.5, 1.5, 1e-3
law = dk.KelvinVoigt(1e4, 10.0, friction=dk.Friction(0.5))


def floor(cells, size):
    u = np.linspace(-2.0, size + 2.0, cells + 1)
    x, z = np.meshgrid(u, u, indexing="ij")
    vertices = np.stack([x.ravel(), np.zeros(x.size), z.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij")
    a = (i * (cells + 1) + j).ravel()
    b, c, d = a + cells + 1, a + cells + 2, a + 1
    return vertices, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def drum(around, along, radius, length):
    angle = 2 * math.pi * np.arange(around) / around
    z = np.linspace(-2.0, length + 2.0, along + 1)
    vertices = np.stack([np.tile(radius * np.cos(angle), along + 1), np.tile(radius * np.sin(angle), along + 1),
                         np.repeat(z, around)], axis=1)
    k = np.arange(around)
    rows = []
    for s in range(along):
        a, b = s * around + k, s * around + (k + 1) % around
        rows += [np.stack([a, b, a + around], 1), np.stack([b, b + around, a + around], 1)]
    return vertices, np.concatenate(rows)


k = np.arange(n)
flat = kind in ("none", "plane", "vibrated", "mesh2", "mesh2k", "mesh50k", "above50k")
if flat:
    side = int(math.ceil(math.sqrt(n)))
    height = R - press if kind != "above50k" else 1.9 * R
    position = np.stack([(k % side) * 2 * gap, np.full(n, height), (k // side) * 2 * gap], axis=1)
    size = (side - 1) * 2 * gap
    cells = {"mesh2": 1, "mesh2k": 32, "mesh50k": 158, "above50k": 158}.get(kind)
    if kind == "none":
        walls = []
    elif kind in ("plane", "vibrated"):
        vibration = dict(amplitude=(0, 2e-4, 0), frequency=5.0) if kind == "vibrated" else {}
        walls = [dk.Wall((0, 0, 0), (0, 1, 0), **vibration)]
    else:
        walls = [dk.MeshWall(*floor(cells, size), reach=R)]
else:  # a drum: rings of spheres around the axis (z), spaced 3 R along it
    big = 60.0
    ring = int(2 * math.pi * (big - R) / (2 * gap))
    angle = 2 * math.pi * (k % ring) / ring
    arm = big - R + press
    position = np.stack([arm * np.cos(angle), arm * np.sin(angle), (k // ring) * 2 * gap], axis=1)
    length = float(position[:, 2].max())
    if kind == "cylinder":
        walls = [dk.Cylinder((0, 0, 0), (0, 0, 1), big)]
    else:
        mesh = drum(*((50, 20) if kind == "drum2k" else (500, 50)), big, length)
        walls = [dk.MeshWall(*mesh, reach=R)]
        rows = dk.MeshWall(*mesh, reach=4 * R).planes(position)  # pressed into the mesh's own facets
        depth = np.einsum("ij,ij->i", position, rows[:, 1:4]) - rows[:, 0] - (R - press)
        position = position - depth[:, None] * rows[:, 1:4]
p = dk.Particles(position=position, radius=R, mass=1.0, fixed=np.ones(n, dtype=bool))  # held where they are
scene = dk.Scene(p, [law, *walls], tier=tier, parallel=False)  # one thread: CPU time is the step's
sim = dk.Simulation(scene, dk.VelocityVerlet(1e-4), notes=False)
sim.run(duration=20e-4, progress=False)  # compile or load, first lists
steps = 20
while True:
    t = time.process_time(); sim.run(duration=steps * 1e-4, progress=False); took = time.process_time() - t
    if took > seconds:
        break
    steps = int(steps * min(10.0, 1.5 * seconds / max(took, 1e-3)))
mesh = next((w for w in walls if isinstance(w, dk.MeshWall)), None) if hasattr(dk, "MeshWall") else None
print("RESULT", json.dumps({"ns_per_step": took / steps * 1e9, "touching": int(len(scene.contacts().overlap)),
                            "tier": sim.statistics["tier"],
                            "triangles": mesh.triangle_count if mesh is not None else 0,
                            "listed": float(mesh.listed(position).mean()) if mesh is not None else 0.0}))
"""

KINDS = ("none", "plane", "mesh2", "mesh2k", "mesh50k", "above50k", "cylinder", "drum2k", "drum50k")
MAIN_KINDS = ("none", "plane", "vibrated")


def child(kind, tier, seconds, code=None):
    env = dict(os.environ, DEMKIT_QUIET="1")
    env.pop("DEMKIT_TIER", None)
    if code is not None:  # the other checkout, with a cache of its own
        env["PYTHONPATH"] = str(code)
        env["DEMKIT_CACHE_DIR"] = env.get("DEMKIT_CACHE_DIR", "/tmp/demkit-cache") + "-main"
    else:
        env["PYTHONPATH"] = str(HERE.parent)
    done = subprocess.run([sys.executable, "-c", CHILD, kind, str(tier), str(seconds)], capture_output=True,
                          text=True, env=env, timeout=3600)
    if done.returncode:
        raise SystemExit(done.stderr)
    return json.loads(next(line for line in done.stdout.splitlines() if line.startswith("RESULT"))[6:])


def main(argv):
    seconds = float(argv[argv.index("--seconds") + 1]) if "--seconds" in argv else 2.0
    rounds = int(argv[argv.index("--rounds") + 1]) if "--rounds" in argv else 3
    tiers = [int(t) for t in argv[argv.index("--tiers") + 1].split(",")] if "--tiers" in argv else [1, 2]
    main_code = Path(argv[argv.index("--main") + 1]) if "--main" in argv else None
    chosen = argv[argv.index("--kinds") + 1].split(",") if "--kinds" in argv else None
    out = RESULTS.parent / argv[argv.index("--out") + 1] if "--out" in argv else RESULTS
    jobs = [(kind, tier, None) for tier in tiers for kind in KINDS]
    jobs += [(kind, tier, main_code) for tier in tiers for kind in MAIN_KINDS] if main_code else []
    jobs += [("vibrated", tier, None) for tier in tiers] if main_code else []
    jobs = [job for job in jobs if chosen is None or job[0] in chosen]
    runs = {job: [] for job in jobs}
    info = {}
    for job in jobs:  # compile (or load) every scene's code once before timing
        info[job] = child(job[0], job[1], 0.2, job[2])
    for r in range(rounds):
        for job in (jobs if r % 2 == 0 else jobs[::-1]):
            result = child(job[0], job[1], seconds, job[2])
            assert result["tier"] == job[1], result
            runs[job].append(result["ns_per_step"])
            print(job[0], job[1], "main" if job[2] else "", round(result["ns_per_step"]), flush=True)
    rows = []
    for kind, tier, code in jobs:
        if kind == "none":
            continue
        base = statistics.median(runs["none", tier, code])
        step = statistics.median(runs[kind, tier, code])
        got = info[kind, tier, code]
        rows.append({"wall": kind, "tier": tier, "code": "main" if code else "mesh-walls",
                     "triangles": got["triangles"], "listed_per_sphere": got["listed"], "touching": got["touching"],
                     "ns_per_step": step, "baseline_ns_per_step": base, "ns_per_sphere": (step - base) / 4000,
                     "runs": runs[kind, tier, code], "baseline_runs": runs["none", tier, code]})
        print(json.dumps({k: v for k, v in rows[-1].items() if "runs" not in k}), flush=True)
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"machine": {"cores": os.cpu_count(), "date": time.strftime("%Y-%m-%d %H:%M")},
                                   "spheres": 4000, "seconds": seconds, "rounds": rounds, "rows": rows},
                                  indent=1) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
