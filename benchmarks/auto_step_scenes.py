"""Scenes on which ``dt = "auto"`` (a time step chosen for an accuracy of the energy balance) is measured.

    SCENES = {name: builder}       # in order; each builder returns a fresh Case
    build(name) -> Case            # Case(name, scene, method, duration, record_every, note, dt)

``scene`` is a new ``dk.Scene`` with new particles at every call, so a case can be run again from
its start. ``method`` is an integrator class (``dk.VelocityVerlet``) or a callable ``dt -> Integrator``;
``dt`` is the step the source of the scene runs it with (None for the scenes written here, whose
reference is half of ``dk.guards.largest_safe_step(scene)``). ``note`` says where the scene comes
from and what was shortened.

Two groups:

* every example scene in ``examples/``: the scene files through ``dk.load_scene``, the Python
  examples through their own scene-building functions (loaded from the file with ``runpy``), with
  their ``--quick`` sizes and durations where they have a quick mode. Where an example builds its
  scene inline in ``main()``, the builder here repeats those few lines with the example's constants
  (the note says so);
* scenes a new user wrote from the docs (Ewald and P3M gases in a field, a Langevin colloid, an
  open cluster with ``dk.FMM`` (as written, and with the multipole sum forced), a frictional gas),
  and the walled steel pour of ``benchmarks/scenes/steel_pour.toml``.

    python benchmarks/auto_step_scenes.py        # builds every case and prints its size and step
"""
import functools
import math
import runpy
import time
from dataclasses import dataclass
from pathlib import Path

import demkit as dk

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


@dataclass
class Case:
    name: str
    scene: object  # a fresh dk.Scene
    method: object  # an Integrator class, or a callable dt -> Integrator
    duration: float  # simulated time
    record_every: float
    note: str
    dt: float = None  # the step the scene's source runs it with (None: none given)


@functools.lru_cache(maxsize=None)
def example(path):
    """The globals of an example script (its functions and constants), run once, not as __main__."""
    return runpy.run_path(str(EXAMPLES / path), run_name="auto_step_example")


def from_file(name, path, note=""):
    loaded = dk.load_scene(path)
    step = loaded.integrator.dt
    return Case(name, loaded.scene, type(loaded.integrator), loaded.duration, loaded.record_every,
                f"{path.relative_to(ROOT)} through dk.load_scene, as written ({type(loaded.integrator).__name__}, "
                f"dt = {step:g}, duration {loaded.duration:g}){note}", step)


# --- the examples -------------------------------------------------------------------------------

def two_magnets_file():
    return from_file("two_magnets_file", EXAMPLES / "two_magnets" / "collision.toml")


def cluster_file():
    return from_file("cluster_file", EXAMPLES / "magnetic_cluster" / "cluster.toml")


def table():
    ex = example("magnets_on_a_table/run.py")
    n, duration = 12, 0.4  # --quick (30 balls for 0.6 s otherwise)
    particles, _ = ex["build"](n, 0.03, 4)
    contact = dk.Hertz(young=ex["YOUNG"], poisson=ex["POISSON"], restitution=ex["RESTITUTION"],
                       friction=dk.Friction(ex["FRICTION"]), rolling=dk.RollingResistance(ex["ROLLING"]))
    on_table = dk.Hertz(young=ex["YOUNG"], poisson=ex["POISSON"], restitution=ex["RESTITUTION"],
                        friction=dk.Friction(ex["FRICTION"]), rolling=dk.RollingResistance(ex["TABLE_ROLLING"]))
    table = dk.Wall(point=(0, 0, 0), normal=(0, 0, 1), contact=on_table)
    scene = dk.Scene(particles, [contact, dk.Dipole(prefactor=ex["PREFACTOR"]), table, dk.Gravity((0, 0, -ex["G"]))])
    steps = 100 * math.ceil(duration / ex["time_step"](contact)[0] / 100)
    return Case("table", scene, dk.VelocityVerlet, duration, duration / 200,
                "examples/magnets_on_a_table/run.py --quick (12 balls, 0.4 s): particles from its build(), the "
                "scene assembled as in its main() (inline there: contact laws, table wall, dipoles, gravity "
                "repeated here with its constants), its dt (40 steps in the fastest snap)", duration / steps)


