"""Where the force laws are not smooth: the switching functions of a scene (contacts beginning or ending,
dashpot clamps, plain cutoffs, walls), whose sign changes the reference solver stops at exactly."""
from __future__ import annotations

import numpy as np

from ..interactions.contact import KelvinVoigt
from ..interactions.hertz import Hertz
from ..interactions.wall import Wall


GAP, CUTOFF, WALL, KINK, WALL_KINK = range(5)
KIND_NAMES = {GAP: "contact", CUTOFF: "cutoff", WALL: "wall contact", KINK: "dashpot clamp",
              WALL_KINK: "wall dashpot clamp"}


class _Switches:
    """The switching functions g of a scene, as vectors over *items*: g changes sign exactly where a
    force law changes regime. Convention: g >= 0 is the regime the compiled law uses when the
    quantity is zero (out of contact, beyond the cutoff, unclamped dashpot)."""

    def __init__(self, scene, eq, skin=None):
        self.eq = eq
        p = scene.particles
        a = scene.arrays
        self.radius = a["radius"]
        self.movable = np.isfinite(eq.mass)
        self.contact = any(inter.contact_reach for inter in scene.interactions)
        self.cutoffs = sorted({float(inter.cutoff_distance) for inter in scene.interactions
                               if inter.cutoff_distance is not None and getattr(inter, "switch_width", None) is None})
        # dashpots whose force is clamped at zero: (law kind, parameters)
        self.kinks = []
        for inter in scene.interactions:
            if isinstance(inter, KelvinVoigt) and inter.no_tension and inter.damping > 0:
                self.kinks.append(("kv", inter.stiffness, inter.damping))
            elif isinstance(inter, Hertz) and inter.gamma > 0:
                self.kinks.append(("hertz", inter.young_eff, inter.gamma))
        self.walls = []
        for effect in scene.effects:
            if isinstance(effect, Wall):
                if not effect.flat:
                    raise ValueError(f"the accuracy reference locates contacts with plane walls that stand still only, "
                                     f"and this scene has {effect!r}")
                law = effect.law
                kink = None
                if isinstance(law, KelvinVoigt) and law.no_tension and law.damping > 0:
                    kink = ("kv", law.stiffness, law.damping)
                elif isinstance(law, Hertz) and law.gamma > 0:
                    kink = ("hertz", effect.young_eff, law.gamma)
                self.walls.append((effect.plane, effect.normal.copy(), kink))
        n = len(p)
        self.n = n
        i, j = np.triu_indices(n, k=1)
        keep = self.movable[i] | self.movable[j]
        self.all_i, self.all_j = i[keep], j[keep]
        self.skin = float(skin) if skin is not None else 0.5 * float(np.min(self.radius))
        self.anchor = None
        self.build(eq.initial())

    # ---- geometry -----------------------------------------------------------------------------
    def separations(self, x, i, j):
        """x_j - x_i, minimum image along periodic axes."""
        d = x[j] - x[i]
        eq = self.eq
        if eq.periodic.any():
            size = np.where(eq.periodic, eq.size, 0.0)
            d = d - np.round(d / np.where(eq.periodic, eq.size, 1.0)) * size
        return d

    def build(self, y, skin=None):
        """Items of the switching functions that can change sign before a sphere moves skin/2
        (``skin``: default :attr:`skin`; a larger one covers a step already taken)."""
        eq = self.eq
        x = eq.part(y, "position")
        self.anchor = x.copy()
        self.reach = skin = self.skin if skin is None else float(skin)
        kinds, I, J, thresholds, extra = [], [], [], [], []
        if (self.contact or self.cutoffs) and len(self.all_i):
            d = self.separations(x, self.all_i, self.all_j)
            r = np.sqrt((d * d).sum(axis=1))
            reach = self.radius[self.all_i] + self.radius[self.all_j]
            if self.contact:
                near = r - reach < skin
                ci, cj = self.all_i[near], self.all_j[near]
                kinds.append(np.full(len(ci), GAP)), I.append(ci), J.append(cj)
                thresholds.append(reach[near]), extra.append(np.zeros(len(ci)))
                touching = r[near] < reach[near]
                for k, kink in enumerate(self.kinks):
                    ki, kj = ci[touching], cj[touching]
                    kinds.append(np.full(len(ki), KINK)), I.append(ki), J.append(kj)
                    thresholds.append((self.radius[ki] + self.radius[kj])), extra.append(np.full(len(ki), k))
            for rc in self.cutoffs:
                near = np.abs(r - rc) < skin
                kinds.append(np.full(int(near.sum()), CUTOFF)), I.append(self.all_i[near]), J.append(self.all_j[near])
                thresholds.append(np.full(int(near.sum()), rc)), extra.append(np.zeros(int(near.sum())))
        spheres = np.flatnonzero(self.movable)
        for w, (plane, normal, kink) in enumerate(self.walls):
            kinds.append(np.full(len(spheres), WALL)), I.append(spheres), J.append(np.full(len(spheres), w))
            thresholds.append(self.radius[spheres]), extra.append(np.zeros(len(spheres)))
            if kink is not None:
                h = x[spheres] @ normal - plane
                on = spheres[h < self.radius[spheres]]
                kinds.append(np.full(len(on), WALL_KINK)), I.append(on), J.append(np.full(len(on), w))
                thresholds.append(self.radius[on]), extra.append(np.zeros(len(on)))
        cat = (lambda parts, dtype: np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype))
        self.kind = cat(kinds, np.int64)
        self.i, self.j = cat(I, np.int64), cat(J, np.int64)
        self.threshold = cat(thresholds, np.float64)
        self.extra = cat(extra, np.int64)
        self.masks = {k: np.flatnonzero(self.kind == k) for k in KIND_NAMES}
        return self

    def moved_too_far(self, y):
        x = self.eq.part(y, "position")
        return float(np.max(np.abs(x - self.anchor).sum(axis=1))) > 0.5 * self.reach if self.n else False

    def step_reach(self, y0, y1, h):
        """A skin covering every pair that can have switched during the step y0 -> y1 of length h:
        the normal skin plus twice the farthest any sphere can have gone from its start (the larger
        of its displacement and its speed at either end times h, with a margin for curved paths)."""
        eq = self.eq
        x0, x1 = eq.part(y0, "position"), eq.part(y1, "position")
        v0, v1 = eq.part(y0, "velocity"), eq.part(y1, "velocity")
        reach = np.maximum(np.linalg.norm(x1 - x0, axis=1),
                           h * np.maximum(np.linalg.norm(v0, axis=1), np.linalg.norm(v1, axis=1)))
        return self.skin + 2.0 * 1.5 * float(np.max(reach)) if self.n else self.skin

    def touching(self, y):
        """False for the clamp items whose pair (or sphere and wall) no longer overlaps at y."""
        out = np.ones(len(self.kind), dtype=bool)
        x = self.eq.part(y, "position")
        m = self.masks[KINK]
        if len(m):
            d = self.separations(x, self.i[m], self.j[m])
            out[m] = np.sqrt((d * d).sum(axis=1)) < self.threshold[m]
        m = self.masks[WALL_KINK]
        if len(m):
            planes = np.array([wall[0] for wall in self.walls])[self.j[m]]
            normals = np.array([wall[1] for wall in self.walls])[self.j[m]]
            out[m] = (x[self.i[m]] * normals).sum(axis=1) - planes < self.threshold[m]
        return out

    def keys(self):
        return list(zip(self.kind.tolist(), self.i.tolist(), self.j.tolist(), self.extra.tolist()))

    def index(self, key):
        hit = np.flatnonzero((self.kind == key[0]) & (self.i == key[1]) & (self.j == key[2]) & (self.extra == key[3]))
        return int(hit[0]) if len(hit) else None

    # ---- values -------------------------------------------------------------------------------
    def values(self, y, rates=False):
        """(g, scale, dg/dt) of every item at y; dg/dt only for the geometric items (NaN otherwise)
        and only when ``rates``."""
        eq = self.eq
        x = eq.part(y, "position")
        v = eq.part(y, "velocity")
        g = np.zeros(len(self.kind))
        scale = np.ones(len(self.kind))
        dg = np.full(len(self.kind), np.nan) if rates else None
        for kind in (GAP, CUTOFF, KINK):
            m = self.masks[kind]
            if not len(m):
                continue
            i, j = self.i[m], self.j[m]
            d = self.separations(x, i, j)
            r2 = (d * d).sum(axis=1)
            thr = self.threshold[m]
            if kind != KINK:
                g[m] = r2 - thr * thr  # the kernels test r2 against reach^2 (or cutoff^2)
                scale[m] = thr * thr
                if rates:
                    dg[m] = 2.0 * ((v[j] - v[i]) * d).sum(axis=1)
                continue
            r = np.sqrt(r2)
            n = d / r[:, None]
            overlap = thr - r
            rate = -((v[j] - v[i]) * n).sum(axis=1)
            for k, (law, a, b) in enumerate(self.kinks):
                s = self.extra[m] == k
                elastic, damped = self._normal(law, a, b, overlap[s], rate[s], i[s], j[s])
                g[m[s]] = elastic + damped
                scale[m[s]] = np.abs(elastic) + np.abs(damped)
        for kind in (WALL, WALL_KINK):
            m = self.masks[kind]
            if not len(m):
                continue
            i, w = self.i[m], self.j[m]
            planes = np.array([wall[0] for wall in self.walls])[w]
            normals = np.array([wall[1] for wall in self.walls])[w]
            h = (x[i] * normals).sum(axis=1) - planes
            if kind == WALL:
                g[m] = h - self.threshold[m]
                scale[m] = self.threshold[m]
                if rates:
                    dg[m] = (v[i] * normals).sum(axis=1)
                continue
            overlap = self.threshold[m] - h
            rate = -(v[i] * normals).sum(axis=1)
            for idx in range(len(m)):
                law, a, b = self.walls[w[idx]][2]
                elastic, damped = self._normal(law, a, b, overlap[idx:idx + 1], rate[idx:idx + 1], i[idx:idx + 1],
                                               None)
                g[m[idx]] = elastic[0] + damped[0]
                scale[m[idx]] = abs(elastic[0]) + abs(damped[0])
        return g, scale, dg

    def _normal(self, law, a, b, overlap, rate, i, j):
        """(elastic, dashpot) parts of the unclamped normal force, as the compiled laws compute them."""
        if law == "kv":
            return a * overlap, b * rate
        radius = self.radius[i] if j is None else self.radius[i] * self.radius[j] / (self.radius[i] + self.radius[j])
        mass = self.eq.mass[i] if j is None else 1.0 / (1.0 / self.eq.mass[i] + 1.0 / self.eq.mass[j])
        contact = np.sqrt(radius * np.maximum(overlap, 0.0))
        elastic = 4.0 / 3.0 * a * contact * overlap
        eta = b * np.sqrt(mass * 2.0 * a * contact)
        return elastic, np.where(rate != 0.0, eta * rate, 0.0)

    def value(self, y, k):
        return self.values(y)[0][k]

    def describe(self, k):
        kind, i, j = int(self.kind[k]), int(self.i[k]), int(self.j[k])
        ids = self.eq.scene.particles.ids
        tag = self.eq.tag
        if kind in (WALL, WALL_KINK):
            return KIND_NAMES[kind], (int(ids[tag[i]]),), j
        return KIND_NAMES[kind], (int(ids[tag[i]]), int(ids[tag[j]])), None


