"""Replicate the seed paper (Bartz & Shaw, non-central collisions of spherical magnets) end to end.

    python examples/two_magnets/replicate.py [--quick] [--workers N] [--scheduler ADDR] [--out DIR]

Runs every simulation with :func:`demkit.sweep` (one process per core, or a Dask cluster with
``--scheduler local`` or ``tcp://host:8786``), prints a paper-vs-demkit summary and writes, under DIR
(default: the repository root),
    docs/figures/two_magnets/*.png   figures
    docs/data/two_magnets/*.csv      every run (runs.csv) and each result table
    docs/data/two_magnets/summary.json
    docs/two_magnets.md              the report (numbers and tables generated, prose from
                                     examples/two_magnets/report_template.md)
``--quick`` is a reduced replication for tests (3 impact parameters, one threshold).
The sweeps' own tables (one row per simulation job, with its wall time) and the timings go to
DIR/examples/two_magnets/output/ (not tracked), so the tracked files change only when results do.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time
import types
from pathlib import Path

import numpy as np

import demkit as dk
from demkit.two_magnets import analysis, capture, fits
from demkit.two_magnets import TwoMagnets

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
import replication_figures as figures  # noqa: E402  (examples/two_magnets/replication_figures.py)
import replication_report as report  # noqa: E402  (examples/two_magnets/replication_report.py)

#: what the paper reports (dimensionless unless stated)
PAPER = {"beta": 2.80, "beta_power_law": 2.00, "b_max": 4.65, "compression": 1e-5,
         "speed": 5.78e-3, "x_c": 7.2e-4, "t_c": 3.6e-6}
#: SI scales: the paper's rounded ones (R~ = 6.94 <-> R = 5 mm, v = 5.78e-3 <-> 1.16 m/s) and demkit's
PAPER_SCALES = dk.units.PaperUnits(mass=4e-3, length=PAPER["x_c"], time=PAPER["t_c"], radius=5e-3)
DEMKIT_SCALES = dk.units.paper_magnets()
INTEGRATORS = {"euler_cromer": dk.EulerCromer, "velocity_verlet": dk.VelocityVerlet}
ENERGY_CASE = {"b_over_R": 4.5, "speed": 4.3e-3}


# ---- tasks (module-level functions so that worker processes can run them) ------------------------
def sweep_point(model, b_over_R, revolutions=5):
    """One run of the omega_f(b/R) sweep at the paper's settings -> a dict (one CSV row)."""
    setup = TwoMagnets(b_over_R, model=model)
    trajectory = setup.run(revolutions=revolutions)
    row = {"kind": "sweep", "model": model, "b_over_R": b_over_R, "speed": setup.speed,
           "x0": setup.x0, "outcome": analysis.outcome(trajectory, prefactor=setup.prefactor)}
    _, r, reach = analysis._separation(trajectory, (0, 1))
    if (r <= reach).any():
        row["first_contact"] = float(trajectory.time[np.argmax(r <= reach)])
    if row["outcome"] == "stick":
        state = analysis.final_state(trajectory, revolutions)
        omega = state.omega
        # K_f from omega as the paper does: a rigid rotation with the conserved L = m v b has
        # K_f = L omega / 2 (= I omega^2 / 2 with I = L / omega), so K_f/K_i = b omega / (2 v)
        row.update(omega=omega, sigma=state.sigma,
                   beta_point=setup.speed * setup.b / (omega * setup.radius ** 2),
                   k_ratio_from_omega=setup.b * omega / (2 * setup.speed),
                   k_ratio_measured=state.kinetic / setup.initial_kinetic,
                   compression=state.compression,
                   compression_static=static_compression(setup, omega),
                   settle_time=state.settle_time, window_end=state.end_time,
                   omega_rad_s=PAPER_SCALES.to_si(omega, "angular_velocity"),
                   omega_rad_s_demkit_scales=DEMKIT_SCALES.to_si(omega, "angular_velocity"))
        row["rev_s"] = row["omega_rad_s"] / (2 * math.pi)
        row["spin_fraction_at_contact"] = spin_fraction_at_contact(trajectory, setup)
    row["sim_time"] = float(trajectory.time[-1])
    return row