def steel_columns():
    ex = example("steel_columns/run.py")
    n, volume_fraction, duration, per_contact = 60, 0.05, 0.12, 15  # --quick
    particles, box = ex["build"](n, volume_fraction, ex["GAP"], 1)
    d = ex["D"]
    dipole = dk.Dipole(ex["PREFACTOR"], cutoff=ex["CUTOFF"] * d, switch_width=ex["SWITCH"] * d,
                       induction=dk.Induction(tolerance=ex["TOLERANCE"]))
    floor = dk.Wall(point=(0, 0, 0), normal=(0, 0, 1))
    roof = dk.Wall(point=(0, 0, ex["GAP"] * d), normal=(0, 0, -1))
    scene = dk.Scene(particles, [ex["contact_law"](), dipole, floor, roof, dk.Gravity((0, 0, -ex["G"])),
                                 dk.UniformField((0, 0, ex["B0"]))], box=box)
    steps = 60 * math.ceil(duration / (ex["contact_time"]() / per_contact) / 60)
    return Case("steel_columns", scene, dk.VelocityVerlet, duration, duration / 300,
                "examples/steel_columns/run.py --quick (60 balls at volume fraction 0.05, 0.12 s, 15 steps a "
                "contact): particles from its build(), contact law from its contact_law(), the rest of the "
                "scene (induced dipoles, plates, gravity, field) inline in its main(), repeated here", duration / steps)


def _brownian(coupling):
    ex = example("brownian_colloid/run.py")
    n, settle, samples = 100, 10.0, 10  # --quick (500 spheres, t = 30 + 40 otherwise)
    scene = ex["colloid"](n, coupling, 2.0, 1)  # --quick: the one field xi = 2
    return Case(f"colloid_{'weak' if coupling == 1.0 else 'strong'}", scene, dk.VelocityVerlet,
                settle + samples, 1.0,
                f"examples/brownian_colloid/run.py --quick, lambda = {coupling:g}, xi = 2: its colloid(); the run "
                f"is settle {settle:g} + {samples} samples of 1 (Langevin bath: no energy balance)", ex["DT"])


def colloid_weak():
    return _brownian(1.0)


def colloid_strong():
    return _brownian(4.0)


def _magnetised(name, key):
    ex = example("magnetised_colloid/run.py")
    n, settle, samples = 125, 4.0, 12  # --quick (216 spheres, t = 20 + 60 otherwise)
    scene = ex["colloid"](n, 1.0, ex["SUMS"][key](), 1)  # --quick: the one field xi = 1
    return Case(name, scene, dk.VelocityVerlet, settle + samples, 1.0,
                f"examples/magnetised_colloid/run.py --quick, the sum '{key}', xi = 1: its colloid() and SUMS; "
                f"settle {settle:g} + {samples} samples of 1 (Langevin bath: no energy balance)", ex["DT"])


def magnetised_metallic():
    return _magnetised("magnetised_metallic", "Ewald, metallic")


def magnetised_vacuum():
    return _magnetised("magnetised_vacuum", "Ewald, vacuum")


def magnetised_cutoff():
    return _magnetised("magnetised_cutoff", "cut-off at 4 d")


def _cluster(name, flat):
    ex = example("magnetic_cluster/run.py")
    n, coupling, duration = 150, 20.0, 3.0  # --quick (400 spheres, t = 12 otherwise)
    particles, _ = ex["build"](n, coupling, flat, 1)
    stiffness = 6 * coupling / 0.01
    zeta = -math.log(0.7) / math.hypot(math.pi, math.log(0.7))
    damping = 2 * zeta * math.sqrt(stiffness * 0.5)
    scene = dk.Scene(particles, [dk.Dipole(prefactor=1.0), dk.KelvinVoigt(stiffness, damping)])
    steps = 100 * math.ceil(duration / (0.5 * scene.max_time_step()) / 100)
    return Case(name, scene, dk.VelocityVerlet, duration, duration / 200,
                f"examples/magnetic_cluster/run.py --quick{'' if flat else ' --3d'} (150 spheres, t = 3): particles "
                f"from its build(), the contact law (k = 6 lambda / 0.01, restitution 0.7) and scene inline in its "
                f"main(), repeated here; its dt is half of scene.max_time_step()", duration / steps)


def magnetic_cluster():
    return _cluster("magnetic_cluster", True)


def magnetic_cluster_3d():
    return _cluster("magnetic_cluster_3d", False)


