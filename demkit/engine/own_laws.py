"""Functions of your own on tier 1: a small generated module of adapters, compiled in about a second.

Tier 1's pair and sphere loops (:mod:`demkit.engine.generic`) switch over the catalogue's kinds. A pair
interaction or single-sphere effect of your own (a :class:`demkit.PairInteraction` or
:class:`demkit.SphereInteraction` subclass) has kind ``OWN`` in the scene's program, and the loops call
the scene's *adapter* for it: a numba first-class function of one fixed signature
(:data:`demkit.engine.generic.OWN_CALLS`) that picks the function by the interaction's index and calls it with
the arguments its declaration asks for (``reads``, history, table, parameters; see
:mod:`demkit.interactions.base`). Only the adapters are compiled for a new scene of your own: the loops
are tier 1's, compiled once per install. They return the loops' fixed set of outputs (zeros for the
torques and power a function does not give), which add nothing to the sums: the same bits as the
scene's own pieces (tier 2), which call the functions directly.

Pair functions called from a blocked dipole loop, and effects that are plane contacts, are not adapted
(the scene then runs on tier 2 alone).
"""
from __future__ import annotations

from . import catalogue
from .modules import _fingerprint, _load_from_file, _load_in_memory
from .plan import _importable
from .snippets import _callable_arguments, function_imports

_MODULES = {}
PLURAL = {"force": "forces", "energy": "energies"}


def own_members(plan):
    """(pair interactions of your own as (index, interaction), effects of your own as (index, effect))."""
    laws, effects = catalogue.catalogue()
    pairs = [(k, inter) for k, inter in enumerate(plan.interactions) if catalogue._law_of(inter, laws) is None]
    own_effects = [(e, effect) for e, effect in enumerate(plan.effects) if catalogue._law_of(effect, effects) is None]
    return pairs, own_effects


def _reads(inter, pad):
    return [f'{pad}{name} = field(s, "{name}")' for name in inter.reads]


def _pair_branch(k, inter, kind):
    args = ["i", "j", "dx", "dy", "dz", "r2", *inter.reads]
    if inter.history_size:
        args += ["history", "p", "off", "commit" if kind == "force" else "False"]
    args += [f"params[slot + {m}]" for m in range(len(inter.parameters))]
    call = f"{kind}_{k}({', '.join(_callable_arguments(inter, args))})"
    if kind == "energy":
        return [f"        return {call}, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0"]
    outs = ["ax", "ay", "az"] + (["bix", "biy", "biz", "bjx", "bjy", "bjz"] if inter.torque else [])
    outs += ["w"] if inter.dissipative else []
    torques = "bix, biy, biz, bjx, bjy, bjz" if inter.torque else "0.0, 0.0, 0.0, 0.0, 0.0, 0.0"
    return [f"        {', '.join(outs)} = {call}",
            f"        return ax, ay, az, {torques}, {'w' if inter.dissipative else '0.0'}"]


def _effect_branch(e, effect, kind, tabled):
    args = ["i", "x", "y", "z", *effect.reads]
    if effect.history_size:
        args += ["history", "i", "off", "commit" if kind == "force" else "False"]
    if tabled:
        args += ["params", "table"]
    args += [f"params[slot + {m}]" for m in range(len(effect.parameters))]
    call = f"s{kind}_{e}({', '.join(_callable_arguments(effect, args))})"
    if kind == "energy":
        return [f"        return {call}, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0"]
    outs = ["ax", "ay", "az"] + (["bx", "by", "bz"] if effect.torque else []) + (["w"] if effect.dissipative else [])
    torques = "bx, by, bz" if effect.torque else "0.0, 0.0, 0.0"
    return [f"        {', '.join(outs)} = {call}",
            f"        return ax, ay, az, {torques}, {'w' if effect.dissipative else '0.0'}"]


def _adapter(header, options, index, members, branch, outputs):
    """One adapter: a switch over the members by ``index``, each branch's lines from ``branch``,
    ``outputs`` zeros when no member matches."""
    lines = ["", "", f"@njit({options})", f"def {header}:", '    params = field(s, "params")']
    for n, (k, inter) in enumerate(members):
        lines += [f"    {'if' if n == 0 else 'elif'} {index} == {k}:"] + _reads(inter, "        ") + branch(k, inter)
    return lines + ["    return " + ", ".join(["0.0"] * outputs)]


def adapters_source(plan, importable, tables=()):
    """The adapters' module text for the scene's functions of your own (``tables``: the indices of
    the effects that carry a table)."""
    pairs, effects = own_members(plan)
    lines = ['"""Adapters of a scene\'s functions of your own (written by demkit.engine.own_laws, do not edit)."""',
             "from numba import njit", "from demkit.engine.state import field"]
    if importable:
        lines += function_imports(pairs, effects)
    options = f'cache={importable}, _nrt=False, error_model="numpy"'
    for kind in ("force", "energy"):
        lines += _adapter(f"own_pair_{PLURAL[kind]}(k, i, j, dx, dy, dz, r2, s, history, p, off, commit, slot)",
                          options, "k", pairs, lambda k, inter: _pair_branch(k, inter, kind), 10)
        lines += _adapter(f"own_sphere_{PLURAL[kind]}(e, i, x, y, z, s, history, off, commit, slot, table)",
                          options, "e", effects, lambda e, effect: _effect_branch(e, effect, kind, e in tables), 7)
    return "\n".join(lines) + "\n"


def build_adapters(plan, tables=()):
    """The compiled adapters' module of the scene's functions of your own (None without any): on
    disk, cached by numba, when every function can be imported by name; else in memory."""
    pairs, effects = own_members(plan)
    if not pairs and not effects:
        return None
    members = [inter for _, inter in pairs] + [effect for _, effect in effects]
    for inter in members:
        for fn in inter.pair_functions():
            if not hasattr(fn, "py_func"):
                raise TypeError(f"{type(inter).__name__}: pair functions must be numba @njit functions")
    on_disk = all(_importable(fn) for inter in members for fn in inter.pair_functions())
    source = adapters_source(plan, on_disk, tables)
    name = f"demkit_own_{_fingerprint(source, members)}"
    if not on_disk:  # bound to these very function objects
        name += "_" + "_".join(str(id(fn)) for inter in members for fn in inter.pair_functions())
    if name not in _MODULES:
        module = _load_from_file(name, source) if on_disk else _load_in_memory(name, source, plan)
        module.source = source
        _MODULES[name] = module
    return _MODULES[name]
