"""Render docs/two_magnets.md: tables and numbers from the results, prose from report_template.md."""
from __future__ import annotations

import math
import string
from pathlib import Path

TEMPLATE = Path(__file__).resolve().parent / "report_template.md"


def _table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _threshold(summary, name):
    for t in summary["thresholds"]:
        if t["name"] == name:
            return t
    return None


def _range(t):
    return f"{t['b_stick']:.3f} – {t['b_escape']:.3f}"


def values(results, summary, paper, paper_scales, demkit_scales):
    """Every number the report quotes, formatted, by placeholder name."""
    d, p = summary["models"]["dipole"], summary["models"]["power_law"]
    sweep = {m: sorted([r for r in results if r["kind"] == "sweep" and r["model"] == m
                        and r["outcome"] == "stick"], key=lambda r: r["b_over_R"])
             for m in ("dipole", "power_law")}
    v = {"runs": summary["runs"],
         "beta_d": f"{d['beta']:.4f}", "beta_d_sig": f"{d['beta_sigma']:.4f}", "n_d": d["n"],
         "brange_d": f"{d['b_range'][0]:g}–{d['b_range'][1]:g}",
         "beta_pt_d_min": f"{d['beta_point_min']:.4f}", "beta_pt_d_max": f"{d['beta_point_max']:.4f}",
         "dev_d_min": f"{100 * (d['beta_point_min'] / 2.8 - 1):+.2f}",
         "dev_d_max": f"{100 * (d['beta_point_max'] / 2.8 - 1):+.2f}",
         "beta_p": f"{p['beta']:.6f}", "beta_p_sig": f"{p['beta_sigma']:.1g}", "n_p": p["n"],
         "brange_p": f"{p['b_range'][0]:g}–{p['b_range'][1]:g}",
         "beta_pt_p_min": f"{p['beta_point_min']:.6f}",
         "sig_d_min": f"{100 * d['relative_sigma_min']:.4f}", "sig_d_max": f"{100 * d['relative_sigma_max']:.1f}",
         "kb_omega_d": f"{d['k_beta_from_omega']:.4f}", "kb_omega_d_sig": f"{d['k_beta_from_omega_sigma']:.4f}",
         "kb_meas_d": f"{d['k_beta_measured']:.3f}", "kb_meas_d_sig": f"{d['k_beta_measured_sigma']:.3f}",
         "kb_omega_p": f"{p['k_beta_from_omega']:.5f}", "kb_meas_p": f"{p['k_beta_measured']:.5f}",
         "kt_fit": f"{d['k_threshold_fit']:.3f}", "kt_data": f"{d['k_threshold_data']:.3f}",
         "kt_meas": f"{d['k_threshold_measured_data']:.2f}",
         "kt_fit_p": f"{p['k_threshold_fit']:.3f}",
         "excess_min": f"{d['excess_kinetic_min']:.2f}", "excess_max": f"{d['excess_kinetic_max']:.2f}",
         "comp_min": f"{d['compression_min']:.2e}", "comp_max": f"{d['compression_max']:.2e}",
         "spin_min": f"{100 * d['spin_fraction_at_contact'][0]:.0f}",
         "spin_max": f"{100 * d['spin_fraction_at_contact'][1]:.0f}",
         "tc_paper": f"{paper_scales.time:.2e}", "xc_paper": f"{paper_scales.length:.2e}",
         "tc_demkit": f"{demkit_scales.time:.4e}", "xc_demkit": f"{demkit_scales.length:.4e}",
         "R_demkit": f"{demkit_scales.dimensionless_radius:.3f}",
         "v_si_paper": f"{paper_scales.to_si(paper['speed'], 'velocity'):.3f}",
         "v_si_demkit": f"{demkit_scales.to_si(paper['speed'], 'velocity'):.3f}"}
    comps = [r["compression_static"] for r in sweep["dipole"]]
    v.update(static_min=f"{min(comps):.2e}", static_max=f"{max(comps):.2e}")
    ref = next((r for r in sweep["dipole"] if abs(r["b_over_R"] - 4.0) < 1e-9), sweep["dipole"][-1])
    v.update(ref_b=f"{ref['b_over_R']:g}", ref_omega=f"{ref['omega']:.4e}",
             ref_rad_s=f"{ref['omega_rad_s']:.0f}", ref_rev_s=f"{ref['rev_s']:.1f}",
             ref_rad_s_demkit=f"{ref['omega_rad_s_demkit_scales']:.0f}",
             ref_rev_s_demkit=f"{ref['omega_rad_s_demkit_scales'] / (2 * math.pi):.1f}")
    late = sweep["dipole"][-1]
    early = next((r for r in sweep["dipole"] if abs(r["b_over_R"] - 4.0) < 1e-9), sweep["dipole"][0])
    v.update(late_b=f"{late['b_over_R']:g}", late_contact=f"{late['first_contact']:.0f}",
             early_b=f"{early['b_over_R']:g}", early_contact=f"{early['first_contact']:.0f}",
             late_delay=f"{100 * (late['first_contact'] / early['first_contact'] - 1):.0f}",
             late_window=f"{late['window_end'] - late['settle_time']:.0f}")
    mid = next((r for r in sweep["dipole"] if abs(r["b_over_R"] - 4.75) < 1e-9), sweep["dipole"][-2])
    v.update(mid_b=f"{mid['b_over_R']:g}", mid_end=f"{mid['window_end']:.0f}")
    below = summary.get("below_threshold", {"runs": 0, "not_stick": 0})
    v.update(n_below=below["runs"], n_below_bad=below["not_stick"])
    v["comp_factor"] = f"{paper['compression'] / d['compression_max']:.1f}–{paper['compression'] / d['compression_min']:.1f}"
    t = _threshold(summary, "paper settings")
    v.update(bmax=f"{t['b_max']:.3f}", bmax_hw=f"{t['half_width']:.3f}", bmax_range=_range(t),
             bmax_central=f"{t['central_estimate']:.3f}",
             bmax_ratio=f"{100 * (t['b_max'] / t['central_estimate'] - 1):.0f}")
    for key, name in (("pl", "power-law model"), ("x30", "x0 = 30"), ("x50", "x0 = 50"), ("x500", "x0 = 500"),
                      ("v289", "v = 0.00289"), ("v43", "v = 0.0043"), ("v867", "v = 0.00867"),
                      ("dt", "dt = 0.1"), ("vv", "velocity Verlet"), ("g1", "Gamma = 0.01"),
                      ("g25", "Gamma = 0.25"), ("dx", "dipoles along x"), ("half", "half-strength dipoles"),
                      ("v43pl", "v = 0.0043, power law")):
        t = _threshold(summary, name)
        if t is not None:
            v[f"b_{key}"] = f"{t['b_max']:.2f}"
            v[f"c_{key}"] = f"{t['central_estimate']:.3f}"
            v[f"r_{key}"] = _range(t)
    if "b_max_speed_exponent" in summary:
        e = summary["b_max_speed_exponent"]
        v.update(p_exp=f"{e['p']:.3f}", p_exp_sig=f"{e['sigma']:.3f}",
                 v_paper_bmax=f"{e['speed_for_paper_b_max']:.2e}",
                 v_paper_ratio=f"{e['speed_for_paper_b_max'] / paper['speed']:.2f}")
    for key, rec in summary["energy"].items():
        k = "al" if key == "aligned" else "anti"
        v.update({f"{k}_contact": f"{rec['first_contact']:.0f}", f"{k}_settle": f"{rec['settle_time']:.0f}",
                  f"{k}_total": f"{rec['final_total']:.2f}", f"{k}_magnetic": f"{rec['final_magnetic']:.2f}",
                  f"{k}_m1m2": f"{rec['final_m1_dot_m2']:+.2f}", f"{k}_mn": f"{rec['final_abs_m_dot_n']:.2f}",
                  f"{k}_kmin": f"{rec['kinetic_range'][0]:.1f}", f"{k}_kmax": f"{rec['kinetic_range'][1]:.1f}",
                  f"{k}_e0": f"{rec['initial_energy']:.4e}",
                  f"{k}_ui": f"{rec['initial_energy'] / rec['initial_kinetic'] - 1:+.1e}"})
    counts = summary.get("outcome_counts", {})
    v.update(n_stick=counts.get("stick", 0), n_bounce=counts.get("bounce", 0), n_miss=counts.get("miss", 0))
    v.update(cs_min=f"{100 * d['compression_vs_static'][0]:+.1f}", cs_max=f"{100 * d['compression_vs_static'][1]:+.1f}")
    v["summary_table"] = summary_table(summary, paper)
    v["sweep_table"] = sweep_table(sweep)
    v["threshold_table"] = threshold_table(summary)
    v["energy_table"] = energy_table(summary)
    return v