def spin_fraction_at_contact(trajectory, setup):
    """Share of the angular momentum carried by the spins when the spheres first touch."""
    if trajectory.angular_velocity is None:  # no torque, no spin (power-law model)
        return 0.0
    _, r, _ = analysis._separation(trajectory, (0, 1))
    k = int(np.argmax(r <= 2 * setup.radius))
    spin = (trajectory.inertia[:, None] * trajectory.angular_velocity[k]).sum(axis=0)
    total = trajectory.angular_momentum[k]
    return float(spin @ total / (total @ total))


def static_compression(setup, omega):
    """(2R - r)/2R from the force balance of a rigid, head-to-tail barbell turning at omega:
    k delta = 6 A / (2R)^4 - m omega^2 R (attraction minus the centripetal force of each sphere)."""
    reach = 2 * setup.radius
    force = 6 * setup.prefactor / reach ** 4 - setup.mass * omega ** 2 * setup.radius
    return force / setup.stiffness / reach


def energy_series(dipoles, revolutions=5, keep_every=10):
    """Energies over a whole run at b/R = 4.5, v = 4.3e-3 (the paper's energy figures)."""
    setup = TwoMagnets(ENERGY_CASE["b_over_R"], speed=ENERGY_CASE["speed"], dipoles=dipoles)
    trajectory = setup.run(revolutions=revolutions)
    e = trajectory.energy
    e0 = float(e["total"][0])
    state = analysis.final_state(trajectory, revolutions)
    series = {"time": trajectory.time, "kinetic": (e["kinetic"] + e["rotational"]) / e0,
              "magnetic": e["magnetic"] / e0, "elastic": e["contact"] / e0,
              "total": e["total"] / e0, "dissipated": e["dissipated"] / e0}
    _, r, _ = analysis._separation(trajectory, (0, 1))
    first_contact = float(trajectory.time[np.argmax(r <= 2 * setup.radius)])
    zoom = (trajectory.time >= state.end_time - 4000) & (trajectory.time <= state.end_time)
    window = (trajectory.time >= state.settle_time) & (trajectory.time <= state.end_time)
    d = trajectory.position[window, 1] - trajectory.position[window, 0]
    n = d / np.linalg.norm(d, axis=1)[:, None]
    m1, m2 = trajectory.dipole[window, 0], trajectory.dipole[window, 1]
    return {"kind": "energy", "dipoles": dipoles, "initial_energy": e0,
            "initial_kinetic": setup.initial_kinetic, "first_contact": first_contact,
            "settle_time": state.settle_time, "final_total": state.total / e0,
            "final_kinetic": state.kinetic / e0, "omega": state.omega, "sigma": state.sigma,
            "final_magnetic": float(e["magnetic"][window].mean() / e0),
            "final_m1_dot_m2": float((m1 * m2).sum(axis=1).mean()),
            "final_abs_m_dot_n": float(0.5 * (np.abs((m1 * n).sum(axis=1)) + np.abs((m2 * n).sum(axis=1))).mean()),
            "kinetic_range": [float(series["kinetic"][window].min()), float(series["kinetic"][window].max())],
            "series": {k: v[::keep_every] for k, v in series.items()},
            "zoom": {k: v[zoom] for k, v in series.items()}}


def threshold(name, group, setup_kwargs, lo, hi, tol, dt=0.01, integrator="euler_cromer"):
    """Largest sticking b/R by bisection (see demkit.two_magnets.capture.capture_threshold)."""
    setup = TwoMagnets(5.0, **setup_kwargs)
    found = capture.capture_threshold(setup, lo, hi, tol=tol, dt=dt, integrator=INTEGRATORS[integrator])
    central = capture.central_capture(setup.speed, setup.radius, setup.x0, alpha=2 * setup.prefactor,
                                      mass=setup.mass)
    return {"kind": "threshold", "name": name, "group": group, "model": setup.model,
            "speed": setup.speed, "x0": setup.x0, "damping": setup.damping, "prefactor": setup.prefactor,
            "dipoles": setup.dipoles if isinstance(setup.dipoles, str) else "along x",
            "dt": dt, "integrator": integrator, "b_max": found.b_over_R, "b_stick": found.stick,
            "b_escape": found.escape, "half_width": found.half_width,
            "escape_outcome": found.escape_outcome, "central_estimate": central,
            "evaluations": found.evaluations}


