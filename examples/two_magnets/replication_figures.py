"""Figures of the two-magnet replication (matplotlib, Agg backend, modest PNGs)."""
from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402

from demkit.two_magnets import BARBELL_BETA, PAPER_RADIUS, PAPER_SPEED, POINT_MASS_BETA  # noqa: E402

DPI = 100
COLOURS = {"dipole": "tab:blue", "power_law": "tab:orange"}
LABELS = {"dipole": "full dipole force + torque", "power_law": "power-law (central) force"}


def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def _sticks(results, model):
    rows = [r for r in results if r["kind"] == "sweep" and r["model"] == model and r["outcome"] == "stick"]
    return sorted(rows, key=lambda r: r["b_over_R"])


def omega_figure(results, summary, path, scales):
    """omega_f against b/R with the fits, and beta of each run."""
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(6.4, 6.4), sharex=True,
                                 gridspec_kw={"height_ratios": [2.2, 1]})
    x = np.linspace(0, 6, 50)
    g = PAPER_SPEED * x / PAPER_RADIUS
    for model in ("dipole", "power_law"):
        rows = _sticks(results, model)
        if not rows:
            continue
        b = np.array([r["b_over_R"] for r in rows])
        w = np.array([r["omega"] for r in rows])
        s = np.array([r["sigma"] for r in rows])
        fit = summary["models"][model]
        ax.errorbar(b, w * 1e3, yerr=s * 1e3, fmt="o", ms=4, capsize=2, color=COLOURS[model],
                    label=f"{LABELS[model]}: beta = {fit['beta']:.4f} +- {fit['beta_sigma']:.2g}")
        ax.plot(x, g / fit["beta"] * 1e3, "-", lw=1, color=COLOURS[model])
        beta = np.array([r["beta_point"] for r in rows])
        theory = BARBELL_BETA if model == "dipole" else POINT_MASS_BETA
        bx.errorbar(b, 100 * (beta / theory - 1), yerr=100 * beta / theory * s / w, fmt="o", ms=4,
                    capsize=2, color=COLOURS[model])
    ax.plot(x, g / BARBELL_BETA * 1e3, "k--", lw=0.8, label="rigid barbell, beta = 14/5")
    ax.plot(x, g / POINT_MASS_BETA * 1e3, "k:", lw=0.8, label="point masses, beta = 2")
    b_max = [t for t in summary["thresholds"] if t["group"] == "paper"]
    if b_max:
        ax.axvline(b_max[0]["b_max"], color="tab:blue", lw=0.8, alpha=0.6)
        ax.text(b_max[0]["b_max"], 0.15, " b_max (demkit)", rotation=90, fontsize=7, color="tab:blue")
    ax.axvline(4.65, color="grey", lw=0.8, ls="-.")
    ax.text(4.65, 0.15, " paper's b_max", rotation=90, fontsize=7, color="grey")
    ax.set_ylabel("omega_f  [1e-3 / t_c]")
    ax.set_xlim(0, 6)
    ax.set_ylim(0, None)
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title(f"Final spin, v = {PAPER_SPEED:g}, R = {PAPER_RADIUS:g}, Gamma = 0.05 (5 revolutions)", fontsize=9)
    right = ax.secondary_yaxis("right", functions=(lambda y: y * 1e-3 / scales.time / (2 * math.pi),
                                                   lambda f: f * 2 * math.pi * scales.time * 1e3))
    right.set_ylabel("rev/s (5 mm NdFeB, paper's t_c)")
    bx.axhline(0, color="k", lw=0.6, ls="--")
    bx.axhspan(-0.5, 0.5, color="k", alpha=0.07)
    bx.set_ylim(-2.2, 2.2)
    bx.set_ylabel("beta / (14/5 or 2) - 1  [%]", fontsize=8)
    bx.set_xlabel("b / R")
    return _save(fig, path)


def energy_ratio_figure(results, summary, path):
    """K_f / K_i against b/R (from omega as the paper does, and measured) with the fits."""
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    x = np.linspace(0, 6, 60)
    for model in ("dipole", "power_law"):
        rows = _sticks(results, model)
        if not rows:
            continue
        fit = summary["models"][model]
        b = np.array([r["b_over_R"] for r in rows])
        ax.plot(b, [r["k_ratio_from_omega"] for r in rows], "o", ms=4, color=COLOURS[model],
                label=f"{LABELS[model]}, from omega: beta = {fit['k_beta_from_omega']:.3f}")
        ax.plot(b, [r["k_ratio_measured"] for r in rows], "x", ms=5, color=COLOURS[model],
                label=f"{LABELS[model]}, measured mean K: beta = {fit['k_beta_measured']:.3f}")
        ax.plot(x, x ** 2 / (2 * fit["k_beta_from_omega"]), "-", lw=1, color=COLOURS[model])
    ax.axhline(1.0, color="k", lw=0.6)
    t = summary["models"]["dipole"]["k_threshold_fit"]
    ax.axvline(t, color="tab:blue", lw=0.6, ls="--")
    ax.text(t, 6.5, f" K_f > K_i for b/R > {t:.2f}", fontsize=7, color="tab:blue")
    ax.set_xlabel("b / R")
    ax.set_ylabel("K_f / K_i")
    ax.set_xlim(0, 6)
    ax.set_ylim(0, 9)
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title("Final / initial kinetic energy; lines: fits of (b/R)^2 / (2 beta)", fontsize=9)
    return _save(fig, path)


