"""Tier 1 built and loaded: the generic modules (scene-level functions and time loops, serial and on threads;
the pieces of each family), compiled function by function as runs need them and cached on disk, and
:class:`GenericKernels`, what a scene calls them through."""
from __future__ import annotations

import inspect

import numpy as np

from . import neighbours
from .catalogue import BLOCKED, FAMILIES, OWN, SLIDING, catalogue
from .generic import (CALLS, CHUNK_CALLS, COMPILED_ONLY, LIST_CALLS, OWN_CALLS, PIECES, SCENE_PIECES, SHEARED_CALLS, THREAD_PIECES,
                      UPKEEP, _name, _pieces_name)
from .program import (E_KIND, G_BLOCKED, G_COUNT, G_LIST, G_MEMBERS, H_EFFECTS, H_INDUCTION, H_LISTS, H_PERIODIC,
                      H_DEFORM, H_SHEAR, H_SORTED, H_SUMS, MAX_GROUPS, M_COLUMNS, M_ENERGY, M_KIND, effect_row, group_row)
from .snippets import ARRAYS, LIST_ARRAYS, SPEEDS
from .state import pair_loop_arrays, type_key


_MODULES = {}


#: the needs (:func:`needs_of`) record_frame calls (its energies, the list upkeep before them with its builder
#: and fill, a sheared frame's folding): the others are given to it as stubs of the same types
FRAME_CALLS = ("pairs_energies", "sphere_energies", "long_range", "own_pair_energies", "own_sphere_energies",
               "fold_frame", "maintain_lists")


def _load(key, source_and_name):
    if key not in _MODULES:
        import numba

        from .modules import _load_from_file
        source, name = source_and_name()
        module = _load_from_file(name, source)
        numba.get_num_threads()  # start numba's threading layer (see demkit.engine.modules.build_module)
        module.source = source
        _MODULES[key] = module
    return _MODULES[key]


def _pieces(family):
    """The pieces module of a family."""
    return _load(("pieces", family), lambda: _pieces_name(family))


def family_of(program):
    """The smallest family of pieces (:data:`FAMILIES`) holding every law and effect of the program."""
    laws, effects = catalogue()
    kinds = [program[row, G_MEMBERS + M_COLUMNS * m + M_KIND]
             for row in (group_row(g, 0) for g in range(MAX_GROUPS)) for m in range(program[row, G_COUNT])]
    used = [laws[kind] for kind in kinds if kind != OWN]
    used += [effects[kind] for kind in (program[effect_row(e), E_KIND] for e in range(program[0, H_EFFECTS]))
             if kind != OWN]
    sheared = program[0, H_SHEAR] >= 0
    return next(family for family, accepts in FAMILIES.items()
                if all(accepts(law) for law in used) and (family in SLIDING or not sheared))


def build_generic(threads=False, needs=CALLS, pieces=None, family="full", own_energies=True, own=None):
    """The generic module (one for every scene, with neighbour lists or in open space; serial or on
    threads), compiled function by function as called and cached on disk like the fused modules;
    seen by a scene that calls ``needs`` of :data:`CALLS` (see :func:`needs_of`: the others are
    stubbed, never compiled for it) of ``family`` (see :func:`family_of`). ``pieces``: a scene's own
    pieces (tier 2, :func:`demkit.engine.modules.build_pieces`) in place of the generic ones; without
    ``own_energies`` (a scene tier 1 can run) only their forces: the energies, computed once a
    frame, are the family's (the same bits), so that tier 2 compiles what makes steps faster alone.
    ``own``: the adapters of the scene's functions of your own (:func:`demkit.engine.own_laws.build_adapters`)."""
    key = ("generic", bool(threads))
    own_energies = bool(own_energies) or pieces is None  # (tier 1: the family's energies are its own)
    view = key + (tuple(needs), pieces and pieces.__name__, family, own_energies, own and own.__name__)
    if view not in _MODULES:
        module = _load(("generic", False), lambda: _name(False))
        on_threads = _load(key, lambda: _name(True)) if threads else module
        _MODULES[view] = GenericKernels(module, bool(threads), tuple(needs), pieces, family, own_energies, on_threads,
                                        own)
    return _MODULES[view]


