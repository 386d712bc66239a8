"""The named state the compiled kernels work on.

A scene's arrays travel as one object ``s`` with physical names, so that a time-loop template
reads ``kick(s.velocity, s.force, s.mass, h)``. Absent optional fields are (0, 3) arrays.

Two forms with the same field names, so one template source compiles for both:

* :data:`StateTuple` / :data:`PairListTuple`, named tuples, for the fused module of a scene whose
  arrays never change size (tier 2 of an open scene, such as the seed paper's pair). They need no
  numba reference counting, which keeps a two-sphere step at tens of nanoseconds.
* :class:`State` / :class:`PairList`, numba structrefs (mutable, one pointer to pass), for every
  scene on the generic module (tier 1, demkit.engine.generic) and for scenes with neighbour lists, which
  grow inside the compiled loop. Fields that compiled code replaces (the arrays of a list) are read
  back in Python through the proxies' properties; every other array is shared with Python, which
  made it. :func:`tuple_state` views the same arrays as named tuples.

Hot loops never take these objects: they are compiled without reference counting and receive
plain arrays (``s.position``, ...), because numba's counting of array references costs more than
a pair interaction when it happens in an inner loop.

``stage`` is (K, N, 3) working storage of integrators that keep copies of the state within a step
(RK4: K = 9), and (0, 0, 3) for the others: a scene holds it only while such an integrator uses it.

Codes written to ``status[0]`` by the compiled loop (``status[1]`` holds the internal particle index,
``status[2]`` the global step, ``status[3]`` a second particle): :data:`OK`, :data:`NON_FINITE`,
:data:`MOVED_TOO_FAR`, :data:`DEEP_OVERLAP` (the pair loops flag it in ``status[0]``/``[1]``/``[3]``),
:data:`INDUCTION_FAILED` (the induced-moment solve did not converge; demkit.interactions.induction),
:data:`LEFT_LAYER` (a sphere left the layer of a slab sum; demkit.interactions.slab).
"""
from __future__ import annotations

import hashlib
from collections import namedtuple

import numpy as np
from numba import njit
from numba.core.extending import intrinsic
from numba.core import types
from numba.experimental import structref

OK, NON_FINITE, MOVED_TOO_FAR, DEEP_OVERLAP, INDUCTION_FAILED, LEFT_LAYER = 0, 1, 2, 3, 4, 5
#: a contact overlap deeper than this fraction of the smaller radius stops a run (DEEP_OVERLAP): the
#: contact is too soft to stop the spheres, which would tunnel through each other; the same limit
#: as for a start (Scene refuses deeper initial overlaps)
DEEP_OVERLAP_FRACTION = 0.5
#: slots of ``State.counters``: list builds, rebuilt this step (wrap and maybe sort at its end),
#: re-sorts, step of the last re-sort, steps between re-sorts, inner steps per step of multiple
#: time stepping, and the global step count at the start of the current run (the loops count steps
#: from the start of their run; re-sorting goes by the global count, so runs can be cut anywhere)
REBUILDS, WRAP_DUE, SORTS, LAST_SORT, SORT_EVERY, INNER_STEPS, RUN_START = 0, 1, 2, 3, 4, 5, 6

PAIR_LIST_FIELDS = ("reach", "start", "end", "partner", "history", "bounds")
STATE_FIELDS = ("position", "velocity", "angular_velocity", "dipole", "radius", "mass", "inertia",
                "tag", "image", "force", "torque", "accum", "clock", "params", "box", "periodic", "reference",
                "skin", "status", "counters", "lists", "thread_force", "thread_torque", "thread_power",
                "scratch", "gather", "sphere_history", "stage", "program")

StateTuple = namedtuple("StateTuple", STATE_FIELDS)
PairListTuple = namedtuple("PairListTuple", PAIR_LIST_FIELDS)


class _ShortNamed(types.StructRef):
    """A structref type named by a digest of its fields, not by their list: numba spells a type's name into
    every type that holds it (the tuple ``calls`` of first-class functions that take the state: 68 000
    characters) and works on those names at every compile."""

    def __init__(self, fields):
        super().__init__(fields)
        digest = hashlib.sha1(repr(self._fields).encode()).hexdigest()[:20]
        self.name = f"demkit.{self._typename}_{digest}"

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(t)) for name, t in fields)


