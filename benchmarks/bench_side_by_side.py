"""Stepping speed of this tree against another revision, side by side: did a change cost speed?

    python3 benchmarks/bench_side_by_side.py <revision> [scene,...] [--rounds N] [--seconds S] [--out NAME]

For each scene of benchmarks/bench_latency.py (default: the paper's two magnets, the 600-sphere magnetic
gas with Hertz contacts and friction, the 3000-sphere frictional pour onto walls), on tier 1 and on
tier 2, a fresh process of each tree steps for about S seconds after warming up (compiling excluded),
the two trees taking turns round after round so that a slow spell of the machine falls on both. The
revision is checked out in a temporary git worktree; the two trees' compiled modules share one cache
(their names differ by demkit's source fingerprint): DEMKIT_CACHE_DIR when set, else a temporary one. Medians and every run go to
benchmarks/results/side_by_side.json (``--out NAME``: benchmarks/results/NAME.json). This machine's runs of the same code differ by 10-15 %.
"""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results" / "side_by_side.json"
sys.path.insert(0, str(HERE))
import bench_latency  # noqa: E402  (its scenes and its speed child)

DEFAULT_SCENES = ("two_magnets", "gas600", "pour3000")


def speed(tree, scene, tier, seconds, cache):
    """Steps per second of ``scene`` on ``tier`` in a fresh process importing demkit from ``tree``."""
    env = dict(os.environ, PYTHONPATH=str(tree), DEMKIT_CACHE_DIR=str(cache), DEMKIT_QUIET="1")
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("DEMKIT_TIER", None)
    code = bench_latency.SPEED_CHILD.format(scene=textwrap.dedent(bench_latency.SCENES[scene]), tier=tier,
                                            seconds=seconds)
    return bench_latency._child(code, env)["steps_per_s"]


def main(argv):
    flags = {k for k, a in enumerate(argv) if a.startswith("--")}
    args = [a for k, a in enumerate(argv) if k not in flags and k - 1 not in flags]
    if not args:
        raise SystemExit(__doc__)
    revision = args[0]
    scenes = args[1].split(",") if len(args) > 1 else list(DEFAULT_SCENES)
    unknown = [s for s in scenes if s not in bench_latency.SCENES]
    if unknown:
        raise SystemExit(f"unknown scenes {unknown}: use names of bench_latency.SCENES")
    rounds = int(argv[argv.index("--rounds") + 1]) if "--rounds" in argv else 3
    seconds = float(argv[argv.index("--seconds") + 1]) if "--seconds" in argv else 3.0
    base_commit = subprocess.run(["git", "rev-parse", revision], cwd=ROOT, capture_output=True, text=True,
                                 check=True).stdout.strip()
    this_commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                                 check=True).stdout.strip()
    with tempfile.TemporaryDirectory(prefix="demkit-side-by-side-") as tmp:
        worktree = Path(tmp) / "base"
        subprocess.run(["git", "worktree", "add", "--detach", str(worktree), base_commit], cwd=ROOT,
                       capture_output=True, check=True)
        try:
            trees = {"this": ROOT, "base": worktree}
            runs = {}
            for r in range(rounds):
                for scene in scenes:
                    for tier in (1, 2):
                        for name in (("base", "this") if r % 2 == 0 else ("this", "base")):
                            cache = os.environ.get("DEMKIT_CACHE_DIR") or Path(tmp) / "cache"
                            value = speed(trees[name], scene, tier, seconds, cache)
                            runs.setdefault(f"{scene} tier {tier}", {}).setdefault(name, []).append(value)
                            print(f"round {r + 1}: {scene} tier {tier} {name}: {value:,.0f} steps/s", flush=True)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(worktree)], cwd=ROOT, capture_output=True)
    rows = []
    for key, both in runs.items():
        row = {"what": key, "this_median": statistics.median(both["this"]),
               "base_median": statistics.median(both["base"]), "this_runs": both["this"], "base_runs": both["base"]}
        row["ratio_this_to_base"] = row["this_median"] / row["base_median"]
        rows.append(row)
        print(f"{key}: this {row['this_median']:,.0f}, base {row['base_median']:,.0f} steps/s, "
              f"ratio {row['ratio_this_to_base']:.3f}")
    result = {"machine": {"cores": os.cpu_count(), "date": time.strftime("%Y-%m-%d %H:%M")}, "this": this_commit,
              "base": base_commit, "rounds": rounds, "seconds": seconds, "rows": rows}
    out = RESULTS.with_name(argv[argv.index("--out") + 1] + ".json") if "--out" in argv else RESULTS
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1:])