def outcome_point(speed, b_over_R):
    """Outcome of one collision (for the outcome map at higher speeds)."""
    fate, trajectory = TwoMagnets(b_over_R, speed=speed).fate()
    return {"kind": "outcome", "speed": speed, "b_over_R": b_over_R, "outcome": fate,
            "sim_time": float(trajectory.time[-1])}


# ---- the same tasks taking one point of a sweep (dk.sweep) ------------------------------------------
def sweep_task(point):
    return sweep_point(point["model"], point["b_over_R"], point["revolutions"])


def energy_task(point):
    return energy_series(point["dipoles"], point["revolutions"])


def threshold_task(point):
    return threshold(point["name"], point["group"], point["setup"], point["lo"], point["hi"], point["tol"],
                     point["dt"], point["integrator"])


def outcome_task(point):
    return outcome_point(point["speed"], point["b_over_R"])


#: kind -> its task; the sweeps run in this order (the longest jobs first)
TASKS = {"threshold": threshold_task, "sweep": sweep_task, "energy": energy_task, "outcome": outcome_task}
#: what each kind of job is, for the progress bar
JOB_NAMES = {"threshold": "capture thresholds", "sweep": "omega_f(b) sweep", "energy": "energy series",
             "outcome": "outcome grid"}
#: the order of each kind's result keys (as the tasks return them; the tables store them by column)
KEY_ORDER = {
    "sweep": ["kind", "model", "b_over_R", "speed", "x0", "outcome", "first_contact", "omega", "sigma",
              "beta_point", "k_ratio_from_omega", "k_ratio_measured", "compression", "compression_static",
              "settle_time", "window_end", "omega_rad_s", "omega_rad_s_demkit_scales", "rev_s",
              "spin_fraction_at_contact", "sim_time"],
    "energy": ["kind", "dipoles", "initial_energy", "initial_kinetic", "first_contact", "settle_time",
               "final_total", "final_kinetic", "omega", "sigma", "final_magnetic", "final_m1_dot_m2",
               "final_abs_m_dot_n", "kinetic_range", "series", "zoom"],
    "threshold": ["kind", "name", "group", "model", "speed", "x0", "damping", "prefactor", "dipoles", "dt",
                  "integrator", "b_max", "b_stick", "b_escape", "half_width", "escape_outcome",
                  "central_estimate", "evaluations"],
    "outcome": ["kind", "speed", "b_over_R", "outcome", "sim_time"],
}
#: result entries stored as JSON in the tables
JSON_KEYS = ("kinetic_range", "series", "zoom", "evaluations")


