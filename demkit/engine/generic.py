"""Tier 1: one generic kernel module per install, where a scene is data, not code.

:mod:`demkit.engine.kernels` writes one fused module per combination of interactions (tier 2): the
fastest loops, but each new combination compiles for 5-30 CPU s before its first step. This
module writes the *generic* module: the same pair loops, time loops and upkeep, in which every
shipped pair law and single-sphere effect (the :data:`PAIR_LAWS` and :data:`EFFECTS` catalogues)
sits behind an integer *kind* switch, and the scene's *program* -- which laws act in which pair
loop, their parameter slots, cutoffs, history offsets, periodic axes, effects -- is an int64 table
in the state (``s.program``, made by :func:`demkit.engine.program.program_of`). Its source depends on demkit alone, so it
is compiled once per install (function by function, as runs need them) and loaded from numba's
cache in a fraction of a second by every later scene, whatever its combination.

The generic loops do the fused loops' arithmetic in the fused loops' order (members of a pair loop
in the scene's order, the same minimum image, the same blocks of pairs for dipoles), so a run gives
the same bits on either tier and may switch tier between chunks (:mod:`demkit.engine.tiers`).

The catalogue is :mod:`demkit.engine.catalogue`, the program :mod:`demkit.engine.program`; this module
writes the generic module's text, :mod:`demkit.engine.generic_modules` builds, loads and calls it.

Layout of ``s.program`` (rows of :data:`demkit.engine.program.COLUMNS` int64):

* row 0, the header: :data:`H_LISTS` (the scene has neighbour lists), :data:`H_PERIODIC`,
  :data:`H_SORTED`, :data:`H_EFFECTS` (number of effects), :data:`H_SHORTEST` (the first list's group);
* row ``group_row(g, speed)`` for each pair loop g < :data:`MAX_GROUPS` and speed (0: every member,
  1: the fast ones, 2: the slow ones, for multiple time stepping): ``G_*`` flags, then up to
  :data:`MAX_MEMBERS` members of ``M_*`` columns each, then :data:`G_GROUP` and :data:`G_SPEED`;
* row ``effect_row(e)`` for each single-sphere effect: ``E_*`` columns.

Laws and effects of your own have the kind ``OWN``: the loops call the scene's adapters for them
(:mod:`demkit.engine.own_laws`, passed to the pieces as ``own``; :data:`OWN_CALLS`). Scenes this tier
cannot run (more groups, members or effects than the table holds; functions of your own in a
blocked loop or as a plane contact) run on tier 2 only.

Tier 2 of a scene with neighbour lists is these time loops given the scene's own pieces
(:func:`demkit.engine.modules.build_pieces`, ``GenericKernels(pieces=...)``) in place of the catalogue's.

The tier is compiled in pieces never linked into one another (docs/engine.md, "Tier 1 in pieces"):
the pair and sphere loops in a *pieces* module per family of laws (:meth:`_Generic.pieces_text`), the
scene-level functions and time loops in one module (serial) and its twin on threads
(:meth:`_Generic.text`), which take the pieces as numba first-class functions in a tuple ``calls``
(:data:`CALLS`); numba would otherwise link and optimise the whole catalogue again in each of the
seven time loops. Every scene on this tier, with neighbour lists or in open space, has a structref
state (:class:`demkit.engine.state.State`) and runs these same loops: an open scene's pair loops run over
all pairs (``G_LIST`` 0) and it is given stubs for the list upkeep.
"""
from __future__ import annotations

import inspect
import re
import textwrap
import warnings

from .catalogue import BLOCKED, FAMILIES, OWN, SLIDING, SUMS, catalogue
from .program import MAX_GROUPS, _layout_line, effect_row, group_row, sum_row
from .snippets import (ARRAYS, BOX_FUNCTIONS, END_STEP_HEAD, END_STEP_TAIL, LIST_ARRAYS, MAINTAIN_LISTS_HEAD, MAINTAIN_LISTS_TAIL, PERMUTE_BY_ORDER,
                       PIECE_SIGNATURES, CHUNK_CALL, CHUNK_PARAMETERS, RECORD_FRAME, SHIFT, SPEEDS, WALL_PLANE, chunks_run, deep_wall_overlap,
                       borrowing, compiled_only, deep_pair_overlap, effect_sums, piece_prelude, shear_gather, shear_geometry)


# the scene-level functions call the pieces as numba's first-class functions (an experimental
# feature of numba, used here in its documented form: compiled results passed as arguments)
warnings.filterwarnings("ignore", message="First-class function type feature is experimental")

TORQUES = ("tix", "tiy", "tiz", "tjx", "tjy", "tjz")


def _pair_call(law, kind, owner="i", prefix="", held=False):
    """The call of a law's force or energy function; its parameters read from ``params`` at the call,
    or (``held``) from the locals q0, q1, ... (see blocked_loop)."""
    args = [owner, "j", "dx", "dy", "dz", "r2", *(prefix + name for name in law.reads)]
    if law.history:
        args += ["history", "p", "off", "commit" if kind == "force" else "False"]
    args += [f"q{m}" if held else f"params[slot + {m}]" for m in range(law.parameters)]
    if law.shifted and kind == "force":  # the sliding image's velocity shift (0 unless the box shears)
        args.append(SHIFT)
    return f"law_{law.kind}_{kind}({', '.join(args)})"


def wall_plane_line():
    """The line that sets :data:`WALL_PLANE` for sphere i from the wall's first nine parameters and its
    row's geometry block."""
    values = ", ".join(f"params[slot + {m}]" for m in range(len(WALL_PLANE)))
    return (f"{', '.join(WALL_PLANE)} = wall_plane(x, y, z, radius[i], params, program[er, E_GEOMETRY], clock[0], "
            f"{values})")


def _effect_call(law, kind):
    args = ["i", "x", "y", "z", *law.reads]
    if law.history:
        args += ["history", "i", "off", "commit" if kind == "force" else "False"]
    if law.table:
        args += ["params", "table"]
    args += [f"params[slot + {m}]" for m in range(law.parameters)]
    if law.plane_contact:  # walls: the plane they present to sphere i (see wall_plane_line)
        args[-law.parameters:-law.parameters + len(WALL_PLANE)] = WALL_PLANE
    return f"effect_{law.kind}_{kind}({', '.join(args)})"


def _switch(entries, pad, body):
    """An if/elif chain over ``kind``: body(entry) gives each branch's lines."""
    lines = []
    for n, entry in enumerate(entries):
        lines.append(f"{pad}{'if' if n == 0 else 'elif'} kind == {entry.kind}:")
        lines += [f"{pad}    {line}" for line in body(entry)]
    return lines


