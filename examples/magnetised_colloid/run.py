"""The far field of a magnetised colloid: Ewald sums against a cut-off dipole and mean-field theory.

    python examples/magnetised_colloid/run.py [--output DIR] [--quick]

A Brownian magnetic colloid (spheres of diameter d = 1, moments mu, bath at kT = 1, dk.Langevin)
at volume fraction PHI = 0.1 in a periodic box, coupling lambda = mu^2 / (d^3 kT) = 1 (prefactor
A = 1), in a uniform field B along z (Langevin parameter xi = mu B / kT). Once magnetised, the
sample acts on each sphere with the field of all the others. For a magnetisation density M the
part from beyond a few diameters is the Lorentz field (4 pi / 3) A M, which shifts xi by

    chi L(xi),   chi = (4 pi / 3) A n mu^2 / kT = 8 phi lambda   (= 0.8 here),

and the first- and second-order modified mean-field theory (Ivanov & Kuznetsova, Phys. Rev. E 64,
041405 (2001); in these units) predicts

    <m_z> / mu = L(xi_e),   xi_e = xi + chi L(xi) [+ chi^2 / 16 L(xi) L'(xi)],   L = coth x - 1/x,

for a sample whose field is the applied one inside (metallic surroundings: no demagnetising field).
Three sums, the same colloid, the same seeds:

* ``Ewald(1e-3, surface="metallic")``: every image, no demagnetising field -> the mean-field law;
* ``Ewald(1e-3, surface="vacuum")``: a sphere of the lattice in vacuum, whose demagnetising field
  -(4 pi / 3) A M cancels the Lorentz field -> close to the Langevin law L(xi);
* ``Dipole(cutoff=4)``: the neighbours within 4 d, whose field averages to nothing in a uniformly
  magnetised sample (the Lorentz cavity) -> close to the Langevin law too: a cutoff cannot see
  the far field, however long it is.

Writes into DIR (default ``output/`` next to this script) ``magnetisation.png`` and
``magnetisation.json`` and prints a table with standard errors (frames one time unit apart).
"""
import argparse
import importlib.util
import json
import math
from pathlib import Path

import numpy as np

import demkit as dk

HERE = Path(__file__).resolve().parent
R = 0.5
PHI = 0.1
COUPLING = 1.0
CHI = 8.0 * PHI * COUPLING
STIFFNESS = 1000.0  # elastic contacts (no damping: the bath alone sets the temperature)
DRAG = 1.0
DT = 0.005
SKIN = 0.6  # Brownian spheres: fewer list rebuilds (as examples/brownian_colloid)
SUMS = {"Ewald, metallic": lambda: dk.Dipole(1.0, long_range=dk.Ewald(1e-3, surface="metallic")),
        "Ewald, vacuum": lambda: dk.Dipole(1.0, long_range=dk.Ewald(1e-3, surface="vacuum")),
        "cut-off at 4 d": lambda: dk.Dipole(1.0, cutoff=4.0)}


