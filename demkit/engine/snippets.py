"""Lines of generated code that both tiers write the same way (so that they give the same bits): the
arrays a piece reads, list upkeep, recording a frame, the end of a step, deep-overlap checks, sums of an
effect's outputs, the steps' borrowed reads of the state."""
from __future__ import annotations

import re

import numpy as np

from .state import DEEP_OVERLAP_FRACTION


ARRAYS = "position, velocity, angular_velocity, dipole, radius, mass, box, params, status, clock"
LIST_ARRAYS = "start, end, partner, history"

#: each piece's parameters: the state s and pair list pl whole (one pointer each; a first-class call
#: passing the ~20 arrays themselves cost 0.2-0.3 us, more than two spheres' forces), the force
#: buffers, the commit flag, the program row r of the pair loop, and ``own``: the scene's functions
#: of your own behind one first-class function (demkit.engine.own_laws; tier 1's loops call it for kind OWN),
#: and for a pair loop ``chunk``: tier 1's chunk of its loop (CHUNK_PARAMETERS), which tier 1's loop on
#: threads runs (one such loop for every family, demkit.engine.generic); the other pair pieces ignore it
PIECE_SIGNATURES = {"pairs_forces": "s, force, torque, pl, commit, r, own, chunk",
                    "pairs_forces_blocked": "s, force, torque, pl, commit, r, own, chunk",
                    "sphere_forces": "s, force, torque, commit, own", "pairs_energies": "s, pl, out, r, own",
                    "sphere_energies": "s, out, own"}
#: the parameters of a chunk of tier 1's pair loop: owners first..last-1, their forces into cf/ct
CHUNK_PARAMETERS = f"{ARRAYS}, cf, ct, {LIST_ARRAYS}, co, cg, commit, first, last, program, record, entries, s, own"
#: ... and its call by a loop over the chunks (chunks_run)
CHUNK_CALL = (f"({ARRAYS}, cf, ct, {LIST_ARRAYS}, scratch[t], gather[t], commit, bounds[t], bounds[t + 1], program, "
              "np.False_, history, s, own)")


def piece_prelude(name):
    """The first lines of piece ``name`` (also of a scene's own, tier 2): its arrays, by the names its
    loops use, from the state s, the pair list pl and the program row r."""
    lines = [f'    {a} = field(s, "{a}")' for a in ARRAYS.split(", ")]
    if name.startswith("pairs_"):
        lines += [f'    {a} = field(pl, "{a}")' for a in LIST_ARRAYS.split(", ")] + ['    program = field(s, "program")[r]']
    else:
        lines += ['    history = field(s, "sphere_history")', '    program = field(s, "program")']
    if name.startswith("pairs_forces"):
        lines += ['    scratch = field(s, "scratch")', '    gather = field(s, "gather")', '    bounds = field(pl, "bounds")',
                  '    chunk_force = field(s, "thread_force")', '    chunk_torque = field(s, "thread_torque")',
                  '    chunk_power = field(s, "thread_power")']
    return lines


def _state_fields():
    """Call arguments handing the ARRAYS over from the state ``s``."""
    return ", ".join(f"s.{name}" for name in ARRAYS.split(", "))


def _state_arrays(g, scratch=False):
    """Call arguments handing group g's arrays over from the state ``s``."""
    fields = _state_fields()
    lists = ", ".join(f"s.lists[{g}].{name}" for name in LIST_ARRAYS.split(", "))
    return f"{fields}, {{targets}}{lists}" + (", s.scratch, s.gather" if scratch else "")


def as_int64(value):
    """An integer argument of a generated call: a constant as ``np.int64(c)``, a name as it is. numba
    compiles a helper a constant reaches (not inlined: friction, a wall's plane) once for each value,
    as Literal[int](c): a fused module of a walled scene compiled the walls' plane three times more."""
    text = str(value)
    return f"np.int64({text})" if text.lstrip("-").isdigit() else text