class _Generic:
    """Builds the text of a generic module (``threads``: chunked loops on prange) or of a family's
    pieces (:data:`FAMILIES`)."""

    def __init__(self, threads, family="full"):
        self.threads, self.family = threads, family
        self.sheared = family in SLIDING  # its pair loops take sliding images (else no line of shear)
        laws, effects = catalogue()
        accepts = (lambda law: law.branch_free) if family == BLOCKED else FAMILIES[family]  # (no effect is)
        self.laws = [law for law in laws if accepts(law)]
        self.effects = [law for law in effects if accepts(law)]

    # ---- pair loops ---------------------------------------------------------------------------
    def header(self):
        return ["    n = position.shape[0]",
                "    count = program[G_COUNT]",
                "    is_list = program[G_LIST] != 0",
                "    torque_on = program[G_TORQUE] != 0",
                "    width = program[G_WIDTH]",
                "    contact_only = program[G_CONTACT_ONLY] != 0",
                "    any_contact = program[G_CONTACT] != 0",
                "    px = program[G_PX] != 0",
                "    py = program[G_PY] != 0",
                "    pz = program[G_PZ] != 0",
                "    lx = box[0]", "    hx = 0.5 * box[0]", "    ilx = 1.0 / box[0] if px else 0.0",
                "    ly = box[1]", "    hy = 0.5 * box[1]", "    ily = 1.0 / box[1] if py else 0.0",
                "    lz = box[2]", "    hz = 0.5 * box[2]", "    ilz = 1.0 / box[2] if pz else 0.0",
                "    sx = 0.0", "    sy = 0.0", "    sz = 0.0"] + ([
                # a sheared box (demkit.engine.shear): its block in params, the axes read from it
                '    sh = field(s, "program")[0, H_SHEAR]', "    sheared = sh >= 0",
                "    sa = int(params[sh + SH_FLOW]) if sheared else 0",
                "    sb = int(params[sh + SH_GRADIENT]) if sheared else 1",
                "    la = box[sa]", "    lb = box[sb]", "    lc = box[3 - sa - sb]",
                "    pc = program[G_PX + 3 - sa - sb] != 0",
                "    delta = shear_offset(params, sh, box, clock[0]) if sheared else 0.0",
                "    jump = params[sh + SH_JUMP] if sheared else 0.0",
                "    margin = params[sh + SH_MARGIN] if sheared else 0.0"] if self.sheared else [])

    def rows(self, pad, first, last):
        """Loop header over owners first..last-1 and their entries; the body goes at pad + 8. In a
        sheared box, ``edge``: is the owner within the shear block's margin of a face across the gradient
        axis (else none of its partners is through the sliding boundary: the plain minimum image)?"""
        lines = [f"{pad}for i in range({first}, {last}):",
                 f"{pad}    if is_list and start[i] == end[i]:",
                 f"{pad}        continue",
                 f"{pad}    xi = position[i, 0]", f"{pad}    yi = position[i, 1]", f"{pad}    zi = position[i, 2]"]
        if self.sheared:
            lines += [f"{pad}    ob = xi if sb == 0 else (yi if sb == 1 else zi)",
                      f"{pad}    edge = sheared and (ob < margin or ob > lb - margin)",
                      f"{pad}    if not edge:  # (no sliding image's velocity: set per pair by sheared_image)",
                      f"{pad}        sx = 0.0", f"{pad}        sy = 0.0", f"{pad}        sz = 0.0"]
        return lines

    def entries(self, pad):
        return [f"{pad}lo = start[i] if is_list else i + 1",
                f"{pad}hi = end[i] if is_list else n",
                f"{pad}base = 0 if is_list else i * (2 * n - i - 1) // 2 - (i + 1)",
                f"{pad}for q in range(lo, hi):",
                f"{pad}    j = partner[q] if is_list else q",
                f"{pad}    p = q if is_list else base + q"]

    def geometry(self, pad):
        lines = [f"{pad}dx = position[j, 0] - xi", f"{pad}dy = position[j, 1] - yi", f"{pad}dz = position[j, 2] - zi"]
        fold = pad
        if self.sheared:
            lines += [f"{pad}if edge:", shear_geometry(pad + "    ", "sa", "sb", "pc"), f"{pad}else:"]
            fold = pad + "    "
        for axis in "xyz":
            d, l, h = f"d{axis}", f"l{axis}", f"h{axis}"
            lines += [f"{fold}if p{axis}:", f"{fold}    if {d} > {h}:", f"{fold}        {d} -= {l}",
                      f"{fold}    elif {d} < -{h}:", f"{fold}        {d} += {l}"]
        return lines + [f"{pad}r2 = dx * dx + dy * dy + dz * dz"]

    def member(self, pad):
        """The member mm's columns as locals."""
        return [f"{pad}mb = G_MEMBERS + M_COLUMNS * mm",
                f"{pad}kind = program[mb + M_KIND]",
                f"{pad}slot = program[mb + M_SLOT]",
                f"{pad}cut = program[mb + M_CUT]",
                f"{pad}off = program[mb + M_OFFSET]"]

    def force_body(self, pad, force, torque):
        body = [f"{pad}if contact_only and r2 >= (radius[i] + radius[j]) * (radius[i] + radius[j]):",
                f"{pad}    held = False",
                f"{pad}    for h in range(width):",
                f"{pad}        if history[p, h] != 0.0:",
                f"{pad}            held = True",
                f"{pad}            break",
                f"{pad}    if not held:",
                f"{pad}        continue",
                f"{pad}if any_contact:"]
        body += deep_pair_overlap(pad + "    ")
        body += [f"{pad}fx = 0.0", f"{pad}fy = 0.0", f"{pad}fz = 0.0"] + [f"{pad}{c} = 0.0" for c in TORQUES]
        body += [f"{pad}for mm in range(count):"]
        inner = pad + "    "
        body += self.member(inner)
        body += [f"{inner}if cut >= 0 and not r2 < params[cut]:",
                 f"{inner}    if commit:",
                 f"{inner}        for h in range(off, off + program[mb + M_SIZE]):",
                 f"{inner}            history[p, h] = 0.0",
                 f"{inner}    continue"]

        # each branch is the law's call alone, the sums shared (see sphere_functions: adding +0.0 for a
        # law without torque or dissipation leaves the bits alone)
        body += [f"{inner}{name} = 0.0" for name in ("ax", "ay", "az", "bix", "biy", "biz", "bjx", "bjy", "bjz", "w")]

        def branch(law):
            outs = ["ax", "ay", "az"] + (["bix", "biy", "biz", "bjx", "bjy", "bjz"] if law.torque else [])
            outs += ["w"] if law.dissipative else []
            return [f"{', '.join(outs)} = {_pair_call(law, 'force')}"]
        body += _switch(self.laws, inner, branch)
        body += [f"{inner}{'elif' if self.laws else 'if'} kind == OWN:",  # a function of your own, through its adapter (demkit.engine.own_laws)
                 f"{inner}    ax, ay, az, bix, biy, biz, bjx, bjy, bjz, w = own(program[mb + M_INDEX], i, j, dx, dy, "
                 "dz, r2, s, history, p, off, commit, slot)",
                 f"{inner}fx += ax", f"{inner}fy += ay", f"{inner}fz += az",
                 f"{inner}if record:", f"{inner}    entries[p, 3 + 3 * mm] = ax",
                 f"{inner}    entries[p, 4 + 3 * mm] = ay", f"{inner}    entries[p, 5 + 3 * mm] = az",
                 f"{inner}tix += bix", f"{inner}tiy += biy", f"{inner}tiz += biz",
                 f"{inner}tjx += bjx", f"{inner}tjy += bjy", f"{inner}tjz += bjz",
                 f"{inner}power += w"]
        body += [f"{pad}{force}[j, 0] += fx", f"{pad}{force}[j, 1] += fy", f"{pad}{force}[j, 2] += fz",
                 f"{pad}fix -= fx", f"{pad}fiy -= fy", f"{pad}fiz -= fz",
                 f"{pad}if torque_on:",
                 f"{pad}    {torque}[j, 0] += tjx", f"{pad}    {torque}[j, 1] += tjy", f"{pad}    {torque}[j, 2] += tjz",
                 f"{pad}    qix += tix", f"{pad}    qiy += tiy", f"{pad}    qiz += tiz"]
        return body

    def owner_sums(self, pad, force, torque):
        open_ = [f"{pad}{c} = 0.0" for c in ("fix", "fiy", "fiz", "qix", "qiy", "qiz")]
        close = [f"{pad}{force}[i, 0] += fix", f"{pad}{force}[i, 1] += fiy", f"{pad}{force}[i, 2] += fiz",
                 f"{pad}if torque_on:", f"{pad}    {torque}[i, 0] += qix", f"{pad}    {torque}[i, 1] += qiy",
                 f"{pad}    {torque}[i, 2] += qiz"]
        return open_, close

    def plain_loop(self, pad, first, last, force, torque):
        open_, close = self.owner_sums(pad + "    ", force, torque)
        inner = pad + " " * 8
        separation = [f"{inner}if record:", f"{inner}    entries[p, 0] = dx", f"{inner}    entries[p, 1] = dy",
                      f"{inner}    entries[p, 2] = dz"]
        return (self.rows(pad, first, last) + open_ + self.entries(pad + "    ") + self.geometry(inner) + separation
                + self.force_body(inner, force, torque) + close)

    def blocked_loop(self, pad, first, last, force, torque, out, gather):
        """Dipole-like members (branch-free, reading only the moments) over blocks of BLOCK entries
        (see demkit.engine.kernels._Source.blocked_loop): the switch is taken once per block and member."""
        open_, close = self.owner_sums(pad + "    ", force, torque)
        inner = pad + " " * 12
        body = [f"{pad}    {gather}[3, 0] = dipole[i, 0]", f"{pad}    {gather}[4, 0] = dipole[i, 1]",
                f"{pad}    {gather}[5, 0] = dipole[i, 2]",
                f"{pad}    for b0 in range(start[i], end[i], BLOCK):",
                f"{pad}        m = min(BLOCK, end[i] - b0)",
                f"{pad}        for u in range(m):",
                f"{inner}j = np.uint32(partner[b0 + u])",
                f"{inner}{gather}[0, u + 1] = position[j, 0]", f"{inner}{gather}[1, u + 1] = position[j, 1]",
                f"{inner}{gather}[2, u + 1] = position[j, 2]",
                f"{inner}{gather}[3, u + 1] = dipole[j, 0]", f"{inner}{gather}[4, u + 1] = dipole[j, 1]",
                f"{inner}{gather}[5, u + 1] = dipole[j, 2]",
                f"{pad}        if sheared:  # the partners moved to their nearest sliding images (shear_gather)"]
        body += shear_gather(pad + " " * 12, gather, "sa", "sb", "pc") + [f"{pad}        for u in range(m):"]
        body += [f"{inner}{out}[{c}, u] = 0.0" for c in range(9)]
        body += [f"{pad}        for mm in range(count):"]
        body += self.member(inner)
        body += [f"{inner}c = params[cut] if cut >= 0 else math.inf"]

        def branch(law):
            # the parameters read before the loop: read in it, LLVM cannot tell that the stores into
            # the block's rows leave them alone, and the screened (Ewald) pair stayed scalar
            outs = ["ax", "ay", "az"] + (["bix", "biy", "biz", "bjx", "bjy", "bjz"] if law.torque else [])
            lines = [f"q{m} = params[slot + {m}]" for m in range(law.parameters)]
            lines += ["for u in range(m):", "    j = u + 1",
                     f"    dx = {gather}[0, j] - xi", f"    dy = {gather}[1, j] - yi", f"    dz = {gather}[2, j] - zi"]
            for axis in "xyz":
                lines += [f"    if p{axis}:", f"        d{axis} -= l{axis} * np.rint(d{axis} * il{axis})"]
            lines += ["    r2 = dx * dx + dy * dy + dz * dz",
                      f"    {', '.join(outs)} = {_pair_call(law, 'force', owner='0', prefix='g_', held=True)}",
                      "    keep = 1.0 if r2 < c else 0.0"]
            lines += [f"    {out}[{n}, u] += {o} * keep" for n, o in enumerate(outs)]
            return lines
        body += _switch([law for law in self.laws if law.branch_free], inner, branch)
        body += [f"{pad}        for u in range(m):",
                 f"{inner}j = np.uint32(partner[b0 + u])",
                 f"{inner}{force}[j, 0] += {out}[0, u]", f"{inner}{force}[j, 1] += {out}[1, u]",
                 f"{inner}{force}[j, 2] += {out}[2, u]",
                 f"{inner}fix -= {out}[0, u]", f"{inner}fiy -= {out}[1, u]", f"{inner}fiz -= {out}[2, u]",
                 f"{inner}if torque_on:",
                 f"{inner}    qix += {out}[3, u]", f"{inner}    qiy += {out}[4, u]", f"{inner}    qiz += {out}[5, u]",
                 f"{inner}    {torque}[j, 0] += {out}[6, u]", f"{inner}    {torque}[j, 1] += {out}[7, u]",
                 f"{inner}    {torque}[j, 2] += {out}[8, u]"]
        return self.rows(pad, first, last) + open_ + body + close

    def chunked(self, name, loop):
        """A pair-loop function over fixed chunks of owners (see demkit.engine.kernels: the same bits on any
        number of threads, and serially). Each chunk is one call of ``<name>_chunk``, a serial function;
        the loop over the chunks on threads is not here but one function for every family
        (:meth:`threads_loop`), given the chunk as a first-class function (each family's own copy cost
        2-4 CPU s of numba's parallel compiler)."""
        lines = ["", "", "@njit(**INNER)", f"def {name}_chunk({CHUNK_PARAMETERS}):",
                 '    """The owners first..last-1 of the loop, their forces into cf/ct; returns the power. With '
                 'record (the\n    plain loop): entries[p, :3] the separation of entry p, entries[p, 3 + 3 m:] '
                 'member m\'s force on j."""']
        lines += self.header()
        lines += ["    g_dipole = cg[3:6].T", "    power = 0.0"]
        lines += loop("    ", "first", "last", "cf", "ct", "co", "cg")
        lines += ["    return power"]
        lines += ["", "", "@njit(**ENTRY)",
                  f"def {name}({PIECE_SIGNATURES[name]}):  # (chunk: this module's own, called directly)"]
        lines += piece_prelude(name) + ["    torque_on = program[G_TORQUE] != 0"]
        return lines + chunks_run("range", f"{name}_chunk{CHUNK_CALL}")

    @staticmethod
    def threads_loop():
        """Tier 1's pair loop on threads, for every family: the chunks of ``chunk`` on prange."""
        lines = ["", "", "@njit(**ENTRY_PARALLEL)", f"def pairs_on_threads({PIECE_SIGNATURES['pairs_forces']}):"]
        lines += piece_prelude("pairs_forces") + ["    torque_on = program[G_TORQUE] != 0"]
        return lines + chunks_run("prange", f"chunk{CHUNK_CALL}")

    def pair_functions(self):
        if self.family == BLOCKED:
            return self.chunked("pairs_forces_blocked", self.blocked_loop)
        lines = self.chunked("pairs_forces", lambda pad, a, b, f, t, o, g: self.plain_loop(pad, a, b, f, t))
        # energies: the loop, which also records each entry's energies when asked (diagnostics, called from
        # Python, as the force chunk is for each entry's forces: no second copy of the catalogue). The
        # pieces pass record as np.False_, a bool numba does not type as the literal False: a literal
        # would compile the loop a second time for the diagnostics' True.
        lines += ["", "", "@njit(**INNER)",
                  f"def pairs_energies_rows({ARRAYS}, {LIST_ARRAYS}, out, record, entries, program, s, own):",
                  '    """Add the potential energies of the loop to out[kind]; with record, also entry p\'s energy under',
                  '    interaction k to entries[p, k]."""']
        lines += self.header() + ["    commit = False"]
        lines += self.rows("    ", 0, "n if is_list else n - 1") + self.entries("        ")
        pad = " " * 12
        lines += self.geometry(pad)
        lines += [f"{pad}for mm in range(count):"]
        inner = pad + "    "
        lines += self.member(inner) + [f"{inner}if cut >= 0 and not r2 < params[cut]:", f"{inner}    continue"]
        lines += _switch(self.laws, inner, lambda law: [
            f"energy = {_pair_call(law, 'energy')}", "out[program[mb + M_ENERGY]] += energy",
            "if record:", "    entries[p, program[mb + M_INDEX]] += energy"])
        lines += [f"{inner}{'elif' if self.laws else 'if'} kind == OWN:",
                  f"{inner}    energy = own(program[mb + M_INDEX], i, j, dx, dy, dz, r2, s, history, p, off, False, slot)[0]",
                  f"{inner}    out[program[mb + M_ENERGY]] += energy",
                  f"{inner}    if record:", f"{inner}        entries[p, program[mb + M_INDEX]] += energy"]
        lines += ["", "", "@njit(**ENTRY)", f"def pairs_energies({PIECE_SIGNATURES['pairs_energies']}):",
                  '    """Add the potential energies of the loop to out[kind]."""']
        lines += piece_prelude("pairs_energies")
        lines += [f"    pairs_energies_rows({ARRAYS}, {LIST_ARRAYS}, out, np.False_, history, program, s, own)"]
        return lines

    # ---- single-sphere effects ------------------------------------------------------------------
    def sphere_functions(self):
        head = ["    n = position.shape[0]", "    count = program[0, H_EFFECTS]",
                "    for i in range(n):", "        x = position[i, 0]", "        y = position[i, 1]",
                "        z = position[i, 2]", "        for e in range(count):",
                "            er = EFFECT_ROW + e", "            kind = program[er, E_KIND]",
                "            slot = program[er, E_SLOT]", "            table = program[er, E_TABLE]",
                "            off = program[er, E_OFFSET]"]
        lines = ["", "", "@njit(**ENTRY)", f"def sphere_forces({PIECE_SIGNATURES['sphere_forces']}):",
                 '    """Forces and torques of the single-sphere effects; returns the dissipated power."""']
        lines += piece_prelude("sphere_forces") + ["    power = 0.0"]
        lines += ["    for e in range(program[0, H_EFFECTS]):  # servo-controlled walls sum their push afresh",
                  "        servo_clear(params, program[EFFECT_ROW + e, E_GEOMETRY])"] + head

        # one wall plane, one overlap test and one set of sums for every kind: each branch is the law's call
        # alone (the effects' loop body is what numba's compile time grows with). Sums of +0.0 (a kind
        # without torque or dissipation) leave the bits alone: the sums start at +0.0, never -0.0.
        planes = [law.kind for law in self.effects if law.plane_contact]
        pad = " " * 12
        lines += [f"{pad}{name} = 0.0" for name in ("ax", "ay", "az", "bx", "by", "bz", "w") + WALL_PLANE]
        lines += [f"{pad}overlap = 0.0",
                  f"{pad}plane = {' or '.join(f'kind == {k}' for k in planes) or 'False'}",
                  f"{pad}if plane:  # walls: the plane they present to sphere i (see wall_plane_line)",
                  f"{pad}    {wall_plane_line()}",
                  f"{pad}    overlap = radius[i] - (x * wnx + y * wny + z * wnz - wp)",
                  f"{pad}    held = False",
                  f"{pad}    for h in range(off, off + program[er, E_SIZE]):",
                  f"{pad}        if history[i, h] != 0.0:",
                  f"{pad}            held = True",
                  f"{pad}            break",
                  f"{pad}    if not (overlap > 0.0 or held):",
                  f"{pad}        continue"]

        def branch(law):
            outs = ["ax", "ay", "az"] + (["bx", "by", "bz"] if law.torque else []) + (["w"] if law.dissipative else [])
            return [f"{', '.join(outs)} = {_effect_call(law, 'force')}"]
        lines += _switch(self.effects, pad, branch)
        lines += [f"{pad}{'elif' if self.effects else 'if'} kind == OWN:",  # an effect of your own, through its adapter (demkit.engine.own_laws)
                  f"{pad}    ax, ay, az, bx, by, bz, w = own(e, i, x, y, z, s, history, off, commit, slot, table)",
                  f"{pad}if plane:"]
        lines += [f"{pad}    {line}" for line in deep_wall_overlap("e")]
        lines += [f"{pad}    servo_add(params, program[er, E_GEOMETRY], ax, ay, az, wnx, wny, wnz, overlap)"]
        lines += [pad + line for line in effect_sums(True, True)]
        lines.append("    return power")
        lines += ["", "", "@njit(**ENTRY)", f"def sphere_energies({PIECE_SIGNATURES['sphere_energies']}):",
                  '    """Add the potential energies of the single-sphere effects to out[kind]."""']
        lines += piece_prelude("sphere_energies") + head
        lines += _switch(self.effects, " " * 12, lambda law: (
            [wall_plane_line()] if law.plane_contact else [])
            + [f"out[program[er, E_ENERGY]] += {_effect_call(law, 'energy')}"])
        lines += [f"            {'elif' if self.effects else 'if'} kind == OWN:",
                  "                out[program[er, E_ENERGY]] += own(e, i, x, y, z, s, history, off, False, slot, table)[0]"]
        return lines

    # ---- scene-level functions --------------------------------------------------------------------
    @staticmethod
    def call(name):
        """How the scene-level functions call ``name`` (of :data:`CALLS`): through ``calls``."""
        return f"calls[{CALLS.index(name)}]"

    def upkeep_call(self, name, *arguments):
        """The call of the list upkeep ``name`` (maintain_lists, sort_particles) with the list builder and
        the threads' flag of ``calls``."""
        rest = [self.call(n) for n in LIST_CALLS]
        return f"{self.call(name)}({', '.join(['s', *arguments, *rest])})"

    def forces_body(self, speed, force, torque, strict):
        sp = SPEEDS.index(speed)
        lines = [f"    {self.upkeep_call('maintain_lists', f'{strict} != False')}"]
        lines += ["    commit_flag = commit != False"]
        if speed != "fast":  # induced moments first: the slow forces read them
            lines += ["    if s.program[0, H_INDUCTION] != 0:",
                      f"        if {self.call('induce_now')}(s, commit_flag) != 0 and s.status[0] == OK:",
                      "            s.status[0] = INDUCTION_FAILED"]
        lines += [f"    clear({force}, {torque})", "    power = 0.0"]
        # one call site per piece, in a loop over the pair loops (each call site of a first-class
        # function is lowered whole, and every time loop holds these lines)
        args = f"s, {force}, {torque}, pl, commit_flag, row, {self.call('own_pair_forces')}"
        lines += [f"    for g in range({MAX_GROUPS}):",
                  f"        row = {group_row(0, sp)} + 3 * g",
                  "        if s.program[row, G_COUNT] > 0:",
                  "            pl = s.lists[g]"]
        lines += ["            if s.program[row, G_BLOCKED] != 0:",  # (blocked: over neighbour lists only)
                  f"                power += calls[{PIECES.index('pairs_forces_blocked')}]({args}, "
                  f"{self.call('pairs_blocked_chunk')})",
                  "            else:",
                  f"                power += calls[{PIECES.index('pairs_forces')}]({args}, {self.call('pairs_chunk')})"]
        if speed != "slow":
            lines += ["    if s.program[0, H_EFFECTS] > 0:",
                      f"        power += calls[{PIECES.index('sphere_forces')}](s, {force}, {torque}, commit_flag, "
                      f"{self.call('own_sphere_forces')})"]
        if speed != "fast":
            lines += [f"    {self.call('long_range')}(s, {force}, {torque}, s.accum, True)"]
        return lines + ["    return power"]

    @staticmethod
    def sum_switch():
        """For each long-range sum q of the program: energy = its function(..., force, torque, forces)."""
        lines = ["    for q in range(s.program[0, H_SUMS]):", "        kind = s.program[SUM_ROW + q, S_KIND]",
                 "        slot = s.program[SUM_ROW + q, S_SLOT]", "        energy = 0.0"]
        for k in range(len(SUMS)):
            lines += [f"        {'if' if k == 0 else 'elif'} kind == {k}:",
                      f"            energy = sum_{k}(s.position, s.dipole, s.box, s.params, slot, force, torque, forces, "
                      "s.status)"]
        return lines

    def upkeep_functions(self):
        """maintain_lists and sort_particles: the list upkeep, given the list builder and its fill as
        first-class functions (``rebuild_list``: :func:`demkit.engine.neighbours.rebuild`; called directly,
        its whole body was linked into each caller and optimised again there, 1.2 CPU s a caller;
        ``fill_list``: serial or on threads, the same lists) and whether the lists are built on threads
        (``threads``: True in the thread module's ``calls``, for the displacement check)."""
        head = [line.replace("def maintain_lists(s, strict):", "def maintain_lists(s, strict, rebuild_list, fill_list, threads):")
                .replace("d2, k = max_displacement(s.position, s.reference)",
                         "d2, k = max_displacement_threads(s.position, s.reference) if threads else "
                         "max_displacement(s.position, s.reference)") for line in MAINTAIN_LISTS_HEAD]
        lines = []
        # in a sheared box the sliding since the last build counts against the skin (demkit.engine.shear)
        test = head.index("    if d2 <= 0.25 * s.skin * s.skin:")
        # in a deforming box the remap's squeeze since the build (demkit.engine.deform)
        lines += head[:test] + [
            "    sh = s.program[0, H_SHEAR]",
            "    dq = s.program[0, H_DEFORM]",
            "    if sh >= 0:",
            "        if 2.0 * math.sqrt(d2) + slide_since_build(s.params, sh, s.box, s.clock[0], s.skin) <= s.skin:",
            "            return",
            "    elif dq >= 0:",
            "        if 2.0 * math.sqrt(d2) + squeeze_since_build(s.params, dq, s.box) <= s.skin:",
            "            return",
            "    el" + head[test].lstrip()] + head[test + 1:]
        lines += ["    le = list_frame(s.params, sh, s.box, s.clock[0], s.skin)"]
        # one call site of each first-class call, in a loop over the groups (each site is lowered whole)
        lines += [f"    for g in range({MAX_GROUPS}):",
                  f"        if s.program[{group_row(0, 0)} + 3 * g, G_LIST] != 0:",
                  "            rebuild_list(s.lists[g], s.position, s.tag, s.tag, s.box, s.periodic, le, fill_list)"]
        lines += ["    if sh >= 0:", "        s.params[sh + SH_BUILT] = le[2]", "    mark_built(s.params, dq, s.box)"]
        lines += MAINTAIN_LISTS_TAIL
        # the lists are rebuilt after the permutation by the list upkeep's own rebuild, their history
        # saved by the tags the particles had (``before``): saving and restoring it here, inlined for
        # each of the groups, compiled for 10 CPU s a module
        lines += ["", "", "@njit(**UPKEEP)", "def sort_particles(s, rebuild_list, fill_list, threads):",
                  '    """Re-order the particles by cell and rebuild the lists, carrying their history by tag."""',
                  "    before = s.tag.copy()"]
        lines += ["    shortest = s.program[0, H_SHORTEST]",
                  "    reach = s.lists[0].reach if shortest == 0 else (s.lists[1].reach if shortest == 1 else "
                  "s.lists[2].reach)",
                  "    order = cell_order(s.position, s.box, s.periodic, reach)"]
        lines += PERMUTE_BY_ORDER
        lines += ["    if s.sphere_history.shape[1] > 0:",
                  "        permute_rows(s.sphere_history, order)"]
        lines += ["    sh = s.program[0, H_SHEAR]", "    le = list_frame(s.params, sh, s.box, s.clock[0], s.skin)"]
        lines += [f"    for g in range({MAX_GROUPS}):",
                  f"        if s.program[{group_row(0, 0)} + 3 * g, G_LIST] != 0:",
                  "            rebuild_list(s.lists[g], s.position, s.tag, before, s.box, s.periodic, le, fill_list)"]
        lines += ["    if sh >= 0:", "        s.params[sh + SH_BUILT] = le[2]",
                  "    mark_built(s.params, s.program[0, H_DEFORM], s.box)"]
        lines += ["    copy_rows(s.reference, s.position)", "    s.counters[SORTS] += 1"]
        return lines

    def scene_functions(self):
        lines = self.upkeep_functions()
        # the sums are called as in the fused module (the same bits), with_forces the argument ``forces``: a
        # bool, not a literal, so each sum compiles once for forces and energies (P3M's object-mode block
        # around scipy's FFTs is compiled in every process, per overload)
        lines += ["", "", "@njit(**OUTER)", "def long_range(s, force, torque, out, forces):",
                  '    """The long-range sums (an Ewald sum\'s reciprocal part, P3M, FMM): with ``forces``, their forces and',
                  '    torques added to force/torque; else each sum\'s energy added to its column of out. Returns their',
                  '    energy. (One function for both: the sums are linked into it, and optimised again, once.)"""',
                  "    total = 0.0"]
        lines += self.sum_switch()
        lines += ["        if not forces:", "            out[s.program[SUM_ROW + q, S_ENERGY]] += energy",
                  "        total += energy", "    return total"]
        lines += BOX_FUNCTIONS  # the wrap, a deforming box's step, a sheared box's frames (demkit.engine.snippets)
        lines += ["", "", "@njit(**OUTER)", "def induce_now(s, commit):",
                  '    """Solve the induced moments in s.dipole (demkit.interactions.induction; 0: converged)."""',
                  "    g = s.program[0, H_INDUCTION_GROUP]",
                  "    slot = s.program[0, H_INDUCTION_SLOT]",
                  "    offset = s.program[0, H_INDUCTION_OFFSET]",
                  "    frame = list_frame(s.params, s.program[0, H_SHEAR], s.box, s.clock[0], 0.0)  # (sheared images)"]
        # one call site (the solve linked in and optimised once): the group's list, or none (g = -1: all pairs)
        lines += ["    if g >= 0:",
                  "        pl = s.lists[g]",
                  "        start, end, partner = pl.start, pl.end, pl.partner",
                  "    else:",
                  "        start, end = np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64)",
                  "        partner = np.zeros(1, dtype=np.int32)",
                  "    return induce(s.position, s.dipole, s.tag, s.box, s.periodic, s.params, slot, start, end, partner, "
                  "s.sphere_history, offset, commit, frame)"]
        lines += ["", "", "@njit(**OUTER)", "def induce_of(calls, s):",
                  '    """Solve the induced moments in s.dipole at the current positions (0: converged)."""']
        lines.append(f"    {self.upkeep_call('maintain_lists', 'False != False')}")
        lines += [f"    return {self.call('induce_now')}(s, False != False)"]
        lines += ["", "", "@njit(**OUTER)", "def compute_forces(calls, s, force, torque, commit, strict):",
                  '    """Forces and torques at the current state into force/torque; returns the dissipated power."""']
        lines += self.forces_body(None, "force", "torque", "strict")
        lines += ["", "", "@njit(**OUTER)", "def forces_of(calls, s, commit):",
                  '    """Forces and torques into s.force/s.torque (lists kept up to date); returns the power."""']
        lines += self.forces_body(None, "s.force", "s.torque", "True")
        for speed in ("fast", "slow"):
            lines += ["", "", "@njit(**OUTER)", f"def {speed}_forces_of(calls, s, force, torque, commit):",
                      f'    """The {speed} forces and torques only into force/torque."""']
            lines += self.forces_body(speed, "force", "torque", "True")
        lines += ["", "", "@njit(**LOOP)", "def next_contact_event(calls, s, force, horizon):",
                  '    """Earliest time in (0, horizon] at which a contact starts or stops (see demkit.engine.events)."""',
                  "    earliest = math.inf"]
        args = "s.position, s.velocity, force, s.mass, s.radius, s.box, s.periodic"
        # one call site per search, in a loop over the pair loops: each call site is optimised whole
        lines += [f"    for g in range({MAX_GROUPS}):",
                  f"        row = {group_row(0, 0)} + 3 * g",
                  "        if s.program[row, G_COUNT] > 0 and s.program[row, G_CONTACT] != 0:",
                  "            pl = s.lists[g]",
                  f"            earliest = min(earliest, earliest_crossing({args}, pl.start, pl.end, pl.partner, "
                  "s.program[row, G_LIST] != 0, horizon))"]
        lines += ["    for e in range(s.program[0, H_EFFECTS]):",
                  "        if s.program[EFFECT_ROW + e, E_PLANE] != 0:",
                  "            q = s.program[EFFECT_ROW + e, E_SLOT]",
                  "            earliest = min(earliest, earliest_wall_crossing(s.position, s.velocity, force, s.mass, "
                  "s.radius, s.params[q], s.params[q + 1], s.params[q + 2], s.params[q + 3], horizon))",
                  "    return earliest"]
        lines += ["", "", "@njit(**OUTER)", "def energies_of(calls, s, out):",
                  '    """out = [kinetic, rotational, <one potential energy per kind>]."""']
        lines.append(f"    {self.upkeep_call('maintain_lists', 'False != False')}")
        lines += ["    for a in range(out.shape[0]):", "        out[a] = 0.0",
                  "    out[0], out[1] = kinetic_energies(s.velocity, s.angular_velocity, s.mass, s.inertia)"]
        lines += [f"    for g in range({MAX_GROUPS}):",
                  f"        row = {group_row(0, 0)} + 3 * g",
                  "        if s.program[row, G_COUNT] > 0:",
                  "            pl = s.lists[g]",
                  f"            calls[{PIECES.index('pairs_energies')}](s, pl, out, row, {self.call('own_pair_energies')})"]
        lines += ["    if s.program[0, H_EFFECTS] > 0:",
                  f"        calls[{PIECES.index('sphere_energies')}](s, out, {self.call('own_sphere_energies')})"]
        # in the fused module's order: the sums, then the induced moments' energy
        lines += [f"    {self.call('long_range')}(s, s.force, s.torque, out, False)"]
        lines += ["    if s.program[0, H_INDUCTION] != 0:",
                  "        out[s.program[0, H_INDUCTION_ENERGY]] += induction_energy(s.dipole, s.tag, s.params, "
                  "s.program[0, H_INDUCTION_SLOT])"]
        frame = [line.replace("def record_frame(k,", "def record_frame(calls, k,")
                 .replace("energies_of(s,", "energies_of(calls, s,")
                 .replace("def end_step(step,", "def end_step(calls, frame, step,") for line in RECORD_FRAME + END_STEP_HEAD]
        at = frame.index("    e = record[4]")  # after store_frame: the frame folded with the sliding images
        lines += frame[:at] + ["    if s.program[0, H_SHEAR] >= 0:",
                               f"        {self.call('fold_frame')}(s, k, record[0], record[1], record[6])"] + frame[at:]
        lines += ["    if (s.program[0, H_PERIODIC] != 0 or s.program[0, H_SORTED] != 0) and s.counters[WRAP_DUE] != 0:",
                  "        s.counters[WRAP_DUE] = 0",
                  "        if s.program[0, H_PERIODIC] != 0:",
                  f"            {self.call('wrap_positions')}(s)",
                  "        if s.program[0, H_SORTED] != 0:",
                  "            if step + s.counters[RUN_START] - s.counters[LAST_SORT] >= s.counters[SORT_EVERY]:",
                  f"                {self.upkeep_call('sort_particles')}",
                  "                s.counters[LAST_SORT] = step + s.counters[RUN_START]"]
        # record_frame through ``frame`` (a time loop's steps[...]): called, it would be linked into
        # end_step and optimised again there (2.5 CPU s at a scene's first step)
        lines += ["    if timed:  # servo-controlled walls move after the step (read no field of s otherwise: it costs)",
                  "        for e in range(s.program[0, H_EFFECTS]):",
                  "            servo_step(s.params, s.program[EFFECT_ROW + e, E_GEOMETRY], s.clock[0])",
                  "        if s.program[0, H_DEFORM] >= 0:  # a deforming box: its size at the clock, the positions remapped",
                  f"            {self.call('deform_box')}(s)"]
        lines += [line.replace("record_frame(step", "frame(calls, step") for line in END_STEP_TAIL]
        return lines

    def imports(self):
        lines = ['"""demkit\'s generic kernel module (tier 1): written by demkit.engine.generic, do not edit."""',
                 _layout_line(),
                 "import math", "import numpy as np", "from numba import njit, prange",
                 "from demkit.engine.motion import (kick, drift, rotate, advance_spin, state_is_finite, kinetic_energies,",
                 "                           store_frame, clear, rk_save, rk_stage, rk_finish, copy_vectors, kick_all,",
                 "                           total_forces, sum_chunks, KERNEL_OPTIONS)",
                 "from demkit.engine.events import earliest_crossing, earliest_wall_crossing",
                 "from demkit.engine.neighbours import (max_displacement, max_displacement_threads, copy_rows, wrap,",
                 "                               cell_order, permute_vectors, permute_scalars, permute_rows)",
                 "from demkit.engine.state import (OK, NON_FINITE, MOVED_TOO_FAR, DEEP_OVERLAP, REBUILDS, WRAP_DUE, SORTS,",
                 "                          LAST_SORT, SORT_EVERY, INNER_STEPS, RUN_START, field)",
                 "from demkit.engine.plan import BLOCK",
                 "from demkit.engine.shear import (SH_FLOW, SH_GRADIENT, SH_JUMP, SH_BUILT, SH_MARGIN, shear_offset, sheared_image,",
                 "                          list_frame, slide_since_build, wrap_sheared, frame_sheared)",
                 "from demkit.engine.program import H_SHEAR, H_DEFORM",
                 "from demkit.engine.deform import deform_step, squeeze_since_build, mark_built",
                 "from demkit.engine.program import (H_LISTS, H_PERIODIC, H_SORTED, H_EFFECTS, H_SHORTEST, H_CLOCK, G_COUNT,",
                 "                            G_LIST, G_BLOCKED, G_TORQUE, G_WIDTH, G_CONTACT_ONLY, G_CONTACT, G_PX, G_PY, G_PZ,",
                 "                            G_MEMBERS, M_KIND, M_SLOT, M_CUT, M_OFFSET, M_SIZE, M_ENERGY, M_INDEX,",
                 "                            M_COLUMNS, E_KIND, E_SLOT, E_TABLE, E_OFFSET, E_ENERGY, E_SIZE, E_PLANE,",
                 "                            E_GEOMETRY)",
                 "from demkit.interactions.wall_motion import servo_add, servo_clear, servo_step, wall_plane",
                 f"OWN = {OWN}",
                 f"EFFECT_ROW = {effect_row(0)}",
                 f"SUM_ROW = {sum_row(0)}",
                 ""]
        # IEEE arithmetic in every generated loop: with fast-math flags (fused multiply-adds) LLVM
        # rounds differently where code is shaped differently, and the generic and fused modules
        # (demkit.engine.tiers) would not give the same bits (a Langevin bath beside walls, a switched power
        # law on threads differed by an ulp)
        fast = 'error_model="numpy"'
        lines += [f"INNER = dict(cache=True, _nrt=False, {fast})",
                  f"ENTRY = dict(cache=True, _nrt=False, {fast})",  # a piece's entry: reads the state (borrowed)
                  f"ENTRY_PARALLEL = dict(cache=True, parallel=True, {fast})",
                  f"PARALLEL = dict(cache=True, _nrt=False, parallel=True, {fast})",
                  f"OUTER = dict(cache=True, inline='always', {fast})",
                  f"STEP = dict(cache=True, _nrt=False, {fast})",  # called through steps: borrowed reads
                  # the time loops: they read the state's fields and call the steps, never allocate
                  f"TIME_LOOP = dict(cache=True, nogil=True, _nrt=False, {fast})",
                  "UPKEEP = dict(cache=True)",
                  f"LOOP = dict(cache=True, nogil=True, {fast})"]
        return lines

    def pieces_text(self):
        """The pieces: the pair loops and the single-sphere loops over the catalogue (each compiled
        once per install, called through function pointers), and a do-nothing stub of each with its
        arguments (passed in place of a piece a scene never calls, so that it is never compiled)."""
        lines = self.imports()
        for prefix, entries in (("law", self.laws), ("effect", self.effects)):
            for law in entries:
                lines += [f"from {law.module} import {law.force_name} as {prefix}_{law.kind}_force",
                          f"from {law.module} import {law.energy_name} as {prefix}_{law.kind}_energy"]
        blocked = self.family == BLOCKED
        names = ("pairs_forces_blocked",) if blocked else PIECES[:1] + PIECES[2:]
        lines += self.pair_functions()
        if not blocked:
            lines += self.sphere_functions()
        for name in names:
            params, result = PIECE_ARGUMENTS[name]
            lines += ["", "", "@njit(**INNER)", f"def no_{name}({params}):", f"    return {result}"]
        return "\n".join(compiled_only(lines, COMPILED_ONLY)) + "\n"

    def text(self, templates):
        """The scene-level functions and the time loops: every function that reaches a piece takes the
        tuple ``calls`` (the pieces as first-class functions, :data:`PIECES` order) first. On threads,
        the pair loop on threads alone: the time loops and the list upkeep are the serial module's, given
        the pair loop on threads and ``lists_on_threads`` True in ``calls`` (the same types, so the same
        compiled loops)."""
        lines = self.imports()
        if self.threads:
            return "\n".join(lines + self.threads_loop()) + "\n"
        lines += ["from demkit.engine.state import INDUCTION_FAILED",
                  "from demkit.interactions.induction import induce, induction_energy",
                  "from demkit.engine.program import (H_SUMS, H_INDUCTION, H_INDUCTION_GROUP, H_INDUCTION_SLOT, "
                  "H_INDUCTION_OFFSET, H_INDUCTION_ENERGY, S_KIND, S_SLOT, S_ENERGY)"]
        lines += [f"from {module} import {name} as sum_{k}" for k, (module, name) in enumerate(SUMS)]
        from .motion import CALLED_PASSES
        lines += ["from demkit.engine.motion import (" + ", ".join(f"{name}_called as {name}" for name in CALLED_PASSES)
                  + ")"]
        lines += self.scene_functions()
        # stubs passed for the list upkeep, the sums and the induction solve to scenes without them
        lines += ["", "", "@njit(**LOOP)", "def no_maintain_lists(s, strict, rebuild_list, fill_list, threads):", "    return",
                  "", "", "@njit(**LOOP)", "def no_sort_particles(s, rebuild_list, fill_list, threads):", "    return",
                  "", "", "@njit(**LOOP)", "def no_rebuild_list(pl, position, tag, before, box, periodic, le, fill_list):",
                  "    return",
                  "", "", "@njit(**LOOP)", "def no_fill_list(ts, xs, members, box, periodic, reach, radius, ncell, "
                  "cell_start, near, shift, counts, start, end, partner, lo, hi, image, near_x, near_id, cells, region, "
                  "used, le):", "    return",
                  "", "", "@njit(**LOOP)", "def no_long_range(s, force, torque, out, forces):", "    return 0.0",
                  "", "", "@njit(**LOOP)", "def no_induce_now(s, commit):", "    return 0",
                  "", "", "@njit(**LOOP)", "def no_wrap_positions(s):", "    return",
                  "", "", "@njit(**LOOP)", "def no_fold_frame(s, k, rec_position, rec_velocity, rec_image):",
                  "    return",
                  "", "", "@njit(**LOOP)", "def no_deform_box(s):", "    return",
                  "", "", "@njit(**INNER)",
                  "def no_own_pair_forces(k, i, j, dx, dy, dz, r2, s, history, p, off, commit, slot):",
                  "    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0",
                  "", "", "no_own_pair_energies = no_own_pair_forces",
                  "", "", "@njit(**INNER)",
                  "def no_own_sphere_forces(e, i, x, y, z, s, history, off, commit, slot, table):",
                  "    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0",
                  "", "", "no_own_sphere_energies = no_own_sphere_forces",
                  "", "", "@njit(**INNER)", f"def no_pairs_chunk({CHUNK_PARAMETERS}):", "    return 0.0"]
        steps_of = {}  # each time loop: the functions in its tuple steps, in order
        for name, template in templates.items():
            src = textwrap.dedent(inspect.getsource(template))
            pattern = r"\b(forces_of|fast_forces_of|slow_forces_of|end_step|next_contact_event)\("
            # the scene-level functions through ``steps``
            src = src.replace(f"def {template.__name__}(", f"def {name}_steps(calls, steps, ", 1)
            used = [step for step in STEPS if re.search(rf"\b{step}\(", src)]
            used += ["record_frame"] if "end_step" in used else []  # end_step's frame
            steps_of[f"{name}_steps"] = tuple(used)

            def call(m, used=used):
                frame = f"steps[{used.index('record_frame')}], " if m.group(1) == "end_step" else ""
                return f"steps[{used.index(m.group(1))}](calls, {frame}"
            src = re.sub(pattern, call, src)
            lines += ["", "", "@njit(**TIME_LOOP)"] + src.rstrip().splitlines()
        lines += ["", "", f"STEPS_OF = {steps_of!r}"]
        return "\n".join(compiled_only(borrowing(lines, STEPS + tuple(steps_of)), COMPILED_ONLY)) + "\n"


