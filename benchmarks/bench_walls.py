"""What a wall costs per sphere touching it: a plane wall (dk.Wall) at rest and vibrated, against a
cylinder (dk.Cylinder) at rest and turning and a turning cone (dk.Cone), on tier 1 and tier 2.

    python3 benchmarks/bench_walls.py [--seconds S] [--rounds N] [--kinds none,plane,cone] [--tiers 1]

(--kinds or --tiers: a part of the table, written to results/walls_<kinds>_tier<tiers>.json instead.)

Each scene is N = 4000 fixed spheres (radius 0.5: their forces are computed every step and they stay
where they are) with a Kelvin-Voigt contact law with friction over neighbour lists, spaced 3 radii
apart so that no two touch, every one pressed 1e-3 into the wall: on a floor (the plane; vibrated:
the floor swinging by 4e-4 along its normal at frequency 5, so the spheres stay pressed), on the
inside of a drum of radius 60 with its axis along z (the cylinder, at rest or turning at 0.5 rad per
unit time; a ring of spheres repeated along the axis), on the face of a hopper cone (apex at the origin,
axis z, half-angle 30 degrees, turning at 0.5; rings of spheres up its face from 10 to ~80 from the
apex). The same spheres without any wall are the baseline;
(time a step - baseline) / N is the cost of one sphere touching one wall. Each figure is the
median of ``rounds`` fresh processes, stepping for about S seconds after warming up (compiling
excluded), the scenes taking turns. Results: benchmarks/results/walls.json.
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
RESULTS = HERE / "results" / "walls.json"

CHILD = r"""
import json, math, sys, time
import numpy as np
import demkit as dk
kind, tier, seconds = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
n, R, gap = 4000, 0.5, 1.5
law = dk.KelvinVoigt(1e4, 10.0, friction=dk.Friction(0.5))
if kind in ("none", "plane", "vibrated"):
    side = int(math.ceil(math.sqrt(n)))
    k = np.arange(n)
    position = np.stack([(k % side) * 2 * gap, np.full(n, R - 1e-3), (k // side) * 2 * gap], axis=1)
    vibration = dict(amplitude=(0, 2e-4, 0), frequency=5.0) if kind == "vibrated" else {}
    walls = [dk.Wall((0, 0, 0), (0, 1, 0), **vibration)] if kind != "none" else []
elif kind == "cone":  # rings up the face of a hopper, 3 R apart along its generators and round
    alpha, lift = math.radians(30.0), R - 1e-3
    rows, s = [], 10.0
    while sum(len(r) for r in rows) < n:
        d = s * math.sin(alpha) - lift * math.cos(alpha)
        h = s * math.cos(alpha) + lift * math.sin(alpha)
        count = int(2 * math.pi * d / (2 * gap))
        angle = 2 * math.pi * np.arange(count) / count
        rows.append(np.stack([d * np.cos(angle), d * np.sin(angle), np.full(count, h)], axis=1))
        s += 2 * gap
    position = np.concatenate(rows)[:n]
    walls = [dk.Cone((0, 0, 0), (0, 0, 1), alpha, upper=200.0, angular_velocity=0.5)]
else:  # a drum: rings of spheres around the axis (z), spaced 3 R along it
    big = 60.0
    ring = int(2 * math.pi * (big - R) / (2 * gap))
    k = np.arange(n)
    angle = 2 * math.pi * (k % ring) / ring
    arm = big - R + 1e-3
    position = np.stack([arm * np.cos(angle), arm * np.sin(angle), (k // ring) * 2 * gap], axis=1)
    walls = [dk.Cylinder((0, 0, 0), (0, 0, 1), big, angular_velocity=0.5 if kind == "turning" else 0.0)]
p = dk.Particles(position=position, radius=R, mass=1.0, fixed=np.ones(n, dtype=bool))  # held pressed in the wall
scene = dk.Scene(p, [law, *walls], tier=tier)
sim = dk.Simulation(scene, dk.VelocityVerlet(1e-4), notes=False)
sim.run(duration=20e-4, progress=False)  # compile or load, first lists
steps = 20
while True:
    t = time.perf_counter(); sim.run(duration=steps * 1e-4, progress=False); took = time.perf_counter() - t
    if took > seconds:
        break
    steps = int(steps * min(10.0, 1.5 * seconds / max(took, 1e-3)))
print("RESULT", json.dumps({"ns_per_step": took / steps * 1e9, "touching": int(len(scene.contacts().overlap)),
                            "tier": sim.statistics["tier"]}))
"""

KINDS = ("none", "plane", "vibrated", "cylinder", "turning", "cone")


def child(kind, tier, seconds):
    env = dict(os.environ, DEMKIT_QUIET="1")
    env.pop("DEMKIT_TIER", None)
    done = subprocess.run([sys.executable, "-c", CHILD, kind, str(tier), str(seconds)], capture_output=True,
                          text=True, env=env, timeout=1800)
    if done.returncode:
        raise SystemExit(done.stderr)
    return json.loads(next(line for line in done.stdout.splitlines() if line.startswith("RESULT"))[6:])


def main(argv):
    seconds = float(argv[argv.index("--seconds") + 1]) if "--seconds" in argv else 3.0
    rounds = int(argv[argv.index("--rounds") + 1]) if "--rounds" in argv else 3
    kinds = tuple(argv[argv.index("--kinds") + 1].split(",")) if "--kinds" in argv else KINDS
    tiers = tuple(int(t) for t in argv[argv.index("--tiers") + 1].split(",")) if "--tiers" in argv else (1, 2)
    if kinds[0] != "none" or not set(kinds) <= set(KINDS):
        raise SystemExit(f"--kinds starts with none (the baseline), then some of {KINDS[1:]}")
    results = RESULTS if (kinds, tiers) == (KINDS, (1, 2)) else RESULTS.with_name(
        f"walls_{'_'.join(kinds[1:])}_tier{''.join(map(str, tiers))}.json")
    runs = {(kind, tier): [] for kind in kinds for tier in tiers}
    touching = {}
    for tier in tiers:  # compile (or load) every scene's code once before timing
        for kind in kinds:
            touching[kind] = child(kind, tier, 0.2)["touching"]
    for r in range(rounds):
        for tier in tiers:
            for kind in (kinds if r % 2 == 0 else kinds[::-1]):
                result = child(kind, tier, seconds)
                assert result["tier"] == tier, result
                runs[kind, tier].append(result["ns_per_step"])
                print(kind, tier, round(result["ns_per_step"]), flush=True)
    rows = []
    for tier in tiers:
        base = statistics.median(runs["none", tier])
        for kind in kinds[1:]:
            step = statistics.median(runs[kind, tier])
            rows.append({"wall": kind, "tier": tier, "touching": touching[kind], "ns_per_step": step,
                         "baseline_ns_per_step": base, "ns_per_touching_sphere": (step - base) / touching[kind],
                         "runs": runs[kind, tier], "baseline_runs": runs["none", tier]})
            print(json.dumps({k: v for k, v in rows[-1].items() if "runs" not in k}), flush=True)
    results.parent.mkdir(exist_ok=True)
    results.write_text(json.dumps({"machine": {"cores": os.cpu_count(), "date": time.strftime("%Y-%m-%d %H:%M")},
                                   "spheres": 4000, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
