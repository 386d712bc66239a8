"""Measurements on recorded trajectories of a colliding pair (the seed paper's observables).

* :func:`final_spin` -- the paper's (and the experiment's) measurement of the barbell's spin: after
  the pair stopped bouncing (contact no longer broken), the mean angular velocity of the line of
  centres over the first ``revolutions`` full turns, omega = 2 pi / mean(T_k), with the standard
  deviation of the periods T_k as its uncertainty.
* :func:`final_state` -- the same window, plus the mean kinetic energy and compression in it.
* :func:`outcome` -- 'miss', 'bounce' or 'stick', decided only when the fate is certain.

Contact means r <= R_i + R_j on the recorded frames (and, for :func:`outcome`, any dissipated work).
A contact break shorter than the recording interval is invisible here; the revolution-based omega
does not depend on where its window starts, so this only shifts the window (see docs/two_magnets.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: energy entries that are not potential energies
_NOT_POTENTIAL = ("kinetic", "rotational", "total", "dissipated")


class UndeterminedOutcome(ValueError):
    """The recorded run ends before the pair's fate is certain: run longer."""


def _separation(trajectory, pair):
    i, j = pair
    n = trajectory.position.shape[1]
    if not (0 <= i < n and 0 <= j < n) or i == j:
        raise ValueError(f"pair {pair} is not two distinct particle indices of {n}")
    d = trajectory.position[:, j] - trajectory.position[:, i]
    return d, np.linalg.norm(d, axis=1), trajectory.radius[i] + trajectory.radius[j]


def settle_index(trajectory, pair=(0, 1)):
    """First frame after which the pair stays in contact (r <= R_i + R_j) to the end of the run.

    Raises ValueError if the pair never touched or is apart in the last frame.
    """
    _, r, reach = _separation(trajectory, pair)
    touching = r <= reach
    if not touching.any():
        raise ValueError("the spheres never touched (outcome 'miss')")
    if not touching[-1]:
        raise ValueError("the spheres are apart in the last frame: they have not settled")
    apart = np.flatnonzero(~touching)
    return 0 if len(apart) == 0 else int(apart[-1] + 1)