def needs_of(program):
    """What a scene of this program calls, of :data:`CALLS`."""
    rows = [group_row(g, sp) for g in range(MAX_GROUPS) for sp in range(len(SPEEDS))]
    needs = []
    if any(program[r, G_COUNT] > 0 and program[r, G_BLOCKED] == 0 for r in rows):
        needs += ["pairs_forces"]
    if any(program[r, G_COUNT] > 0 and program[r, G_BLOCKED] != 0 for r in rows):
        needs += ["pairs_forces_blocked"]
    if program[0, H_EFFECTS] > 0:
        needs += ["sphere_forces", "sphere_energies"]
    if any(program[group_row(g, 0), G_COUNT] > 0 for g in range(MAX_GROUPS)):
        needs += ["pairs_energies"]
    if program[0, H_SUMS] > 0:
        needs += ["long_range"]
    if program[0, H_INDUCTION] != 0:
        needs += ["induce_now"]
    if program[0, H_LISTS] != 0:
        needs += ["maintain_lists"]
    if program[0, H_SORTED] != 0:
        needs += ["sort_particles"]
    if program[0, H_PERIODIC] != 0:
        needs += ["wrap_positions"]
    if program[0, H_SHEAR] >= 0:
        needs += ["fold_frame"]  # (and the sheared wrap: generic.SHEARED_CALLS)
    if program[0, H_DEFORM] >= 0:
        needs += ["deform_box"]
    if any(program[r, G_MEMBERS + M_COLUMNS * m + M_KIND] == OWN for r in rows for m in range(program[r, G_COUNT])):
        needs += ["own_pair_forces", "own_pair_energies"]
    if any(program[effect_row(e), E_KIND] == OWN for e in range(program[0, H_EFFECTS])):
        needs += ["own_sphere_forces", "own_sphere_energies"]
    return tuple(needs)


def is_cached(threads, function):
    """Is ``function`` of the generic module in numba's disk cache already (on threads: and tier 1's
    pair loop on threads)?"""
    from .modules import cached_function
    return cached_function(_name(False)[1], function) and (not threads or
                                                            cached_function(_name(True)[1], "pairs_on_threads"))


def _fields(ty):
    """name -> numba type of the fields of a state or pair list type (a structref or a named tuple)."""
    if hasattr(ty, "field_dict"):
        return dict(ty.field_dict)
    return dict(zip(ty.instance_class._fields, ty.types))


def piece_arguments(state_type):
    """name -> the argument types of each piece, for states of this numba type (the calls made in
    the scene-level functions, :meth:`_Generic.forces_body`)."""
    from numba import types
    f = _fields(state_type)
    pair_list = f["lists"][0]
    chunked = (state_type, f["force"], f["torque"], pair_list, types.boolean, types.int64)
    out = types.Array(types.float64, 1, "C")
    frames = types.Array(types.float64, 3, "C")  # the record's positions and velocities (demkit.recording)
    # the list builder (demkit.engine.neighbours.rebuild) as the upkeep calls it, and its first-class type
    fill = neighbours.fill_signature(pair_list, f["box"], f["periodic"])
    filler = types.FunctionType(types.none(*fill))
    rebuild = (pair_list, f["position"], f["tag"], f["tag"], f["box"], f["periodic"], out, filler)
    builder = types.FunctionType(types.none(*rebuild))
    arguments = {"maintain_lists": (state_type, types.boolean, builder, filler, types.boolean),
                 "sort_particles": (state_type, builder, filler, types.boolean), "rebuild_list": rebuild,
                 "fill_list": fill,
                 "long_range": (state_type, f["force"], f["torque"], out, types.boolean),
                 "induce_now": (state_type, types.boolean), "wrap_positions": (state_type,),
                 "deform_box": (state_type,),
                 "fold_frame": (state_type, types.int64, frames, frames, types.Array(types.int64, 3, "C")),
                 "pairs_forces": chunked, "pairs_forces_blocked": chunked,
                 "sphere_forces": (state_type, f["force"], f["torque"], types.boolean),
                 "pairs_energies": (state_type, pair_list, out, types.int64),
                 "sphere_energies": (state_type, out)}
    own = {kind: own_signature(kind, state_type) for kind in ("pair", "sphere")}
    for name in PIECES:  # each piece takes its kind's adapter
        arguments[name] += (types.FunctionType(own["pair" if name.startswith("pairs") else "sphere"]),)
    chunk = chunk_arguments(state_type, arguments["pairs_forces"][-1])
    for name in CHUNK_CALLS:
        arguments[name] = chunk
    for name in THREAD_PIECES:  # and the pair pieces, tier 1's chunk of their loop last
        arguments[name] += (types.FunctionType(types.float64(*chunk)),)
    for name in OWN_CALLS:
        arguments[name] = own["pair" if name.startswith("own_pair") else "sphere"].args
    return arguments