#: the pieces, in the order of the ``calls`` tuple the scene-level functions take
PIECES = ("pairs_forces", "pairs_forces_blocked", "sphere_forces", "pairs_energies", "sphere_energies")
THREAD_PIECES = ("pairs_forces", "pairs_forces_blocked")
#: the scene-level functions the time loops call, passed to them in the tuple ``steps`` (compiled
#: once per state type instead of inlined into each of the seven time loops; the state is a
#: structref, one pointer, cheap to pass)
STEPS = ("forces_of", "end_step", "fast_forces_of", "slow_forces_of", "next_contact_event")
#: the list upkeep and the allocating sums (long-range sums, induced moments), also passed through
#: ``calls`` (linked into every time loop, they would be optimised again in each)
SCENE_PIECES = ("maintain_lists", "sort_particles", "long_range", "induce_now", "wrap_positions",
                "fold_frame", "deform_box")
#: ... of which the list upkeep, given the two LIST_CALLS (below) as its last arguments
UPKEEP = SCENE_PIECES[:2]
#: the scene pieces a sheared box takes in place of the plain ones (its own name in the module), and
#: what only a sheared box calls: a scene in a fixed box compiles none of their shear code
SHEARED_CALLS = {"wrap_positions": "wrap_positions_sheared", "fold_frame": "fold_frame"}