def _pair_call(k, inter, offset, kind, owner="i", fields="", shift=False):
    """Source of the call to interaction k's force or energy function. ``owner`` is the index of
    particle i in the field arrays, which are named ``fields + <field name>``. ``shift`` (a sheared
    box): a force function that takes ``vshift`` is given the sliding image's (sx, sy, sz)."""
    args = [owner, "j", "dx", "dy", "dz", "r2", *(fields + name for name in inter.reads)]
    if inter.history_size:
        args += ["history", "p", as_int64(offset), "commit" if kind == "force" else "False"]
    args += [f"p{k}_{n}" for n in range(len(inter.parameters))]
    if shift and kind == "force" and takes_shift(inter.pair_functions()[0]):
        args.append(SHIFT)
    return f"{kind}_{k}({', '.join(_callable_arguments(inter, args))})"


#: the velocity shift of the sliding image, the last argument of a law that takes ``vshift``
SHIFT = "(sx, sy, sz)"


def takes_shift(function):
    """Does this pair force function take the velocity shift of a sliding image (``vshift``)?"""
    import inspect
    return "vshift" in inspect.signature(getattr(function, "py_func", function)).parameters


def shear_prelude(plan, slot):
    """Tier 2's lines binding the sliding images' numbers in a pair loop of a sheared box (the axes
    written in; tier 1 reads them from the shear block): the offset delta at the clock, the jump u,
    the lengths of the flow, gradient and third axes."""
    a, b = plan.shear.axes
    return [f"    sh = {slot}", "    delta = shear_offset(params, sh, box, clock[0])", "    jump = params[sh + 2]",
            "    margin = params[sh + 4]",
            f"    la = box[{a}]", f"    lb = box[{b}]", f"    lc = box[{3 - a - b}]",
            "    sx = 0.0", "    sy = 0.0", "    sz = 0.0"]


def shear_slot_after(plan, slot):
    """The slot of a sheared box's block in params (after the induction table, which starts at ``slot``)."""
    if plan.shear is None:
        return None
    return slot + (0 if plan.induction is None else int(np.size(plan.induction.table_values())))


def sheared_line(plan, pad, shift=True):
    """Tier 2's :func:`shear_geometry` line, the axes and the third axis's periodicity written in."""
    a, b = plan.shear.axes
    return shear_geometry(pad, a, b, bool(plan.periodic[3 - a - b]), shift)


def shear_gather(pad, gather, a, b, pc):
    """A pass of the blocked (dipole) loops over a block's gathered partners, before the loop the
    compiler vectorises: a partner more than half a period away along the gradient b is moved one period
    along b and by delta along a, to its sliding image (x_j + k L_b e_b + k delta e_a), so that the
    vectorised loop's rint minimum image, as in any periodic box, finds its nearest image and keeps no
    branch of the shear (in tier 1 it ran 15-25 % slower with one per pair; the pass costs one
    comparison per pair). Owners farther than ``margin`` (the shear block's SH_MARGIN) from both faces
    across b have no partner through the sliding boundary and skip the pass (the same bits: it would
    move none). ``pc`` is unused (the vectorised loop takes the third axis)."""
    ob = ("xi", "yi", "zi")[b] if isinstance(b, int) else f"(xi if {b} == 0 else (yi if {b} == 1 else zi))"
    return [f"{pad}ob = {ob}", f"{pad}if ob < margin or ob > lb - margin:", f"{pad}    for u in range(m):",
            f"{pad}        db = {gather}[{b}, u + 1] - ob",
            f"{pad}        if db > 0.5 * lb:", f"{pad}            {gather}[{b}, u + 1] -= lb",
            f"{pad}            {gather}[{a}, u + 1] -= delta",
            f"{pad}        elif db < -0.5 * lb:", f"{pad}            {gather}[{b}, u + 1] += lb",
            f"{pad}            {gather}[{a}, u + 1] += delta"]