def accuracy_cluster():
    ex = example("accuracy/cluster.py")
    return Case("accuracy_cluster", ex["cluster_scene"](), dk.VelocityVerlet, ex["DURATION"], 0.01,
                "examples/accuracy/cluster.py: its cluster_scene() (27 magnets collapsing), its duration; it "
                "compares seven methods at dt = 4e-3 .. 5e-4, velocity Verlet taken here (no quick mode)", 1e-3)


def accuracy_approach():
    return Case("accuracy_approach", dk.two_magnets.TwoMagnets(b_over_R=4.0).scene(), dk.VelocityVerlet, 24000.0,
                1.0, "examples/accuracy/run.py, report 'approach': dk.two_magnets.TwoMagnets(b_over_R=4).scene() for "
                "24000 (before the first contact); it runs dt = 0.2 .. 0.00625 with Euler-Cromer and velocity "
                "Verlet, velocity Verlet taken here (no quick mode)", 0.0125)


def accuracy_collision():
    return Case("accuracy_collision", dk.two_magnets.TwoMagnets(b_over_R=4.0).scene(), dk.VelocityVerlet, 60000.0,
                1.0, "examples/accuracy/run.py, report 'collision': the same scene for all 60000 (23 bounces, then "
                "stuck and turning); dt = 0.2 .. 0.00625, velocity Verlet taken here (no quick mode)", 0.0125)


# --- scenes a new user wrote from the docs -------------------------------------------------------

def _gas_field(name, long_range):
    n, radius = 200, 0.5
    box = dk.build.box_for(n, radius, 0.2, periodic=True)
    particles = dk.Particles(position=dk.build.random_packing(n, radius, box, seed=1), radius=radius, mass=1.0,
                             velocity=dk.build.thermal_velocities(n, kT=1.0, mass=1.0, seed=2),
                             dipole=dk.build.random_directions(n, seed=3))
    # unit moments pull two touching spheres together with 6; E = 5e4 squeezes them by 0.5 % of d
    contact = dk.Hertz(young=5e4, poisson=0.3, restitution=0.5, friction=dk.Friction(0.5))
    scene = dk.Scene(particles, [dk.Dipole(prefactor=1.0, long_range=long_range), contact,
                                 dk.UniformField([0.0, 0.0, 1.0])], box=box)
    return Case(name, scene, dk.VelocityVerlet, 20.0, 0.1,
                f"new user: {n} unit dipoles at volume fraction 0.2, periodic, kT = 1, {type(long_range).__name__}"
                f"(1e-4), Hertz E = 5e4 (pull squeezes 0.5 %) with friction 0.5, restitution 0.5, field 1 along z; "
                f"t = 20, some 500 contact times (Ewald measured 2.4 ms a step, ~31 s at half the safe step; P3M "
                f"estimated 1.6 times Ewald, ~50 s)")


def ewald_gas_field():
    return _gas_field("ewald_gas_field", dk.Ewald(1e-4))


def p3m_gas_field():
    return _gas_field("p3m_gas_field", dk.P3M(1e-4))


def steel_pour():
    return from_file("steel_pour", ROOT / "benchmarks" / "scenes" / "steel_pour.toml",
                     "; not shortened: 16 s at its own dt (benchmarks/results/info_estimate.json), ~8 s at half "
                     "the safe step (dk.cost.estimate)")


def langevin_colloid():
    n, radius = 100, 0.5
    box = dk.build.box_for(n, radius, 0.1, periodic=True)
    particles = dk.Particles(position=dk.build.random_packing(n, radius, box, seed=4), radius=radius, mass=1.0,
                             velocity=dk.build.thermal_velocities(n, kT=1.0, mass=1.0, seed=5),
                             dipole=1.5 * dk.build.random_directions(n, seed=6))
    scene = dk.Scene(particles, [dk.Dipole(prefactor=1.0, cutoff=4.0), dk.KelvinVoigt(stiffness=1000.0),
                                 dk.Langevin(temperature=1.0, drag=1.0, seed=7)], box=box)
    return Case("langevin_colloid", scene, dk.VelocityVerlet, 20.0, 0.5,
                f"new user: {n} moments of 1.5 (lambda = 2.25) at volume fraction 0.1, periodic, dipoles cut at "
                f"4 d, elastic Kelvin-Voigt k = 1000, Langevin kT = 1, drag 1 (no energy balance with a bath)")


def damped(stiffness, restitution, **kw):
    """A Kelvin-Voigt law with the restitution asked for between two unit masses (m* = 1/2)."""
    zeta = -math.log(restitution) / math.hypot(math.pi, math.log(restitution))
    return dk.KelvinVoigt(stiffness, 2 * zeta * math.sqrt(stiffness * 0.5), **kw)


