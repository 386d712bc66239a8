"""Notes at the end of a run: what a careful user would want to know, said plainly; never a stop.

At the end of a run, :class:`RunNotes` reads the frames the run recorded (all of them, or an evenly
spaced subset: at most one frame per :data:`STEPS_PER_FRAME` steps of the run and
:data:`SPHERE_FRAMES` sphere-frames in all, so that reading them costs a few percent of the run at
most; a run shorter than STEPS_PER_FRAME steps reads none and reports no overlaps). The figures
depend only on the run, never on the machine's speed:

* **contact overlaps**: delta / R_min of every touching pair (R_min the smaller radius) when the
  scene has a contact law, and delta / R of every sphere on a wall. The *largest* is the maximum over
  the frames, the *typical* the mean over the contacts of a frame, averaged over the frames with
  contacts. What happens between two frames is not seen: the largest overlap is a lower bound,
  as close as the recording is fine;
* **the energy balance**: E = kinetic + rotational + potential + dissipated, which the equations of
  motion keep constant. Its drift is max |E - E_start| over the frames, as a fraction of the
  energy scale (kinetic + rotational + the sum of |potential energies|, largest frame), the same
  scale as ``Simulation(max_energy_growth=...)``. Not reported when a moving wall works on the
  spheres or a thermostat exchanges energy with its bath (the balance then has a term demkit does
  not book).

A run resumed from a checkpoint goes on from the figures the checkpoint kept
(:meth:`RunNotes.state`, read from the frames recorded before it): its notes cover the whole run.

A note is due when the largest overlap exceeds :data:`LARGEST_OVERLAP`, the typical one
:data:`TYPICAL_OVERLAP`, or the drift :data:`ENERGY_DRIFT`. The notes go into
``Simulation.statistics["notes"]`` (with the figures under ``"overlap_largest"``,
``"overlap_typical"`` and ``"energy_drift"``) and on stderr (``DEMKIT_QUIET=1`` keeps stderr quiet).
"""
from __future__ import annotations

import functools
import sys

import numpy as np

from .interactions.wall import Wall
from .progress import quiet
from .clustering import close_pairs

#: a contact overlapping by more than this fraction of the smaller radius, in any frame, gets a note
LARGEST_OVERLAP = 0.05
#: contacts overlapping on average by more than this fraction of the smaller radius get a note
TYPICAL_OVERLAP = 0.02
#: an energy balance drifting by more than this fraction of the energy scale gets a note
ENERGY_DRIFT = 0.01
#: up to this many spheres, overlaps are found among all pairs (above, with a k-d tree)
FEW = 64
#: the overlaps are read from at most this many sphere-frames of a run (about a second of work)
SPHERE_FRAMES = 2_000_000
#: and from at most one frame per this many steps of the run: a frame's overlaps (a k-d tree, ~2.5 us
#: a sphere above FEW spheres) cost what 20-80 steps of the fastest contact-only scenes cost, so at
#: most a few percent of their run (well under 1 % with dipoles)
STEPS_PER_FRAME = 1000


def frame_overlaps(position, radius, box, pairs, walls, time=None):
    """delta / R_min of the touching pairs (when ``pairs``: the scene has a contact law) and
    delta / R of the spheres on the ``walls`` in one frame at ``time`` (one array; empty without contacts)."""
    times = None if time is None else np.array([float(time)])
    parts = [rel[rel > 0.0] for _, rel in _relative(np.asarray(position)[None], radius, box, pairs, walls, times)]
    return np.concatenate([np.zeros(0)] + parts)


@functools.lru_cache(maxsize=8)
def _all_pairs(n):
    """Index arrays i < j of every pair of n spheres (np.triu_indices costs ~70 us a call)."""
    return np.triu_indices(n, k=1)


def _relative(position, radius, box, pairs, walls, times=None):
    """Relative overlaps (positive where touching) of frames (F, N, 3) (at ``times``, for walls that
    move; default 0), as (frames, values) items:
    (slice of every frame, (F, M) array) for the pairs up to FEW spheres and for the walls, and
    (frame k, (M,) array) for the pairs of each frame above FEW spheres (a k-d tree a frame)."""
    count, n = position.shape[:2]
    if pairs and n <= FEW:  # every pair of every frame at once
        i, j = _all_pairs(n)
        d = position[:, j] - position[:, i]
        if box is not None and (box.shear is not None or getattr(box, "deform", None) is not None):  # each frame's images
            d = np.stack([box.minimum_image(dk, t) for dk, t in zip(d, _times(times, box))])
        elif box is not None:
            d = box.minimum_image(d)
        yield slice(None), (radius[i] + radius[j] - np.linalg.norm(d, axis=2)) / np.minimum(radius[i], radius[j])
    for wall in walls:
        if getattr(wall, "travels", False) and times is not None:
            yield slice(None), np.stack([(radius - wall.heights(x, t)) / radius for x, t in zip(position, times)])
        else:
            yield slice(None), (radius - wall.heights(position)) / radius
    if pairs and n > FEW:
        for k in range(count):
            touching, r = close_pairs(position[k], radius, box, distances=True,
                                      time=None if times is None else times[k])
            ri, rj = radius[touching[:, 0]], radius[touching[:, 1]]
            yield k, (ri + rj - r) / np.minimum(ri, rj)


def _times(times, box):
    """The frames' times, which a sheared box's images need."""
    if times is None:
        raise ValueError("overlaps in a sheared or deforming box need the frames' times: its images move")
    return times


