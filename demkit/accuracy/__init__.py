"""What accuracy costs: an adaptive reference solution and work-precision reports.

:func:`reference` integrates a small scene's equations of motion with scipy's DOP853 (8th order,
adaptive step) on the scene's own compiled forces, restarting exactly at every point where a force
law is not smooth (a contact begins or ends, a dashpot's clamp engages, a plain cutoff is crossed),
so that no DOP853 step straddles a jump. It is the truth against which fixed-step runs are measured.

:func:`work_precision` runs a scene with several integrators and time steps from the same initial
state and tabulates, for every run, its error against a reference (positions, velocities, the
energy balance, angular momentum, an observable of your choice) against what it cost (wall time,
force evaluations). ``report.suggest(target)`` names the cheapest run meeting a target;
:func:`suggest_dt` proposes a time step from a short pilot. See docs/accuracy.md.

The parts: :mod:`~demkit.accuracy.equations` (the scene's compiled forces as an ODE),
:mod:`~demkit.accuracy.switches` (where force laws are not smooth), :mod:`~demkit.accuracy.solver`
(the adaptive solver) and :mod:`~demkit.accuracy.study` (work-precision studies and time steps) with
:mod:`~demkit.accuracy.report` (their reports).
"""
from .solver import MAX_PARTICLES, ReferenceTrajectory, reference
from .report import MEASURES, Suggestion, WorkPrecision
from .study import DtSuggestion, copy_scene, suggest_dt, work_precision

__all__ = ["reference", "ReferenceTrajectory", "work_precision", "WorkPrecision", "Suggestion", "suggest_dt",
           "DtSuggestion", "copy_scene", "MEASURES", "MAX_PARTICLES"]