def summary_table(summary, paper):
    d, p = summary["models"]["dipole"], summary["models"]["power_law"]
    t = _threshold(summary, "paper settings")
    rows = [
        ["β, full dipole model (fit of ω_f = v b/(β R²))", f"{paper['beta']:.2f}",
         f"{d['beta']:.4f} ± {d['beta_sigma']:.4f} ({d['n']} runs, b/R {d['b_range'][0]:g}–{d['b_range'][1]:g})",
         "14/5 = 2.8"],
        ["β, power-law model", f"{paper['beta_power_law']:.2f}",
         f"{p['beta']:.6f} ± {p['beta_sigma']:.1g} ({p['n']} runs)", "2 (point masses)"],
        ["β from the fit of K_f/K_i = (b/R)²/(2β), K_f from ω_f", "“matches the prediction”",
         f"{d['k_beta_from_omega']:.4f} ± {d['k_beta_from_omega_sigma']:.4f}", "2.8"],
        ["β from the fit of K_f/K_i, K_f = measured mean kinetic energy", "—",
         f"{d['k_beta_measured']:.3f} ± {d['k_beta_measured_sigma']:.3f}", "2.8 for a rigid barbell"],
        ["b/R above which K_f > K_i", "√(2β) = 2.37 (text; 1/√(2β) in Sec. 3 is a typo)",
         f"{d['k_threshold_fit']:.3f} (fit), {d['k_threshold_data']:.3f} (data); "
         f"{d['k_threshold_measured_data']:.2f} with measured K_f", "√5.6 = 2.366"],
        ["compression (2R − r)/2R, final state", "~1e-5",
         f"{d['compression_min']:.1e} – {d['compression_max']:.1e} (b/R {d['b_range'][1]:g} … {d['b_range'][0]:g})",
         "static force balance: measured/static − 1 = "
         f"{100 * d['compression_vs_static'][0]:+.1f} … {100 * d['compression_vs_static'][1]:+.1f} %"],
        ["largest sticking b/R at v = 5.78e-3", f"{paper['b_max']}",
         f"{t['b_max']:.3f} ± {t['half_width']:.3f} (misses beyond)" if t else "—",
         f"{t['central_estimate']:.3f} (central −α/r³ estimate)" if t else "—"],
    ]
    return _table(["quantity", "paper", "demkit", "independent expectation"], rows)


