"""Friction speed, side by side with LAMMPS in one run. Writes benchmarks/results/friction.json.

The N = 8000 reference scene (benchmarks/reference_scene.py: periodic, phi = 0.2, dipoles of 2,
kT = 1), velocity Verlet dt = 0.001, skin 0.3, four physics (benchmarks/lammps/in.reference):

    full          Dipole(1, cutoff 4) + KelvinVoigt(1000, 1.5, friction)
    nofric        Dipole(1, cutoff 4) + KelvinVoigt(1000, 1.5)
    nodip         KelvinVoigt(1000, 1.5, friction)       (spheres without dipoles)
    nodip_nofric  KelvinVoigt(1000, 1.5)

friction = Friction(0.5, stiffness=2/7 * 1000, damping=0.5 * 1.5, slip_radius="full"), LAMMPS'
``tangential linear_history 285.7 0.5 0.5``. Two starting states:

* ``built``: the scene as built (a gas without contacts; contacts form as it runs), the protocol
  of the issue's LAMMPS figures;
* ``settled``: the state after 2000 LAMMPS steps of the full physics (chains: 9113 contacts,
  1.1 per sphere), where friction has work to do. Without dipoles the chains fall apart within a
  few hundred steps, so ``nodip`` and ``nodip_nofric`` run 300 steps from it (twice as many repeats).

Parts (all by default; name some to run only those):

* ``speed``: each physics, state and core count (1, 2): demkit in a fresh process (1 core: the
  serial kernels, NUMBA_NUM_THREADS=1; 2 cores: threads, NUMBA_NUM_THREADS=2), a new Scene from
  the state for every repeat, against LAMMPS (1 rank, ``mpirun -np 2``) on the same data file; best
  of ``--repeats``. Friction's cost is full/nofric and nodip/nodip_nofric in each code.
* ``unused``: what friction's presence in the code costs scenes that do not use it: ``nofric`` and
  ``nodip_nofric`` with this tree against the tree before friction existed (commit c4f06a3, taken
  with ``git archive``), runs alternating between the two, best of ``--repeats`` (and the ratio of
  the medians).
* ``profile``: where a friction step's time goes: the contact kernel alone (forces only, no
  integration) with and without friction on the settled state.

Run it alone on the machine (2 cores: anything else running slows the 2-core figures most, and
demkit's threads wait for each other). Before every measurement it waits until other processes use
less than a tenth of a core (``--no-wait`` to skip).

    python benchmarks/bench_friction.py [speed] [unused] [profile] [--repeats 3] [--quick]
"""
from __future__ import annotations

import argparse
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
sys.path.insert(0, str(HERE))
RESULTS = HERE / "results" / "friction.json"
DECK = HERE / "lammps" / "in.reference"
N = 8000
MODELS = ("full", "nofric", "nodip", "nodip_nofric")
#: timed steps per run: a few seconds each on one core. Without dipoles the settled chains come
#: apart within a few hundred steps, so there the runs are short, to time friction among contacts
STEPS = {"full": 1000, "nofric": 1000, "nodip": 8000, "nodip_nofric": 8000}
STEPS_SETTLED = {"full": 1000, "nofric": 1000, "nodip": 300, "nodip_nofric": 300}
SETTLE_STEPS = 2000
BEFORE_FRICTION = "c4f06a3"  # the last commit before Friction (255a0e8)