# ---- the plan -------------------------------------------------------------------------------------
def plan(quick):
    """List of (cost estimate, kind, point) (kind: a key of TASKS); the most expensive run first."""
    tasks = []
    if quick:
        grid = {"dipole": [1.5, 3.0, 4.5], "power_law": [1.5, 3.0, 4.5]}
    else:
        grid = {"dipole": list(np.round(np.arange(1.0, 5.51, 0.25), 2)) + [5.7],
                "power_law": list(np.round(np.arange(1.0, 5.01, 0.5), 2)) + [5.35]}
    for model, values in grid.items():
        for b in values:
            tasks.append((1.0 / b, "sweep", {"model": model, "b_over_R": float(b), "revolutions": 5}))
    for dipoles in ("aligned", "anti-aligned"):
        tasks.append((1.0, "energy", {"dipoles": dipoles, "revolutions": 2 if quick else 5}))

    def bracket(kwargs, model="dipole"):
        setup = TwoMagnets(5.0, **kwargs)
        c = capture.central_capture(setup.speed, setup.radius, setup.x0, alpha=2 * setup.prefactor)
        return (0.97 * c, 1.03 * c) if model == "power_law" else (0.97 * c, 1.12 * c)

    def add(name, group, kwargs, tol, dt=0.01, integrator="euler_cromer"):
        lo, hi = bracket(kwargs, kwargs.get("model", "dipole"))
        x0 = kwargs.get("x0", 150.0)
        cost = 1.5 * (x0 / 150.0) * (5.78e-3 / kwargs.get("speed", 5.78e-3)) * (0.01 / dt)
        tasks.append((cost, "threshold", {"name": name, "group": group, "setup": kwargs, "lo": lo, "hi": hi,
                                          "tol": tol, "dt": dt, "integrator": integrator}))

    add("paper settings", "paper", {}, 0.05 if quick else 0.01)
    if quick:
        return tasks
    add("power-law model", "model", {"model": "power_law"}, 0.01)
    for x0 in (30.0, 50.0, 500.0):
        add(f"x0 = {x0:g}", "x0", {"x0": x0}, 0.02)
    for v in (2.89e-3, 4.3e-3, 8.67e-3):
        add(f"v = {v:g}", "speed", {"speed": v}, 0.02)
    add("v = 0.0043, power law", "speed power law", {"speed": 4.3e-3, "model": "power_law"}, 0.02)
    add("dt = 0.1", "numerics", {}, 0.02, dt=0.1)
    add("velocity Verlet", "numerics", {}, 0.02, integrator="velocity_verlet")
    add("Gamma = 0.01", "contact", {"damping": 0.02}, 0.02)
    add("Gamma = 0.25", "contact", {"damping": 0.5}, 0.02)
    add("dipoles along x", "orientation", {"dipoles": [[1.0, 0, 0], [1.0, 0, 0]]}, 0.02)
    add("half-strength dipoles", "what-if", {"prefactor": 1.0 / 6.0}, 0.02)
    for v in (5.78e-3, 1.0e-2, 1.156e-2, 1.445e-2):
        for b in np.round(np.arange(0.0, 5.01, 0.25), 2):
            tasks.append((0.05, "outcome", {"speed": v, "b_over_R": float(b)}))
    return tasks


def _warm_up(quick):
    """Compile (or load from the disk cache) every kernel once before the workers fork."""
    for model in ("dipole", "power_law"):
        integrators = ["euler_cromer"] if quick else list(INTEGRATORS)
        for name in integrators:
            TwoMagnets(3.0, model=model).simulation(0.01, INTEGRATORS[name]).run(0.02)


def _importable():
    """Make this module's functions picklable by reference even when it was loaded from its path
    without being registered in sys.modules (as importlib.util.module_from_spec does)."""
    module = sys.modules.get(__name__)
    if module is not None and getattr(module, "sweep_point", None) is sweep_point:
        return
    module = types.ModuleType(__name__)
    module.__dict__.update(globals())
    sys.modules[__name__] = module


def execute(tasks, workers, scheduler=None, tables=None, resume=False, progress=None):
    """Run the tasks with :func:`demkit.sweep`, one sweep per kind, the most expensive points first;
    returns the results in task order (each a dict as its task returned it, with ``wall_s``).

    ``tables``: folder of the sweeps' tables (default: a temporary one); without ``resume`` they are
    started afresh, so that every result comes from this run. ``progress``: one bar over all the
    jobs, the kind under way in its postfix (None: on a terminal, as :class:`demkit.progress.Progress`).
    """
    import tempfile
    from demkit.progress import Progress
    if workers > 1 and scheduler is None:
        _importable()
    results = [None] * len(tasks)
    with tempfile.TemporaryDirectory() as scratch, \
            Progress(len(tasks), progress, desc="replication", unit="job") as bar:
        folder = Path(tables) if tables is not None else Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        for kind, task in TASKS.items():
            order = sorted((k for k in range(len(tasks)) if tasks[k][1] == kind), key=lambda k: -tasks[k][0])
            if not order:
                continue
            table = folder / f"replication_{kind}.csv"
            if not resume and table.exists():
                table.unlink()
            bar.update(bar.done, note=f"{JOB_NAMES[kind]} ({len(order)} jobs)")
            rows = dk.sweep(task, [tasks[k][2] for k in order], results=table, workers=workers,
                            scheduler=scheduler, progress=bar)
            for k, row in zip(order, rows):
                results[k] = _restore(kind, row, tasks[k][2])
    return results