def _negative(g):
    return g < 0.0


def _grazing(g0, g1, d0, d1, h):
    """(flags, extrema): items whose cubic Hermite interpolant over the step (from g and dg/dt at
    both ends) changes sign inside although both ends agree (a graze: the gap dips below zero and
    comes back within one step), and where in the step (fractions, NaN: none) its extrema lie."""
    c0, c1 = g0, h * d0
    c2 = 3.0 * (g1 - g0) - h * (2.0 * d0 + d1)
    c3 = 2.0 * (g0 - g1) + h * (d0 + d1)
    out = np.zeros(len(g0), dtype=bool)
    extrema = np.full((len(g0), 2), np.nan)
    with np.errstate(all="ignore"):
        a, b, c = 3.0 * c3, 2.0 * c2, c1  # p'(s) = a s^2 + b s + c
        disc = b * b - 4.0 * a * c
        ok = np.isfinite(disc) & (disc >= 0)
        # the stable pair of roots q/a and c/q (no cancellation when a is tiny, as for a quadratic g)
        q = -0.5 * (b + np.copysign(np.sqrt(np.where(ok, disc, 0.0)), b))
        for col, s in enumerate((q / a, c / q)):
            inside = ok & np.isfinite(s) & (s > 0) & (s < 1)
            p = c0 + s * (c1 + s * (c2 + s * c3))
            out |= inside & (_negative(p) != _negative(g0))
            extrema[:, col] = np.where(inside, s, np.nan)
    out &= (_negative(g0) == _negative(g1)) & np.isfinite(d0) & np.isfinite(d1)
    return out, extrema
