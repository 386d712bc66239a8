"""The plan of a scene's pair loops, which both tiers share: interactions of the same reach share a pair loop
(a :class:`Group`), over a neighbour list (``kind="list"``) or over all pairs i < j (``kind="all"``); the
scene's groups, effects and history layout make its :class:`Plan`."""
from __future__ import annotations

import importlib
import os
from dataclasses import dataclass, field


ENERGY_KINDS = ("magnetic", "contact")
#: pairs per block of a blocked pair loop (the scratch buffers hold one block)
BLOCK = 64
#: per-particle fields that are scalars (the others are 3-vectors)
SCALAR_FIELDS = ("radius", "mass")
#: rows of the gather buffer: the partner's position, then at most every field
GATHER_ROWS = 3 + 3 * 3 + 2


@dataclass
class Group:
    """Interactions sharing one pair loop: ``members`` are (global index, interaction) pairs."""

    members: list
    kind: str  # "list" or "all"
    reach: float  # interaction reach (the list adds the skin)
    parallel: bool = False
    offsets: dict = field(default_factory=dict)  # global index -> history offset in the group's rows

    def __post_init__(self):
        width = 0
        for k, inter in self.members:
            self.offsets[k] = width
            width += inter.history_size
        self.width = width

    @property
    def torque(self):
        return any(inter.torque for _, inter in self.members)

    @property
    def blocked(self):
        """Evaluate blocks of pairs in a vectorisable loop, then scatter (branch-free lists only)."""
        return self.kind == "list" and all(inter.branch_free and not inter.history_size for _, inter in self.members)


@dataclass
class Plan:
    """Everything the generated source depends on."""

    interactions: tuple
    groups: list
    periodic: tuple  # three bools
    growing: bool  # neighbour lists (mutable state, reference counting on)
    sorted: bool = False  # particles re-sorted by cell now and then (internal order)
    effects: tuple = ()  # single-sphere interactions (walls, gravity, fields)
    sums: tuple = ()  # long-range sums over all spheres (an Ewald sum's reciprocal part, an FMM sum)
    induction: object = None  # induced moments solved before the slow forces (InducedMoments), or None
    shear: object = None  # Lees-Edwards images of a sheared box (demkit.Shear), or None

    @property
    def energy_sources(self):
        """Everything that reports an energy kind: interactions, effects, the induction solve."""
        return self.interactions + self.effects + ((self.induction,) if self.induction is not None else ())

    @property
    def effect_offsets(self):
        """History offset of each effect in the per-sphere history rows."""
        offsets, width = [], 0
        for effect in self.effects:
            offsets.append(width)
            width += effect.history_size
        return offsets

    @property
    def effect_width(self):
        """Per-sphere history values: the effects', then the induction solve's (its last moments)."""
        own = self.induction.history_size if self.induction is not None else 0
        return sum(effect.history_size for effect in self.effects) + own

    @property
    def lists(self):
        return [g for g, group in enumerate(self.groups) if group.kind == "list"]


def energy_kinds(interactions):
    """Energy categories reported for these interactions: the standard ones, then any new ones."""
    kinds = list(ENERGY_KINDS)
    for inter in interactions:
        if inter.energy_kind not in kinds:
            kinds.append(inter.energy_kind)
    return kinds


def _importable(fn):
    """Can the generated file import ``fn`` by name (needed for the on-disk cache)?"""
    module = getattr(fn, "__module__", None)
    if not module or module == "__main__":
        return False
    try:
        found = getattr(importlib.import_module(module), fn.__name__, None)
    except Exception:  # any import failure just means: compile in memory
        return False
    return found is fn


def functions_importable(plan):
    """Can every pair and sphere function of the plan be imported by name (so its module is cached)?"""
    return all(_importable(fn) for inter in plan.interactions + plan.effects for fn in inter.pair_functions())


def importable(plan):
    """Can a generated file import every function of the plan by name, and may it be cached on disk
    (not with DEMKIT_NO_CACHE)? Else its fused module is compiled in memory."""
    return functions_importable(plan) and os.environ.get("DEMKIT_NO_CACHE", "") in ("", "0")
