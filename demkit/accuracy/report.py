"""A work-precision report: one row per (method, dt) run of a study (:func:`demkit.accuracy.work_precision`),
its table, plots and CSV/JSON, and the cheapest run meeting a target (:meth:`WorkPrecision.suggest`)."""
from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass

import numpy as np



#: timings are not trusted when the repeats of a run differ by more than this fraction
#: ((median - least) / least) ...
TIMING_SPREAD = 0.25
#: ... or when its wall time exceeds its CPU time by more than this factor (it waited for a processor)
TIMING_WAIT = 1.5

#: error measures of a report row: (key, heading, what it is)
MEASURES = {
    "position": ("position_error", "pos err", "max over the check times and spheres of |x - x_ref| (length)"),
    "velocity": ("velocity_error", "vel err", "max over the check times and spheres of |v - v_ref| (speed)"),
    "energy": ("energy_error", "energy err",
               "max over frames of |(E + W)(t) - (E + W)(0)| / energy_scale (E total energy, W dissipated work)"),
    "angular_momentum": ("angular_momentum_drift", "L drift", "max over frames of |L(t) - L(0)| (angular momentum)"),
    "observable": ("observable_error", "obs err", "|observable(run) - observable(reference)|"),
}


class WorkPrecision:
    """What accuracy costs for one scene: one row per (method, dt) run. See :func:`work_precision`.

    rows : list of dicts (method, dt, steps, evaluations, seconds, cpu_seconds, repeats,
        timing_spread, stable, message, errors, observable, is_reference).
    reference : a dict describing the reference (kind, description, evaluations, seconds, restarts,
        energy_error, angular_momentum_drift, observable).
    energy_scale, energy_scale_source : the scale dividing the energy-balance error and where it
        comes from. times : the check times of the position and velocity errors.
    spread : None or a dict (samples, perturbation, observable values and spread, position spread
        per check time): how far references from perturbed starts drift apart, the floor below which
        more accuracy buys nothing.
    """

    def __init__(self, rows, reference, energy_scale, energy_scale_source, times, duration, spread=None,
                 observable_name=None, length_scale=None):
        self.length_scale = length_scale  # the smallest radius: the size at which position errors saturate
        self.rows = rows
        self.reference = reference
        self.energy_scale, self.energy_scale_source = energy_scale, energy_scale_source
        self.times, self.duration = times, duration
        self.spread = spread
        self.observable_name = observable_name

    def measures(self):
        """The error measures present (names of :data:`MEASURES`)."""
        out = ["position", "velocity", "energy"]
        if any(math.isfinite(r["angular_momentum_drift"]) for r in self.rows):
            out.append("angular_momentum")
        if self.observable_name is not None:
            out.append("observable")
        return out

    def floor(self, measure):
        """The chaotic floor of a measure from the spread of perturbed references (None if not measured)."""
        if not self.spread:
            return None
        if measure == "position":
            return self.spread["position_max"]
        if measure == "observable" and self.spread.get("observable_range") is not None:
            return self.spread["observable_range"]
        return None

    def _timed_rows(self):
        return [r for r in self.rows if r["stable"] and math.isfinite(r.get("seconds", math.nan))]

    def timing_notes(self):
        """Why the wall times cannot be trusted, one sentence each (empty when nothing says so): repeats
        of a run that differ by more than :data:`TIMING_SPREAD`, wall time above CPU time by more than
        :data:`TIMING_WAIT` (the process waited for a processor), and a method whose time does not
        grow with its force evaluations (fixed costs of a run, not the integrator, are measured)."""
        notes, rows = [], self._timed_rows()
        spread = [r for r in rows if r.get("timing_spread", math.nan) > TIMING_SPREAD]
        if spread:
            worst = max(spread, key=lambda r: r["timing_spread"])
            notes.append(f"the repeats of {len(spread)} of {len(rows)} runs differ by more than "
                         f"{TIMING_SPREAD:.0%} (up to {worst['timing_spread']:.0%}: {worst['method']} "
                         f"dt = {worst['dt']:.4g}, {worst['repeats']} runs): the machine was busy or the runs "
                         f"are too short to time")
        waited = [r for r in rows if r.get("cpu_seconds", 0) > 0 and r["seconds"] > TIMING_WAIT * r["cpu_seconds"]]
        if waited:
            worst = max(waited, key=lambda r: r["seconds"] / r["cpu_seconds"])
            notes.append(f"{len(waited)} of {len(rows)} runs took more than {TIMING_WAIT:g}x their CPU time in wall "
                         f"time (up to {worst['seconds'] / worst['cpu_seconds']:.1f}x: {worst['method']} "
                         f"dt = {worst['dt']:.4g}): the process waited for a processor (a busy machine); "
                         f"compare CPU times (cpu_seconds) or force evaluations")
        for method in dict.fromkeys(r["method"] for r in rows):
            mine = sorted((r for r in rows if r["method"] == method and not r.get("is_reference")),
                          key=lambda r: r["evaluations"])
            if len(mine) < 2 or mine[0]["evaluations"] == mine[-1]["evaluations"]:
                continue
            slope = float(np.polyfit(np.log([r["evaluations"] for r in mine]), np.log([r["seconds"] for r in mine]),
                                     1)[0])
            faster = [(a, b) for a, b in zip(mine, mine[1:]) if b["seconds"] < a["seconds"]]
            if slope < 0.5 or faster:
                a, b = faster[0] if faster else (mine[0], mine[-1])
                notes.append(f"{method}: the wall time does not follow the work (time ~ evaluations^{slope:.2f}; "
                             f"dt = {b['dt']:.4g} took {b['seconds']:.3g} s for {b['evaluations']} force "
                             f"evaluations, dt = {a['dt']:.4g} {a['seconds']:.3g} s for {a['evaluations']}): "
                             f"fixed costs of each run (Python, recording, the pieces between check times) or "
                             f"noise dominate; compare force evaluations")
        return notes

    def convergence_notes(self):
        """Where position errors stall while energy errors converge, and why, one sentence per method."""
        notes = []
        for method in dict.fromkeys(r["method"] for r in self.rows):
            mine = sorted((r for r in self.rows if r["method"] == method and r["stable"] and not r.get("is_reference")
                           and r["position_error"] > 0 and r["energy_error"] > 0), key=lambda r: -r["dt"])
            if len(mine) < 3:
                continue
            dts = np.log([r["dt"] for r in mine])
            position = float(np.polyfit(dts, np.log([r["position_error"] for r in mine]), 1)[0])
            energy = float(np.polyfit(dts, np.log([r["energy_error"] for r in mine]), 1)[0])
            rises = any(b["position_error"] > 1.2 * a["position_error"] for a, b in zip(mine, mine[1:]))
            if energy < 0.7 or not (position < 0.5 or rises):
                continue
            largest = max(r["position_error"] for r in mine)
            text = (f"{method}: position errors do not converge with dt (fitted order {position:.2f}, "
                    f"{min(r['position_error'] for r in mine):.2e} to {largest:.2e}"
                    f"{', rising at some halvings' if rises else ''}) while energy errors do (order {energy:.2f}). "
                    f"Positions compared at fixed times depend on when each contact begins and ends, which a fixed "
                    f"step finds only to within a step, differently for every dt (first order at best, erratic); "
                    f"the energy balance is an integral over the run and averages these phase errors out")
            if self.length_scale and largest >= 0.1 * self.length_scale:
                text += (f". Errors of {largest:.2e}, a sizeable part of a radius ({self.length_scale:.3g}), mean "
                         f"runs that parted from the reference for good (a chaotic scene, or a contact gained or "
                         f"missed): such errors saturate at the size of the scene instead of shrinking")
            floor = self.floor("position")
            if floor is not None and min(r["position_error"] for r in mine) < 10 * floor:
                text += f". They also reach the spread of perturbed references ({floor:.2e}), the chaotic floor"
            notes.append(text + ". Trust the energy column, or resolve contacts (VelocityVerlet:resolve).")
        return notes

    def table(self):
        """A plain-text table: method, dt, each error, wall time (least of its repeats), CPU time, force
        evaluations, stable; then the reference, the notes on the timings and on convergence."""
        measures = self.measures()
        head = (["method", "dt"] + [MEASURES[m][1] for m in measures]
                + ["seconds", "cpu s", "runs", "evaluations", "stable"])
        lines = []
        for r in self.rows:
            cells = [r["method"], f"{r['dt']:.4g}"]
            for m in measures:
                value = r[MEASURES[m][0]]
                cells.append("ref" if r.get("is_reference") else (f"{value:.3e}" if math.isfinite(value) else "nan"))
            seconds = f"{r['seconds']:.4g}" if math.isfinite(r["seconds"]) else "-"
            cpu = r.get("cpu_seconds", math.nan)
            cells += [seconds, f"{cpu:.4g}" if math.isfinite(cpu) else "-", str(r.get("repeats", 1)),
                      str(r["evaluations"]), "yes" if r["stable"] else "NO"]
            lines.append(cells)
        widths = [max(len(h), *(len(c[k]) for c in lines)) if lines else len(h) for k, h in enumerate(head)]
        fmt = lambda cells: "  ".join(c.rjust(w) if k else c.ljust(w) for k, (c, w) in enumerate(zip(cells, widths)))  # noqa: E731
        out = [fmt(head), fmt(["-" * w for w in widths])] + [fmt(c) for c in lines]
        ref = self.reference
        out.append("")
        out.append(f"reference: {ref['description']}")
        out.append(f"energy err is divided by {self.energy_scale:.6g} ({self.energy_scale_source})")
        if self.spread:
            s = self.spread
            text = (f"spread of {s['samples']} references started {s['perturbation']:.3g} apart: positions "
                    f"{s['position_max']:.3e}")
            if s.get("observable_range") is not None:
                text += f", observable {s['observable_range']:.3e}"
            out.append(text + " (errors below this are not meaningful)")
        for r in self.rows:
            if not r["stable"]:
                out.append(f"{r['method']} dt={r['dt']:.4g}: {r['message']}")
        notes = self.timing_notes()
        runs = [r.get("repeats", 1) for r in self._timed_rows()]
        if runs:
            kept = f"the least wall time of {min(runs)}" + (f"-{max(runs)}" if max(runs) > min(runs) else "") + \
                " runs each"
            if notes:
                out.append(f"timings ({kept}) cannot be trusted:")
                out += [f"  - {note}" for note in notes]
            else:
                checked = (f"repeats within {TIMING_SPREAD:.0%}, " if max(runs) >= 3 else "")
                out.append(f"timings: {kept}; {checked}wall time within {TIMING_WAIT:g}x CPU time, growing with the "
                           f"force evaluations" + ("" if max(runs) >= 3 else
                                                   " (runs timed fewer than 3 times cannot show how much they vary)"))
        notes = self.convergence_notes()
        if notes:
            out.append("convergence:")
            out += [f"  - {note}" for note in notes]
        return "\n".join(out)

    def __str__(self):
        return self.table()

    def __repr__(self):
        return f"WorkPrecision({len(self.rows)} runs, reference: {self.reference['kind']})"

    def suggest(self, target, measure="position"):
        """The cheapest (least wall time) stable run whose ``measure`` error is at most ``target``:
        a :class:`Suggestion` (its ``row`` is None, and its message says why, when none does)."""
        if measure not in MEASURES:
            raise ValueError(f"measure must be one of {sorted(MEASURES)}, got {measure!r}")
        key = MEASURES[measure][0]
        good = [r for r in self.rows if r["stable"] and not r.get("is_reference") and math.isfinite(r[key])
                and r[key] <= target and math.isfinite(r["seconds"])]
        floor = self.floor(measure)
        note = ""
        if floor is not None and target < floor:
            note = (f" Note: the target is below the spread {floor:.3e} of references started "
                    f"{self.spread['perturbation']:.3g} apart: errors that small are not meaningful here.")
        if not good:
            measured = [r[key] for r in self.rows if r["stable"] and math.isfinite(r[key]) and not r.get("is_reference")]
            best = f"the smallest {measure} error measured is {min(measured):.3e}" if measured else "no run was stable"
            return Suggestion(None, f"no run meets {measure} error <= {target:.3e}: {best}; try smaller time steps "
                                    f"or a higher-order method.{note}")
        row = min(good, key=lambda r: r["seconds"])
        return Suggestion(row, f"{row['method']} with dt = {row['dt']:.6g}: {measure} error {row[key]:.3e} <= "
                               f"{target:.3e} in {row['seconds']:.4g} s ({row['evaluations']} force evaluations)"
                               f".{note}")

    # ---- output -------------------------------------------------------------------------------
    COLUMNS = ("method", "dt", "steps", "evaluations", "seconds", "cpu_seconds", "repeats", "timing_spread",
               "stable", "position_error", "velocity_error",
               "energy_error", "angular_momentum_drift", "observable", "observable_error", "is_reference", "message")

    def to_csv(self, path):
        """Write the rows as CSV (one line per run)."""
        with open(path, "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(self.COLUMNS)
            for r in self.rows:
                writer.writerow([r.get(c, "") for c in self.COLUMNS])
        return path

    def as_dict(self):
        def clean(value):
            if isinstance(value, dict):
                return {k: clean(v) for k, v in value.items()}
            if isinstance(value, (list, tuple, np.ndarray)):
                return [clean(v) for v in value]
            if isinstance(value, (np.floating, float)):
                return float(value) if math.isfinite(value) else None
            if isinstance(value, np.integer):
                return int(value)
            if isinstance(value, np.bool_):
                return bool(value)
            return value
        return clean({"duration": self.duration, "times": list(self.times), "energy_scale": self.energy_scale,
                      "energy_scale_source": self.energy_scale_source, "reference": self.reference,
                      "spread": self.spread, "observable": self.observable_name, "rows": self.rows,
                      "timing_notes": self.timing_notes(), "convergence_notes": self.convergence_notes()})

    def to_json(self, path=None):
        """The report as JSON (NaN as null); written to ``path`` if given, else returned as text."""
        text = json.dumps(self.as_dict(), indent=1)
        if path is None:
            return text
        with open(path, "w") as fh:
            fh.write(text)
        return path

    def plot(self, path, x="seconds", title=None):
        """Log-log error against cost (``x``: "seconds", "cpu_seconds" or "evaluations"), one line per method, one
        panel per error measure, dashed: the chaotic floor when a spread was measured. Saved to path."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        if x not in ("seconds", "cpu_seconds", "evaluations"):
            raise ValueError(f"x must be 'seconds', 'cpu_seconds' or 'evaluations', got {x!r}")
        from matplotlib.ticker import NullFormatter
        measures = self.measures()
        ncols = min(3, len(measures))
        nrows = -(-len(measures) // ncols)
        fig, axes = plt.subplots(nrows, ncols, figsize=(4.6 * ncols, 3.7 * nrows), squeeze=False)
        for ax in axes.ravel()[len(measures):]:
            ax.set_visible(False)
        methods = list(dict.fromkeys(r["method"] for r in self.rows))
        for ax, measure in zip(axes.ravel(), measures):
            key = MEASURES[measure][0]
            for method in methods:
                rows = [r for r in self.rows if r["method"] == method and r["stable"] and not r.get("is_reference")
                        and math.isfinite(r[key]) and r[key] > 0 and math.isfinite(float(r.get(x, math.nan)))
                        and r[x] > 0]
                if not rows:
                    continue
                rows.sort(key=lambda r: r[x])
                line, = ax.loglog([r[x] for r in rows], [r[key] for r in rows], "o-", label=method)
                for r in rows:
                    ax.annotate(f"{r['dt']:.2g}", (r[x], r[key]), fontsize=6, color=line.get_color(),
                                xytext=(3, 3), textcoords="offset points")
            floor = self.floor(measure)
            if floor is not None and floor > 0:
                ax.axhline(floor, color="grey", ls="--", lw=1, label="spread of perturbed references")
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.set_xlabel({"seconds": "wall time [s]", "cpu_seconds": "CPU time [s]"}.get(x, "force evaluations"))
            label = {"energy": f"energy balance error / {self.energy_scale:.3g}"}.get(measure, MEASURES[measure][1])
            if measure == "observable":
                label = f"error of {self.observable_name}"
            ax.set_ylabel(label)
            ax.grid(True, which="both", alpha=0.3)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=7)
            else:  # every error is zero (angular momentum kept exactly) or failed
                ax.text(0.5, 0.5, "all zero or not finite", transform=ax.transAxes, ha="center", fontsize=8)
        if x != "evaluations" and self.timing_notes():
            fig.text(0.5, 0.005, "timings cannot be trusted: see report.timing_notes()", ha="center",
                     fontsize=7, color="firebrick")
        fig.suptitle(title or f"work-precision (numbers: dt); reference: {self.reference['kind']}", fontsize=9)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return path


@dataclass
class Suggestion:
    """What :meth:`WorkPrecision.suggest` found: the row (None when no run meets the target) and why."""

    row: dict | None
    message: str

    def __bool__(self):
        return self.row is not None

    def __str__(self):
        return self.message
