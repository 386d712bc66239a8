"""A scene's *program*: the int64 table in the state that tells tier 1's loops which laws act in which pair
loop, their parameter slots, cutoffs, history offsets, periodic axes and effects (:func:`program_of`), and
its layout (the ``H_*``, ``G_*``, ``M_*``, ``E_*``, ``S_*`` columns), which generated modules import by name."""
from __future__ import annotations

import re

import numpy as np

from .catalogue import MAX_SUMS, OWN, SUMS, _law_of, catalogue
from .snippets import SPEEDS


MAX_GROUPS = 3
MAX_MEMBERS = 4
MAX_EFFECTS = 16
# header row
(H_LISTS, H_PERIODIC, H_SORTED, H_EFFECTS, H_SHORTEST, H_SUMS, H_INDUCTION, H_INDUCTION_GROUP, H_INDUCTION_SLOT,
 H_INDUCTION_OFFSET, H_INDUCTION_ENERGY, H_CLOCK, H_SHEAR, H_DEFORM) = range(14)
# group rows: flags, then the members
(G_COUNT, G_LIST, G_BLOCKED, G_TORQUE, G_WIDTH, G_CONTACT_ONLY, G_CONTACT, G_PX, G_PY, G_PZ, G_EXISTS) = range(11)
G_MEMBERS = 11
M_KIND, M_SLOT, M_CUT, M_OFFSET, M_SIZE, M_ENERGY, M_INDEX = range(7)
M_COLUMNS = 7
# effect rows
E_KIND, E_SLOT, E_TABLE, E_OFFSET, E_ENERGY, E_SIZE, E_PLANE, E_GEOMETRY = range(8)
# long-range sum rows
S_KIND, S_SLOT, S_ENERGY = range(3)
# ... and after the members, the row's own group and speed (read by a scene's own pieces, tier 2)
G_GROUP = G_MEMBERS + MAX_MEMBERS * M_COLUMNS
G_SPEED = G_GROUP + 1
COLUMNS = G_SPEED + 1

def group_row(g, speed):
    return 1 + 3 * g + speed


def effect_row(e):
    return 1 + 3 * MAX_GROUPS + e


def sum_row(q):
    return 1 + 3 * MAX_GROUPS + MAX_EFFECTS + q


