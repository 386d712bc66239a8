"""Which dipole sum for my scene: dk.compare_dipole_sums on the N = 8000 reference scene, on a polarised
variant of it, and on an open cluster. Writes benchmarks/results/dipole_sums.json and dipole_sums.png.

Scenes (prefactor A = 1, diameter 1, moments of magnitude 2, so the touching pull is 24):

* ``reference``: benchmarks/reference_scene.py (periodic cube, volume fraction 0.2, random moments);
* ``polarised``: the same positions, each moment tilted from +z by a polar angle |N(0, 20 deg)| (RMS
  20 deg) with a uniform azimuth, as in a sample magnetised along z;
* ``open``: a random cluster at volume fraction 0.15 in open space (as benchmarks/bench_fmm.py),
  random moments;
* ``slab``: the reference scene's spheres and moments in a box periodic along x and y only, open along
  z (the spheres fill a layer as thick as the box): slab sums (demkit.interactions.slab) as reference
  and candidates.

Periodic scenes: plain and switched (width r_c/4) cutoffs at 2-6 diameters, Ewald and P3M at
accuracy 1e-3 ... 1e-6, errors against Ewald at 1e-10. Open cluster: the same cutoffs, the exact
all-pairs sum and FMM at eps 1e-3, 1e-6, 1e-9 (if fmm3dpy is installed), errors against the exact
sum. One thread (NUMBA_NUM_THREADS and OMP_NUM_THREADS = 1, set before the imports); one force
evaluation timed as the least of 5 after a warm-up. The machine's load average is recorded before and
after each scene: above ~1 another process shared the 2 cores and the timings are indicative.

    python benchmarks/bench_dipole_sums.py [--quick]      (--quick: N = 1000)
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import demkit as dk  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from reference_scene import make_reference_scene, particles_and_box  # noqa: E402

MOMENT, PREFACTOR, TILT_DEGREES, OPEN_PHI = 2.0, 1.0, 20.0, 0.15
TARGETS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)


def polarised(particles, seed=5):
    """The same spheres with moments of magnitude MOMENT tilted from +z by |N(0, TILT_DEGREES)|."""
    rng = np.random.default_rng(seed)
    theta = np.abs(rng.normal(0.0, np.radians(TILT_DEGREES), len(particles)))
    phi = rng.uniform(0.0, 2.0 * np.pi, len(particles))
    dip = MOMENT * np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1)
    return dk.Particles(position=particles.position, radius=particles.radius, mass=1.0, dipole=dip)


def cluster(n, seed=1):
    box = dk.build.box_for(n, 0.5, OPEN_PHI)
    pos = dk.build.random_packing(n, 0.5, box, seed=seed)
    dip = MOMENT * dk.build.random_directions(n, seed=seed + 1)
    return dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip)


def run(name, particles, box):
    t = time.perf_counter()
    report = dk.compare_dipole_sums(particles, box, PREFACTOR, repeats=5)
    print(f"== {name}\n{report.table()}\n", flush=True)
    out = report.as_dict()
    out["wall_seconds"] = time.perf_counter() - t
    out["cheapest"] = {f"{a:g}": (lambda r: None if r is None else dict(label=r.label, ms=1e3 * r.seconds,
                                                                          cpu_ms=1e3 * r.cpu_seconds,
                                                                          force_error=r.force_error))(
        report.cheapest(a)) for a in TARGETS}
    return report, out


def main(argv=None):
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--quick", action="store_true")
    opts = args.parse_args(argv)
    n = 1000 if opts.quick else 8000
    particles, box = particles_and_box(make_reference_scene(n, moment=MOMENT))
    polar = polarised(particles)
    cosines = polar.dipole[:, 2] / MOMENT
    slab = dk.Box(box.size, periodic=[True, True, False])
    scenes = [("reference", particles, box), ("polarised", polar, box), ("open", cluster(n), None),
              ("slab", particles, slab)]
    load = os.getloadavg()
    reports, result = [], dict(
        machine=dict(platform=platform.platform(), date=time.strftime("%Y-%m-%d %H:%M"), cores=os.cpu_count(),
                     threads=1, load_average_1_5_15_min_at_start=list(load)),
        code=_code(), n=n, prefactor=PREFACTOR, moment=MOMENT,
        polarised=dict(tilt_degrees_rms=TILT_DEGREES, mean_cos_to_z=float(cosines.mean()),
                       magnetisation_per_sphere=float(np.linalg.norm(polar.dipole.mean(0)))),
        fmm=_has_fmm(), scenes={})
    for name, p, b in scenes:
        report, out = run(name, p, b)
        reports.append((name, report))
        result["scenes"][name] = out
    result["machine"]["load_average_1_5_15_min_at_end"] = list(os.getloadavg())
    busy = max([load[0]] + [max(s["load_before_after"]) for s in result["scenes"].values()])
    result["note"] = (f"1-minute load average up to {busy:.2f} on {os.cpu_count()} cores during the run: "
                      + ("other processes shared the machine (another engineer's work), so timings are indicative "
                         "(each the least of 5 evaluations, which filters most of it)" if busy > 1.0 else
                         "no other load worth naming"))
    path = HERE / "results" / ("dipole_sums_quick.json" if opts.quick else "dipole_sums.json")
    path.write_text(json.dumps(result, indent=1) + "\n")
    plot(reports, n, path.with_suffix(".png"))
    print("written", path, "and", path.with_suffix(".png"))


def _code():
    """The commit measured and whether demkit/ differs from it (git, if this is a work tree)."""
    import subprocess
    def git(*a):
        return subprocess.run(["git", *a], cwd=HERE, capture_output=True, text=True).stdout.strip()
    try:
        return dict(commit=git("rev-parse", "--short", "HEAD"), demkit=str(Path(dk.__file__).parent),
                    demkit_files_differing_from_commit=git("status", "--short", "--", ":/demkit").splitlines())
    except OSError:
        return dict(commit=None)


def _has_fmm():
    try:
        import fmm3dpy  # noqa: F401
        return True
    except ImportError:
        return False


def plot(reports, n, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(reports), figsize=(5.2 * len(reports), 4.4))
    titles = dict(reference=f"N = {n}, periodic, random moments", polarised=f"N = {n}, periodic, polarised along z",
                  open=f"N = {n}, open cluster", slab=f"N = {n}, slab periodic along x and y")
    for ax, (name, report) in zip(axes, reports):
        report.plot(None, title=f"{titles[name]}\nagainst {report.reference['label']}", ax=ax)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