def _fmm_cluster(name, n, fmm, duration, note):
    radius, coupling = 0.5, 1.0
    box = dk.build.box_for(n, radius, 0.15, periodic=False)  # open: only where the spheres start
    particles = dk.Particles(position=dk.build.random_packing(n, radius, box, seed=8), radius=radius, mass=1.0,
                             dipole=math.sqrt(coupling) * dk.build.random_directions(n, seed=9))
    contact = damped(6 * coupling / 0.01, 0.5)  # the touching pull squeezes by 1 % of d
    scene = dk.Scene(particles, [dk.Dipole(prefactor=1.0, long_range=fmm), contact])
    return Case(name, scene, dk.VelocityVerlet, duration, 0.1,
                f"new user: {n} unit magnets at rest at volume fraction 0.15 in open space, collapsing into "
                f"chains; Kelvin-Voigt k = 600, restitution 0.5; {note}")


def fmm_cluster():
    return _fmm_cluster("fmm_cluster", 1000, dk.FMM(1e-6), 10.0,
                        "FMM(1e-6). 1000 magnets, not the issue's 2000: 2000 take ~86 s at half the safe step "
                        "(dk.cost.estimate), 1000 ~22 s. Below FMM's crossover (~10600 spheres at 1e-6) demkit keeps "
                        "the exact all-pairs sum, so this case runs no multipole code (as the user's 2000 did not)")


def fmm_cluster_forced():
    return _fmm_cluster("fmm_cluster_forced", 300, dk.FMM(1e-6, exact_below=0), 5.0,
                        "FMM(1e-6, exact_below=0): the fast multipole sum forced, its force errors (1e-6 relative) "
                        "not the gradient of an energy; 300 magnets for t = 5 to keep it under a minute. An addition "
                        "to the brief's list, the only case that runs FMM3D")


def friction_gas_mu08():
    n, radius = 200, 0.5
    box = dk.build.box_for(n, radius, 0.3, periodic=True)
    particles = dk.Particles(position=dk.build.random_packing(n, radius, box, seed=10), radius=radius, mass=1.0,
                             velocity=dk.build.thermal_velocities(n, kT=1.0, mass=1.0, seed=11))
    contact = damped(1e4, 0.7, friction=dk.Friction(0.8))
    scene = dk.Scene(particles, [contact], box=box)
    return Case("friction_gas_mu08", scene, dk.VelocityVerlet, 10.0, 0.05,
                f"new user: {n} spheres at volume fraction 0.3, periodic, kT = 1 at the start, no dipoles; "
                f"Kelvin-Voigt k = 1e4, restitution 0.7, friction 0.8 (a cooling granular gas)")


SCENES = {f.__name__: f for f in (
    two_magnets_file, cluster_file, table, steel_columns, colloid_weak, colloid_strong, magnetised_metallic,
    magnetised_vacuum, magnetised_cutoff, magnetic_cluster, magnetic_cluster_3d, accuracy_cluster,
    accuracy_approach, accuracy_collision, ewald_gas_field, p3m_gas_field, steel_pour, langevin_colloid,
    fmm_cluster, fmm_cluster_forced, friction_gas_mu08)}


def build(name):
    """A fresh Case of the scene ``name`` (a key of SCENES)."""
    return SCENES[name]()


if __name__ == "__main__":
    print(f"{'case':20} {'N':>5} {'method':14} {'duration':>8} {'build s':>7} {'safe step':>9} {'steps at half':>13} "
          f"{'est. s':>6} {'source dt':>9}")
    for name in SCENES:
        clock = time.perf_counter()
        case = build(name)
        seconds = time.perf_counter() - clock
        limit, why = dk.guards.largest_safe_step(case.scene)
        if math.isfinite(limit):
            steps = math.ceil(case.duration / (0.5 * limit))
            method = case.method(0.5 * limit)
            estimate = dk.cost.estimate(case.scene, method, case.duration, record_every=case.record_every).total
        else:
            steps = estimate = float("nan")
            print(f"    no finite limit: {why}")
        method = getattr(case.method, "__name__", repr(case.method))
        source = f"{case.dt:.3g}" if case.dt else "-"
        print(f"{name:20} {len(case.scene.particles):5d} {method:14} {case.duration:8g} {seconds:7.2f} {limit:9.3g} "
              f"{steps:13} {estimate:6.1f} {source:>9}", flush=True)