def _restore(kind, row, point):
    """A table row back to the task's dict (keys in the task's order, JSON entries decoded), with wall_s."""
    if row["status"] != "ok":
        raise RuntimeError(f"replication job {kind} {point} failed: {row['error']}")
    out = {}
    for key in KEY_ORDER[kind]:
        value = point.get(key, row.get(key))
        if value is None:
            continue
        if key in JSON_KEYS and isinstance(value, str):
            value = json.loads(value)
            if key in ("series", "zoom"):
                value = {k: np.asarray(v) for k, v in value.items()}
        out[key] = value
    out["wall_s"] = row["wall_s"]
    return out


# ---- analysis of the results ------------------------------------------------------------------------
def summarise(results, quick):
    """Every number of the report (no timings: this goes to the tracked summary.json)."""
    sweep = [r for r in results if r["kind"] == "sweep"]
    out = {"quick": quick, "paper": PAPER, "models": {}, "runs": count_runs(results)}
    for model in ("dipole", "power_law"):
        rows = [r for r in sweep if r["model"] == model and r["outcome"] == "stick"]
        b = np.array([r["b_over_R"] for r in rows])
        omega = np.array([r["omega"] for r in rows])
        sigma = np.array([r["sigma"] for r in rows])
        # unweighted: sigma is the spread of the libration, not an independent measurement error
        # (it varies 1000-fold between neighbouring b/R and would hand the fit to a few runs)
        beta, dbeta = fits.fit_beta(b, omega, rows[0]["speed"], TwoMagnets(1.0).radius)
        k_omega = np.array([r["k_ratio_from_omega"] for r in rows])
        k_meas = np.array([r["k_ratio_measured"] for r in rows])
        bk, dbk = fits.fit_energy_ratio(b, k_omega)
        bm, dbm = fits.fit_energy_ratio(b, k_meas)
        comp = np.array([r["compression"] for r in rows])
        static = np.array([r["compression_static"] for r in rows])
        out["models"][model] = {
            "beta": beta, "beta_sigma": dbeta, "n": len(rows), "b_range": [float(b.min()), float(b.max())],
            "beta_points": [r["beta_point"] for r in rows],
            "k_beta_from_omega": bk, "k_beta_from_omega_sigma": dbk,
            "k_beta_measured": bm, "k_beta_measured_sigma": dbm,
            "k_threshold_fit": math.sqrt(2 * bk), "k_threshold_data": fits.crossing(b, k_omega),
            "k_threshold_measured_data": fits.crossing(b, k_meas),
            "compression_min": float(comp.min()), "compression_max": float(comp.max()),
            "compression_vs_static": [float(np.min(comp / static - 1)), float(np.max(comp / static - 1))],
            "relative_sigma_max": float(np.max(sigma / omega)),
            "relative_sigma_min": float(np.min(sigma / omega)),
            "beta_point_min": float(min(r["beta_point"] for r in rows)),
            "beta_point_max": float(max(r["beta_point"] for r in rows)),
            "excess_kinetic_min": float(np.min(k_meas - k_omega)),
            "excess_kinetic_max": float(np.max(k_meas - k_omega)),
            "spin_fraction_at_contact": [float(np.min([r["spin_fraction_at_contact"] for r in rows])),
                                         float(np.max([r["spin_fraction_at_contact"] for r in rows]))],
            "not_sticking": [r["b_over_R"] for r in sweep if r["model"] == model and r["outcome"] != "stick"],
        }
    thresholds = [r for r in results if r["kind"] == "threshold"]
    # no timings in the data files, so that they change only when results do
    out["thresholds"] = [{k: v for k, v in r.items() if k not in ("evaluations", "wall_s")} for r in thresholds]
    speed_rows = [r for r in thresholds if r["model"] == "dipole" and r["group"] in ("paper", "speed")
                  and r["dipoles"] == "aligned" and r["prefactor"] == 1 / 3]
    if len(speed_rows) >= 3:
        v = np.array([r["speed"] for r in speed_rows])
        bmax = np.array([r["b_max"] for r in speed_rows])
        p, dp, c = fits.fit_power_law(v, bmax)
        # sigma comes from polyfit's covariance (LAPACK): its last bits vary between machines'
        # BLAS kernels, so it is kept to 10 digits (a rerun must leave the tracked file unchanged)
        out["b_max_speed_exponent"] = {"p": p, "sigma": float(f"{dp:.10g}"), "c": c,
                                       "speed_for_paper_b_max": (PAPER["b_max"] / c) ** (1 / p)}
    out["energy"] = {r["dipoles"]: {k: v for k, v in r.items() if k not in ("series", "zoom", "wall_s")}
                     for r in results if r["kind"] == "energy"}
    paper_threshold = next((t for t in thresholds if t["group"] == "paper"), None)
    if paper_threshold is not None:
        default = [r for r in every_run(results) if r["model"] == "dipole" and r["speed"] == 5.78e-3
                   and r["x0"] == 150.0 and r["damping"] == 0.1 and r["prefactor"] == 1 / 3
                   and r["dipoles"] == "aligned" and r["dt"] == 0.01 and r["integrator"] == "euler_cromer"
                   and r["b_over_R"] <= paper_threshold["b_stick"]]
        out["below_threshold"] = {"runs": len(default),
                                  "not_stick": sum(r["outcome"] != "stick" for r in default)}
    outcomes = [r for r in results if r["kind"] == "outcome"]
    out["outcome_counts"] = {o: sum(r["outcome"] == o for r in outcomes) for o in ("stick", "bounce", "miss")}
    return out