def _turn_angle(trajectory, start, pair):
    """Unwrapped angle (rad) of the line of centres from frame ``start`` on, growing in the sense
    of the relative orbital angular momentum d x (v_j - v_i) (so a moving centre of mass is fine)."""
    i, j = pair
    d = (trajectory.position[start:, j] - trajectory.position[start:, i])
    v = (trajectory.velocity[start:, j] - trajectory.velocity[start:, i])
    axis = np.cross(d, v).sum(axis=0)
    norm = np.linalg.norm(axis)
    if norm == 0 or not np.isfinite(norm):
        raise ValueError("the line of centres does not turn (zero orbital angular momentum)")
    axis /= norm
    e1 = np.cross(axis, [1.0, 0.0, 0.0])
    if np.linalg.norm(e1) < 0.5:
        e1 = np.cross(axis, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    angle = np.unwrap(np.arctan2(d @ e2, d @ e1))
    return angle - angle[0]


def revolution_times(trajectory, revolutions=5, pair=(0, 1)):
    """(start, times): the settle frame and the revolutions + 1 times t_0 (settling) ... t_n at which
    the line of centres completed each full turn after settling (linear interpolation in frames)."""
    revolutions = int(revolutions)
    if revolutions < 2:
        raise ValueError("revolutions must be at least 2 (the spread of the periods is the uncertainty)")
    start = settle_index(trajectory, pair)
    angle = _turn_angle(trajectory, start, pair)
    turns = 2 * np.pi * np.arange(1, revolutions + 1)
    if angle.max() < turns[-1]:
        raise ValueError(f"only {angle.max() / (2 * np.pi):.2f} revolutions were recorded after the "
                         f"spheres settled; {revolutions} are needed: run longer")
    # the libration of a real barbell never reverses the turn at the recorded resolution; if it did,
    # the first time each angle is reached is used
    angle = np.maximum.accumulate(angle)
    t = trajectory.time[start:]
    first = np.searchsorted(angle, turns)  # first frame at or beyond each full turn
    crossings = np.empty(revolutions + 1)
    crossings[0] = t[0]
    for k, (target, f) in enumerate(zip(turns, first)):
        a0, a1 = angle[f - 1], angle[f]
        crossings[k + 1] = t[f - 1] + (t[f] - t[f - 1]) * (target - a0) / (a1 - a0)
    return start, crossings


def final_spin(trajectory, revolutions=5, pair=(0, 1)):
    """(omega, sigma) of the settled pair, in rad per time unit.

    omega = 2 pi / mean(T_k) is the mean angular velocity of the line of centres over the first
    ``revolutions`` full turns after the pair settled (contact no longer broken); sigma =
    omega std(T_k) / mean(T_k) propagates the sample standard deviation (ddof = 1) of the periods,
    the seed paper's uncertainty. Raises ValueError if the pair did not settle or turned too little.
    """
    _, times = revolution_times(trajectory, revolutions, pair)
    periods = np.diff(times)
    mean = periods.mean()
    omega = 2 * np.pi / mean
    return float(omega), float(omega * periods.std(ddof=1) / mean)


@dataclass(frozen=True)
class FinalState:
    """The settled barbell over the window of :func:`final_spin` (time units of the run).

    omega, sigma: as :func:`final_spin`; periods: the T_k; settle_time, end_time: the window;
    kinetic: mean translational + rotational kinetic energy in the centre-of-mass frame;
    total: mean total energy; compression: mean (R_i + R_j - r)/(R_i + R_j).
    """

    omega: float
    sigma: float
    periods: np.ndarray
    settle_time: float
    end_time: float
    kinetic: float
    total: float
    compression: float


def final_state(trajectory, revolutions=5, pair=(0, 1)):
    """:class:`FinalState` of the settled pair (energies are the whole system's, as recorded)."""
    start, times = revolution_times(trajectory, revolutions, pair)
    stop = int(np.searchsorted(trajectory.time, times[-1], side="right"))
    window = slice(start, max(stop, start + 1))
    periods = np.diff(times)
    omega = 2 * np.pi / periods.mean()
    e = trajectory.energy
    mass = trajectory.mass
    momentum = (mass[None, :, None] * trajectory.velocity[window]).sum(axis=1)
    centre_of_mass = 0.5 * (momentum ** 2).sum(axis=1) / mass.sum()
    kinetic = e["kinetic"][window] + e["rotational"][window] - centre_of_mass
    _, r, reach = _separation(trajectory, pair)
    return FinalState(omega=float(omega), sigma=float(omega * periods.std(ddof=1) / periods.mean()),
                      periods=periods, settle_time=float(times[0]), end_time=float(times[-1]),
                      kinetic=float(kinetic.mean()), total=float(e["total"][window].mean()),
                      compression=float(((reach - r[window]) / reach).mean()))


# ---- outcome ----------------------------------------------------------------------------------
def _dipolar_strength(trajectory, pair, prefactor):
    """S such that the pair's potential obeys |U| <= S / r^3 and |F.n| <= 3 S / r^4 at any
    orientation: S = 2 A |m_i||m_j| for the dipole and power-law laws (|m_i.(1 - 3nn).m_j| <= 2|m_i||m_j|).

    Without ``prefactor`` S is read from the recorded magnetic energy: the larger of max |U| r^3
    (exact for the power law) and 2 |m_i||m_j| |U| r^3 / |f| at the frame of largest dipole geometry
    |f| = |m_i.m_j - 3 (m_i.n)(m_j.n)| (exact for the full law); never below the true S for either.
    """
    u = np.asarray(trajectory.energy.get("magnetic", 0.0)) * np.ones(len(trajectory.time))
    if trajectory.dipole is None:
        if np.any(u != 0):
            raise ValueError("magnetic energy without recorded dipoles: pass prefactor=")
        return 0.0
    i, j = pair
    mi, mj = trajectory.dipole[:, i], trajectory.dipole[:, j]
    size = np.linalg.norm(mi, axis=1) * np.linalg.norm(mj, axis=1)
    if prefactor is not None:
        return float(2.0 * prefactor * size[-1])
    d, r, _ = _separation(trajectory, pair)
    seen = float(np.max(np.abs(u) * r ** 3))  # = S for the power law, <= S for the full law
    n = d / r[:, None]
    f = (mi * mj).sum(axis=1) - 3.0 * (mi * n).sum(axis=1) * (mj * n).sum(axis=1)
    k = int(np.argmax(np.abs(f)))
    if f[k] == 0:
        return seen
    return max(seen, float(2.0 * size[k] * abs(u[k]) * r[k] ** 3 / abs(f[k])))


def pair_energy(trajectory, frame=-1, pair=(0, 1)):
    """Energy of the isolated pair's relative motion at ``frame``: mu |v_j - v_i|^2 / 2 + spin
    kinetic energy + recorded potential energies (mu = m_i m_j/(m_i + m_j)). Negative: bound."""
    i, j = pair
    m_i, m_j = trajectory.mass[i], trajectory.mass[j]
    v = trajectory.velocity[frame, j] - trajectory.velocity[frame, i]
    energy = 0.5 * m_i * m_j / (m_i + m_j) * float(v @ v)
    if trajectory.angular_velocity is not None:
        w = trajectory.angular_velocity[frame]
        energy += 0.5 * float((trajectory.inertia[[i, j]] * (w[[i, j]] ** 2).sum(axis=1)).sum())
    return energy + sum(float(np.asarray(trajectory.energy[k])[frame]) for k in trajectory.energy
                        if k not in _NOT_POTENTIAL)


def escaping(trajectory, frame=-1, pair=(0, 1), prefactor=None):
    """True if the pair is certain to separate for good: apart, receding, and its radial kinetic
    energy mu rdot^2 / 2 exceeds S / r^3, the most work any dipolar attraction can do against it on
    the way out (|F.n| <= 3 S / r^4; the centrifugal term only helps). Two-body scenes only."""
    d, r, reach = _separation(trajectory, pair)
    i, j = pair
    m_i, m_j = trajectory.mass[i], trajectory.mass[j]
    v = trajectory.velocity[frame, j] - trajectory.velocity[frame, i]
    rdot = float(d[frame] @ v) / r[frame]
    if r[frame] <= reach or rdot <= 0:
        return False
    radial = 0.5 * m_i * m_j / (m_i + m_j) * rdot * rdot
    return bool(radial > _dipolar_strength(trajectory, pair, prefactor) / r[frame] ** 3)


def outcome(trajectory, pair=(0, 1), prefactor=None):
    """'miss' (never touched), 'bounce' (touched, then separate for good) or 'stick' (barbell).

    Decided only when certain, for an isolated pair with dipolar forces and a contact law
    (the energies recorded in the trajectory are the pair's):

    * 'miss' / 'bounce': the pair is :func:`escaping` in the last frame, without / after contact;
    * 'stick': after contact the pair is bound (:func:`pair_energy` < 0, so it can never separate
      for good and each further contact dissipates), or it has stayed in contact for a full turn;
    * otherwise :class:`UndeterminedOutcome` (a ValueError): run longer.

    Contact: some frame with r <= R_i + R_j, or dissipated work (a graze between frames).
    ``prefactor`` (the Dipole's A) sharpens the escape bound; without it A is read from the
    recorded magnetic energy.
    """
    if trajectory.position.shape[1] != 2:
        raise ValueError("outcome() needs a two-particle trajectory (the energies must be the pair's)")
    _, r, reach = _separation(trajectory, pair)
    touching = r <= reach
    dissipated = np.asarray(trajectory.energy.get("dissipated", 0.0)) * np.ones(len(r))
    touched = bool(touching.any() or dissipated[-1] > dissipated[0])
    if escaping(trajectory, -1, pair, prefactor):
        return "bounce" if touched else "miss"
    if touched and pair_energy(trajectory, -1, pair) < 0:
        return "stick"
    if touched and touching[-1]:
        start = settle_index(trajectory, pair)
        try:
            if _turn_angle(trajectory, start, pair).max() >= 2 * np.pi:
                return "stick"
        except ValueError:
            pass
    state = "in contact" if touching[-1] else "apart"
    raise UndeterminedOutcome(f"the spheres are {state} and neither bound nor certain to escape in the "
                              f"last frame (t = {trajectory.time[-1]:.6g}): run longer")