# one demkit measurement in a fresh process (threads are per process)
CHILD = textwrap.dedent("""
    import json, sys, time
    sys.path.insert(0, {here!r})
    import numpy as np, demkit as dk
    from reference_scene import particles_and_box
    with np.load({npz!r}) as f:
        state = {{k: f[k] for k in f.files}}
    state["L"], state["d"], state["m"] = float(state["L"]), float(state["d"]), float(state["m"])
    model = {model!r}

    def scene():
        p, box = particles_and_box(state)
        if model.startswith("nodip"):
            p = dk.Particles(position=p.position, velocity=p.velocity, radius=p.radius, mass=p.mass,
                             angular_velocity=p.angular_velocity if model == "nodip" else None)
        extra = {{}}  # (no friction keyword at all: the tree before friction runs this too)
        if model in ("full", "nodip"):
            extra["friction"] = dk.Friction(0.5, stiffness=2.0 / 7.0 * 1000.0, damping=0.75, slip_radius="full")
        contact = dk.KelvinVoigt(stiffness=1000.0, damping=1.5, **extra)
        laws = [contact] if model.startswith("nodip") else [dk.Dipole(prefactor=1.0, cutoff=4.0), contact]
        return dk.Scene(p, laws, box=box, skin=0.3)

    dk.Simulation(scene(), dk.VelocityVerlet(dt=1e-3)).run(duration=0.02)  # compile or load the kernels
    best = None
    for _ in range({repeats}):
        sim = dk.Simulation(scene(), dk.VelocityVerlet(dt=1e-3))
        sim.run(duration={steps} * 1e-3)
        st = sim.statistics
        if best is None or st["particle_steps_per_second"] > best["particle_steps_per_second"]:
            best = st
    best["parallel"] = sim.scene.parallel
    print("RESULT", json.dumps(best, default=float))
""")


def busy_cores(seconds=3.0):
    """Cores kept busy by other processes over ``seconds`` (this process sleeps meanwhile)."""
    def sample():
        fields = [float(v) for v in Path("/proc/stat").read_text().split("\n")[0].split()[1:]]
        return sum(fields), fields[3] + fields[4]  # total, idle + iowait
    t0, i0 = sample()
    time.sleep(seconds)
    t1, i1 = sample()
    return (os.cpu_count() or 1) * (1.0 - (i1 - i0) / max(t1 - t0, 1e-9))


def wait_quiet(limit=0.1, patience=3600.0):
    """Wait (at most ``patience`` s) until other processes use less than ``limit`` of a core; returns
    the busy fraction seen last. Off with --no-wait. Does nothing without /proc/stat."""
    if not WAIT or not Path("/proc/stat").exists():
        return None
    end = time.monotonic() + patience
    busy = busy_cores()
    while busy > limit and time.monotonic() < end:
        time.sleep(10.0)
        busy = busy_cores()
    return busy


WAIT = True


def demkit_run(npz, model, cores, steps, repeats, tree=ROOT):
    """Best statistics of ``repeats`` runs of ``steps`` steps, demkit from ``tree`` on ``cores`` cores."""
    code = CHILD.format(here=str(HERE), npz=str(npz), model=model, steps=steps, repeats=repeats)
    env = dict(os.environ, NUMBA_NUM_THREADS=str(cores), PYTHONPATH=str(tree))
    wait_quiet()
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tree)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")][-1]
    return json.loads(line[len("RESULT "):])


def lammps_rate(data, model, cores, steps, repeats):
    from lammps_run import lammps_available, run_deck
    if not lammps_available(cores):
        return None
    rates = []
    for _ in range(repeats):
        wait_quiet()
        rates.append(run_deck(DECK, {"data": str(data), "model": model, "nsteps": steps}, ranks=cores)["atom_steps_per_s"])
    return max(rates)


def states(folder):
    """{"built": (npz, data), "settled": (npz, data)} and the contacts of each."""
    import numpy as np
    from scipy.spatial import cKDTree

    from lammps_run import run_deck
    from reference_scene import write_lammps_data, write_reference_scene
    folder = Path(folder)
    scene, npz, data = write_reference_scene(N, folder)
    out = {"built": (npz, data)}
    dump = folder / "settle.dump"
    run_deck(DECK, {"data": str(data), "model": "full", "nsteps": SETTLE_STEPS, "dump": str(dump),
                    "dumpevery": SETTLE_STEPS}, workdir=folder / "settle")
    lines = dump.read_text().splitlines()
    n = int(lines[3])
    last = lines[-n:]
    rows = np.array(" ".join(last).split(), dtype=float).reshape(n, -1)
    rows = rows[np.argsort(rows[:, 0])]
    settled = dict(scene, x=rows[:, 1:4] % scene["L"], v=rows[:, 4:7].copy(), mu=rows[:, 13:16].copy(),
                   omega=rows[:, 16:19].copy())
    npz2, data2 = folder / "settled.npz", folder / "settled.data"
    np.savez(npz2, **settled)
    write_lammps_data(settled, data2, comment=f"after {SETTLE_STEPS} steps of the full model")
    out["settled"] = (npz2, data2)
    contacts = {name: len(cKDTree(s["x"], boxsize=s["L"]).query_pairs(1.0)) for name, s in
                (("built", scene), ("settled", settled))}
    return out, contacts


