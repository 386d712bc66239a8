"""Which dipole sum for my scene: force error against time per step for cut-off, Ewald, P3M and FMM sums.

:func:`compare_dipole_sums` evaluates the dipole forces and torques of one configuration with each
candidate sum and measures, against a converged reference (periodic box: an Ewald sum tuned to
1e-10; open space: the exact all-pairs sum),

    force error  = sqrt(<|F - F_ref|^2>) / P,         P = 6 A <|m|^2> / d^4
    torque error = sqrt(<|T - T_ref|^2>) / (P d)

(A the prefactor, <|m|^2> the mean squared moment, d the mean diameter: P is the pull of two
touching spheres with head-to-tail moments, the measure ``Ewald(accuracy=...)`` is tuned to), and
the wall time of one force evaluation (least of a few, neighbour lists built, one thread unless
asked; the tuning of Ewald and P3M is timed apart). ``report.cheapest(1e-4)`` names the fastest
candidate whose force error is at most 1e-4; ``report.table()`` and ``report.plot(path)`` show them
all. See docs/long_range.md, "Which sum for my scene".
"""
from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from .interactions.dipole import Dipole
from .interactions.ewald import Ewald
from .interactions.fmm import FMM
from .interactions.slab import open_axis
from .interactions.p3m import P3M
from .particles import Particles
from .scene import Scene

#: default cutoffs, in mean diameters, and the switch width as a fraction of the cutoff
CUTOFFS = (2.0, 3.0, 4.0, 5.0, 6.0)
SWITCH_FRACTION = 0.25
#: default accuracies of Ewald and P3M, and the FMM3D precisions tried in open space
ACCURACIES = (1e-3, 1e-4, 1e-5, 1e-6)
FMM_ACCURACIES = (1e-3, 1e-6, 1e-9)
#: the periodic reference: an Ewald sum tuned to this accuracy
REFERENCE_ACCURACY = 1e-10


@dataclass
class SumRow:
    """One candidate: ``label``, ``dipole`` (the ``dk.Dipole`` to put in your scene), ``force_error``
    and ``torque_error`` (see the module docstring), ``seconds`` (one force evaluation, least of the
    repeats), ``cpu_seconds`` (its CPU time, least of the repeats: what a busy machine
    disturbs least), ``tuning_seconds`` (tuning a long-range sum; 0 without), ``tuned`` (what the tuning
    chose, or the scene's note on it, or "")."""

    label: str
    dipole: Dipole
    force_error: float
    torque_error: float
    seconds: float
    cpu_seconds: float = math.nan
    tuning_seconds: float = 0.0
    tuned: str = ""

    def as_dict(self):
        return dict(label=self.label, dipole=repr(self.dipole), force_error=self.force_error,
                    torque_error=self.torque_error, seconds=self.seconds, cpu_seconds=self.cpu_seconds,
                    tuning_seconds=self.tuning_seconds,
                    tuned=self.tuned)


