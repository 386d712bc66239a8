"""Outcome map of the seed paper's collision: miss / bounce / stick over (b/R, v) and over the dipoles'
initial orientation, with the capture boundary (docs/outcome_map.md).

    python examples/two_magnets/outcome_map.py [--workers N] [--scheduler local|tcp://host:8786]

Runs the sweeps outcome_map_speed.toml and outcome_map_orientation.toml (tables with timings under
examples/two_magnets/output/, resumable), copies them without timings to docs/data/two_magnets/ and
draws docs/figures/outcome_map.png and docs/figures/outcome_map_orientation.png. For a finer map,
raise num in the .toml files (and run it on a cluster with --scheduler).
"""
from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

import demkit as dk
from demkit.sweep import read_sweep_file, read_table
from demkit.two_magnets import PAPER_RADIUS, PAPER_SPEED, capture

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
SWEEPS = {"speed": HERE / "outcome_map_speed.toml", "orientation": HERE / "outcome_map_orientation.toml"}
COLOURS = {"miss": "#c8c8c8", "bounce": "#f39c34", "stick": "#2c6fbb", "failed": "#d62728"}
X0 = 150.0  # TwoMagnets' default start


def run(workers=None, scheduler=None):
    """Both sweeps -> {name: rows}; each table also copied, without wall_s, to docs/data/two_magnets/."""
    tables = {}
    for name, path in SWEEPS.items():
        start = time.perf_counter()
        rows = dk.sweep_file(path, workers=workers, scheduler=scheduler)
        print(f"{name}: {len(rows)} points in {time.perf_counter() - start:.0f} s "
              f"({sum(r['wall_s'] for r in rows):.0f} s summed over the points)", flush=True)
        tables[name] = rows
    return tables


def write_data(tables, out_root):
    data = out_root / "docs" / "data" / "two_magnets"
    data.mkdir(parents=True, exist_ok=True)
    for name, rows in tables.items():
        source = read_sweep_file(SWEEPS[name])["results"]
        with open(source, newline="") as fh:
            reader = csv.DictReader(fh)
            columns = [c for c in reader.fieldnames if c != "wall_s"]
            kept = [{c: r[c] for c in columns} for r in reader]
        with open(data / f"outcome_map_{name}.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, columns)
            w.writeheader()
            w.writerows(kept)


def grid(rows, x, y):
    """(xs, ys, outcome names (len(ys), len(xs))) of a grid table."""
    xs = sorted({r[x] for r in rows})
    ys = sorted({r[y] for r in rows})
    names = np.full((len(ys), len(xs)), "failed", dtype=object)
    for r in rows:
        if r["status"] == "ok":
            names[ys.index(r[y]), xs.index(r[x])] = r["outcome"]
    return np.array(xs, float), np.array(ys, float), names


def edges(values, log=False):
    v = np.log(values) if log else values
    mid = 0.5 * (v[1:] + v[:-1])
    e = np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])
    return np.exp(e) if log else e


def largest_stick(xs, ys, names):
    """Per column: midpoint between the largest sticking b/R and the next grid value (None if none)."""
    out = []
    for k in range(len(xs)):
        stuck = np.flatnonzero(names[:, k] == "stick")
        if len(stuck) == 0 or stuck[-1] == len(ys) - 1:
            out.append(np.nan)
        else:
            out.append(0.5 * (ys[stuck[-1]] + ys[stuck[-1] + 1]))
    return np.array(out)


def draw_map(ax, xs, ys, names, log_x):
    from matplotlib.colors import ListedColormap
    order = list(COLOURS)
    index = np.vectorize(order.index)(names)
    ax.pcolormesh(edges(xs, log_x), edges(ys), index, cmap=ListedColormap(list(COLOURS.values())),
                  vmin=-0.5, vmax=len(order) - 0.5, shading="flat")
    if log_x:
        ax.set_xscale("log")
    from matplotlib.patches import Patch
    present = [o for o in order if (names == o).any()]
    return [Patch(color=COLOURS[o], label=o) for o in present]


