"""`demkit info`'s cost estimate (demkit/cost.py) against what `demkit run` then takes.

For each scene file: the estimate (stepping + outputs, one thread, compilation excluded), then
`demkit run` twice in a child process (the first fills the kernel caches; the second is timed:
its "done in" line, which holds loading the cached kernels, the steps and writing every output);
also `demkit info --measure`'s estimate (a timing of the first steps plus the model's later contacts).
Scenes: the examples' scene files and the two scenes of the issue on pictures and notes
(benchmarks/scenes/: a 600-sphere magnetic gas with Hertz contacts and friction, a 3000-sphere
frictional pour into a walled box) and issue 42's pour of 300 magnetisable spheres in a field. The target: estimate / run within [1/1.5, 1.5].

    python benchmarks/bench_info.py          # writes benchmarks/results/info_estimate.json
"""
from __future__ import annotations

import json
import platform
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import demkit as dk
from demkit import cost

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results" / "info_estimate.json"
SCENES = [ROOT / "examples" / "two_magnets" / "collision.toml", ROOT / "examples" / "magnetic_cluster" / "cluster.toml",
          HERE / "scenes" / "gas600.toml", HERE / "scenes" / "pour3000.toml", HERE / "scenes" / "steel_pour.toml"]


def estimated(path):
    loaded = dk.load_scene(path)
    out = loaded.outputs
    est = cost.estimate(loaded.scene, loaded.integrator, loaded.duration, record_every=loaded.record_every,
                        vtk_every=(out.get("vtk") or {}).get("every"),
                        animation_frames=(out.get("animation") or {}).get("max_frames") or 0)
    return est


def measured(path):
    """`demkit info --measure`'s estimate for the run (seconds): a timing of the first steps, plus the
    touching pairs the model expects later, plus the outputs."""
    done = subprocess.run([sys.executable, "-m", "demkit", "info", str(path), "--measure"],
                          capture_output=True, text=True, check=True)
    value, unit = re.search(r"-> ~([0-9.e+-]+) (s|min|h) for the run", done.stdout).groups()
    return float(value) * {"s": 1, "min": 60, "h": 3600}[unit]


def run_seconds(path, out):
    """'done in' seconds of `demkit run` (the second of two runs: warm kernel caches)."""
    for _ in range(2):
        done = subprocess.run([sys.executable, "-m", "demkit", "run", str(path), "--out", out, "--no-progress"],
                              capture_output=True, text=True, check=True)
    return float(re.search(r"done in ([0-9.]+) s", done.stdout).group(1))


def main():
    rows = []
    for path in SCENES:
        est = estimated(path)
        with tempfile.TemporaryDirectory() as out:
            seconds = run_seconds(path, out)
        ratio = est.total / seconds
        timed = measured(path)
        rows.append({"scene": str(path.relative_to(ROOT)), "estimate_s": round(est.total, 2),
                     "estimate_stepping_s": round(est.stepping, 2), "estimate_outputs_s": round(est.outputs, 2),
                     "run_s": seconds, "estimate_over_run": round(ratio, 3), "within_1_5x": 1 / 1.5 <= ratio <= 1.5,
                     "measure_estimate_s": round(timed, 2), "measure_over_run": round(timed / seconds, 3)})
        print(f"{rows[-1]['scene']:45s} estimate {est.total:7.2f} s (stepping {est.stepping:.2f} + outputs "
              f"{est.outputs:.2f})  run {seconds:7.2f} s  ratio {ratio:.2f}  (--measure {timed:.2f} s, "
              f"ratio {timed / seconds:.2f})", flush=True)
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps({"machine": platform.node(), "python": platform.python_version(),
                                   "target": "estimate / run within [1/1.5, 1.5]", "scenes": rows}, indent=1) + "\n")
    print(f"wrote {RESULTS}")
    return 0 if all(r["within_1_5x"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
