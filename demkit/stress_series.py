"""The stress of a scene as a time series, measured while a run goes on, and the rheology of a sheared
sample from it.

A :class:`StressSeries` is a writer (``Simulation(..., writers=[series])``): every ``every`` time units
it takes :func:`demkit.measure.stress` of the scene as it stands, with the contact history the run holds
at that moment (recorded frames alone cannot give friction's springs), so its samples are the
pressure tensor P(t) and its parts::

    series = dk.StressSeries(every=0.05, path="stress.csv")   # the file: one line per sample, flushed
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt), writers=[series])
    sim.run(20.0)
    mean, error = series.mean(after=10.0)     # <P> over t >= 10 and its standard error (block averages)
    r = series.rheology(after=10.0)           # a sheared box: shear stress, viscosity, N1, N2

**Rheology of simple shear** (:class:`demkit.Shear`, flow along a, gradient along b, vorticity c;
sigma = -P, tension positive)::

    sigma_ab = -P_ab,   eta = sigma_ab / gammadot,   N1 = sigma_aa - sigma_bb = P_bb - P_aa,
    N2 = sigma_bb - sigma_cc = P_cc - P_bb,   p = trace(P) / 3

**Errors** are standard errors of the mean from :data:`BLOCKS` block averages over the samples kept
(samples a correlation time apart are not independent; blocks longer than it are): with fewer than
2 samples per block the error is not given (NaN).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .checks import writer_interval

#: the number of blocks the samples of a mean are cut into for its standard error
BLOCKS = 8
_AXES = "xyz"
_COMPONENTS = tuple(a + b for a in _AXES for b in _AXES)


def rheology(pressure_tensor, shear):
    """The rheology (module docstring) of a pressure tensor P (3, 3) under ``shear`` (a
    :class:`demkit.Shear`): a dict of shear_stress, viscosity, n1, n2, pressure."""
    P = np.asarray(pressure_tensor, dtype=float)
    a, b = shear.axes
    c = 3 - a - b
    sigma = -P[a, b]
    return {"shear_stress": float(sigma), "viscosity": float(sigma / shear.rate) if shear.rate != 0 else math.nan,
            "n1": float(P[b, b] - P[a, a]), "n2": float(P[c, c] - P[b, b]), "pressure": float(np.trace(P) / 3.0)}


def block_mean(values):
    """(mean, standard error) over axis 0 of ``values``, the error from :data:`BLOCKS` block means
    (NaN with fewer than 2 samples per block)."""
    values = np.asarray(values, dtype=float)
    mean = values.mean(axis=0)
    per = values.shape[0] // BLOCKS
    if per < 2:
        return mean, np.full_like(mean, math.nan)
    blocks = values[values.shape[0] - per * BLOCKS:].reshape(BLOCKS, per, *values.shape[1:]).mean(axis=1)
    return mean, blocks.std(axis=0, ddof=1) / math.sqrt(BLOCKS)


class StressSeries:
    """Measure the stress every ``every`` time units of a run (a writer of :class:`demkit.Simulation`).

    every : time between samples (rounded to whole steps by the simulation); the state each run
        ends in is sampled too.
    path : a CSV file the samples also go to, a line each, flushed as it is taken (a killed run
        keeps what it measured): time, then P_xx ... P_zz, then the kinetic part (kinetic_xx ...)
        and each pair interaction's virial part (``<name>_xx`` ...), all divided by the volume.
        An existing file is refused unless ``overwrite=True`` or ``resume=True`` (a run resumed
        from a checkpoint: its samples up to the checkpoint's time are kept, the later ones dropped).
    volume : the volume to divide by (default: the box's at each sample; required in open space).
    """

    def __init__(self, every, path=None, volume=None, overwrite=False, resume=False):
        self.every = writer_interval(every, overwrite, resume, "samples")
        self.path = None if path is None else Path(path)
        if self.path is not None and self.path.exists() and not (overwrite or resume):
            raise ValueError(f"{self.path} exists: pass overwrite=True to replace it (or resume=True to continue it)")
        self.volume = volume
        self._resume = resume
        self._times, self._totals, self._kinetic, self._parts = [], [], [], {}
        self._file = None
        self.shear = None

    # ---- writer protocol ---------------------------------------------------------------------
    def open(self, simulation):
        """Start the series (called by the simulation). A series measures one simulation: given to a
        second one it refuses (its samples, and its file, would mix two runs)."""
        from .measure import volume_of
        if self._times or self._file is not None:
            raise ValueError("this StressSeries has measured a simulation already: give each simulation a new one "
                             "(its samples and file would mix two runs)")
        volume_of(simulation.scene, self.volume)  # refuses an open scene without volume= now
        box = simulation.scene.box
        self.shear = box.shear if box is not None else None
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(self.path, "w")

    def resume(self, simulation):
        """Continue the file of a run resumed at ``simulation.time``: its samples up to that time are
        read back (the later ones, taken after the checkpoint, are dropped). Returns whether the
        current state is to be sampled (not when the file has a sample at this time)."""
        kept = []
        if self.path is not None and self.path.exists():
            with open(self.path) as f:
                header = f.readline().strip().split(",")
                kept = [line for line in f if line.strip() and float(line.split(",")[0]) <= simulation.time
                        * (1 + 1e-12)]
        self.open(simulation)
        if kept:
            names = [h[:-3] for h in header[19::9]]
            self._parts = {name: [] for name in names}
            for line in kept:
                row = np.array(line.split(","), dtype=float)
                self._store(row[0], row[1:10].reshape(3, 3), row[10:19].reshape(3, 3),
                            {name: row[19 + 9 * k:28 + 9 * k].reshape(3, 3) for k, name in enumerate(names)})
            self._file.write(",".join(header) + "\n" + "".join(kept))
            self._file.flush()
        return not kept or self._times[-1] < simulation.time * (1 - 1e-12)

    def write(self, simulation):
        """Measure the current state of ``simulation`` (called by the simulation)."""
        from .measure import stress
        s = stress(simulation.scene, self.volume)
        parts = {name: w / s.volume for name, w in s.virial.items()}
        if self._file is not None and not self._times:
            columns = ["time", *("P_" + c for c in _COMPONENTS), *("kinetic_" + c for c in _COMPONENTS)]
            columns += [f"{name}_{c}" for name in parts for c in _COMPONENTS]
            self._file.write(",".join(columns) + "\n")
        self._store(float(simulation.time), s.pressure_tensor, s.kinetic / s.volume, parts)
        if self._file is not None:
            row = [self._times[-1], *self._totals[-1].ravel(), *self._kinetic[-1].ravel()]
            row += [v for name in self._parts for v in self._parts[name][-1].ravel()]
            self._file.write(",".join(repr(float(v)) for v in row) + "\n")
            self._file.flush()

    def close(self):
        """Close the file (the samples stay in memory)."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def _store(self, time, total, kinetic, parts):
        self._times.append(time)
        self._totals.append(np.asarray(total, dtype=float))
        self._kinetic.append(np.asarray(kinetic, dtype=float))
        for name, value in parts.items():
            self._parts.setdefault(name, [np.zeros((3, 3))] * (len(self._times) - 1)).append(value)

    # ---- the samples -------------------------------------------------------------------------
    @property
    def time(self):
        """(k,) the times of the samples."""
        return np.array(self._times)

    @property
    def pressure_tensor(self):
        """(k, 3, 3) P at each sample."""
        return np.array(self._totals).reshape(-1, 3, 3)

    @property
    def kinetic(self):
        """(k, 3, 3) the kinetic part of P (relative to the imposed flow in a sheared box)."""
        return np.array(self._kinetic).reshape(-1, 3, 3)

    @property
    def parts(self):
        """{pair interaction name: (k, 3, 3) its virial part of P}."""
        return {name: np.array(v) for name, v in self._parts.items()}

    def _kept(self, after):
        if not self._times:
            raise ValueError("the series has no samples yet: run a simulation with it among its writers")
        start = -math.inf if after is None else float(after)
        keep = self.time >= start
        if not keep.any():
            raise ValueError(f"no sample at or after t = {after} (the last is at t = {self._times[-1]:.6g})")
        return keep

    def mean(self, after=None):
        """(<P>, its standard error), both (3, 3), over the samples at t >= ``after`` (all by default);
        the error is NaN with fewer than 16 samples (2 per block of :data:`BLOCKS`: no estimate)."""
        return block_mean(self.pressure_tensor[self._kept(after)])

    def statistics(self, since):
        """What a run's ``sim.statistics`` says of its stress (the samples at t >= ``since``, the run's
        start): ``{"stress": {"samples", "pressure_tensor", "pressure_tensor_error", "pressure",
        "rheology"}}``, the tensors as nested lists, ``rheology`` (see :meth:`rheology`) in a sheared box
        only; ``{"stress": None}`` when the run took no sample."""
        if not self._times or self._times[-1] < since:
            return {"stress": None}
        keep = self._kept(since)
        mean, error = block_mean(self.pressure_tensor[keep])
        return {"stress": {"samples": int(keep.sum()), "pressure_tensor": mean.tolist(),
                           "pressure_tensor_error": error.tolist(), "pressure": float(np.trace(mean) / 3.0),
                           "rheology": self.rheology(after=since) if self.shear is not None else None}}

    def rheology(self, after=None):
        """The rheology of a sheared sample (module docstring) over the samples at t >= ``after``:
        a dict of shear_stress, viscosity, n1, n2, pressure and each one's ``<name>_error`` (NaN with
        fewer than 16 samples, as :meth:`mean`), and rate."""
        if self.shear is None:
            raise ValueError("rheology needs a sheared box (dk.Box(..., shear=dk.Shear(rate, ...))); "
                             "mean() gives the stress of any scene")
        samples = [rheology(P, self.shear) for P in self.pressure_tensor[self._kept(after)]]
        out = {"rate": float(self.shear.rate)}
        for name in samples[0]:
            out[name], out[name + "_error"] = (float(v) for v in block_mean([s[name] for s in samples]))
        return out