@dataclass
class DipoleSums:
    """What :func:`compare_dipole_sums` measured: ``rows`` (:class:`SumRow`), ``reference`` (a dict:
    label, dipole, seconds, tuning_seconds, tuned), ``pull`` P and ``diameter`` d (the error
    units), ``n``, ``periodic``, ``repeats``, ``threads`` ("1 thread" or "threads as each scene chose") and
    ``load`` (the machine's 1-minute load average before and after: above ~0.5 per core other work
    ran beside the timings), ``space`` (what was summed: periodic box, slab or open space)."""

    rows: list
    reference: dict
    pull: float
    diameter: float
    n: int
    periodic: bool
    repeats: int
    threads: str
    load: tuple = field(default=(math.nan, math.nan))
    #: "periodic box", "slab open along z" (or x, y) or "open space"
    space: str = "periodic box"

    def cheapest(self, accuracy, torque=None):
        """The fastest :class:`SumRow` whose force error is at most ``accuracy`` and, if ``torque``
        is given, whose torque error is at most ``torque`` (None if none is)."""
        good = [r for r in self.rows if r.force_error <= accuracy and (torque is None or r.torque_error <= torque)]
        return min(good, key=lambda r: r.seconds) if good else None

    def table(self):
        """A plain-text table, fastest first: label, force and torque error, wall and CPU ms per
        evaluation, tuning seconds; then the reference and the units."""
        head = ["candidate", "force err", "torque err", "ms/eval", "cpu ms", "tuning s"]
        cells = [[r.label, f"{r.force_error:.2e}", f"{r.torque_error:.2e}", f"{1e3 * r.seconds:.4g}",
                  f"{1e3 * r.cpu_seconds:.4g}",
                  f"{r.tuning_seconds:.3g}" if r.tuning_seconds else "-"]
                 for r in sorted(self.rows, key=lambda r: r.seconds)]
        widths = [max(len(h), *(len(c[k]) for c in cells)) if cells else len(h) for k, h in enumerate(head)]
        def line(c):
            return "  ".join(x.ljust(w) if k == 0 else x.rjust(w) for k, (x, w) in enumerate(zip(c, widths)))
        out = [line(head), line(["-" * w for w in widths])] + [line(c) for c in cells]
        ref = self.reference
        out += ["", f"{self.n} spheres, {self.space}; errors against "
                    f"{ref['label']} ({1e3 * ref['seconds']:.4g} ms/eval)",
                f"force err: RMS |F - F_ref| / {self.pull:.4g} (the touching pull 6 A <m^2>/d^4, d = "
                f"{self.diameter:.4g}); torque err: RMS |T - T_ref| / {self.pull * self.diameter:.4g} (pull x d)",
                f"ms/eval, cpu ms: least wall and CPU time of {self.repeats} force evaluations, lists built, "
                f"{self.threads}; "
                f"load average {self.load[0]:.2f} before, {self.load[1]:.2f} after"]
        return "\n".join(out)

    def __str__(self):
        return self.table()

    def as_dict(self):
        return dict(n=self.n, periodic=self.periodic, space=self.space, pull=self.pull, diameter=self.diameter,
                    repeats=self.repeats, threads=self.threads, load_before_after=list(self.load), reference=self.reference,
                    rows=[r.as_dict() for r in self.rows])

    def to_json(self, path=None):
        """The report as JSON text, written to ``path`` if given."""
        text = json.dumps(self.as_dict(), indent=1)
        if path is not None:
            with open(path, "w") as fh:
                fh.write(text + "\n")
        return text

    def plot(self, path, title=None, ax=None):
        """Log-log force error against ms per evaluation, one line per kind of sum; saved to ``path``
        (or drawn on a matplotlib ``ax``, then not saved). A candidate without error (the exact sum
        in open space) is a dotted vertical line at its time."""
        import matplotlib
        if ax is None:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        own = ax is None
        if own:
            fig, ax = plt.subplots(figsize=(6.4, 4.4))
        kinds = {}
        for r in self.rows:
            kinds.setdefault(_kind(r.dipole), []).append(r)
        for kind, rows in kinds.items():
            exact = [r for r in rows if r.force_error == 0.0]  # the reference itself: a time, no error
            for r in exact:
                ax.axvline(1e3 * r.seconds, color="grey", ls=":", label=f"{r.label} (the reference)")
            rows = sorted((r for r in rows if r.force_error > 0.0), key=lambda r: r.seconds)
            if not rows:
                continue
            x = [1e3 * r.seconds for r in rows]
            y = [r.force_error for r in rows]
            line, = ax.loglog(x, y, "o-", label=kind)
            for r, xi, yi in zip(rows, x, y):
                ax.annotate(_tag(r.dipole, self.diameter), (xi, yi), fontsize=6, color=line.get_color(),
                            xytext=(3, 3), textcoords="offset points")
        from matplotlib.ticker import NullFormatter
        ax.xaxis.set_minor_formatter(NullFormatter())  # the minor labels of a short log axis overlap
        ax.set_xlabel(f"one force evaluation (ms, {self.threads})")
        ax.set_ylabel("RMS force error / touching pull")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title(title or f"N = {self.n}, {self.space}; against "
                              f"{self.reference['label']}", fontsize=9)
        if own:
            fig.tight_layout()
            fig.savefig(path, dpi=120)
            plt.close(fig)
        return path


def _kind(dipole):
    if dipole.long_range is not None:
        return type(dipole.long_range).__name__
    if dipole.cutoff_distance is None:
        return "exact (all pairs)"
    return "switched cutoff" if dipole.switch_width is not None else "plain cutoff"


def _tag(dipole, diameter):
    """The candidate's parameter: accuracy of a long-range sum, cutoff in diameters, or ''."""
    if dipole.long_range is not None:
        return f"{dipole.long_range.accuracy:.0e}".replace("e-0", "e-")
    if dipole.cutoff_distance is None:
        return ""
    return f"{dipole.cutoff_distance / diameter:g} d"