def count_runs(results):
    n = 0
    for r in results:
        n += len(r["evaluations"]) if r["kind"] == "threshold" else 1
    return n


# ---- output ---------------------------------------------------------------------------------------
def write_csv(path, rows, columns):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for r in rows:
            w.writerow([_fmt(r.get(c, "")) for c in columns])


def _fmt(value):
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.8g}"
    return value


SWEEP_COLUMNS = ["model", "b_over_R", "speed", "x0", "outcome", "omega", "sigma", "beta_point",
                 "omega_rad_s", "rev_s", "omega_rad_s_demkit_scales", "k_ratio_from_omega",
                 "k_ratio_measured", "compression", "compression_static", "spin_fraction_at_contact", "first_contact", "settle_time",
                 "window_end", "sim_time"]
THRESHOLD_COLUMNS = ["name", "group", "model", "speed", "x0", "damping", "prefactor", "dipoles", "dt",
                     "integrator", "b_stick", "b_escape", "b_max", "half_width", "escape_outcome",
                     "central_estimate"]
RUN_COLUMNS = ["kind", "model", "b_over_R", "speed", "x0", "damping", "prefactor", "dipoles", "dt",
               "integrator", "outcome", "omega", "sigma", "note"]


def every_run(results):
    """One row per simulation, bisection evaluations included."""
    rows = []
    for r in results:
        base = {"model": r.get("model", "dipole"), "speed": r.get("speed", 5.78e-3),
                "x0": r.get("x0", 150.0), "damping": r.get("damping", 0.1),
                "prefactor": r.get("prefactor", 1 / 3), "dipoles": r.get("dipoles", "aligned"),
                "dt": r.get("dt", 0.01), "integrator": r.get("integrator", "euler_cromer")}
        if r["kind"] == "threshold":
            for b, fate in r["evaluations"]:
                rows.append(dict(base, kind="bisection", b_over_R=b, outcome=fate, note=r["name"]))
        elif r["kind"] == "energy":
            rows.append(dict(base, kind="energy", b_over_R=ENERGY_CASE["b_over_R"],
                             speed=ENERGY_CASE["speed"], dipoles=r["dipoles"], outcome="stick",
                             omega=r["omega"], sigma=r["sigma"], note="energy time series"))
        else:
            rows.append(dict(base, kind=r["kind"], b_over_R=r["b_over_R"], outcome=r["outcome"],
                             omega=r.get("omega", ""), sigma=r.get("sigma", "")))
    return rows