def sweep_table(sweep):
    rows = []
    for model, label in (("dipole", "full"), ("power_law", "power law")):
        for r in sweep[model]:
            rows.append([label, f"{r['b_over_R']:g}", f"{1e3 * r['omega']:.4f}", f"{100 * r['sigma'] / r['omega']:.2g}",
                         f"{r['beta_point']:.4f}", f"{r['omega_rad_s']:.0f}", f"{r['rev_s']:.1f}",
                         f"{r['k_ratio_from_omega']:.3f}", f"{r['k_ratio_measured']:.3f}",
                         f"{r['compression']:.2e}"])
    return _table(["model", "b/R", "ω_f [1e-3/t_c]", "σ/ω [%]", "β", "ω_f [rad/s]", "rev/s",
                   "K_f/K_i from ω", "K_f/K_i measured", "(2R−r)/2R"], rows)


def threshold_table(summary):
    rows = []
    for t in summary["thresholds"]:
        rows.append([t["name"], t["model"].replace("_", " "), f"{t['speed']:g}", f"{t['x0']:g}",
                     f"{t['damping'] / 2:g}", f"{t['dt']:g}", t["integrator"].replace("_", " "),
                     t["dipoles"], f"{t['prefactor']:.3g}", _range(t), f"{t['b_max']:.3f}",
                     f"{t['central_estimate']:.3f}", t["escape_outcome"]])
    return _table(["case", "model", "v", "x0", "Γ", "dt", "integrator", "dipoles", "A",
                   "sticks … does not [b/R]", "b_max", "central estimate", "beyond"], rows)


