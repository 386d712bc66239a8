"""What a scene's state gives now, computed on demand and changing nothing: forces and torques, energies,
each pair's energies and forces, per-pair and per-sphere history, contacts, neighbour lists, momenta.

These are methods of :class:`demkit.Scene` (it inherits :class:`SceneDiagnostics`); they run on the
scene's compiled code of tier 1 whenever it can run the scene (docs/engine.md).
"""
from __future__ import annotations

import numpy as np

from .engine import neighbours


class SceneDiagnostics:
    """The diagnostics of :class:`demkit.Scene` (see the module docstring)."""

    def forces(self):
        """(force, torque), each (N,3), at the current state; changes nothing (history included)."""
        n = len(self.particles)
        force, torque = np.zeros((n, 3)), np.zeros((n, 3))
        self.check_layers()
        self.induce()
        self.push()
        self.kernels.compute_forces(self.state, force, torque, False, False)
        self.pull()
        return self.to_user_order(force), self.to_user_order(torque)

    def energy(self):
        """Energies: kinetic, rotational, one per energy kind (magnetic, contact, ...), total and
        dissipated. total = kinetic + rotational + potentials; total + dissipated is conserved."""
        out = np.zeros(2 + len(self.energy_kinds))
        self.check_layers()
        self.induce()
        self.push()
        self.kernels.energies_of(self.state, out)
        self.pull()
        return energy_dict(out, self.energy_kinds, self.dissipated)

    def pair_energies(self):
        """(pairs, energies): the (P,2) particle indices i < j of every pair some interaction can
        reach (within its list or all pairs) and a (P, n_interactions) array of the potential
        energy of each pair under each interaction, in ``self.interactions`` order."""
        chunks = []
        self.push()
        tag = self.arrays["tag"]
        for g, group in enumerate(self.plan.groups):
            owners, partners, values = self._entries(g, group, "pair_energies", len(self.interactions))
            chunks.append((tag[owners], tag[partners], values))
        if not chunks:
            return np.zeros((0, 2), dtype=np.int64), np.zeros((0, len(self.interactions)))
        i = np.concatenate([c[0] for c in chunks])
        j = np.concatenate([c[1] for c in chunks])
        values = np.concatenate([c[2] for c in chunks])
        pairs = np.stack([np.minimum(i, j), np.maximum(i, j)], axis=1)
        unique, inverse = np.unique(pairs, axis=0, return_inverse=True)
        merged = np.zeros((len(unique), len(self.interactions)))
        np.add.at(merged, inverse.ravel(), values)
        return unique, merged

    def _entries(self, g, group, kernel, columns):
        """(owners, partners, values (P, columns)): every entry of group g (its list, or all pairs)
        and what the kernel ``<kernel>_<g>`` writes for each, in the internal order (pushed state)."""
        n = len(self.particles)
        size = n * (n - 1) // 2 if group.kind == "all" else self._list(g).size
        owners, partners = np.zeros(size, dtype=np.int64), np.zeros(size, dtype=np.int64)
        values = np.zeros((size, columns))
        getattr(self.kernels, f"{kernel}_{g}")(self.state, owners, partners, values)
        return owners, partners, values

    def pair_forces(self):
        """[(interaction, pairs (P, 2), separations (P, 3), forces (P, 3))] for each pair interaction
        (``self.interactions`` order): the pairs it exerts a force on now, their separations
        x_j - x_i (minimum image) and the force on j (that on i is its negative). Computed by the
        compiled pair loops without committing anything (history included)."""
        found = {}
        self.push()
        tag = self.arrays["tag"]
        for g, group in enumerate(self.plan.groups):
            owners, partners, values = self._entries(g, group, "pair_forces", 3 + 3 * len(group.members))
            for m, (_, inter) in enumerate(group.members):  # each interaction is in one group
                force = values[:, 3 + 3 * m: 6 + 3 * m]
                acts = np.any(force != 0.0, axis=1)
                pairs = np.stack([tag[owners[acts]], tag[partners[acts]]], axis=1)
                found[id(inter)] = (pairs, values[acts, :3], force[acts])
        return [(inter, *found[id(inter)]) for inter in self.interactions if id(inter) in found]

    @property
    def history_values(self):
        """Number of per-pair history values stored (0 when no interaction keeps history)."""
        return sum(self._list(g).history.size for g in range(len(self.plan.groups)))

    def _group_of(self, interaction):
        for g, group in enumerate(self.plan.groups):
            for k, inter in group.members:
                if inter is interaction or getattr(inter, "original", None) is interaction:  # (a tuned copy)
                    return g, group, k
        raise ValueError(f"{interaction!r} is not an interaction of this scene")

    def candidate_pairs(self, interaction):
        """(P,2) particle indices (owner first) of the pairs the interaction's loop visits now: its
        neighbour list (every pair within cutoff + skin at the last build) or all pairs."""
        g, group, _ = self._group_of(interaction)
        tag = self.arrays["tag"]
        if group.kind == "list":
            self.push()
            return neighbours.pairs_of(self._list(g), tag)
        i, j = np.triu_indices(len(self.particles), k=1)
        return np.stack([tag[i], tag[j]], axis=1)

    def history(self, interaction):
        """(pairs, values): :meth:`candidate_pairs` of the interaction and its (P, history_size)
        per-pair history values for them."""
        g, group, k = self._group_of(interaction)
        if not interaction.history_size:
            raise ValueError(f"{interaction!r} keeps no per-contact history (friction, rolling or twisting "
                             f"resistance, or a function of your own with history_size)")
        pairs = self.candidate_pairs(interaction)
        offset = group.offsets[k]
        history = self._list(g).history[:, offset:offset + interaction.history_size]
        if group.kind == "list":
            return pairs, history[neighbours.entry_owners(self._list(g))[1]]
        return pairs, history[: len(pairs)].copy()

    def sphere_history(self, effect):
        """(N, history_size) per-sphere history values of a single-sphere effect (user order)."""
        for e, mine in enumerate(self.effects):
            if mine is effect:
                self.push()
                o = self.plan.effect_offsets[e]
                values = self.arrays["sphere_history"][:, o:o + effect.history_size]  # permuted in place
                return self.to_user_order(values.copy())
        raise ValueError(f"{effect!r} is not an effect of this scene")

    def contacts(self):
        """Every contact now (pairs of spheres under the contact laws, spheres on walls): geometry,
        forces, torques, sliding state, dissipated power (a :class:`demkit.contacts.Contacts`).
        Changes nothing."""
        from .contacts import contacts_of
        return contacts_of(self)

    def neighbour_lists(self):
        """One dict per neighbour list: interactions served, reach (cutoff + skin), pairs, capacity."""
        out = []
        for g, group in enumerate(self.plan.groups):
            if group.kind != "list":
                continue
            pl = self._list(g)
            out.append({"interactions": [type(i).__name__ for _, i in group.members], "cutoff": group.reach,
                        "reach": pl.reach, "pairs": pl.size, "capacity": len(pl.partner),
                        "history_width": group.width})
        return out

    def angular_momentum(self, origin=(0.0, 0.0, 0.0)):
        """Orbital + spin angular momentum about ``origin``, shape (3,) (unwrapped positions)."""
        p = self.particles
        if p.image is None:
            return p.angular_momentum(origin)
        unwrapped = p.copy()
        unwrapped.position, unwrapped.velocity = self.box.continued(p.position, p.velocity, p.image, self.time)
        return unwrapped.angular_momentum(origin)

    def linear_momentum(self):
        """Total linear momentum, shape (3,)."""
        return self.particles.linear_momentum()


def energy_dict(values, kinds, dissipated):
    """Name the columns [kinetic, rotational, *kinds] (arrays or scalars) and add total, dissipated."""
    out = {"kinetic": values[..., 0], "rotational": values[..., 1]}
    for k, kind in enumerate(kinds):
        out[kind] = values[..., 2 + k]
    out["total"] = values[..., : 2 + len(kinds)].sum(axis=-1)
    out["dissipated"] = dissipated
    if np.ndim(out["total"]) == 0:
        out = {key: float(value) for key, value in out.items()}
    return out