#: the adapters of a scene's functions of your own (:mod:`demkit.engine.own_laws`), given to the pieces
#: (stubs for a scene of shipped interactions): a pair force's and energy's take
#: (k, i, j, dx, dy, dz, r2, s, history, p, offset, commit, slot) and return 10 floats (force, torques on
#: i and j, power; an energy in the first), a single-sphere effect's (e, i, x, y, z, s, history,
#: offset, commit, slot, table) and 7 (force, torque, power)
OWN_CALLS = ("own_pair_forces", "own_pair_energies", "own_sphere_forces", "own_sphere_energies")
#: tier 1's chunks of its pair loops, given to the pair pieces (tier 1's loop on threads runs them; a scene
#: without a loop of that kind, or with its own pieces, is given the stub ``no_pairs_chunk``)
CHUNK_CALLS = {"pairs_chunk": "pairs_forces", "pairs_blocked_chunk": "pairs_forces_blocked"}
#: the list builder (demkit.engine.neighbours.rebuild, or a stub for a scene without lists) and its fill
#: (neighbours.filler: serial, or on threads in the thread module's ``calls``) as first-class functions,
#: and whether the lists are built on threads (a bool), passed on to the list upkeep (UPKEEP): one
#: compiled upkeep for both, the builder linked into none of them, the fill into no builder
LIST_CALLS = ("rebuild_list", "fill_list", "lists_on_threads")
#: the names in the ``calls`` tuple, in order
CALLS = PIECES + SCENE_PIECES + OWN_CALLS + tuple(CHUNK_CALLS) + LIST_CALLS


#: the scene-level functions (and stubs ``no_*``) only compiled code calls, compiled without numba's wrapper for calls
#: from Python (it unboxed ``calls``: 0.1-0.2 CPU s each), which they would crash: :class:`GenericKernels` refuses them
COMPILED_ONLY = STEPS + ("long_range", "induce_now", "wrap_positions", "wrap_positions_sheared", "deform_box", "fold_frame")


#: ... and what each stub returns
PIECE_ARGUMENTS = {name: (params, "0.0" if "force" in name else "None") for name, params in PIECE_SIGNATURES.items()}


def generic_source(threads=False):
    """Python source of the generic module's scene-level functions and time loops (serial, or
    calling the thread pieces and the threaded passes)."""
    from .templates import TEMPLATES
    return _Generic(threads).text(TEMPLATES)


def _name(threads):
    from .modules import _fingerprint
    source = generic_source(threads)
    return source, f"demkit_generic_{_fingerprint(source, [])}"


def _pieces_name(family):
    from .modules import _fingerprint
    source = _Generic(False, family).pieces_text()
    return source, f"demkit_generic_pieces_{family}_{_fingerprint(source, [])}"