def sheared_gather(plan, pad, gather):
    """Tier 2's :func:`shear_gather`, the axes written in (no lines where the box does not shear)."""
    if plan.shear is None:
        return []
    a, b = plan.shear.axes
    return shear_gather(pad, gather, a, b, bool(plan.periodic[3 - a - b]))


def shear_geometry(pad, a, b, pc, shift=True):
    """The line taking (dx, dy, dz) to the nearest Lees-Edwards image (demkit.engine.shear.sheared_image),
    with the velocity shift (sx, sy, sz) unless ``shift`` is False."""
    outs = "sx, sy, sz" if shift else "_sx, _sy, _sz"
    return f"{pad}dx, dy, dz, {outs} = sheared_image(dx, dy, dz, {a}, {b}, la, lb, delta, jump, {pc}, lc)"


def function_imports(pairs, effects):
    """Import lines binding the pair functions of ``pairs`` and ``effects`` ((index, interaction)
    pairs) to the names generated code calls: ``force_<k>``/``energy_<k>``, ``sforce_<e>``/``senergy_<e>``."""
    lines = []
    for prefix, members in (("", pairs), ("s", effects)):
        for k, inter in members:
            for kind, fn in zip(("force", "energy"), inter.pair_functions()):
                lines.append(f"from {fn.__module__} import {fn.__name__} as {prefix}{kind}_{k}")
    return lines


#: Python 3.11 compiles a call with more arguments than this into a form numba cannot inline
MAX_ARGUMENTS = 30


def _callable_arguments(inter, args):
    """The call's arguments, refused clearly when there are too many for the compiler."""
    if len(args) > MAX_ARGUMENTS:
        raise TypeError(f"{type(inter).__name__}: its functions take {len(args)} arguments, more than the "
                        f"{MAX_ARGUMENTS} numba can inline (Python compiles longer calls as f(*args)); "
                        f"combine parameters")
    return args


#: the generated maintain_lists around its rebuild calls (the fused and the generic modules)
MAINTAIN_LISTS_HEAD = ["", "", "@njit(**UPKEEP)", "def maintain_lists(s, strict):",
                       '    """Rebuild the neighbour lists once a sphere has moved half the skin since the last',
                       '    build; ``strict``: flag MOVED_TOO_FAR when it moved more than the skin (a step too long',
                       '    for the lists to be trusted)."""',
                       "    d2, k = max_displacement(s.position, s.reference)",
                       "    if d2 <= 0.25 * s.skin * s.skin:",
                       "        return",
                       "    if strict and d2 > s.skin * s.skin and s.status[0] == OK:",
                       "        s.status[0] = MOVED_TOO_FAR",
                       "        s.status[1] = k"]
MAINTAIN_LISTS_TAIL = ["    copy_rows(s.reference, s.position)",
                       "    s.counters[REBUILDS] += 1",
                       "    s.counters[WRAP_DUE] = 1"]


#: the generated sort_particles' permutation of every per-particle array by ``order``
PERMUTE_BY_ORDER = (["    n = order.shape[0]",
                     "    vectors = np.empty((n, 3))",
                     "    scalars = np.empty(n)",
                     "    integers = np.empty(n, dtype=np.int64)",
                     "    count = np.empty((n, 3), dtype=np.int64)"]
                    + [f"    permute_vectors(s.{name}, order, vectors)" for name in
                       ("position", "velocity", "angular_velocity", "dipole", "force", "torque")]
                    + [f"    permute_scalars(s.{name}, order, scalars)" for name in ("radius", "mass", "inertia")]
                    + ["    permute_scalars(s.tag, order, integers)", "    permute_vectors(s.image, order, count)",
                       "    for k in range(s.stage.shape[0]):  # integrators' arrays that outlive a step",
                       "        permute_vectors(s.stage[k], order, vectors)"])