def part_speed(files, repeats, quick, models=MODELS):
    rows = []
    for state, (npz, data) in files.items():
        for model in models:
            for cores in (1, 2):
                steps = (STEPS_SETTLED if state == "settled" else STEPS)[model] // (5 if quick else 1)
                runs = repeats if steps >= 1000 else 2 * repeats  # short runs: more of them
                ours = demkit_run(npz, model, cores, steps, runs)
                theirs = lammps_rate(data, model, cores, steps, runs)
                row = {"state": state, "model": model, "cores": cores, "steps": steps,
                       "demkit": ours["particle_steps_per_second"], "lammps": theirs,
                       "ratio": None if theirs is None else ours["particle_steps_per_second"] / theirs,
                       "demkit_threads": ours["threads"], "demkit_parallel": ours["parallel"],
                       "steps_per_list_build": ours["steps_per_build"],
                       "contact_list_pairs": [g["pairs"] for g in ours["lists"] if "KelvinVoigt" in g["interactions"]]}
                rows.append(row)
                print(json.dumps(row), flush=True)
    return rows


def friction_costs(rows):
    """Friction's cost (with / without - 1, in time per step) in each code, state and core count."""
    speed = {(r["state"], r["model"], r["cores"]): r for r in rows}
    out = []
    for (state, model, cores), r in speed.items():
        if model not in ("full", "nodip"):
            continue
        base = speed.get((state, "nofric" if model == "full" else "nodip_nofric", cores))
        if base is None:
            continue
        entry = {"state": state, "physics": model, "cores": cores,
                 "demkit_cost": base["demkit"] / r["demkit"] - 1.0}
        if r["lammps"] and base["lammps"]:
            entry["lammps_cost"] = base["lammps"] / r["lammps"] - 1.0
        out.append(entry)
    return out


def targets(results):
    """The issue's targets against the figures measured (None where a part was not run)."""
    speed = {(r["state"], r["model"], r["cores"]): r for r in results.get("speed", [])}
    out = {}
    for cores in (1, 2):
        full = [speed[k]["ratio"] for k in speed if k[1] == "full" and k[2] == cores and speed[k]["ratio"]]
        nodip = [speed[k]["ratio"] for k in speed if k[1] == "nodip" and k[2] == cores and speed[k]["ratio"]]
        out[f"full >= 2x LAMMPS, {cores} core(s)"] = {"measured": full, "met": bool(full) and min(full) >= 2.0}
        out[f"nodip >= 1x LAMMPS, {cores} core(s)"] = {"measured": nodip, "met": bool(nodip) and min(nodip) >= 1.0}
    costs = results.get("friction_cost", [])
    if costs:
        worse = [c for c in costs if "lammps_cost" in c and c["demkit_cost"] > c["lammps_cost"]]
        out["friction costs no more than in LAMMPS"] = {
            "measured": [{k: c[k] for k in ("state", "physics", "cores", "demkit_cost", "lammps_cost") if k in c}
                         for c in costs], "met": not worse}
    unused = results.get("unused", [])
    if unused:
        out["no friction: <= 2 % slower than before friction"] = {
            "measured": {f"{u['model']} {u['cores']}": {"best": u["cost"], "median": u.get("cost_of_medians")}
                         for u in unused},
            "met": max(u["cost"] for u in unused) <= 0.02}
    return out