def measured_thresholds():
    """(speed, b_max, half width) of the replication's bisections (dipole model, head to tail)."""
    path = ROOT / "docs" / "data" / "two_magnets" / "thresholds.csv"
    rows = [r for r in csv.DictReader(open(path)) if r["group"] in ("paper", "speed")
            and r["model"] == "dipole" and r["dipoles"] == "aligned"]
    return [(float(r["speed"]), float(r["b_max"]), float(r["half_width"])) for r in rows]


def figures(tables, out_root):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    figdir = out_root / "docs" / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    paths = []

    xs, ys, names = grid(tables["speed"], "speed", "b_over_R")
    fig, ax = plt.subplots(figsize=(7.0, 4.8))
    handles = draw_map(ax, xs, ys, names, log_x=True)
    v = np.geomspace(xs[0] * 0.9, xs[-1] * 1.1, 200)
    central = [capture.central_capture(s, PAPER_RADIUS, X0) for s in v]
    handles += ax.plot(v, central, "k-", lw=1.4, label=r"central $-\alpha/r^3$ capture $b_c$ (x0 = 150)")
    far = [capture.central_capture(s, PAPER_RADIUS) for s in v]
    handles += ax.plot(v, far, "k:", lw=1.0, label=r"from infinity, $b_c \propto v^{-2/3}$")
    t = np.array(measured_thresholds())
    handles.append(ax.errorbar(t[:, 0], t[:, 1], yerr=t[:, 2], fmt="wD", mec="k", ms=5,
                               label="bisection (replication)"))
    edge = largest_stick(xs, ys, names)
    handles += ax.plot(xs, edge, "k_", ms=9, mew=1.5, label="largest stick on this grid")
    ax.axvline(PAPER_SPEED, color="k", lw=0.6, ls="--")
    ax.text(PAPER_SPEED * 1.02, ys[-1] * 0.97, "paper", va="top", fontsize=8)
    ax.set_xlim(edges(xs, True)[[0, -1]])
    ax.set_ylim(edges(ys)[[0, -1]])
    ax.set_xlabel("speed of each sphere v [x_c / t_c]")
    ax.set_ylabel("impact parameter b / R")
    ax.set_title("two magnets: outcome of the collision (dipoles head to tail)")
    ax.legend(handles=handles, fontsize=7, loc="upper right", framealpha=0.9)
    fig.tight_layout()
    paths.append(figdir / "outcome_map.png")
    fig.savefig(paths[-1], dpi=110, metadata={"Software": None})
    plt.close(fig)

    xs, ys, names = grid(tables["orientation"], "orientation", "b_over_R")
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    handles = draw_map(ax, xs, ys, names, log_x=False)
    handles += ax.plot(xs, largest_stick(xs, ys, names), "k_", ms=9, mew=1.5, label="largest stick on this grid")
    b_c = capture.central_capture(PAPER_SPEED, PAPER_RADIUS, X0)
    handles.append(ax.axhline(b_c, color="k", lw=1.2, label=f"central capture b_c/R = {b_c:.2f}"))
    ax.set_xticks(np.arange(0, 181, 30))
    ax.set_xlabel("initial orientation of both dipoles from head to tail [degrees]")
    ax.set_ylabel("impact parameter b / R")
    ax.set_title(f"two magnets at the paper's v = {PAPER_SPEED:g}: outcome against orientation")
    ax.legend(handles=handles, fontsize=7, loc="lower right", framealpha=0.9)
    fig.tight_layout()
    paths.append(figdir / "outcome_map_orientation.png")
    fig.savefig(paths[-1], dpi=110, metadata={"Software": None})
    plt.close(fig)
    return paths


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, help="processes or Dask workers (default: cores)")
    parser.add_argument("--scheduler", help="Dask: 'local' or tcp://host:8786 (default: local processes)")
    parser.add_argument("--out", type=Path, default=ROOT, help="root folder of docs/ (default: repository)")
    args = parser.parse_args([] if argv is None else list(argv))
    start = time.perf_counter()
    tables = run(args.workers, args.scheduler)
    write_data(tables, args.out)
    for path in figures(tables, args.out):
        print(f"wrote {path}")
    print(f"outcome maps done in {time.perf_counter() - start:.0f} s")
    return tables


if __name__ == "__main__":
    main(sys.argv[1:])