def program_of(plan, slots, kinds):
    """(program, None): the scene's program (int64 table, see the module docstring; laws and effects of
    your own have kind :data:`OWN`: tier 1 calls them through adapters, :mod:`demkit.engine.own_laws`);
    (program, why) when some of them cannot be adapted (in a blocked dipole loop, or a plane contact:
    the scene's own pieces run it, tier 1 cannot); (None, why) when the table cannot describe the scene. ``slots``: the parameter slots
    (``param_slot``, ``cutoff_slot``, ``effect_slot``, ``table_slot`` as :class:`demkit.engine.kernels._Source`
    gives them); ``kinds``: the energy kinds."""
    laws, effect_laws = catalogue()
    if len(plan.sums) > MAX_SUMS:
        return None, f"{len(plan.sums)} long-range sums, more than {MAX_SUMS}"
    if len(plan.groups) > MAX_GROUPS:
        return None, f"{len(plan.groups)} pair loops (interactions of different reach), more than {MAX_GROUPS}"
    if len(plan.effects) > MAX_EFFECTS:
        return None, f"{len(plan.effects)} single-sphere effects, more than {MAX_EFFECTS}"
    rows = 1 + 3 * MAX_GROUPS + MAX_EFFECTS + MAX_SUMS
    program = np.zeros((rows, COLUMNS), dtype=np.int64)
    for q, (tuned, slot) in enumerate(zip(plan.sums, slots.sum_slot)):
        kind = [f"{module}.{name}" for module, name in SUMS].index(".".join(tuned.kernel)) \
            if ".".join(tuned.kernel) in [f"{module}.{name}" for module, name in SUMS] else None
        if kind is None:
            return None, f"the long-range sum {tuned.kernel} is not in the generic module's catalogue"
        program[sum_row(q)] [:3] = (kind, slot, 2 + kinds.index(tuned.energy_kind))
    program[0, H_SUMS] = len(plan.sums)
    if plan.induction is not None:
        program[0, H_INDUCTION] = 1
        program[0, H_INDUCTION_GROUP] = -1 if plan.induction.group is None else plan.induction.group
        program[0, H_INDUCTION_SLOT] = slots.induction_slot
        program[0, H_INDUCTION_OFFSET] = plan.effect_width - plan.induction.history_size
        program[0, H_INDUCTION_ENERGY] = 2 + kinds.index(plan.induction.energy_kind)
    program[0, H_LISTS] = bool(plan.lists)
    program[0, H_PERIODIC] = any(plan.periodic)
    program[0, H_SORTED] = plan.sorted
    program[0, H_EFFECTS] = len(plan.effects)
    program[0, H_SHORTEST] = plan.lists[0] if plan.lists else 0
    program[0, H_SHEAR] = -1 if plan.shear is None else slots.shear_slot  # Lees-Edwards: its block in params
    if plan.shear is not None:
        program[0, H_CLOCK] = 1  # the sliding offset follows the clock (demkit.engine.shear)
    program[0, H_DEFORM] = -1  # a deforming box: its block's slot, set by the scene (demkit.engine.deform)
    from .plan import Group
    own = []  # the names of the laws and effects of your own
    for g, group in enumerate(plan.groups):
        if len(group.members) > MAX_MEMBERS:
            return None, f"{len(group.members)} interactions in one pair loop, more than {MAX_MEMBERS}"
        for sp, speed in enumerate(SPEEDS):
            members = [(k, inter) for k, inter in group.members if speed is None or inter.slow == (speed == "slow")]
            if not members:
                continue
            sub = Group(members, group.kind, group.reach, group.parallel)
            row = program[group_row(g, sp)]
            row[G_EXISTS] = 1
            row[G_GROUP] = g
            row[G_SPEED] = sp
            row[G_COUNT] = len(members)
            row[G_LIST] = group.kind == "list"
            row[G_BLOCKED] = sub.blocked
            row[G_TORQUE] = sub.torque
            row[G_WIDTH] = group.width
            row[G_CONTACT_ONLY] = all(inter.contact_reach for _, inter in members)
            row[G_CONTACT] = any(inter.contact_reach for _, inter in members)
            for a in range(3):
                row[G_PX + a] = plan.periodic[a] and group.kind == "list"
            for m, (k, inter) in enumerate(members):
                law = _law_of(inter, laws)
                if law is not None and sub.blocked and law.reads != ("dipole",):
                    law = None  # the generic blocked loops gather the moments alone
                if law is None and sub.blocked:
                    own.append(type(inter).__name__)  # (the blocked loops call no adapter)
                base = G_MEMBERS + M_COLUMNS * m
                row[base + M_KIND] = OWN if law is None else law.kind
                row[base + M_SLOT] = slots.param_slot[k]
                row[base + M_CUT] = slots.cutoff_slot[k] if inter.cutoff_distance is not None else -1
                row[base + M_OFFSET] = group.offsets[k]
                row[base + M_SIZE] = inter.history_size
                row[base + M_ENERGY] = 2 + kinds.index(inter.energy_kind)
                row[base + M_INDEX] = k
    offsets = plan.effect_offsets
    for e, effect in enumerate(plan.effects):
        law = _law_of(effect, effect_laws)
        if law is None and getattr(effect, "plane_contact", False):
            own.append(type(effect).__name__)  # (a plane contact's guard is the shipped walls')
        row = program[effect_row(e)]
        row[E_KIND] = OWN if law is None else law.kind
        row[E_PLANE] = bool(getattr(effect, "plane_contact", False)) and getattr(effect, "flat", True)
        row[E_GEOMETRY] = slots.geometry_slot.get(e, -1)  # a moving or curved wall's block (-1: a plane's own)
        if row[E_GEOMETRY] >= 0:
            program[0, H_CLOCK] = 1  # the time loops keep the clock (demkit.engine.templates)
        row[E_SLOT] = slots.effect_slot[e]
        row[E_TABLE] = slots.table_slot.get(e, -1)
        row[E_OFFSET] = offsets[e]
        row[E_ENERGY] = 2 + kinds.index(effect.energy_kind)
        row[E_SIZE] = effect.history_size
    if own:
        names = ", ".join(dict.fromkeys(own))
        return program, (f"{names}: functions of your own in a blocked dipole loop or as a plane contact, which "
                         "tier 1 does not call")
    return program, None


def _layout_line():
    """The program's layout as a comment line: generated modules import its constants by name, and
    numba's cache (keyed by their text) must not serve code compiled for another layout."""
    layout = ", ".join(f"{name}={value}" for name, value in sorted(globals().items())
                       if re.fullmatch(r"[HGMES]_[A-Z_]+|COLUMNS|MAX_[A-Z]+", name))
    return f"# program layout: {layout}"
