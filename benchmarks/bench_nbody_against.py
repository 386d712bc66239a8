"""The N = 8000 reference scene (benchmarks/bench_nbody.py's speed part) stepped by this tree on tier 2 and
by another revision of demkit, side by side: did the two tiers cost the long runs anything?

    python3 benchmarks/bench_nbody_against.py <revision> [model[:threads] ...]

Default models: full:1 full:2 nodip_nofric:1 nodip_nofric:2. For each, three rounds of a fresh process of
each tree taking turns (the order swapped every round; best of three runs in each process, 1000 steps with
dipoles, 5000 without, from the data file as LAMMPS' runs start); the figure kept is the median of the
rounds' ratios. Writes benchmarks/results/nbody_against.json (one entry per revision and model). A revision
older than the tiers (before 2026-11-28) has no ``tier`` argument: its scenes run its fused modules.
"""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results" / "nbody_against.json"
sys.path.insert(0, str(HERE))
import bench_nbody  # noqa: E402
from reference_scene import write_reference_scene  # noqa: E402


def rate(tree, cache, model, threads, folder, tier):
    steps = 5 * bench_nbody.STEPS if model.startswith("nodip") else bench_nbody.STEPS
    code = bench_nbody.CHILD.format(here=str(HERE), threads=threads, n=bench_nbody.N_REFERENCE, folder=folder,
                                    model=model, steps=steps, repeats=3, tier=tier)
    if tier is None:  # (a revision without tiers)
        code = code.replace(", tier=None)", ")")
    env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_NUM_THREADS=str(max(2, threads)), DEMKIT_CACHE_DIR=str(cache))
    env.pop("DEMKIT_TIER", None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    if out.returncode:
        raise RuntimeError(out.stderr[-3000:])
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")][-1]
    return json.loads(line[len("RESULT "):])["particle_steps_per_second"]


def main(argv):
    revision = argv[0]
    runs = [(a.split(":")[0], int(a.split(":")[1]) if ":" in a else 1) for a in argv[1:]] or \
        [("full", 1), ("full", 2), ("nodip_nofric", 1), ("nodip_nofric", 2)]
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    with tempfile.TemporaryDirectory() as tmp:
        other = Path(tmp) / "other"
        other.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", revision, "demkit"], capture_output=True,
                                 check=True)
        subprocess.run(["tar", "-x", "-C", str(other)], input=archive.stdout, check=True)
        old_tiers = "tier=None" in (other / "demkit" / "scene.py").read_text()
        write_reference_scene(bench_nbody.N_REFERENCE, tmp)
        trees = {revision: (other, 2 if old_tiers else None), "this": (ROOT, 2)}
        for model, threads in runs:
            rates = {name: [] for name in trees}
            for r in range(3):
                for name in (list(trees) if r % 2 == 0 else list(trees)[::-1]):
                    tree, tier = trees[name]
                    rates[name].append(rate(tree, Path(tmp) / f"cache_{name}", model, threads, tmp, tier))
            ratio = statistics.median(a / b for a, b in zip(rates["this"], rates[revision]))
            row = {"model": model, "threads": threads, "rates": rates, "ratio_this_to_revision": ratio,
                   "measured": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                   "this": subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                                          capture_output=True, text=True).stdout.strip()}
            print(json.dumps(row), flush=True)
            results.setdefault(revision, {})[f"{model}:{threads}"] = row
    RESULTS.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