def part_unused(files, repeats, quick):
    """nofric and nodip_nofric: this tree against the tree before friction, alternating."""
    npz = files["built"][0]
    rows = []
    with tempfile.TemporaryDirectory(prefix="demkit-before-friction-") as old:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", BEFORE_FRICTION], check=True, capture_output=True)
        subprocess.run(["tar", "-x", "-C", old], input=archive.stdout, check=True)
        for model in ("nofric", "nodip_nofric"):
            for cores in (1, 2):
                steps = STEPS[model] // (5 if quick else 1)
                now, before = [], []
                for _ in range(repeats):  # alternate, one run each, so that drifts hit both
                    now.append(demkit_run(npz, model, cores, steps, 1)["particle_steps_per_second"])
                    before.append(demkit_run(npz, model, cores, steps, 1, tree=Path(old))["particle_steps_per_second"])
                row = {"model": model, "cores": cores, "now": max(now), "before_friction": max(before),
                       "cost": max(before) / max(now) - 1.0,
                       "cost_of_medians": statistics.median(before) / statistics.median(now) - 1.0,
                       "all_now": now, "all_before": before}
                rows.append(row)
                print(json.dumps(row), flush=True)
    return rows


PROFILE_CHILD = textwrap.dedent("""
    import json, sys, time
    sys.path.insert(0, {here!r})
    import numpy as np, demkit as dk
    from reference_scene import particles_and_box
    with np.load({npz!r}) as f:
        state = {{k: f[k] for k in f.files}}
    state["L"], state["d"], state["m"] = float(state["L"]), float(state["d"]), float(state["m"])
    out = {{}}
    for name, friction in (("contact", None),
                           ("contact+friction", dk.Friction(0.5, stiffness=2000.0 / 7.0, damping=0.75,
                                                             slip_radius="full"))):
        p, box = particles_and_box(state)
        p = dk.Particles(position=p.position, velocity=p.velocity, radius=p.radius, mass=p.mass,
                         angular_velocity=p.angular_velocity)
        scene = dk.Scene(p, [dk.KelvinVoigt(1000.0, 1.5, friction=friction)], box=box, skin=0.3)
        kern, s = scene.kernels, scene.state
        kern.forces_of(s, False)
        best = 1e9
        for _ in range(7):
            t = time.perf_counter()
            for _ in range(200):
                kern.forces_of(s, False)
            best = min(best, (time.perf_counter() - t) / 200)
        out[name] = best
        out[name + "_pairs"] = [g["pairs"] for g in scene.neighbour_lists()]
    print("RESULT", json.dumps(out))
""")


def part_profile(files, cores=1):
    """Seconds per force evaluation (pair loop over the contact list, no integration), settled state."""
    code = PROFILE_CHILD.format(here=str(HERE), npz=str(files["settled"][0]))
    env = dict(os.environ, NUMBA_NUM_THREADS=str(cores), PYTHONPATH=str(ROOT))
    wait_quiet()
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    row = json.loads([ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")][-1][7:])
    row["friction_share_of_contact_forces"] = 1.0 - row["contact"] / row["contact+friction"]
    row["cores"] = cores
    print(json.dumps(row), flush=True)
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("parts", nargs="*", default=["speed", "unused", "profile"])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--no-wait", action="store_true", help="do not wait for a quiet machine before each run")
    a = ap.parse_args(argv)
    global WAIT
    WAIT = not a.no_wait
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    with tempfile.TemporaryDirectory(prefix="demkit-friction-") as folder:
        files, contacts = states(folder)
        results["contacts"] = contacts
        for part in a.parts:
            t = time.perf_counter()
            load = os.getloadavg()[0]
            if part == "speed":
                results["speed"] = part_speed(files, a.repeats, a.quick, a.models.split(","))
                results["friction_cost"] = friction_costs(results["speed"])
            elif part == "unused":
                results["unused"] = part_unused(files, a.repeats, a.quick)
            elif part == "profile":
                results["profile"] = [part_profile(files, 1), part_profile(files, 2)]
            else:
                raise SystemExit(f"unknown part {part!r}")
            results.setdefault("load_average_at_start", {})[part] = load
            print(f"{part}: {time.perf_counter() - t:.0f} s", flush=True)
    results["targets"] = targets(results)
    results["machine"] = f"{os.uname().machine}, {os.cpu_count()} cores"
    results["date"] = time.strftime("%Y-%m-%d")
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=2, default=float) + "\n")


if __name__ == "__main__":
    main()