def write_outputs(results, summary, out_root):
    figdir = out_root / "docs" / "figures" / "two_magnets"
    datadir = out_root / "docs" / "data" / "two_magnets"
    figdir.mkdir(parents=True, exist_ok=True)
    datadir.mkdir(parents=True, exist_ok=True)
    sweep = sorted([r for r in results if r["kind"] == "sweep"], key=lambda r: (r["model"], r["b_over_R"]))
    write_csv(datadir / "sweep.csv", sweep, SWEEP_COLUMNS)
    thresholds = [r for r in results if r["kind"] == "threshold"]
    write_csv(datadir / "thresholds.csv", thresholds, THRESHOLD_COLUMNS)
    write_csv(datadir / "runs.csv", every_run(results), RUN_COLUMNS)
    outcomes = [r for r in results if r["kind"] == "outcome"]
    if outcomes:
        write_csv(datadir / "outcomes.csv", outcomes, ["speed", "b_over_R", "outcome", "sim_time"])
    for r in results:
        if r["kind"] == "energy":
            name = "energy_" + r["dipoles"].replace("-", "_")
            s = r["series"]
            keys = ["time", "kinetic", "magnetic", "elastic", "total", "dissipated"]
            rows = [dict(zip(keys, vals)) for vals in zip(*(s[k] for k in keys))]
            write_csv(datadir / f"{name}.csv", rows, keys)
    with open(datadir / "summary.json", "w") as fh:
        json.dump(summary, fh, indent=1, default=_json_default)
    paths = figures.draw_all(results, summary, figdir, PAPER_SCALES)
    text = report.render(results, summary, PAPER, PAPER_SCALES, DEMKIT_SCALES)
    (out_root / "docs" / "two_magnets.md").write_text(text)
    return paths


def _json_default(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot serialise {type(value).__name__}")


def main(argv=None):
    """Run the replication with command-line ``argv`` (None: the defaults); returns the summary
    dict (also written to docs/data/two_magnets/summary.json) with the timings added."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="reduced replication (for tests)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes (default: cores)")
    parser.add_argument("--scheduler", help="Dask: 'local' or tcp://host:8786 (default: local processes)")
    parser.add_argument("--out", type=Path, default=ROOT, help="root folder of docs/ (default: repository)")
    args = parser.parse_args([] if argv is None else list(argv))  # None: defaults, not sys.argv
    workers = max(1, args.workers)
    output = args.out / "examples" / "two_magnets" / "output"  # not tracked
    start = time.perf_counter()
    _warm_up(args.quick)
    # the replication always takes a while: on a terminal its bar shows from the start, not only once
    # the first (longest) job is done and the automatic bar could judge
    from demkit.progress import quiet
    results = execute(plan(args.quick), workers, args.scheduler, tables=output,
                      progress=sys.stderr is not None and sys.stderr.isatty() and not quiet())
    wall = time.perf_counter() - start
    print(f"simulations done in {wall:.0f} s; writing the figures and the report (a few seconds)...", flush=True)
    summary = summarise(results, args.quick)
    write_outputs(results, summary, args.out)
    timing = {"workers": workers, "scheduler": args.scheduler, "wall_s": wall,
              "cpu_s": sum(r["wall_s"] for r in results), "wall_total_s": time.perf_counter() - start}
    (output / "replication_timing.json").write_text(json.dumps(timing, indent=1))
    print(report.console_table(summary))
    print(f"{summary['runs']} runs, simulations {wall:.1f} s wall on {workers} worker(s) "
          f"({timing['cpu_s']:.1f} s summed over runs); with figures and report "
          f"{timing['wall_total_s']:.1f} s. Outputs under {args.out / 'docs'}; timings in {output}")
    return dict(summary, **timing)


if __name__ == "__main__":
    main(sys.argv[1:])