def _label(dipole, diameter, n=0):
    if getattr(dipole.long_range, "uses_exact_sum", lambda n: False)(n):
        return f"{_kind(dipole)} {_tag(dipole, diameter)} (kept the exact sum)"
    if dipole.switch_width is not None:
        return f"switched cutoff {_tag(dipole, diameter)} (width {dipole.switch_width / diameter:g} d)"
    return " ".join(x for x in (_kind(dipole).replace("plain ", ""), _tag(dipole, diameter)) if x)


def default_candidates(prefactor, particles, box, surface="metallic"):
    """The candidates :func:`compare_dipole_sums` tries when given none (``Dipole`` objects):
    periodic box (or slab): plain and switched (width a quarter of the cutoff) cutoffs at 2-6 mean
    diameters shorter than half the shortest periodic side, Ewald and P3M at 1e-3 ... 1e-6; open
    space: the same cutoffs, the exact sum and, if fmm3dpy imports, FMM at eps 1e-3, 1e-6, 1e-9
    (``exact_below=0``: the FMM itself, even where the exact sum is cheaper). ``surface``: of Ewald
    and P3M."""
    d = 2.0 * float(np.mean(particles.radius))
    periodic = _periodic(box)
    half = 0.5 * float(np.min(np.asarray(box.size)[box.periodic])) if periodic else math.inf
    out = []
    for k in CUTOFFS:
        if k * d < half:
            rc = k * d
            out += [Dipole(prefactor, cutoff=rc), Dipole(prefactor, cutoff=rc, switch_width=SWITCH_FRACTION * rc)]
    if periodic:
        return out + [Dipole(prefactor, long_range=kind(a, surface)) for kind in (Ewald, P3M) for a in ACCURACIES]
    out.append(Dipole(prefactor))
    try:
        import fmm3dpy  # noqa: F401
    except ImportError:
        return out
    return out + [Dipole(prefactor, long_range=FMM(a, exact_below=0)) for a in FMM_ACCURACIES]


def _checked(candidate, prefactor, periodic, surface):
    """A candidate as a Dipole: Ewald / P3M / FMM settings get ``Dipole(prefactor, long_range=...)``;
    a Dipole must have this prefactor."""
    if isinstance(candidate, (Ewald, FMM)):  # P3M is a kind of Ewald
        candidate = Dipole(prefactor, long_range=candidate)
    if type(candidate) is not Dipole:
        raise ValueError(f"a candidate must be a dk.Dipole (with a cutoff, switch_width or long_range), dk.Ewald, "
                         f"dk.P3M or dk.FMM, got {candidate!r}")
    if candidate.prefactor != prefactor:
        raise ValueError(f"candidate {candidate!r} has prefactor {candidate.prefactor!r}, the comparison "
                         f"{prefactor!r}: every candidate must sum the same interaction")
    if periodic and candidate.long_range is None and candidate.cutoff_distance is None:
        raise ValueError(f"candidate {candidate!r} has no cutoff, which a periodic box cannot hold: give it a "
                         f"cutoff or long_range=dk.Ewald(...) / dk.P3M(...)")
    if getattr(candidate.long_range, "surface", surface) != surface:
        raise ValueError(f"candidate {candidate!r} sums in {candidate.long_range.surface!r} surroundings, the "
                         f"comparison in {surface!r} ones: pass surface={candidate.long_range.surface!r}")
    return candidate


def _measure(particles, box, dipole, repeats, parallel):
    """(forces, torques, least wall and CPU seconds of one evaluation, seconds of tuning the long-range
    sum (0 without), what the scene's tuning chose or its note, "" without)."""
    tuning = 0.0
    if dipole.long_range is not None:  # timed apart: Scene() would add compiling on first use
        t = time.perf_counter()
        dipole.long_range.tune(dipole.prefactor, particles, box, dipole.user_cutoff)
        tuning = time.perf_counter() - t
    scene = Scene(particles, [dipole], box=box, parallel=parallel)
    bound = scene.interactions[0]
    tuned = repr(bound.tuned) if bound.tuned is not None else getattr(bound, "long_range_note", None) or ""
    force, torque = scene.forces()  # compiles (first time) and builds the lists
    best, cpu = math.inf, math.inf
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        scene.forces()
        best, cpu = min(best, time.perf_counter() - t), min(cpu, time.process_time() - c)
    return force, torque, best, cpu, tuning, tuned