#: the generated record_frame (a fused module records its frames with its own energies), and end_step's opening
RECORD_FRAME = ["", "", "@njit(**LOOP)", "def record_frame(k, s, record):",
                '    """Frame k of the record (a real call: it runs once a frame, kept out of the hot loop)."""',
                "    store_frame(k, s.position, s.velocity, s.angular_velocity, s.dipole, s.image, s.tag, s.mass,",
                "                s.inertia, s.box, s.periodic, record)",
                "    e = record[4]",
                "    last = e.shape[1] - 1",
                "    energies_of(s, e[k, :last])",
                "    e[k, last] = s.accum[0]"]
#: a fused module's end_step, its head
END_STEP_HEAD = ["", "", "@njit(**OUTER)", "def end_step(step, countdown, stride, s, record, timed):",
                '    """After global step ``step``: -1 if the run must stop (s.status says why), else the',
                '    steps left until the next frame (recording frame step // stride when it is due); with',
                '    ``timed`` (the scene keeps its clock), the servos take their step."""']
#: end_step after its list upkeep: stops, the finiteness check, the frame when due
END_STEP_TAIL = ["    if s.status[0] != OK:  # list upkeep or a pair loop flagged a stop",
                 "        s.status[2] = step", "        return -1",
                 "    if not state_is_finite(s.position, s.velocity, s.angular_velocity):",
                 "        s.status[0] = NON_FINITE",
                 "        s.status[2] = step",
                 "        return -1",
                 "    if countdown == 1:",
                 "        record_frame(step // stride, s, record)",
                 "        return stride",
                 "    return countdown - 1"]


#: the plane a wall presents to sphere i (its own, or a cylinder's tangent plane there) and the
#: surface's velocity, set by demkit.interactions.wall_motion.wall_plane: the first seven parameters
#: of every plane-contact law, and its next two (a Hertz law's E*, G*: scaled on a curved wall)
WALL_PLANE = ("wp", "wnx", "wny", "wnz", "wux", "wuy", "wuz", "wq7", "wq8")


#: the speeds of a pair loop's members, for multiple time stepping: all of them, the fast, the slow
SPEEDS = (None, "fast", "slow")


def chunks_run(loop, call):
    """Body lines of a pair loop cut into fixed chunks of owners: ``call`` (an expression of t, cf, ct)
    runs chunk t, chunk 0 adding into force/torque, the others into buffers of their own (zero on
    entry), over ``loop`` ("range", or "prange" on threads); then the buffers are summed in chunk order
    (torque too when ``torque_on``, set before) and zeroed again by sum_chunks: the same bits on any
    number of threads. Returns the dissipated power."""
    return ["    chunks = bounds.shape[0] - 1",
            f"    for t in {loop}(chunks):",
            "        cf = force if t == 0 else chunk_force[t - 1]",
            "        ct = torque if t == 0 else chunk_torque[t - 1]",
            f"        chunk_power[t] = {call}",
            "    if chunks > 1:",
            "        sum_chunks(force, chunk_force, chunks - 1)",
            "        if torque_on:",
            "            sum_chunks(torque, chunk_torque, chunks - 1)",
            "    power = 0.0", "    for t in range(chunks):", "        power += chunk_power[t]",
            "    return power"]


def deep_pair_overlap(pad):
    """Lines flagging DEEP_OVERLAP in ``status`` for a pair overlapping by more than DEEP_OVERLAP_FRACTION
    of the smaller radius (a contact too soft to stop it: the spheres would tunnel through)."""
    return [f"{pad}small = radius[i] if radius[i] < radius[j] else radius[j]",
            f"{pad}deep = radius[i] + radius[j] - {DEEP_OVERLAP_FRACTION!r} * small",
            f"{pad}if r2 < deep * deep and status[0] == OK:",
            f"{pad}    status[0] = DEEP_OVERLAP", f"{pad}    status[1] = i", f"{pad}    status[3] = j"]


def deep_wall_overlap(index):
    """Lines flagging a sphere pushed deeper than DEEP_OVERLAP_FRACTION of its radius into wall ``index``."""
    return [f"if overlap > {DEEP_OVERLAP_FRACTION!r} * radius[i] and status[0] == OK:",
            "    status[0] = DEEP_OVERLAP", "    status[1] = i", f"    status[3] = -1 - {index}"]