def energy_table(summary):
    rows = []
    for key, rec in summary["energy"].items():
        rows.append([key, f"{rec['first_contact']:.0f}", f"{rec['settle_time']:.0f}", f"{rec['final_total']:.2f}",
                     f"{rec['final_magnetic']:.2f}", f"{rec['kinetic_range'][0]:.1f} – {rec['kinetic_range'][1]:.1f}",
                     f"{rec['final_m1_dot_m2']:+.2f}", f"{rec['final_abs_m_dot_n']:.2f}",
                     f"{rec['omega'] * 1e3:.4f}"])
    return _table(["dipoles at start", "first contact [t_c]", "settled [t_c]", "final E_total/E_i",
                   "mean U_mag/E_i", "K/E_i range", "⟨m1·m2⟩", "⟨|m·r̂|⟩", "ω_f [1e-3/t_c]"], rows)


class _NotRun(dict):
    """Placeholders of parts a --quick replication skips."""

    def __missing__(self, key):
        return "n/a (--quick)"


def render(results, summary, paper, paper_scales, demkit_scales):
    """The report; every placeholder must be filled unless the replication was --quick."""
    numbers = values(results, summary, paper, paper_scales, demkit_scales)
    template = string.Template(TEMPLATE.read_text())
    return template.substitute(_NotRun(numbers) if summary["quick"] else numbers)


def console_table(summary):
    """Plain-text paper-vs-demkit summary printed by replicate.py."""
    d, p = summary["models"]["dipole"], summary["models"]["power_law"]
    t = _threshold(summary, "paper settings")
    lines = [f"{'quantity':44s} {'paper':>10s}  demkit",
             f"{'beta, full dipole':44s} {'2.80':>10s}  {d['beta']:.4f} +- {d['beta_sigma']:.4f} ({d['n']} runs)",
             f"{'beta, power law':44s} {'2.00':>10s}  {p['beta']:.6f} +- {p['beta_sigma']:.1g} ({p['n']} runs)",
             f"{'beta from K_f/K_i fit (K_f from omega)':44s} {'-':>10s}  {d['k_beta_from_omega']:.4f}"
             f" +- {d['k_beta_from_omega_sigma']:.4f}",
             f"{'beta from K_f/K_i fit (measured mean K_f)':44s} {'-':>10s}  {d['k_beta_measured']:.3f}"
             f" +- {d['k_beta_measured_sigma']:.3f}",
             f"{'b/R where K_f > K_i':44s} {'2.37':>10s}  {d['k_threshold_fit']:.3f} (fit), "
             f"{d['k_threshold_data']:.3f} (data)",
             f"{'compression (2R - r)/2R':44s} {'~1e-5':>10s}  {d['compression_min']:.2e} .. {d['compression_max']:.2e}"]
    if t:
        lines.append(f"{'largest sticking b/R (v = 5.78e-3)':44s} {'4.65':>10s}  {t['b_max']:.3f} +- "
                     f"{t['half_width']:.3f}")
    for t in summary["thresholds"]:
        if t["name"] != "paper settings":
            lines.append(f"  b_max, {t['name']:36s} {'':>10s}  {t['b_max']:.3f} +- {t['half_width']:.3f}"
                         f"  (central estimate {t['central_estimate']:.3f})")
    for key, rec in summary["energy"].items():
        lines.append(f"{'final E_total / E_i, dipoles ' + key:44s} {'-':>10s}  {rec['final_total']:.2f}")
    return "\n".join(lines)