def chunk_arguments(state_type, own):
    """The argument types of a chunk of tier 1's pair loop (snippets.CHUNK_PARAMETERS) as the loops over
    chunks call it (snippets.CHUNK_CALL): the state's arrays, the forces' buffer of chunk t (the force
    array or a row of the threads' buffers: numba's unified type), the pair list's, ``own``'s type."""
    import operator

    from numba import types
    from numba.core.registry import cpu_target
    typing = cpu_target.typing_context
    typing.refresh()

    def row(array):  # the type of array[t]
        return typing.resolve_function_type(operator.getitem, (array, types.int64), {}).return_type

    f = _fields(state_type)
    pl = _fields(f["lists"][0])
    state = tuple(f[name] for name in ARRAYS.split(", "))
    buffers = (typing.unify_types(f["force"], row(f["thread_force"])),
               typing.unify_types(f["torque"], row(f["thread_torque"])))
    lists = tuple(pl[name] for name in LIST_ARRAYS.split(", "))
    return state + buffers + lists + (row(f["scratch"]), row(f["gather"]), types.boolean, row(pl["bounds"]),
                                      row(pl["bounds"]), row(f["program"]), types.boolean, pl["history"],
                                      state_type, own)


def own_signature(kind, state_type):
    """The numba signature of the adapters of functions of your own (see :data:`OWN_CALLS`)."""
    from numba import types
    i64, f64 = types.int64, types.float64
    f = _fields(state_type)
    if kind == "pair":
        history = _fields(f["lists"][0])["history"]
        return types.UniTuple(f64, 10)(i64, i64, i64, f64, f64, f64, f64, state_type, history, i64, i64,
                                       types.boolean, i64)
    return types.UniTuple(f64, 7)(i64, i64, f64, f64, f64, state_type, f["sphere_history"], i64, types.boolean,
                                  i64, i64)


