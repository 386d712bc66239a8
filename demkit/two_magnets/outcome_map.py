"""The outcome map of the paper's collision: miss / bounce / stick over impact parameter, speed and
the dipoles' initial orientation (a sweep task for :func:`demkit.sweep`; docs/outcome_map.md).

:func:`two_magnets_point` runs one :class:`TwoMagnets` collision until its outcome is certain
(:meth:`TwoMagnets.fate`) and returns the outcome with a few observables of the approach.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from . import analysis
from .scene import TwoMagnets
from ..integrators import EulerCromer, VelocityVerlet

#: the fields of TwoMagnets a point may set (b_over_R is required)
SETUP_FIELDS = tuple(f.name for f in dataclasses.fields(TwoMagnets))
INTEGRATORS = {"euler_cromer": EulerCromer, "velocity_verlet": VelocityVerlet}
#: run settings a point may set besides the set-up, with their defaults
RUN_SETTINGS = {"dt": 0.01, "integrator": "euler_cromer", "max_time": None, "seed": None}


def two_magnets_point(point):
    """One collision of the sweep: ``point`` holds TwoMagnets fields (b_over_R, speed, orientation
    in degrees, dipoles, model, x0, damping, prefactor, ...) and optionally dt, integrator
    ('euler_cromer' or 'velocity_verlet'), max_time (see :meth:`TwoMagnets.fate`) and seed (unused:
    the collision is deterministic).

    Returns outcome ('miss' / 'bounce' / 'stick'), closest (the smallest centre distance over 2R;
    <= 1 once touched), first_contact (time of the first recorded contact, None for a miss),
    contacts (separate contacts seen: a bounce has one or more, a stick usually several before it
    settles) and sim_time (simulated time needed to be certain of the outcome).
    """
    unknown = sorted(set(point) - set(SETUP_FIELDS) - set(RUN_SETTINGS))
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown}: use TwoMagnets fields {list(SETUP_FIELDS)} "
                         f"or {list(RUN_SETTINGS)}")
    if "b_over_R" not in point:
        raise ValueError("a point needs b_over_R")
    run = {k: point.get(k, default) for k, default in RUN_SETTINGS.items()}
    if run["integrator"] not in INTEGRATORS:
        raise ValueError(f"integrator must be one of {sorted(INTEGRATORS)}, got {run['integrator']!r}")
    setup = TwoMagnets(**{k: v for k, v in point.items() if k in SETUP_FIELDS})
    fate, trajectory = setup.fate(dt=run["dt"], integrator=INTEGRATORS[run["integrator"]],
                                  max_time=run["max_time"])
    _, r, reach = analysis._separation(trajectory, (0, 1))
    touching = r <= reach
    starts = int(touching[0]) + int(np.count_nonzero(touching[1:] & ~touching[:-1]))
    return {"outcome": fate, "closest": float(r.min() / reach),
            "first_contact": float(trajectory.time[np.argmax(touching)]) if touching.any() else None,
            "contacts": starts, "sim_time": float(trajectory.time[-1])}
