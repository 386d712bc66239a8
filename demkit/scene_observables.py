"""What a sweep of a scene file measures: the observables (:data:`OBSERVABLES`, add one with
:func:`observable`) and the task that runs one point of such a sweep (:func:`run_scene_point`). Also
reached as ``demkit.sweep.observable``, ``demkit.sweep.OBSERVABLES`` and ``demkit.sweep.run_scene_point``."""
from __future__ import annotations

import numpy as np


#: name -> f(loaded, trajectory) -> a value or a dict of {column suffix: value}
OBSERVABLES = {}
#: name -> the column suffixes of an observable that returns a dict (empty cells when it fails)
COLUMNS = {}


def observable(name, columns=None):
    """Register ``f(loaded, trajectory)`` as a named observable of scene sweeps (a dict result
    becomes columns name_<key>, its '' key the column name itself; ``columns`` lists those keys, so
    that a point where it fails has the same columns, empty)."""
    def register(f):
        OBSERVABLES[name] = f
        if columns is not None:
            COLUMNS[name] = tuple(columns)
        return f
    return register


@observable("sim_time")
def _sim_time(loaded, trajectory):
    """Simulated time at the end of the run."""
    return float(trajectory.time[-1])


@observable("kinetic_energy")
def _kinetic(loaded, trajectory):
    """Translational + rotational kinetic energy in the last frame."""
    e = trajectory.energy
    return float(e["kinetic"][-1] + e.get("rotational", np.zeros(1))[-1])


@observable("energy_drift")
def _drift(loaded, trajectory):
    """(E_total + E_dissipated)(end) - (...)(start), over |E_total(start)| (0 when that is 0):
    the integrator's error in energy."""
    e = trajectory.energy
    kept = e["total"] + e.get("dissipated", np.zeros_like(e["total"]))
    scale = abs(float(e["total"][0])) or 1.0
    return float((kept[-1] - kept[0]) / scale)


@observable("contacts")
def _contacts(loaded, trajectory):
    """Touching pairs (r < R_i + R_j, minimum image in a periodic box) in the last frame."""
    from .clustering import close_pairs
    return len(close_pairs(trajectory.position[-1], trajectory.radius, trajectory.box,
                           time=trajectory.time[-1]))


@observable("outcome")
def _outcome(loaded, trajectory):
    """'miss', 'bounce' or 'stick' of a two-sphere scene (:func:`demkit.two_magnets.analysis.outcome`)."""
    from .two_magnets import analysis
    return analysis.outcome(trajectory)


@observable("final_spin", columns=("", "sigma"))
def _final_spin(loaded, trajectory):
    """omega and its sigma of a settled pair (:func:`demkit.two_magnets.analysis.final_spin`)."""
    from .two_magnets import analysis
    omega, sigma = analysis.final_spin(trajectory)
    return {"": omega, "sigma": sigma}


_TENSOR = tuple(a + b for a in "xyz" for b in "xyz")


@observable("pressure")
def _pressure(loaded, trajectory):
    """p = trace(P) / 3 at the end (kinetic + pair virial over the box volume; :mod:`demkit.measure`)."""
    from . import measure
    return measure.stress(loaded.scene).pressure


@observable("pressure_tensor", columns=_TENSOR)
def _pressure_tensor(loaded, trajectory):
    """The pressure tensor P_ab at the end, columns pressure_tensor_xx ... _zz."""
    from . import measure
    tensor = measure.stress(loaded.scene).pressure_tensor
    return {a + b: float(tensor[i, k]) for i, a in enumerate("xyz") for k, b in enumerate("xyz")}


def _stress_series(loaded, trajectory):
    """The run's dk.StressSeries and the time its second half starts (what the means cover)."""
    series = getattr(loaded, "stress_series", None)
    if series is None:
        raise ValueError("measuring the stress during the run needs run.stress_every in the scene file")
    return series, 0.5 * (float(trajectory.time[0]) + float(trajectory.time[-1]))


@observable("stress", columns=_TENSOR)
def _stress(loaded, trajectory):
    """The pressure tensor P_ab averaged over the second half of the run (run.stress_every: a
    dk.StressSeries), columns stress_xx ... _zz."""
    series, after = _stress_series(loaded, trajectory)
    mean = series.mean(after=after)[0]
    return {a + b: float(mean[i, k]) for i, a in enumerate("xyz") for k, b in enumerate("xyz")}


_RHEOLOGY = ("rate", *(name + tail for name in ("shear_stress", "viscosity", "n1", "n2", "pressure")
                        for tail in ("", "_error")))


@observable("rheology", columns=_RHEOLOGY)
def _rheology(loaded, trajectory):
    """A sheared box's shear stress, viscosity, normal-stress differences N1, N2 and pressure over the
    second half of the run, each with its standard error (dk.StressSeries.rheology), and the rate:
    columns rheology_shear_stress, rheology_shear_stress_error, ..."""
    series, after = _stress_series(loaded, trajectory)
    return series.rheology(after=after)


@observable("coordination")
def _coordination(loaded, trajectory):
    """Mean contacts per sphere (sphere-sphere) at the end (:func:`demkit.measure.coordination`)."""
    from . import measure
    return float(np.mean(measure.coordination(loaded.scene)))


@observable("magnetisation", columns=("x", "y", "z"))
def _magnetisation(loaded, trajectory):
    """Total moment per box volume at the end, columns magnetisation_x, _y, _z."""
    from . import measure
    m = measure.magnetisation(loaded.scene)
    return {"x": float(m[0]), "y": float(m[1]), "z": float(m[2])}


@observable("clusters", columns=("count", "largest", "mean_size"))
def _clusters(loaded, trajectory):
    """Clusters of touching spheres at the end: their number, the largest, the mean size a sphere
    sees (:func:`demkit.measure.clusters`)."""
    from . import measure
    c = measure.clusters(loaded.scene)
    return {"count": c.count, "largest": c.largest, "mean_size": c.mean_size}


def observe(names, loaded, trajectory):
    """The observables ``names`` of a run as one flat dict; one that raises is there as its exception
    (:func:`run_point` records it in ``<name>_error``) and the others are measured all the same."""
    out = {}
    for name in names:
        try:
            value = OBSERVABLES[name](loaded, trajectory)
        except Exception as exc:  # noqa: BLE001 (recorded in the table next to the others)
            out[name] = exc
            out.update({f"{name}_{k}": None for k in COLUMNS.get(name, ()) if k != ""})
            continue
        if isinstance(value, dict):
            out.update({name if k == "" else f"{name}_{k}": v for k, v in value.items()})
        else:
            out[name] = value
    return out


def run_scene_point(point, scene, observables=("sim_time",), seed_key="seed"):
    """Task of scene sweeps: load the scene file with the point's values as overrides (dotted key
    paths; the ``seed`` goes to ``seed_key``), run it, and measure ``observables``. The file's
    [outputs] are not written (every point would overwrite the same files): the observables are
    the result."""
    from .scenefile import load_scene
    overrides = {(seed_key if k == "seed" else k): v for k, v in point.items()}
    loaded = load_scene(scene, overrides=overrides)
    loaded.outputs = {}
    trajectory = loaded.run()
    return observe(observables, loaded, trajectory)