class GenericKernels:
    """A generic module seen through the names of a fused one (``pair_energies_<g>``, ...), by scenes
    that call the pieces ``needs``: its functions that take the pieces are given them (compiled for
    the state's type, the others replaced by stubs, :func:`calls_for`)."""

    def __init__(self, module, threads, needs, pieces=None, family="full", own_energies=True, on_threads=None,
                 own=None):
        self.module, self.threads, self.needs = module, threads, needs
        self.own = own  # the adapters of the scene's functions of your own (demkit.engine.own_laws), or None
        self.on_threads = on_threads or module  # the thread module (tier 1's pair loop on threads)
        self.family, self.own_energies = family, own_energies
        self.pieces = pieces  # a scene's own pieces (tier 2), or None: the generic ones
        self.tier = 1 if pieces is None else 2
        self._calls = {}
        self._steps = {}
        self._bound = {}

    def calls_for(self, state_type, only=None):
        """The tuple of first-class functions the scene-level functions take, for this state type;
        with ``only`` (names of :func:`needs_of`), the others the scene needs given as their stubs, of
        the same types (:data:`FRAME_CALLS`: what record_frame calls, for a run's first frame)."""
        key = (state_type, only)
        if key not in self._calls:
            needs = self.needs if only is None else tuple(name for name in self.needs if name in only)
            arguments = piece_arguments(state_type)
            calls = []
            for name in CALLS:
                if name in CHUNK_CALLS:  # tier 1's chunk of a pair loop the scene runs, else a stub
                    piece = CHUNK_CALLS[name]
                    family = BLOCKED if piece == "pairs_forces_blocked" else self.family
                    function = (getattr(_pieces(family), f"{piece}_chunk")
                                if piece in needs and self.pieces is None else self.module.no_pairs_chunk)
                    calls.append(self._wrapped(function, arguments[name]))
                    continue
                if name == "lists_on_threads":  # a bool, the same type in both modules' calls
                    calls.append(np.bool_(self.threads))
                    continue
                if name == "rebuild_list":  # the list builder, or a stub for a scene without lists
                    function = neighbours.rebuild if "maintain_lists" in needs else self.module.no_rebuild_list
                    calls.append(self._wrapped(function, arguments[name]))
                    continue
                if name == "fill_list":  # its fill, serial or on threads (or a stub)
                    if "maintain_lists" in needs:
                        f = _fields(state_type)
                        calls.append(neighbours.filler(f["lists"][0], f["box"], f["periodic"], self.threads))
                    else:
                        calls.append(self._wrapped(self.module.no_fill_list, arguments[name]))
                    continue
                family = BLOCKED if name == "pairs_forces_blocked" else self.family
                module = self.module if name in SCENE_PIECES + OWN_CALLS else _pieces(family)
                # the piece, or its stub when the scene never calls it
                stubbed = (name not in needs or (name in OWN_CALLS and self.own is None)) and \
                    hasattr(module, f"no_{name}")
                own_piece = name in PIECES and (self.own_energies or "energies" not in name)
                if self.pieces is not None and own_piece and not stubbed:
                    own = self.pieces  # the scene's own; its thread pieces hold the chunked loops alone
                    if not (self.threads and name in THREAD_PIECES):
                        own = getattr(own, "serial", own)
                    function = getattr(own, f"piece_{name}")
                elif name in OWN_CALLS and not stubbed:
                    function = getattr(self.own, name)
                elif self.threads and name in THREAD_PIECES and not stubbed:  # tier 1's loop on threads
                    function = self.on_threads.pairs_on_threads  # (running the chunk in calls)
                elif "fold_frame" in needs and name in SHEARED_CALLS:  # a sheared box's
                    function = getattr(module, SHEARED_CALLS[name])
                else:
                    function = getattr(module, f"no_{name}" if stubbed else name)
                calls.append(self._wrapped(function, arguments[name]))
            self._calls[key] = tuple(calls)
        return self._calls[key]

    def _diagnostic(self, kind, g):
        """pair_energies_<g> / pair_forces_<g>(s, owners, partners, out): every entry of pair loop g and
        its energies or forces. Tier 1: the family's own loops (``pairs_energies_rows``, the serial
        ``pairs_forces_chunk``) recording each entry, called from Python with the types the pieces
        compiled them for, so nothing compiles for diagnostics; tier 2: the scene's own
        ``group_<g>_<kind>``."""
        if self.pieces is not None:  # the scene's own loop of group g (it takes no program row)
            function = getattr(getattr(self.pieces, "serial", self.pieces), f"group_{g}_{kind}")
        else:
            pieces = _pieces(self.family)
            function = pieces.pairs_energies_rows if kind == "pair_energies" else pieces.pairs_forces_chunk

        def run(s, owners, partners, out):
            import numba
            if "maintain_lists" in self.needs:
                self.maintain_lists(s, False)
            *arrays, program = pair_loop_arrays(s, g)
            if self.pieces is not None:
                return function(*arrays, owners, partners, out)
            row = program[group_row(g, 0)]
            position, velocity, spin, dipole, radius, mass, box, params, status, clock, *lists = arrays
            n, partner, is_list = position.shape[0], lists[2], row[G_LIST] != 0
            entries = np.zeros((partner.shape[0] if is_list else n * (n - 1) // 2, out.shape[1]))
            status = status.copy()  # a deep overlap seen by a diagnostic stops no run
            if kind == "pair_energies":
                members = G_MEMBERS + M_COLUMNS * np.arange(row[G_COUNT])
                kinds = np.zeros(1 + int(row[members + M_ENERGY].max(initial=0)))  # the sums by kind, unused
                own = self.calls_for(numba.typeof(s))[CALLS.index("own_pair_energies")]
                function(position, velocity, spin, dipole, radius, mass, box, params, status, clock, *lists, kinds, True,
                         entries, row, s, own)
            else:
                force, unused = np.zeros((n, 3)), np.zeros((9, 1))  # (the blocked loop's scratch and gather)
                own = self.calls_for(numba.typeof(s))[CALLS.index("own_pair_forces")]
                function(position, velocity, spin, dipole, radius, mass, box, params, status, clock, force, force.copy(),
                         *lists, unused, unused, False, 0, n, row, True, entries, s, own)
            # every entry, owner by owner (rows past the entries, if any, stay zero: the caller's size)
            if is_list:
                owner, rows = neighbours.entry_owners(s.lists[g])
                other = partner[rows]
            else:
                (owner, other), rows = np.triu_indices(n, k=1), slice(None)
            k = len(owner)
            owners[:k], partners[:k], out[:k] = owner, other, entries[rows]
        return run

    def steps_for(self, state_type, record_type, uses):
        """The tuple of first-class functions ``uses`` (of :data:`STEPS`, a time loop's ``STEPS_OF``)
        a time loop takes second, for this state and record type."""
        key = (state_type, record_type, uses)
        if key not in self._steps:
            import numba
            from numba import types
            # (the calls' type: the same with or without stubs; the frames' need no force piece compiled)
            calls_type = numba.typeof(self.calls_for(state_type, FRAME_CALLS))
            stage = _fields(state_type)["stage"]
            vector = types.Array(stage.dtype, stage.ndim - 1, "C" if stage.layout == "C" else "A")
            frame = self._wrapped(self.module.record_frame, (calls_type, types.int64, state_type, record_type))
            arguments = {"forces_of": (calls_type, state_type, types.boolean),
                         "end_step": (calls_type, numba.typeof(frame), types.int64, types.int64, types.int64,
                                      state_type, record_type, types.boolean),
                         "fast_forces_of": (calls_type, state_type, vector, vector, types.boolean)}
            arguments["slow_forces_of"] = arguments["fast_forces_of"]
            arguments["next_contact_event"] = (calls_type, state_type, vector, types.float64)
            self._steps[key] = tuple(frame if name == "record_frame" else
                                     self._wrapped(getattr(self.module, name), arguments[name]) for name in uses)
        return self._steps[key]

    @staticmethod
    def _wrapped(function, arguments):
        """``function`` compiled for ``arguments``, as a first-class function value."""
        from numba.core.types.function_type import CompileResultWAP
        function.compile(arguments)
        return CompileResultWAP(function.overloads[arguments])

    def __getattr__(self, name):
        for kind in ("pair_energies", "pair_forces"):
            if name.startswith(kind + "_") and name[len(kind) + 1:].isdigit():
                return self._diagnostic(kind, int(name[len(kind) + 1:]))
        if name in COMPILED_ONLY or name.startswith("no_"):
            raise AttributeError(f"{name} of tier 1's generic module is called from compiled code only")
        if name not in self._bound:  # the module's function, or it bound to the pieces when it takes them
            function = getattr(self.module, name)
            takes = "calls" in inspect.signature(function.py_func).parameters
            self._bound[name] = _Bound(self, function) if takes else (self._upkeep(function) if name in UPKEEP
                                                                      else function)
        return self._bound[name]

    def _upkeep(self, function):
        """The list upkeep called from Python: given the list builder and the threads' flag of ``calls``."""
        import numba
        rest = [CALLS.index(name) for name in LIST_CALLS]

        def upkeep(s, *arguments):
            calls = self.calls_for(numba.typeof(s))
            return function(s, *arguments, *(calls[k] for k in rest))
        return upkeep


class _Bound:
    """A scene-level function of the generic module with its first arguments, the pieces (and for the
    time loops the scene-level functions they call), supplied for the types of the state and record
    among the arguments; ``signatures`` and ``compile`` without them."""

    def __init__(self, kernels, function):
        self.kernels, self.function = kernels, function
        names = list(inspect.signature(function.py_func).parameters)
        self.steps = "steps" in names
        self.position = names.index("s") - (2 if self.steps else 1)
        self.uses = kernels.module.STEPS_OF[function.__name__] if self.steps else ()
        # record_frame is given the pieces it calls, the rest as stubs of the same types (the same
        # compiled function): a fused module's run records its first frame compiling no force piece
        self.only = FRAME_CALLS if function.__name__ == "record_frame" else None
        self._entries = {}  # argument types -> (compiled entry point, the pieces' tuples)

    def _first(self, state_type, record_type):
        calls = self.kernels.calls_for(state_type, self.only)
        if not self.steps:
            return (calls,)
        return calls, self.kernels.steps_for(state_type, record_type, self.uses)

    def __call__(self, *args):
        """Call with the pieces supplied. The dispatcher would type the tuples of first-class
        functions anew at every call (3 ms, more than a chunk of a small scene): after the first call
        of a signature, its compiled entry point is called directly."""
        import numba
        key = tuple(type_key(a) for a in args)
        entry = self._entries.get(key)
        if entry is None:
            types = tuple(numba.typeof(a) for a in args)
            p = self.position
            first = self._first(types[p], types[p + 1] if self.steps else None)
            result = self.function(*first, *args)
            compiled = self.function.overloads.get((*(numba.typeof(f) for f in first), *types))
            if compiled is not None:
                self._entries[key] = (compiled.entry_point, first)
            return result
        function, first = entry
        return function(*first, *args)

    @property
    def signatures(self):
        return [signature[2 if self.steps else 1:] for signature in self.function.signatures]

    def compile(self, signature):
        import numba
        p = self.position
        first = self._first(signature[p], signature[p + 1] if self.steps else None)
        return self.function.compile((*(numba.typeof(f) for f in first), *signature))