@structref.register
class PairListType(_ShortNamed):
    pass


@structref.register
class StateType(_ShortNamed):
    pass


class PairList(structref.StructRefProxy):
    """A half neighbour list: the partners of internal particle i are ``partner[start[i]:end[i]]``
    (each pair once, owned by the lower tag; ``start[N]`` entries in all), ``history`` has one row
    per entry. ``reach`` = interaction cutoff + skin; ``bounds`` splits the owners into equal
    shares of pairs for threads."""

    @property
    def reach(self):
        return _get_reach(self)

    @property
    def start(self):
        return _get_start(self)

    @property
    def end(self):
        return _get_end(self)

    @property
    def partner(self):
        return _get_partner(self)

    @property
    def history(self):
        return _get_history(self)

    @property
    def bounds(self):
        return _get_bounds(self)

    @property
    def size(self):
        """Number of pairs in the list."""  # noqa
        return int(self.start[-1])


class State(structref.StructRefProxy):
    """The arrays of a scene, by name (see the module docstring)."""

    @property
    def lists(self):
        return _get_lists(self)


structref.define_proxy(PairList, PairListType, list(PAIR_LIST_FIELDS))
structref.define_proxy(State, StateType, list(STATE_FIELDS))


@intrinsic
def field(typingctx, s, name):
    """``field(s, "position")``: the field of a state or pair list, borrowed. numba reads a structref's
    field through NRT (it takes a reference and gives it back): an atomic increment and decrement
    per field, and the pieces of tier 1 read some twenty fields on each call (34 % of a two-sphere
    run's time). This reads the field from the structref's data block directly, so a function
    compiled without NRT (``_nrt=False``) can read it; in a function with NRT it takes the reference
    as numba's own read does."""
    if not isinstance(s, types.StructRef) or not isinstance(name, types.StringLiteral):
        return None
    attr = name.literal_value
    kind = s.field_dict[attr]

    def codegen(context, builder, signature, args):
        from numba.core import cgutils, imputils
        from numba.core.runtime.nrtdynmod import _meminfo_struct_type
        meminfo = context.make_helper(builder, s, args[0]).meminfo
        # NRT_MemInfo_data_fast without NRT: the data pointer is the MemInfo's fourth member
        info = builder.bitcast(meminfo, _meminfo_struct_type.as_pointer())
        data = builder.load(cgutils.gep(builder, info, 0, 3))
        block = s.get_data_type()
        data = builder.bitcast(data, context.data_model_manager[block].get_value_type().as_pointer())
        value = getattr(cgutils.create_struct_proxy(block)(context, builder, ref=data), attr)
        return imputils.impl_ret_borrowed(context, builder, kind, value)

    return kind(s, name), codegen


@njit(cache=True)
def _get_reach(s):
    return s.reach


@njit(cache=True)
def _get_start(s):
    return s.start


@njit(cache=True)
def _get_end(s):
    return s.end


@njit(cache=True)
def _get_partner(s):
    return s.partner


@njit(cache=True)
def _get_history(s):
    return s.history


@njit(cache=True)
def _get_bounds(s):
    return s.bounds


@njit(cache=True)
def _get_lists(s):
    return s.lists


@njit(cache=True)
def pair_loop_arrays(s, g):
    """The arrays a pair loop's diagnostics read (demkit.engine.snippets.ARRAYS, then pair list g's
    demkit.engine.snippets.LIST_ARRAYS), and the program, from a state with neighbour lists."""
    pl = s.lists[g]
    return (s.position, s.velocity, s.angular_velocity, s.dipole, s.radius, s.mass, s.box, s.params, s.status,
            s.clock, pl.start, pl.end, pl.partner, pl.history, s.program)