def effect_sums(torque, dissipative):
    """Lines adding a single-sphere effect's (ax, ay, az), (bx, by, bz) and w to sphere i's force,
    torque and the dissipated power."""
    lines = [f"force[i, {a}] += {o}" for a, o in enumerate(("ax", "ay", "az"))]
    if torque:
        lines += [f"torque[i, {a}] += {o}" for a, o in enumerate(("bx", "by", "bz"))]
    return lines + (["power += w"] if dissipative else [])


#: scene functions of the generic module through its ``calls`` (generic.SCENE_PIECES): the wrap (a scene
#: without periodic axes compiles neither fold: 2 CPU s of a fresh install's first step with the sliding
#: images' beside the plain one; a sheared box's, with its sliding images, in that slot of its calls:
#: generic.SHEARED_CALLS), a deforming box's step and a sheared box's frames (scenes in fixed boxes
#: compile neither)
BOX_FUNCTIONS = ["", "", "@njit(**LOOP)", "def wrap_positions(s):",
                 '    """Fold the periodic coordinates into the box."""',
                 "    wrap(s.position, s.reference, s.image, s.box, s.periodic)",
                 "", "", "@njit(**LOOP)", "def wrap_positions_sheared(s):",
                 '    """Fold the periodic coordinates into a sheared box, through its sliding images."""',
                 "    wrap_sheared(s.position, s.velocity, s.reference, s.image, s.box, s.periodic, s.params,",
                 "                 s.program[0, H_SHEAR], s.clock[0])",
                 "", "", "@njit(**LOOP)", "def deform_box(s):",
                 '    """The box at the clock and the positions remapped into it (demkit.engine.deform)."""',
                 "    deform_step(s.position, s.reference, s.box, s.params, s.program[0, H_DEFORM], s.clock[0])",
                 "", "", "@njit(**LOOP)", "def fold_frame(s, k, rec_position, rec_velocity, rec_image):",
                 '    """Frame k folded through a sheared box\'s sliding images (store_frame folds each axis alone)."""',
                 "    frame_sheared(k, s.position, s.velocity, s.image, s.tag, s.box, s.periodic, s.params,",
                 "                  s.program[0, H_SHEAR], s.clock[0], rec_position, rec_velocity, rec_image)"]


def borrowing(lines, names):
    """The functions ``names`` of the module's ``lines`` compiled without reference counting (STEP):
    their reads of the state's fields (``s.force``, ``pl.start``) become borrowed reads
    (:func:`demkit.engine.state.field`). A time loop calls them through ``steps`` once or twice a step; with
    numba's reads each field took an atomic increment and decrement (a quarter of the time of a
    small scene's step on tier 1, measured with perf)."""
    out, inside, docstring = [], False, False
    for line in lines:
        quotes = line.count('"""') % 2 == 1
        if line.startswith("def "):
            inside = line[4:line.index("(")] in names
            if inside and out and out[-1] in ("@njit(**OUTER)", "@njit(**LOOP)"):
                out[-1] = "@njit(**STEP)"
        elif inside and not docstring and not quotes and not line.lstrip().startswith(('"""', "#")):
            code, hash_, comment = line.partition("  #")
            line = re.sub(r"\b(s|pl)\.([a-z_]+)\b", r'field(\1, "\2")', code) + hash_ + comment
        docstring = docstring != quotes
        out.append(line)
    return out


def compiled_only(lines, names):
    """``lines`` of a module with the functions ``names`` and the stubs (``no_*``) compiled without numba's
    wrapper for calls from Python (only compiled code calls them: demkit.engine.generic.COMPILED_ONLY)."""
    out = []
    for line in lines:
        if line.startswith("def ") and out and out[-1].startswith("@njit(**") and out[-1].endswith(")"):
            name = line[4:line.index("(")]
            if name in names or name.startswith("no_"):
                out[-1] = out[-1][:-1] + ", no_cpython_wrapper=True)"
        out.append(line)
    return out