def compare_dipole_sums(particles, box, prefactor, candidates=None, repeats=3, parallel=False,
                        reference_accuracy=REFERENCE_ACCURACY, surface="metallic"):
    """Force and torque errors and time per evaluation of dipole sums on one configuration.

    particles : dk.Particles with dipole moments (the current positions and moments are compared).
    box : a dk.Box periodic along x, y and z, or along two of them (a slab: the reference and the Ewald
        and P3M candidates are slab sums, demkit.interactions.slab), or None (or a box without periodic
        axes) for open space.
    prefactor : A of ``dk.Dipole`` (mu0/4pi in SI).
    candidates : a list of ``dk.Dipole`` (same prefactor; a cutoff in a periodic box), ``dk.Ewald``,
        ``dk.P3M`` or ``dk.FMM`` objects; None: :func:`default_candidates`.
    repeats : timed force evaluations per candidate, after one untimed (compiling, building lists).
    parallel : passed to ``dk.Scene``: False (default) times one thread; None lets each scene decide.
    reference_accuracy : the accuracy of the periodic reference Ewald sum (open space: the exact sum).
    surface : what surrounds the periodic sample, "metallic" (default) or "vacuum" (see ``dk.Ewald``), for
        the reference and the default Ewald and P3M candidates. It decides what a cutoff misses in a
        polarised sample: metallic, the whole Lorentz field (4 pi/3) M; vacuum (a sphere of boxes), nothing
        on average, the cavity's field cancelling the sphere's demagnetising field.

    Returns a :class:`DipoleSums` report (module docstring). ValueError for particles without
    moments, a box periodic along one axis only, or a candidate that is none of the above.
    """
    if not isinstance(particles, Particles):
        raise ValueError(f"particles must be a dk.Particles, got {type(particles).__name__}")
    if particles.dipole is None or not np.any(particles.dipole):
        raise ValueError("compare_dipole_sums needs particles with dipole moments (Particles(..., dipole=...)), "
                         "but " + ("they have none" if particles.dipole is None else "every moment is zero"))
    periodic = _periodic(box)
    if box is not None and any(box.periodic) and not periodic:
        raise ValueError(f"compare_dipole_sums needs a box periodic along x, y and z or along two of them (a slab), "
                         f"or open space (got periodic={[bool(f) for f in box.periodic]}): no converged sum exists "
                         f"for a box periodic along one axis in demkit yet")
    if not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats must be a whole number of at least 1, got {repeats!r}")
    if candidates is None:
        candidates = default_candidates(prefactor, particles, box, surface)
    candidates = [_checked(c, prefactor, periodic, surface) for c in candidates]
    if not candidates:
        raise ValueError("compare_dipole_sums needs at least one candidate")
    d = 2.0 * float(np.mean(particles.radius))
    pull = 6.0 * prefactor * float(np.mean((particles.dipole ** 2).sum(1))) / d ** 4
    load = os.getloadavg()[0]
    ref = Dipole(prefactor, long_range=Ewald(reference_accuracy, surface)) if periodic else Dipole(prefactor)
    f_ref, t_ref, seconds, _, tuning, tuned = _measure(particles, box, ref, 1, parallel)
    reference = dict(label=_label(ref, d) + (f" ({surface})" if periodic else ""), dipole=repr(ref), seconds=seconds,
                     tuning_seconds=tuning, tuned=tuned)
    rows = []
    for dipole in candidates:
        force, torque, seconds, cpu, tuning, tuned = _measure(particles, box, dipole, repeats, parallel)
        rows.append(SumRow(_label(dipole, d, len(particles)), dipole, _rms(force - f_ref) / pull,
                           _rms(torque - t_ref) / (pull * d), seconds, cpu, tuning, tuned))
    axis = open_axis(box, "compare_dipole_sums", "") if periodic else -1
    space = "open space" if not periodic else "periodic box" if axis < 0 else f"slab open along {'xyz'[axis]}"
    return DipoleSums(rows, reference, pull, d, len(particles), periodic, repeats,
                      "1 thread" if parallel is False else "threads as each scene chose", (load, os.getloadavg()[0]),
                      space)


def _periodic(box):
    """Is ``box`` periodic along three axes or two (a slab)? (Open space otherwise.)"""
    return box is not None and int(np.count_nonzero(box.periodic)) >= 2


def _rms(a):
    return float(np.sqrt(np.mean((a ** 2).sum(1))))