def _brownian_example():
    path = HERE.parent / "brownian_colloid" / "run.py"
    spec = importlib.util.spec_from_file_location("brownian_colloid_run", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


langevin = _brownian_example().langevin  # L(xi) = coth xi - 1/xi


def langevin_slope(xi):
    """L'(xi) = 1/xi^2 - 1/sinh^2 xi (xi -> 0: 1/3)."""
    xi = np.asarray(xi, dtype=float)
    small = np.abs(xi) < 1e-3
    safe = np.where(small, 1.0, xi)
    return np.where(small, 1.0 / 3.0 - xi ** 2 / 15.0, 1.0 / safe ** 2 - 1.0 / np.sinh(safe) ** 2)


def mean_field(xi, chi=CHI, second_order=True):
    """<m_z>/mu of the modified mean-field theory (module docstring), first or second order."""
    shift = chi * langevin(xi)
    if second_order:
        shift = shift + chi ** 2 / 16.0 * langevin(xi) * langevin_slope(xi)
    return langevin(xi + shift)


def colloid(n, xi, dipole, seed):
    box = dk.build.box_for(n, R, PHI)
    mu = math.sqrt(COUPLING)
    p = dk.Particles(position=dk.build.random_packing(n, R, box, seed=seed), radius=R, mass=1.0,
                     velocity=np.zeros((n, 3)), dipole=mu * dk.build.random_directions(n, seed=seed + 1))
    return dk.Scene(p, [dipole, dk.KelvinVoigt(stiffness=STIFFNESS), dk.UniformField([0.0, 0.0, xi / mu]),
                        dk.Langevin(temperature=1.0, drag=DRAG, seed=seed)], box=box, skin=SKIN)


def magnetisation(n, xi, dipole, settle, samples, seed=1):
    """<m_z>/mu over ``samples`` frames one time unit apart after ``settle``, and its standard error."""
    scene = colloid(n, xi, dipole, seed)
    sim = dk.Simulation(scene, dk.VelocityVerlet(DT), notes=False)
    sim.run(duration=settle, progress=False)
    values = []
    for _ in range(samples):
        sim.run(duration=1.0, progress=False)
        values.append(float(np.mean(scene.particles.dipole[:, 2])) / math.sqrt(COUPLING))
    return float(np.mean(values)), float(np.std(values, ddof=1) / math.sqrt(len(values)))


def plot(rows, xis, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.2))
    x = np.linspace(0.0, max(xis) * 1.1, 200)
    ax.plot(x, langevin(x), "k-", label="Langevin law L(xi)")
    ax.plot(x, mean_field(x), "k--", label=f"mean-field theory, chi = 8 phi lambda = {CHI:g}")
    for name, marker in zip(SUMS, "os^"):
        pts = [r for r in rows if r["sum"] == name]
        ax.errorbar([r["xi"] for r in pts], [r["m"] for r in pts], yerr=[2 * r["error"] for r in pts],
                    fmt=marker, capsize=3, label=f"demkit, {name}")
    ax.set_xlabel("xi = mu B / kT")
    ax.set_ylabel("<m_z> / mu")
    ax.set_title(f"Magnetised colloid, volume fraction {PHI}, lambda = {COUPLING:g}")
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default=str(HERE / "output"), help="folder for the results")
    parser.add_argument("--quick", action="store_true", help="125 spheres, one field, short runs (for tests)")
    args = parser.parse_args(argv)
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    n, settle, samples = (125, 4.0, 12) if args.quick else (216, 20.0, 60)
    xis = [1.0] if args.quick else [0.5, 1.0, 2.0]
    print(f"{n} spheres, volume fraction {PHI}, lambda = {COUPLING:g}, kT = 1; <m_z>/mu after t = {settle:g}, "
          f"{samples} frames")
    print(f"{'sum':>16} {'xi':>5} {'<m_z>/mu':>9} {'+-':>6} {'L(xi)':>7} {'mean field':>10}")
    rows = []
    for name, make in SUMS.items():
        for xi in xis:
            m, error = magnetisation(n, xi, make(), settle, samples)
            rows.append({"sum": name, "xi": xi, "m": m, "error": error, "langevin": float(langevin(xi)),
                         "mean_field": float(mean_field(xi)),
                         "mean_field_first_order": float(mean_field(xi, second_order=False))})
            print(f"{name:>16} {xi:5g} {m:9.4f} {error:6.4f} {float(langevin(xi)):7.4f} {float(mean_field(xi)):10.4f}",
                  flush=True)
    plot(rows, xis, out / "magnetisation.png")
    summary = {"spheres": n, "volume_fraction": PHI, "lambda": COUPLING, "chi": CHI, "settle": settle,
               "samples": samples, "rows": rows}
    (out / "magnetisation.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(f"wrote {out / 'magnetisation.png'}, {out / 'magnetisation.json'}")
    return summary


if __name__ == "__main__":
    main()