def energy_figure(record, path):
    """Energy time series scaled by the initial energy: whole run and the last 4000 t_c."""
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(6.4, 6.0))
    style = {"kinetic": "tab:red", "magnetic": "tab:blue", "elastic": "tab:green", "total": "k"}
    for panel, data in ((ax, record["series"]), (bx, record["zoom"])):
        for key, colour in style.items():
            panel.plot(data["time"], data[key], lw=0.7 if panel is bx else 0.5, color=colour, label=key)
        panel.axhline(0, color="grey", lw=0.4)
        panel.set_xlabel("t / t_c")
        panel.set_ylabel("E / E_initial")
    ax.set_xlim(record["first_contact"] - 3000, record["series"]["time"][-1])
    ax.legend(fontsize=7, ncol=4, loc="lower left")
    ax.set_title(f"b/R = 4.5, v = 4.3e-3, dipoles {record['dipoles']} at the start "
                 f"(first contact t = {record['first_contact']:.0f})", fontsize=9)
    bx.set_title("the settled barbell: the last 4000 t_c of the 5 revolutions", fontsize=8)
    return _save(fig, path)


def capture_figure(results, summary, path):
    """Largest sticking b/R against speed (with the central-force estimate) and against x0."""
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(9.0, 4.0), gridspec_kw={"width_ratios": [1.6, 1]})
    th = [r for r in results if r["kind"] == "threshold"]
    v = np.geomspace(2.5e-3, 1.6e-2, 60)
    from demkit.two_magnets.capture import central_capture
    ax.plot(v, [central_capture(s, PAPER_RADIUS, 150.0) for s in v], "k--", lw=0.8,
            label="central -alpha/r^3 estimate (exact for power law)")
    for model, group, marker in (("dipole", ("paper", "speed"), "o"), ("power_law", ("model", "speed power law"), "s")):
        rows = sorted([r for r in th if r["model"] == model and r["group"] in group], key=lambda r: r["speed"])
        if rows:
            ax.errorbar([r["speed"] for r in rows], [r["b_max"] for r in rows],
                        yerr=[r["half_width"] for r in rows], fmt=marker, ms=5, color=COLOURS[model],
                        label=f"{LABELS[model]} (bisection)")
    out = [r for r in results if r["kind"] == "outcome"]
    marks = {"stick": ("tab:blue", "."), "bounce": ("tab:red", "x"), "miss": ("lightgrey", ".")}
    for fate, (colour, m) in marks.items():
        pts = [(r["speed"], r["b_over_R"]) for r in out if r["outcome"] == fate]
        if pts:
            ax.scatter(*zip(*pts), s=10, marker=m, color=colour, label=f"{fate} (full model)")
    ax.plot([PAPER_SPEED], [4.65], "*", ms=11, color="grey", label="paper: b/R = 4.65")
    ax.set_xscale("log")
    ax.set_xlabel("v (each sphere)")
    ax.set_ylabel("b/R: largest that sticks; dots: outcome map")
    ax.legend(fontsize=6.5, loc="upper right")
    ax.set_title("capture threshold (x0 = 150)", fontsize=9)
    rows = sorted([r for r in th if r["group"] in ("x0", "paper")], key=lambda r: r["x0"])
    if rows:
        bx.errorbar([r["x0"] for r in rows], [r["b_max"] for r in rows], yerr=[r["half_width"] for r in rows],
                    fmt="o-", ms=5, color=COLOURS["dipole"], label="full model")
        bx.plot([r["x0"] for r in rows], [r["central_estimate"] for r in rows], "k--", lw=0.8,
                label="central estimate")
        bx.axhline(4.65, color="grey", ls="-.", lw=0.8, label="paper")
        bx.set_xscale("log")
        bx.set_xticks([r["x0"] for r in rows])
        bx.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        bx.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        bx.set_xlabel("initial x0 of each sphere")
        bx.set_ylabel("largest b/R that sticks")
        bx.set_title(f"v = {PAPER_SPEED:g}", fontsize=9)
        bx.legend(fontsize=7)
    return _save(fig, path)


def draw_all(results, summary, folder, scales):
    paths = [omega_figure(results, summary, folder / "omega_vs_b.png", scales),
             energy_ratio_figure(results, summary, folder / "energy_ratio.png")]
    for r in results:
        if r["kind"] == "energy":
            name = "energy_" + r["dipoles"].replace("-", "_") + ".png"
            paths.append(energy_figure(r, folder / name))
    if any(r["kind"] == "threshold" for r in results):
        paths.append(capture_figure(results, summary, folder / "capture.png"))
    return paths