def touch_getters(state):
    """Read every list field of ``state`` through the proxies once, so that their compiled getters
    exist for its types before a run starts. Compiled (or loaded from the cache) later, in the
    middle of a run, a getter waited for numba's compiler lock, which the background compilation of
    the thread module holds for tens of seconds on a cold cache: the end of a first run (its
    statistics read the lists) and Ctrl-C stalled 5-12 s on an 8000-sphere frictional gas."""
    for pl in state.lists:
        pl.reach, pl.start, pl.end, pl.partner, pl.history, pl.bounds


# Constructors compiled once and cached on disk. Calling State(...) or PairList(...) from Python
# goes through numba's StructRefProxy constructor, which is compiled anew in every process for
# every combination of field types (about 1 s for a State, 0.2-0.3 s for a PairList, each time a
# process builds its first scene of a kind, even with every kernel cached).
@njit(cache=True)
def make_pair_list(*fields):
    """A :class:`PairList` of these fields, in the order of :data:`PAIR_LIST_FIELDS`."""
    return PairList(*fields)


@njit(cache=True)
def make_state(*fields):
    """A :class:`State` of these fields, in the order of :data:`STATE_FIELDS`."""
    return State(*fields)



def new_pair_list(reach, n, history_width, chunks, capacity=None):
    """An empty growing list for n particles (filled, and grown, in compiled code). It starts with
    room for one pair per particle; the first build grows it to what it holds and 1/8 more
    (demkit.engine.neighbours.GROWTH), so a list's memory follows its pairs, not a guess."""
    capacity = max(n, 16) if capacity is None else max(int(capacity), 16)
    return make_pair_list(float(reach), np.zeros(n + 1, dtype=np.int64), np.zeros(n, dtype=np.int64),
                          np.zeros(capacity, dtype=np.int32),
                          np.zeros((0, history_width)), np.zeros(chunks + 1, dtype=np.int64))


def tuple_state(arrays):
    """The named-tuple form (:data:`StateTuple`) over the arrays of a state (``Scene.arrays``): the
    same arrays, seen as the fused module of a scene without neighbour lists takes them."""
    lists = tuple(PairListTuple(*(getattr(pl, name) for name in PAIR_LIST_FIELDS)) for pl in arrays["lists"])
    return StateTuple(*(lists if name == "lists" else arrays[name] for name in STATE_FIELDS))


class TupleStateModule:
    """A fused module of a scene without neighbour lists (tier 2, named tuples, no reference counting)
    called with the structref state of tier 1, which the scene keeps after a switch of tier: each call
    is given :func:`tuple_state` of the scene's arrays (open scenes' arrays never change size, so both
    forms see the same memory), and ``compile`` takes tier 1's signatures. Its time loops record their
    frames with its own record_frame (its own energies); a frame recorded from Python is tier 1's (the
    same bits, nothing to compile on the main thread)."""

    def __init__(self, module, scene):
        self.module, self.scene = module, scene
        self._functions = {}

    def __getattr__(self, name):
        if name == "record_frame":
            return self.scene.kernels.record_frame
        if name not in self._functions:
            self._functions[name] = _TupleStateFunction(getattr(self.module, name), self.scene)
        return self._functions[name]


class _TupleStateFunction:
    def __init__(self, function, scene):
        self.function, self.scene = function, scene

    def __call__(self, *args):
        state = tuple_state(self.scene.arrays)
        return self.function(*(state if isinstance(a, State) else a for a in args))

    @property
    def signatures(self):
        return self.function.signatures

    def compile(self, signature):
        import numba
        ty = numba.typeof(tuple_state(self.scene.arrays))
        return self.function.compile(tuple(ty if isinstance(t, StateType) else t for t in signature))


def type_key(value):
    """What decides the numba type of an argument, read without numba's typeof (arrays: dtype,
    dimensions, layout, writability; a state: its numba type; tuples: their items)."""
    if isinstance(value, np.ndarray):
        flags = value.flags
        return value.dtype.str, value.ndim, flags.c_contiguous, flags.f_contiguous, flags.writeable, flags.aligned
    if isinstance(value, tuple):
        return tuple(type_key(v) for v in value)
    numba_type = getattr(value, "_numba_type_", None)
    return numba_type if numba_type is not None else type(value)
