"""What a scene with functions of your own costs before its first step, and how fast it steps on each tier.

Writes benchmarks/results/plugins.json. Scenes (benchmarks/bench_latency.py, ``SCENES``): ``plugin``, the
guide's SoftRepulsion beside a dipole and gravity, three spheres in open space; ``plugin_lists``, 600
spheres in a periodic box with a cut-off dipole and SoftRepulsion (neighbour lists). The plug-in lives in
an importable module, as the guide advises (cached on disk).

For each scene, in fresh processes with demkit's install-wide code cached (warmed by another scene of
the same kind, as bench_latency's ``tiers`` part does), CPU s from ``import demkit`` to the first step:
``new_combination`` (the plug-in never compiled before: tier 1 compiles its adapters,
demkit.engine.own_laws), ``cached`` (the same again), ``tier2_first_step`` (then on tier 2, its own pieces).
Then steps/s of ``plugin_lists`` on tier 1 and tier 2 (three alternating rounds, medians).

Usage: python benchmarks/bench_plugins.py [--against=<git revision>]  (the same first-step figures for
that revision's code, in a tree of its own: before and after side by side)
"""
from __future__ import annotations

import json
import os
import shutil
import statistics
import sys
import tempfile
import textwrap
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_latency as latency  # noqa: E402

RESULTS = latency.HERE / "results" / "plugins.json"


def first_steps(tree, tmp):
    cache = Path(tmp) / f"kernels-{Path(tree).name}"
    env = dict(os.environ, DEMKIT_CACHE_DIR=str(cache), DEMKIT_QUIET="1", PYTHONPATH=str(tree))
    env.pop("NUMBA_CACHE_DIR", None)
    latency._empty_caches(cache, tree)
    rows = []
    for name in ("plugin", "plugin_lists"):
        source, kind, integrator = latency.TIER_SCENES[name]
        warm = latency.COMPILE_CHILD.format(
            scene=textwrap.dedent(latency.WARM_GENERIC[kind].format(integrator=integrator)))
        latency._child(warm + latency.WARM_PIECES, env)
        child = latency.COMPILE_CHILD.format(scene=latency._scene_source(source, tmp))
        for what, extra in (("new_combination", {}), ("cached", {}), ("tier2_first_step", {"DEMKIT_TIER": "2"})):
            rows.append({"what": what, "scene": name, **latency._child(child, dict(env, **extra))})
            print(json.dumps(rows[-1]), flush=True)
    return rows, env


def main(argv):
    against = next((a.split("=", 1)[1] for a in argv if a.startswith("--against=")), None)
    tmp = tempfile.mkdtemp(prefix="demkit-plugins-")
    out = {"machine": {"cores": os.cpu_count(), "date": time.strftime("%Y-%m-%d %H:%M")}}
    try:
        out["this"], env = first_steps(latency.ROOT, tmp)
        row = {"scene": "plugin_lists", "tier1_runs": [], "tier2_runs": []}
        for r in range(3):
            for tier in ((1, 2) if r % 2 == 0 else (2, 1)):
                res = latency._child(latency.SPEED_CHILD.format(scene=latency._scene_source("plugin_lists", tmp),
                                                                tier=tier, seconds=3.0), env)
                row[f"tier{tier}_runs"].append(round(res["steps_per_s"], 1))
        row["tier1"], row["tier2"] = statistics.median(row["tier1_runs"]), statistics.median(row["tier2_runs"])
        row["ratio_tier1_to_tier2"] = row["tier1"] / row["tier2"]
        out["speed"] = row
        print(json.dumps(row), flush=True)
        if against:
            out[f"against_{against}"] = first_steps(latency._export(against, tmp), tmp)[0]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    RESULTS.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
