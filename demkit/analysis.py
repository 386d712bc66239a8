"""Measurements on recorded trajectories (two-body collisions).

``final_spin`` mimics the seed paper's (and the experiment's) measurement of the barbell's spin:
after the last separation of the pair, the mean angular velocity of the line of centres over the
first ``revolutions`` full turns, with the spread of those periods as the uncertainty.
"""
from __future__ import annotations

import numpy as np


def _separation(trajectory, pair):
    i, j = pair
    n = trajectory.position.shape[1]
    if not (0 <= i < n and 0 <= j < n) or i == j:
        raise ValueError(f"pair {pair} is not two distinct particle indices of {n}")
    d = trajectory.position[:, j] - trajectory.position[:, i]
    return d, np.linalg.norm(d, axis=1), trajectory.radius[i] + trajectory.radius[j]


def settle_index(trajectory, pair=(0, 1)):
    """First frame after which the pair stays in contact (r <= R_i + R_j) until the end.

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


def final_spin(trajectory, revolutions=5, pair=(0, 1)):
    """(omega, sigma): mean angular velocity of the line of centres over the first ``revolutions``
    turns after the pair settled, omega = 2 pi / mean(T_k), and sigma = 2 pi std(T_k) / mean(T_k)^2
    from the sample standard deviation of the periods T_k. Angles are measured in the plane normal to
    the total angular momentum; frames are interpolated linearly to find each full turn.
    """
    revolutions = int(revolutions)
    if revolutions < 2:
        raise ValueError("revolutions must be at least 2 (the spread of the periods is the uncertainty)")
    start = settle_index(trajectory, pair)
    d, _, _ = _separation(trajectory, pair)
    axis = trajectory.angular_momentum[start]
    norm = np.linalg.norm(axis)
    if norm == 0:
        raise ValueError("the total angular momentum is zero: there is no rotation axis")
    axis = axis / norm
    e1 = np.cross(axis, [1.0, 0.0, 0.0])
    if np.linalg.norm(e1) < 0.5:
        e1 = np.cross(axis, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    seg = d[start:]
    angle = np.unwrap(np.arctan2(seg @ e2, seg @ e1))
    angle -= angle[0]
    turns = 2 * np.pi * np.arange(1, revolutions + 1)
    if angle[-1] < turns[-1]:
        raise ValueError(f"only {angle[-1] / (2 * np.pi):.2f} revolutions were recorded after the "
                         f"spheres settled; {revolutions} are needed: run longer")
    if np.any(np.diff(angle) < 0):
        # angle must grow monotonically for the interpolation to be unique
        angle = np.maximum.accumulate(angle)
    t = trajectory.time[start:]
    crossings = np.concatenate([[t[0]], np.interp(turns, angle, t)])
    periods = np.diff(crossings)
    mean = periods.mean()
    omega = 2 * np.pi / mean
    sigma = 2 * np.pi * periods.std(ddof=1) / mean**2
    return float(omega), float(sigma)


def outcome(trajectory, pair=(0, 1), prefactor=None):
    """'miss' (never touched), 'bounce' (touched, then apart and flying apart unbound at the end)
    or 'stick' (in contact in the last frame).

    A pair that is apart but still bound (or approaching) at the end raises ValueError: the run is
    too short to tell. Boundness uses the relative kinetic energy plus the recorded potential
    energies (trajectory.energy), so it is exact for an isolated pair.
    """
    d, r, reach = _separation(trajectory, pair)
    touching = r <= reach
    if not touching.any():
        return "miss"
    if touching[-1]:
        return "stick"
    i, j = pair
    m_i, m_j = trajectory.mass[i], trajectory.mass[j]
    v_rel = trajectory.velocity[-1, j] - trajectory.velocity[-1, i]
    receding = float(d[-1] @ v_rel) > 0
    potential = sum(trajectory.energy[k][-1] for k in trajectory.energy
                    if k not in ("kinetic", "rotational", "total", "dissipated"))
    relative = 0.5 * m_i * m_j / (m_i + m_j) * float(v_rel @ v_rel) + potential
    if receding and relative > 0:
        return "bounce"
    raise ValueError("the spheres are apart but still bound or approaching in the last frame: "
                     "run longer to tell 'bounce' from 'stick'")