class RunNotes:
    """The figures and notes of one run, from its recorded frames (see the module docstring)."""

    #: what a checkpoint keeps of the notes of the run that wrote it (:meth:`state`)
    STATE = ("largest", "typical_sum", "typical_frames", "origin", "drift", "scale", "read")

    def __init__(self, scene, state=None):
        self.scene = scene
        self.pairs = any(inter.contact_reach for inter in scene.interactions)
        walls = [e for e in scene.effects if isinstance(e, Wall)]
        # a moving wall's work and a thermostat's bath are not booked
        self.balance = not any(w.surface_speed() > 0.0 for w in walls) and not scene.heat_baths and (
            scene.box is None or (scene.box.shear is None and getattr(scene.box, "deform", None) is None))  # (nor
        # the work of shearing or deforming a box)
        # (a servo-controlled wall's past positions are not kept: its contacts are read by the run's guards only)
        self.walls = [w for w in walls if getattr(w, "servo", None) is None]
        self.largest = self.drift = self.scale = 0.0
        self.typical_sum, self.typical_frames = 0.0, 0  # frames' mean overlaps summed; frames with contacts
        self.origin = None  # the balance at the run's first frame
        self.read = 0  # frames whose overlaps were read
        if state:  # a run resumed from a checkpoint: its notes go on from the figures saved there
            for name in self.STATE:
                setattr(self, name, state[name])

    @property
    def typical(self):
        return self.typical_sum / self.typical_frames if self.typical_frames else 0.0

    def state(self):
        """The figures so far (JSON numbers), from which :class:`RunNotes` goes on after a resume."""
        return {name: getattr(self, name) for name in self.STATE}

    def frames(self, position, energy, steps, times=None):
        """Read frames covering ``steps`` steps of the run (all its frames at once, or the frames
        recorded since the last call): ``position`` (F, N, 3) as recorded, ``energy`` (F, K) rows
        [kinetic, rotational, potentials..., dissipated], ``times`` (F,) their times (where moving
        walls stood; default 0)."""
        count, n = position.shape[:2]
        taken = min(SPHERE_FRAMES // max(n, 1), steps // STEPS_PER_FRAME)
        if (self.pairs or self.walls) and count and n and taken > 0:
            radius = np.asarray(self.scene.particles.radius, dtype=np.float64)
            if count > taken:
                kept = np.unique(np.linspace(0, count - 1, max(taken, 2)).round().astype(np.int64))
                position = position[kept]
                times = times[kept] if times is not None else None
            self.read += len(position)
            total, touching = np.zeros(len(position)), np.zeros(len(position))  # per frame
            for frames, rel in _relative(position, radius, self.scene.box, self.pairs, self.walls, times):
                positive = np.maximum(rel, 0.0)
                self.largest = max(self.largest, float(positive.max(initial=0.0)))
                total[frames] += positive.sum(axis=-1)
                touching[frames] += (rel > 0.0).sum(axis=-1)
            seen = touching > 0
            self.typical_sum += float(np.sum(total[seen] / touching[seen]))
            self.typical_frames += int(seen.sum())
        if self.balance and len(energy):
            total = energy.sum(axis=1)
            if self.origin is None:
                self.origin = float(total[0])
            self.drift = max(self.drift, float(np.max(np.abs(total - self.origin))))
            self.scale = max(self.scale, float(np.max(np.abs(energy[:, :-1]).sum(axis=1))))

    def figures(self):
        """The run's figures: largest and typical relative overlap, energy drift / scale (None: not measured)."""
        contacts = (self.pairs or bool(self.walls)) and self.read > 0
        drift = self.drift / self.scale if self.balance and self.scale > 0.0 else None
        return {"overlap_largest": self.largest if contacts else None,
                "overlap_typical": self.typical if contacts else None, "energy_drift": drift}

    def notes(self, dt):
        """The notes due for this run (strings; empty when nothing happened)."""
        f = self.figures()
        out = []
        if f["overlap_largest"] is not None and (f["overlap_largest"] > LARGEST_OVERLAP
                                                 or f["overlap_typical"] > TYPICAL_OVERLAP):
            out.append(f"contacts overlapped by up to {f['overlap_largest']:.1%} of the smaller radius (typically "
                       f"{f['overlap_typical']:.1%}): the contact law is soft for these forces and speeds, and "
                       f"results that depend on where spheres touch are off by as much; a stiffer law (larger "
                       f"stiffness or Young's modulus) keeps overlaps small (a smaller time step does not)")
        if f["energy_drift"] is not None and f["energy_drift"] > ENERGY_DRIFT:
            # contact events need contacts without per-contact history (friction, rolling, twisting springs)
            events = ("" if self.scene.history_keepers() else
                      ", or step impacts exactly with VelocityVerlet(dt, resolve_contacts=True)")
            out.append(f"the energy balance (kinetic + rotational + potential + dissipated) drifted by "
                       f"{f['energy_drift']:.1%} of the energy scale {self.scale:.4g}: the time step dt = {dt:.4g} "
                       f"is too long for this accuracy; halve it (the drift of a dissipative run falls about as "
                       f"dt){events}")
        return out


def say(notes):
    """Print the notes on stderr unless DEMKIT_QUIET is set."""
    if quiet():
        return
    for text in notes:
        print(f"demkit note: {text}", file=sys.stderr, flush=True)
