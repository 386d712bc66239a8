"""Generate one fused, compiled kernel module for a scene.

The scene's interactions come in *groups* (:class:`Group`): interactions of the same reach share a
pair loop, over a neighbour list (``kind="list"``) or over all pairs i < j (``kind="all"``, for no
cutoff or a handful of spheres). For each group the module holds

* ``group_<g>_forces(<arrays>, force, torque, start, end, partner, history, commit)``: its pair loop,
  calling only its interactions' pair functions, Newton's third law applied once per pair, minimum
  image only along periodic axes; returns the dissipated power. ``_parallel`` variants split the
  owners into fixed chunks with their own force buffers (results independent of the thread count);
* ``group_<g>_energies``, ``group_<g>_pair_energies`` and ``group_<g>_pair_forces`` (diagnostics,
  measurements),

and for the scene ``forces_of(s, commit)``, ``energies_of(s, out)``, ``end_step`` (list upkeep,
wrapping, finiteness, recording) and one ``<name>_steps`` time loop per integrator template (see
:mod:`demkit.integrators`), pasted from ordinary Python source. ``s`` is the scene's named state
(:mod:`demkit.engine.state`). Parameters arrive in ``s.params`` (an argument, not a frozen global).

The source is written to a cache folder named by a hash of everything it depends on (its own text
and the source of every pair function), so numba's on-disk cache is reused safely between runs;
set ``DEMKIT_CACHE_DIR`` to move it, ``DEMKIT_NO_CACHE=1`` to disable it.
"""
from __future__ import annotations

import numpy as np

from .plan import BLOCK, SCALAR_FIELDS, Group, energy_kinds
from .templates import fused_loop
from .snippets import (ARRAYS, END_STEP_HEAD, END_STEP_TAIL, LIST_ARRAYS, RECORD_FRAME, MAINTAIN_LISTS_HEAD, MAINTAIN_LISTS_TAIL,
                       PERMUTE_BY_ORDER, PIECE_SIGNATURES, SPEEDS, WALL_PLANE, _callable_arguments,
                       _pair_call, _state_arrays, _state_fields, chunks_run, deep_wall_overlap, effect_sums,
                       as_int64, deep_pair_overlap, function_imports, piece_prelude, shear_prelude, shear_slot_after,
                       sheared_gather, sheared_line)


class _Source:
    """Builds the text of the generated module."""

    def __init__(self, plan, importable, threads=False):
        self.plan = plan
        self.threads = threads  # the thread module: chunked loops on prange, per-step passes on threads
        self.kinds = energy_kinds(plan.energy_sources)
        self.importable = importable
        self.parts = self.split_groups()
        # parameter slots: each interaction's parameters, each effect's, then one squared cutoff per
        # interaction, then the effects' tables (Scene builds params in this order)
        self.param_slot, slot = {}, 0
        for k, inter in enumerate(plan.interactions):
            self.param_slot[k] = slot
            slot += len(inter.parameters)
        self.effect_slot = {}
        for e, effect in enumerate(plan.effects):
            self.effect_slot[e] = slot
            slot += len(effect.parameters)
        self.cutoff_slot = {k: slot + k for k in range(len(plan.interactions))}
        self.table_slot, slot = {}, slot + len(plan.interactions)
        for e, effect in enumerate(plan.effects):
            size = np.size(effect.table_values())
            if size:
                self.table_slot[e] = slot
                slot += size
        self.geometry_slot = {}  # geometry blocks of walls that move or curve follow the tables
        for e, effect in enumerate(plan.effects):
            size = np.size(effect.geometry_values())
            if size:
                self.geometry_slot[e] = slot
                slot += size
        self.sum_slot = []  # long-range sums: their tables follow the effects'
        for tuned in plan.sums:
            self.sum_slot.append(slot)
            slot += np.size(tuned.table_values())
        self.induction_slot = slot  # the induction table follows the sums' (demkit.interactions.induction); a shear's block last
        self.shear_slot = shear_slot_after(plan, slot)

    # ---- pair loops ------------------------------------------------------------------------
    def prelude(self, group):
        lines = ["    n = position.shape[0]"]
        for a, axis in enumerate("xyz"):
            if self.plan.periodic[a] and group.kind == "list":
                lines += [f"    l{axis} = box[{a}]", f"    h{axis} = 0.5 * box[{a}]"]
                if group.blocked:
                    lines.append(f"    il{axis} = 1.0 / box[{a}]")
        for k, inter in group.members:
            for m in range(len(inter.parameters)):
                lines.append(f"    p{k}_{m} = params[{self.param_slot[k] + m}]")
            if inter.cutoff_distance is not None:
                lines.append(f"    c{k} = params[{self.cutoff_slot[k]}]")
        return lines + (shear_prelude(self.plan, self.shear_slot) if self.plan.shear and group.kind == "list" else [])

    def rows(self, group, indent, first, last):
        """Loop headers over the pairs of owners first..last-1 and the pair geometry; the body goes
        at indent + 8."""
        pad = " " * indent
        if group.kind == "all" and last == "n":
            last = "n - 1"  # the last row of the triangle is empty
        lines = [f"{pad}for i in range({first}, {last}):",
                 f"{pad}    xi = position[i, 0]", f"{pad}    yi = position[i, 1]", f"{pad}    zi = position[i, 2]"]
        if self.plan.shear is not None and group.kind == "list":  # near a face across the gradient axis?
            ob = ("xi", "yi", "zi")[self.plan.shear.axes[1]]  # (demkit.engine.generic._Generic.rows)
            lines += [f"{pad}    edge = {ob} < margin or {ob} > lb - margin", f"{pad}    if not edge:",
                      f"{pad}        sx = 0.0", f"{pad}        sy = 0.0", f"{pad}        sz = 0.0"]
        if group.kind == "list":
            lines.insert(1, f"{pad}    if start[i] == end[i]:")
            lines.insert(2, f"{pad}        continue")
            lines.append(f"{pad}    for p in range(start[i], end[i]):")
            lines.append(f"{pad}        j = partner[p]")
        else:
            if group.width:
                lines.append(f"{pad}    p = i * (2 * n - i - 1) // 2 - 1")
            lines.append(f"{pad}    for j in range(i + 1, n):")
            if group.width:
                lines.append(f"{pad}        p += 1")
        return lines + self.geometry(group, pad + " " * 8)

    def geometry(self, group, pad, select=False):
        """dx, dy, dz = x_j - x_i (minimum image along periodic axes: branches, or selects that a
        vectorising compiler keeps) and r2."""
        lines = [f"{pad}dx = position[j, 0] - xi", f"{pad}dy = position[j, 1] - yi", f"{pad}dz = position[j, 2] - zi"]
        fold = pad
        if self.plan.shear is not None and group.kind == "list":  # Lees-Edwards images (demkit.engine.shear)
            lines += [f"{pad}if edge:", sheared_line(self.plan, pad + "    "), f"{pad}else:"]
            fold = pad + "    "  # (an owner away from the faces across b: the plain minimum image, the same bits)
        for a, axis in enumerate("xyz"):
            if self.plan.periodic[a] and group.kind == "list":
                d, l, h = f"d{axis}", f"l{axis}", f"h{axis}"
                if select:
                    lines.append(f"{fold}{d} = {d} - {l} if {d} > {h} else ({d} + {l} if {d} < -{h} else {d})")
                else:
                    lines += [f"{fold}if {d} > {h}:", f"{fold}    {d} -= {l}", f"{fold}elif {d} < -{h}:",
                              f"{fold}    {d} += {l}"]
        return lines + [f"{pad}r2 = dx * dx + dy * dy + dz * dz"]

    def guarded(self, k, inter, statements, pad, offset=None):
        """``statements`` under interaction k's cutoff test; beyond the cutoff a pair has no history:
        with ``offset`` (committing force loops) its history values are zeroed there."""
        if inter.cutoff_distance is None:
            return [pad + st for st in statements]
        lines = [f"{pad}if r2 < c{k}:"] + [pad + "    " + st for st in statements]
        if offset is not None and inter.history_size:
            lines += [f"{pad}elif commit:", f"{pad}    for h in range({offset}, {offset + inter.history_size}):",
                      f"{pad}        history[p, h] = 0.0"]
        return lines

    def force_body(self, group, indent, force, torque):
        pad = " " * indent
        torque_on = group.torque
        body = []
        if all(inter.contact_reach for _, inter in group.members):
            # contact laws only: a pair that does not touch and holds no history costs a distance
            # test, not calls and accumulations of zeros (a pair that held history goes through
            # its law once more, which releases the springs and books their energy)
            test = "r2 >= (radius[i] + radius[j]) * (radius[i] + radius[j])"
            test += "".join(f" and history[p, {h}] == 0.0" for h in range(group.width))
            body += [f"{pad}if {test}:", f"{pad}    continue"]
        if any(inter.contact_reach for _, inter in group.members):
            body += deep_pair_overlap(pad)
        body += [f"{pad}fx = 0.0", f"{pad}fy = 0.0", f"{pad}fz = 0.0"]
        if torque_on:
            body += [f"{pad}{c} = 0.0" for c in ("tix", "tiy", "tiz", "tjx", "tjy", "tjz")]
        for k, inter in group.members:
            outs = ["ax", "ay", "az"]
            acc = ["fx += ax", "fy += ay", "fz += az"]
            if inter.torque:
                outs += ["bix", "biy", "biz", "bjx", "bjy", "bjz"]
                acc += ["tix += bix", "tiy += biy", "tiz += biz", "tjx += bjx", "tjy += bjy", "tjz += bjz"]
            if inter.dissipative:
                outs += ["w"]
                acc += ["power += w"]
            call = f"{', '.join(outs)} = {_pair_call(k, inter, group.offsets[k], 'force', shift=bool(self.plan.shear))}"
            body += self.guarded(k, inter, [call] + acc, pad, group.offsets[k])
        body += [f"{pad}{force}[j, 0] += fx", f"{pad}{force}[j, 1] += fy", f"{pad}{force}[j, 2] += fz",
                 f"{pad}fix -= fx", f"{pad}fiy -= fy", f"{pad}fiz -= fz"]
        if torque_on:
            body += [f"{pad}{torque}[j, 0] += tjx", f"{pad}{torque}[j, 1] += tjy", f"{pad}{torque}[j, 2] += tjz",
                     f"{pad}qix += tix", f"{pad}qiy += tiy", f"{pad}qiz += tiz"]
        return body

    def owner_sums(self, group, indent, force, torque):
        """Per-owner accumulators: opened after the row header, stored after the row."""
        pad = " " * indent
        open_ = [f"{pad}fix = 0.0", f"{pad}fiy = 0.0", f"{pad}fiz = 0.0"]
        close = [f"{pad}{force}[i, 0] += fix", f"{pad}{force}[i, 1] += fiy", f"{pad}{force}[i, 2] += fiz"]
        if group.torque:
            open_ += [f"{pad}qix = 0.0", f"{pad}qiy = 0.0", f"{pad}qiz = 0.0"]
            close += [f"{pad}{torque}[i, 0] += qix", f"{pad}{torque}[i, 1] += qiy", f"{pad}{torque}[i, 2] += qiz"]
        return open_, close

    def gathered_fields(self, group):
        """Rows of the gather buffer: the partners' positions (rows 0-2), then each field the group's
        interactions read, as {field: first row}; and the number of those rows."""
        rows, row = {}, 3
        for _, inter in group.members:
            for name in inter.reads:
                if name not in rows:
                    rows[name] = row
                    row += 1 if name in SCALAR_FIELDS else 3
        return rows, row

    def blocked_loop(self, group, indent, first, last, force, torque, out, gather):
        """Rows in blocks of BLOCK entries, in three loops. A copy loop puts the partners' positions
        and fields in contiguous rows of ``gather`` (column 0 holds the owner's fields); a
        branch-free loop the compiler vectorises takes the separations (minimum image by rounding,
        ``d -= L rint(d / L)``), evaluates every entry and multiplies by 0 the pairs beyond a cutoff
        (cheaper than compacting the list: the skin's 20 % extra pairs cost less than a branchy
        copy), into ``out``; a scalar loop scatters the forces and torques. Partner indices are
        read as unsigned (no negative-index test per access)."""
        pad = " " * indent
        rows, _ = self.gathered_fields(group)
        head = self.rows(group, indent, first, last)[:6]
        open_, close = self.owner_sums(group, indent + 4, force, torque)
        cols = ["fx", "fy", "fz"] + (["tix", "tiy", "tiz", "tjx", "tjy", "tjz"] if group.torque else [])
        inner = pad + " " * 12

        def copy(index, column, target):
            lines = []
            for name, row in rows.items():
                if name in SCALAR_FIELDS:
                    lines.append(f"{target}{gather}[{row}, {column}] = {name}[{index}]")
                else:
                    lines += [f"{target}{gather}[{row + a}, {column}] = {name}[{index}, {a}]" for a in range(3)]
            return lines

        body = copy("i", 0, pad + "    ")
        body += [f"{pad}    for b0 in range(start[i], end[i], {BLOCK}):",
                 f"{pad}        m = min({BLOCK}, end[i] - b0)",
                 f"{pad}        for u in range(m):",
                 f"{inner}j = np.uint32(partner[b0 + u])",
                 f"{inner}{gather}[0, u + 1] = position[j, 0]", f"{inner}{gather}[1, u + 1] = position[j, 1]",
                 f"{inner}{gather}[2, u + 1] = position[j, 2]"]
        body += copy("j", "u + 1", inner) + sheared_gather(self.plan, pad + " " * 8, gather)
        body += [f"{pad}        for u in range(m):",
                 f"{inner}j = u + 1",
                 f"{inner}dx = {gather}[0, j] - xi", f"{inner}dy = {gather}[1, j] - yi",
                 f"{inner}dz = {gather}[2, j] - zi"]
        for a, axis in enumerate("xyz"):
            if self.plan.periodic[a]:
                body.append(f"{inner}d{axis} -= l{axis} * np.rint(d{axis} * il{axis})")
        body.append(f"{inner}r2 = dx * dx + dy * dy + dz * dz")
        body += [f"{inner}{c} = 0.0" for c in cols]
        for k, inter in group.members:
            outs = ["ax", "ay", "az"] + (["bix", "biy", "biz", "bjx", "bjy", "bjz"] if inter.torque else [])
            call = _pair_call(k, inter, 0, "force", owner="0", fields="g_")  # the gathered columns
            body.append(f"{inner}{', '.join(outs)} = {call}")
            keep = ""
            if inter.cutoff_distance is not None:  # beyond it r2 >= c > 0: the values are finite
                body.append(f"{inner}keep = 1.0 if r2 < c{k} else 0.0")
                keep = " * keep"
            body += [f"{inner}{c} += {o}{keep}" for c, o in zip(cols, outs)]
        body += [f"{inner}{out}[{n}, u] = {c}" for n, c in enumerate(cols)]
        body += [f"{pad}        for u in range(m):",
                 f"{inner}j = np.uint32(partner[b0 + u])",
                 f"{inner}{force}[j, 0] += {out}[0, u]", f"{inner}{force}[j, 1] += {out}[1, u]",
                 f"{inner}{force}[j, 2] += {out}[2, u]",
                 f"{inner}fix -= {out}[0, u]", f"{inner}fiy -= {out}[1, u]", f"{inner}fiz -= {out}[2, u]"]
        if group.torque:
            body += [f"{inner}qix += {out}[3, u]", f"{inner}qiy += {out}[4, u]", f"{inner}qiz += {out}[5, u]",
                     f"{inner}{torque}[j, 0] += {out}[6, u]", f"{inner}{torque}[j, 1] += {out}[7, u]",
                     f"{inner}{torque}[j, 2] += {out}[8, u]"]
        return head + open_ + body + close

    def gather_views(self, group, gather, pad):
        """The gathered columns seen as field arrays: g_<field>[j, c] = gather[row + c, j]."""
        rows, _ = self.gathered_fields(group)
        return [f"{pad}g_{name} = {gather}[{row}]" if name in SCALAR_FIELDS else
                f"{pad}g_{name} = {gather}[{row}:{row + 3}].T" for name, row in rows.items()]

    def force_loop(self, group, indent, first, last, force, torque):
        rows = self.rows(group, indent, first, last)
        open_, close = self.owner_sums(group, indent + 4, force, torque)
        # the accumulators open right after the owner's coordinates are read
        cut = 6 if group.kind == "list" else 4
        return rows[:cut] + open_ + rows[cut:] + self.force_body(group, indent + 8, force, torque) + close

    def loop(self, group, indent, first, last, force, torque, out, gather):
        if group.blocked:
            return (self.gather_views(group, gather, " " * indent)
                    + self.blocked_loop(group, indent, first, last, force, torque, out, gather))
        return self.force_loop(group, indent, first, last, force, torque)

    def group_forces(self, g, group, name=None, chunk=True):
        """Group g's pair loop (or the part of it ``name``); a chunked loop calls ``<name>_chunk`` for
        each chunk (:meth:`group_chunk`, written here unless ``chunk`` is False: the thread pieces
        import the serial ones), on prange in the thread module."""
        name = name or f"group_{g}"
        signature = f"{ARRAYS}, force, torque, {LIST_ARRAYS}, scratch, gather, commit"
        if not group.parallel:
            lines = ["", "", "@njit(**INNER)", f"def {name}_forces({signature}):",
                     f'    """Forces and torques of group {g} added to force/torque; returns the dissipated power."""']
            lines += self.prelude(group) + ["    power = 0.0", "    out = scratch[0]", "    gat = gather[0]"]
            lines += self.loop(group, 4, 0, "n", "force", "torque", "out", "gat")
            lines.append("    return power")
            return lines
        # chunked: the same chunks run on threads (prange, the thread module) or one after the other
        # (range, the serial module), so both give the same bits
        lines = self.group_chunk(name, group) if chunk else []
        lines += ["", "", "@njit(**PARALLEL)" if self.threads else "@njit(**INNER)",
                  f"def {name}_forces_chunked({signature}, bounds, chunk_force, chunk_torque, chunk_power):",
                  f'    """Group {g}\'s owners cut into fixed chunks (see chunks_run)."""',
                  f"    torque_on = {bool(group.torque)}"]
        return lines + chunks_run("prange" if self.threads else "range",
                                  f"{name}_chunk({ARRAYS}, cf, ct, {LIST_ARRAYS}, scratch[t], gather[t], commit, "
                                  "bounds[t], bounds[t + 1])")

    def energy_statements(self, group, target):
        body = []
        for k, inter in group.members:
            call = _pair_call(k, inter, group.offsets[k], "energy")
            body += self.guarded(k, inter, [f"{target(k)} += {call}"], " " * 12)
        return body

    def group_energies(self, g, group):
        lines = ["", "", "@njit(**INNER)", f"def group_{g}_energies({ARRAYS}, {LIST_ARRAYS}, out):",
                 f'    """Add the potential energies of group {g} to out[2 + kind]."""']
        lines += self.prelude(group)
        lines += self.rows(group, 4, 0, "n")
        lines += self.energy_statements(group, lambda k: f"out[{2 + self.kinds.index(self.plan.interactions[k].energy_kind)}]")
        lines += ["", "", "@njit(**INNER)",
                  f"def group_{g}_pair_energies({ARRAYS}, {LIST_ARRAYS}, owners, partners, out):",
                  f'    """owners[q], partners[q], out[q, k]: entry q of group {g} and its energy under',
                  '    interaction k (global numbering)."""']
        lines += self.prelude(group) + ["    q = 0"]
        lines += self.rows(group, 4, 0, "n")
        lines += ["            owners[q] = i", "            partners[q] = j"]
        lines += self.energy_statements(group, lambda k: f"out[q, {k}]") + ["            q += 1"]
        return lines

    def group_pair_forces(self, g, group):
        """Every entry of group g with its separation and each member's force on j, committing
        nothing (for measurements: demkit.measure)."""
        lines = ["", "", "@njit(**INNER)",
                 f"def group_{g}_pair_forces({ARRAYS}, {LIST_ARRAYS}, owners, partners, out):",
                 f'    """owners[q], partners[q]: entry q of group {g}; out[q, :3] its separation x_j - x_i,',
                 '    out[q, 3 + 3 m: 6 + 3 m] the force on j of the group\'s member m."""']
        lines += self.prelude(group) + ["    q = 0", "    commit = False"]
        lines += self.rows(group, 4, 0, "n")
        pad = " " * 12
        lines += [f"{pad}owners[q] = i", f"{pad}partners[q] = j", f"{pad}out[q, 0] = dx", f"{pad}out[q, 1] = dy",
                  f"{pad}out[q, 2] = dz"]
        for m, (k, inter) in enumerate(group.members):
            outs = ["ax", "ay", "az"] + (["bix", "biy", "biz", "bjx", "bjy", "bjz"] if inter.torque else [])
            outs += ["w"] if inter.dissipative else []
            call = f"{', '.join(outs)} = {_pair_call(k, inter, group.offsets[k], 'force', shift=bool(self.plan.shear))}"
            stores = [f"out[q, {3 + 3 * m + a}] = {c}" for a, c in enumerate(("ax", "ay", "az"))]
            lines += self.guarded(k, inter, [call] + stores, pad)
        return lines + [f"{pad}q += 1"]

    # ---- single-sphere effects ---------------------------------------------------------------
    def effect_call(self, e, effect, offset, kind, q=None, table=None):
        """The call of effect e's force or energy function (``q``: the names holding its parameters,
        ``table``: the expression of its table's slot)."""
        args = ["i", "x", "y", "z", *effect.reads]
        if effect.history_size:
            args += ["history", "i", as_int64(offset), "commit" if kind == "force" else "False"]
        if e in self.table_slot:
            args += ["params", as_int64(table or self.table_slot[e])]
        args += q if q is not None else [f"q{e}_{m}" for m in range(len(effect.parameters))]
        return f"s{kind}_{e}({', '.join(_callable_arguments(effect, args))})"

    def effect_runs(self):
        """The effects in runs (first, last) of consecutive effects of one law: the same functions,
        parameters, history size and table size, their parameters, history and tables side by side. A
        run's effects share one call site in a loop (a box of five walls: one copy of the wall law,
        not five, for numba and LLVM to compile), in the scene's order. Walls that move or curve join the
        run of their law: the loop reads each one's geometry slot (-1: a steady plane, passed as it is)."""
        plan, runs = self.plan, []
        for e, effect in enumerate(plan.effects):
            if runs:
                first, last = runs[-1]
                one = plan.effects[first]
                tables = self.table_slot.get(first), self.table_slot.get(e), np.size(one.table_values())
                if (effect.pair_functions() == one.pair_functions() and effect.parameters == one.parameters
                        and effect.history_size == one.history_size and effect.energy_kind == one.energy_kind
                        and np.size(effect.table_values()) == tables[2]
                        and (tables[0] is None) == (tables[1] is None)
                        and (tables[0] is None or tables[1] == tables[0] + (e - first) * tables[2])):
                    runs[-1] = (first, e)
                    continue
            runs.append((e, e))
        return runs

    def sphere_functions(self):
        plan = self.plan
        if not plan.effects:
            return []
        offsets = plan.effect_offsets
        runs = self.effect_runs()
        prelude = [f"    q{e}_{m} = params[{self.effect_slot[e] + m}]"
                   for e, last in runs if e == last for m in range(len(plan.effects[e].parameters))]
        head = ["    n = position.shape[0]"] + prelude + ["    for i in range(n):", "        x = position[i, 0]",
                                                          "        y = position[i, 1]", "        z = position[i, 2]"]

        def effect_lines(e, last, body_of):
            """Lines for the effects e..last (a run: a loop whose parameters and history offset follow e);
            ``body_of(index, offset, q, table, geometry)``, geometry: the block's slot, or None (no block)."""
            effect = plan.effects[e]
            moving = any(k in self.geometry_slot for k in range(e, last + 1))
            if e == last:
                return [" " * 8 + line for line in body_of(str(e), str(offsets[e]), [f"q{e}_{m}" for m in range(
                    len(effect.parameters))], None, str(self.geometry_slot[e]) if moving else None)]
            size, width = len(effect.parameters), effect.history_size
            lines = [f"        for e in range({e}, {last + 1}):",
                     f"            qb = {self.effect_slot[e]} + {size} * (e - {e})",
                     f"            ob = {offsets[e]} + {width} * (e - {e})"]
            if e in self.table_slot:
                lines.append(f"            tb = {self.table_slot[e]} + {np.size(effect.table_values())} * (e - {e})")
            if moving:
                slots = ", ".join(str(self.geometry_slot.get(k, -1)) for k in range(e, last + 1))
                lines.append(f"            gb = ({slots})[e - {e}]")
            lines += [f"            u{m} = params[qb + {m}]" for m in range(size)]
            return lines + [" " * 12 + line for line in body_of("e", "ob", [f"u{m}" for m in range(size)], "tb",
                                                                "gb" if moving else None)]

        def force_body(e, last):
            effect = plan.effects[e]
            servo = any(getattr(plan.effects[k], "servo", None) is not None for k in range(e, last + 1))

            def body(index, offset, q, table, geometry):
                outs = ["ax", "ay", "az"] + (["bx", "by", "bz"] if effect.torque else []) + (
                    ["w"] if effect.dissipative else [])
                lines, pad = [], ""
                call = [f"{', '.join(outs)} = {self.effect_call(e, effect, offset, 'force', q, table)}"]
                if getattr(effect, "plane_contact", False):  # walls: plane, nx, ny, nz come first
                    # a sphere clear of the wall, holding no history there, costs this test and no
                    # call (the law would return zeros: measured 13 ns a sphere and frictional wall)
                    held = "".join(f" or history[i, {offset} + {h}] != 0.0" for h in range(effect.history_size))
                    if geometry is not None:  # a moving or curved wall: the plane it presents to sphere i
                        lines += [self.wall_plane_line(geometry, q)]
                        q = self.plane_of(geometry, q)
                        call = [f"{', '.join(outs)} = {self.effect_call(e, effect, offset, 'force', q, table)}"]
                    lines += [f"overlap = radius[i] - (x * {q[1]} + y * {q[2]} + z * {q[3]} - {q[0]})",
                              f"if overlap > 0.0{held}:"]
                    pad = "    "
                    call += deep_wall_overlap(index)
                    if servo:  # its push and stiffness, for its step (servo_add: nothing for the others)
                        call += [f"servo_add(params, {as_int64(geometry)}, ax, ay, az, {q[1]}, {q[2]}, {q[3]}, overlap)"]
                call += effect_sums(effect.torque, effect.dissipative)
                return lines + [pad + line for line in call]
            return body

        lines = ["", "", "@njit(**CALLED)",
                 f"def sphere_forces({ARRAYS}, force, torque, history, commit):",
                 '    """Forces and torques of the single-sphere effects; returns the dissipated power."""',
                 "    power = 0.0"] + [f"    servo_clear(params, {as_int64(g)})" for g in self.servo_slots()] + head
        for e, last in runs:
            lines += effect_lines(e, last, force_body(e, last))
        lines.append("    return power")
        lines += ["", "", "@njit(**INNER)", f"def sphere_energies({ARRAYS}, history, out):",
                  '    """Add the potential energies of the single-sphere effects to out[2 + kind]."""'] + head
        for e, last in runs:
            effect = plan.effects[e]
            slot = 2 + self.kinds.index(effect.energy_kind)
            lines += effect_lines(e, last, lambda index, offset, q, table, geometry, e=e, effect=effect, slot=slot: (
                [self.wall_plane_line(geometry, q)] if geometry is not None else []) + [
                f"out[{slot}] += {self.effect_call(e, effect, offset, 'energy', self.plane_of(geometry, q), table)}"])
        return lines

    @staticmethod
    def plane_of(geometry, q):
        """An effect's parameter names ``q``; with a geometry block (``geometry``: its slot's expression, or
        None) the first nine replaced by the wall's plane for sphere i and two parameters (:meth:`wall_plane_line`)."""
        return list(WALL_PLANE) + list(q[len(WALL_PLANE):]) if geometry is not None else q

    @staticmethod
    def wall_plane_line(geometry, q):
        """The line setting the plane presented to sphere i by a wall with its block at ``geometry`` (as tier 1's)."""
        return (f"{', '.join(WALL_PLANE)} = wall_plane(x, y, z, radius[i], params, {as_int64(geometry)}, clock[0], "
                f"{', '.join(q[:len(WALL_PLANE)])})")

    # ---- scene-level functions -----------------------------------------------------------------
    def group_call(self, g, group, kind, targets, extra, name=None):
        args = _state_arrays(g, scratch=kind.startswith("forces")).format(targets=targets)
        return f"{name or f'group_{g}'}_{kind}({args}{extra})"

    def split_groups(self):
        """The fast and slow parts of each group, for multiple time stepping: (g, name, subgroup,
        speed) for every group holding both kinds of interaction (a group of one kind is used whole).
        Empty unless the scene has slow interactions without history next to fast ones."""
        plan = self.plan
        slow = [inter.slow for inter in plan.interactions]
        if not any(slow):
            return []
        if any(inter.slow and inter.history_size for inter in plan.interactions):
            return []  # refused by MultipleTimeStep (slow forces cannot keep per-step history)
        out = []
        for g, group in enumerate(plan.groups):
            kinds = {inter.slow for _, inter in group.members}
            if len(kinds) == 2:
                for speed in ("fast", "slow"):
                    members = [(k, inter) for k, inter in group.members if inter.slow == (speed == "slow")]
                    out.append((g, f"group_{g}_{speed}", Group(members, group.kind, group.reach, group.parallel),
                                speed))
        return out

    def force_calls(self, speed, force="force", torque="torque"):
        """Statements adding the forces of the groups (or group parts) of one speed ('fast', 'slow'
        or None: all) into the arrays named ``force``/``torque`` and their dissipated power into
        ``power``."""
        plan = self.plan
        split = {g: (name, sub) for g, name, sub, s in self.parts if s == speed}
        lines = []
        for g, group in enumerate(plan.groups):
            name, sub = None, group
            if speed is not None:
                if g in split:
                    name, sub = split[g]
                elif any(inter.slow != (speed == "slow") for _, inter in group.members):
                    continue
            if sub.parallel:
                extra = f", commit_flag, s.lists[{g}].bounds, s.thread_force, s.thread_torque, s.thread_power"
                lines.append("    power += " + self.group_call(g, sub, "forces_chunked", f"{force}, {torque}, ", extra, name))
            else:
                lines.append("    power += " + self.group_call(g, sub, "forces", f"{force}, {torque}, ", ", commit_flag", name))
        if plan.effects and speed != "slow":
            lines.append(f"    power += sphere_forces({_state_fields()}, {force}, {torque}, s.sphere_history, commit_flag)")
        if speed != "fast":  # long-range sums are slow forces (dipoles)
            lines += [f"    long_range_{q}(s.position, s.dipole, s.box, s.params, {slot}, {force}, {torque}, np.True_, "
                      "s.status)"
                      for q, slot in enumerate(self.sum_slot)]
        return lines

    def forces_body(self, speed, force, torque, strict):
        """Body of a scene-level force function: lists kept up to date (``strict``: see
        maintain_lists), the arrays named ``force``/``torque`` cleared, then filled by the groups of
        ``speed`` (see force_calls); returns the dissipated power."""
        # commit_flag: a plain bool. Called with the constants True/False, numba would compile every
        # pair loop once per literal value and once more for calls from Python (3x the compile time
        # of the largest functions, for no measurable speed: N = 8000 within the +-4 % noise).
        lines = [f"    maintain_lists(s, {strict} != False)"] if self.plan.lists else []
        lines += ["    commit_flag = commit != False"]
        if self.plan.induction is not None and speed != "fast":  # moments first: slow forces read them
            lines += [f"    if {self.induce_call('commit_flag')} != 0 and s.status[0] == OK:",
                      "        s.status[0] = INDUCTION_FAILED"]
        lines += [f"    clear({force}, {torque})", "    power = 0.0"]
        return lines + self.force_calls(speed, force, torque) + ["    return power"]

    def induce_call(self, commit):
        """The call solving the induced moments in s.dipole (its pairs: the Dipole's group's list;
        its last moments kept in the per-sphere history after the effects', when ``commit``)."""
        g = self.plan.induction.group
        if g is None:
            lists = "np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int32)"
        else:
            lists = f"s.lists[{g}].start, s.lists[{g}].end, s.lists[{g}].partner"
        offset = self.plan.effect_width - self.plan.induction.history_size
        return (f"induce(s.position, s.dipole, s.tag, s.box, s.periodic, s.params, {self.induction_slot}, {lists}, "
                f"s.sphere_history, {offset}, {commit}, np.zeros(0))")  # (no shear: a sheared box runs on tier 1's loops)

    def scene_functions(self):
        plan = self.plan
        lines = self.sphere_functions()
        spheres = _state_fields()
        if plan.lists:
            # callers pass strict as a bool *variable* (True != False): numba compiles a function
            # once per literal argument value, and this one links the whole list builder
            lines += MAINTAIN_LISTS_HEAD
            lines += [f"    rebuild(s.lists[{g}], s.position, s.tag, s.tag, s.box, s.periodic, np.zeros(0), np.bool_(LISTS_ON_THREADS))" for g in plan.lists]
            lines += MAINTAIN_LISTS_TAIL
        if plan.sorted:
            shortest = plan.lists[0]  # groups come sorted by reach: the cells of the shortest list
            lines += ["", "", "@njit(**UPKEEP)", "def sort_particles(s):",
                      '    """Re-order the particles by cell (memory locality) and rebuild the lists, carrying',
                      '    their history by tag. Only between steps: every per-particle array moves."""']
            lines += ["    before = s.tag.copy()  # the tags the lists were built with (their history's keys)"]
            lines += [f"    order = cell_order(s.position, s.box, s.periodic, s.lists[{shortest}].reach)"]
            lines += PERMUTE_BY_ORDER
            if plan.effect_width:
                lines.append("    permute_rows(s.sphere_history, order)")
            lines += [f"    rebuild(s.lists[{g}], s.position, s.tag, before, s.box, s.periodic, np.zeros(0), np.bool_(LISTS_ON_THREADS))" for g in plan.lists]
            lines += ["    copy_rows(s.reference, s.position)", "    s.counters[SORTS] += 1"]
        # forces. forces_of has compute_forces' body written out on s.force/s.torque rather than a
        # call of it: numba re-reads and copies a function at every level of inlining (the time
        # loops inline forces_of), and one level less is ~1 CPU s less for the paper's scene
        lines += ["", "", "@njit(**OUTER)", "def compute_forces(s, force, torque, commit, strict):",
                  '    """Forces and torques at the current state into force/torque; returns the dissipated power."""']
        lines += self.forces_body(None, "force", "torque", "strict")
        lines += ["", "", "@njit(**OUTER)", "def forces_of(s, commit):",
                  '    """Forces and torques into s.force/s.torque (lists kept up to date); returns the dissipated power."""']
        lines += self.forces_body(None, "s.force", "s.torque", "True")
        for speed in ("fast", "slow"):  # multiple time stepping: compiled only when called
            lines += ["", "", "@njit(**OUTER)", f"def {speed}_forces_of(s, force, torque, commit):",
                      f'    """The {speed} forces and torques only (see Interaction.slow) into force/torque."""']
            lines += self.forces_body(speed, "force", "torque", "True")
        # contact events (VelocityVerlet(resolve_contacts=True)): compiled only when called
        lines += ["", "", "@njit(**OUTER)", "def next_contact_event(s, force, horizon):",
                  '    """Earliest time in (0, horizon] at which a pair of a contact law starts or stops',
                  '    touching along the velocity-Verlet path under ``force`` (math.inf: none; see demkit.engine.events)."""',
                  "    earliest = math.inf"]
        for g, group in enumerate(plan.groups):
            if not any(inter.contact_reach for _, inter in group.members):
                continue
            args = "s.position, s.velocity, force, s.mass, s.radius, s.box, s.periodic"
            lines.append(f"    earliest = min(earliest, earliest_crossing({args}, s.lists[{g}].start, s.lists[{g}].end, "
                         f"s.lists[{g}].partner, {group.kind == 'list'}, horizon))")
        for e, effect in enumerate(plan.effects):
            if getattr(effect, "plane_contact", False) and getattr(effect, "flat", True):
                q = self.effect_slot[e]  # plane walls: parameters plane, nx, ny, nz first
                lines.append(f"    earliest = min(earliest, earliest_wall_crossing(s.position, s.velocity, force, "
                             f"s.mass, s.radius, s.params[{q}], s.params[{q + 1}], s.params[{q + 2}], "
                             f"s.params[{q + 3}], horizon))")
        lines.append("    return earliest")
        # energies
        lines += ["", "", "@njit(**OUTER)", "def energies_of(s, out):",
                  '    """out = [kinetic, rotational, <one potential energy per kind>]."""']
        if plan.lists:
            lines.append("    maintain_lists(s, False != False)")
        lines += ["    for a in range(out.shape[0]):", "        out[a] = 0.0",
                  "    out[0], out[1] = kinetic_energies(s.velocity, s.angular_velocity, s.mass, s.inertia)"]
        for g, group in enumerate(plan.groups):
            lines.append("    " + self.group_call(g, group, "energies", "", ", out"))
        if plan.effects:
            lines.append(f"    sphere_energies({spheres}, s.sphere_history, out)")
        for q, (tuned, slot) in enumerate(zip(plan.sums, self.sum_slot)):
            lines.append(f"    out[{2 + self.kinds.index(tuned.energy_kind)}] += long_range_{q}(s.position, s.dipole, "
                         f"s.box, s.params, {slot}, s.force, s.torque, np.False_, s.status)")
        if plan.induction is not None:
            lines.append(f"    out[{2 + self.kinds.index(plan.induction.energy_kind)}] += induction_energy(s.dipole, "
                         f"s.tag, s.params, {self.induction_slot})")
            lines += ["", "", "@njit(**OUTER)", "def induce_of(s):",
                      '    """Solve the induced moments in s.dipole at the current positions (0: converged)."""']
            if plan.lists:
                lines.append("    maintain_lists(s, False != False)")
            lines.append(f"    return {self.induce_call('False != False')}")
        for g, group in enumerate(plan.groups):
            for kind in ("pair_energies", "pair_forces"):
                lines += ["", "", "@njit(**OUTER)", f"def {kind}_{g}(s, owners, partners, out):"]
                if plan.lists:
                    lines.append("    maintain_lists(s, False != False)")
                lines.append("    " + self.group_call(g, group, kind, "", ", owners, partners, out"))
        # end of step and recording
        lines += RECORD_FRAME + END_STEP_HEAD  # (its own frames: with tier 1's, 4-6 % slower stepping, docs/engine.md)
        if plan.lists and (any(plan.periodic) or plan.sorted):
            lines += ["    if s.counters[WRAP_DUE] != 0:", "        s.counters[WRAP_DUE] = 0"]
            if any(plan.periodic):
                lines += ["        wrap(s.position, s.reference, s.image, s.box, s.periodic)"]
            if plan.sorted:
                lines += ["        if step + s.counters[RUN_START] - s.counters[LAST_SORT] >= s.counters[SORT_EVERY]:",
                          "            sort_particles(s)",
                          "            s.counters[LAST_SORT] = step + s.counters[RUN_START]"]
        lines += [f"    servo_step(s.params, {as_int64(g)}, s.clock[0])" for g in self.servo_slots()]  # servo-controlled walls move
        return lines + END_STEP_TAIL

    def servo_slots(self):
        """The geometry blocks of the servo-controlled walls, in the scene's order."""
        return [g for e, g in sorted(self.geometry_slot.items()) if getattr(self.plan.effects[e], "servo", None)]

    def head(self):
        """The module's imports and the options of its functions."""
        plan = self.plan
        lines = ["import math", "import numpy as np", "from numba import njit, prange",
                 "from demkit.engine.motion import (kick, drift, rotate, advance_spin, state_is_finite, kinetic_energies,",
                 "                           store_frame, clear, rk_save, rk_stage, rk_finish, copy_vectors, kick_all,",
                 "                           total_forces, sum_chunks, KERNEL_OPTIONS)",
                 "from demkit.engine.events import earliest_crossing",
                 "from demkit.engine.neighbours import (max_displacement, rebuild, copy_rows, wrap, cell_order,",
                 "                               permute_vectors, permute_scalars, permute_rows)",
                 "LISTS_ON_THREADS = False  # (the thread modules' list upkeep: True)",
                 "from demkit.engine.state import (OK, NON_FINITE, MOVED_TOO_FAR, DEEP_OVERLAP, REBUILDS, WRAP_DUE, SORTS, LAST_SORT, SORT_EVERY,",
                 "                          INNER_STEPS, RUN_START, INDUCTION_FAILED, field)",
                 ""]
        if plan.induction is not None:
            lines += ["from demkit.interactions.induction import induce, induction_energy", ""]
        if any(getattr(effect, "plane_contact", False) for effect in plan.effects):
            lines += ["from demkit.engine.events import earliest_wall_crossing", ""]
        if self.geometry_slot:
            lines += ["from demkit.interactions.wall_motion import servo_add, servo_clear, servo_step, wall_plane", ""]
        lines += ["from demkit.engine.shear import shear_offset, sheared_image"] if plan.shear is not None else []
        for q, tuned in enumerate(plan.sums):  # long-range sums: one compiled call each
            module, name = tuned.kernel
            lines += [f"from {module} import {name} as long_range_{q}"]
        if plan.growing:  # scenes with lists: the passes compiled once and called (see demkit.engine.motion)
            from .motion import CALLED_PASSES
            lines += ["from demkit.engine.motion import (" + ", ".join(f"{name}_called as {name}" for name in CALLED_PASSES)
                      + ")"]
        if self.threads:  # the chunk sums on threads, and in scenes with lists every per-step pass
            lines += ["from demkit.engine.motion import sum_chunks_threads as sum_chunks"]
        if self.threads and plan.growing:
            lines += ["from demkit.engine.motion import (kick_threads as kick, drift_threads as drift, clear_threads as clear,",
                      "                           advance_spin_threads as advance_spin, kick_all_threads as kick_all,",
                      "                           state_is_finite_threads as state_is_finite)",
                      "from demkit.engine.neighbours import max_displacement_threads as max_displacement",
                      "LISTS_ON_THREADS = True", ""]
        if self.importable:
            lines += function_imports(enumerate(plan.interactions), enumerate(plan.effects))
        cache = self.importable
        # IEEE arithmetic in every generated loop: with fast-math flags (fused multiply-adds) LLVM
        # rounds differently where code is shaped differently, and the generic and fused modules
        # (demkit.engine.tiers) would not give the same bits (a Langevin bath beside walls, a switched power
        # law on threads differed by an ulp)
        fast = 'error_model="numpy"'
        # no reference counting in small scenes, unless a long-range sum allocates (its arrays into object mode)
        nrt = "" if plan.growing or plan.sums or plan.induction is not None else ", _nrt=False"
        if plan.growing:  # big scenes: separate pair-loop functions, no reference counting inside
            lines.append(f"INNER = dict(cache={cache}, _nrt=False, {fast})")
        else:  # small scenes: everything inlined into the time loop
            lines.append(f"INNER = dict(KERNEL_OPTIONS, cache={cache}, fastmath=False)")
        # (CALLED: the sphere loop, not inlined: one call a force evaluation, not a copy in each time loop)
        lines += [f"CALLED = dict(cache={cache}, _nrt=False, {fast})",
                  f"ENTRY = dict(cache={cache}, _nrt=False, {fast})",  # a piece's entry (tier 2 with lists): reads the state (borrowed)
                  f"PARALLEL = dict(cache={cache}, _nrt=False, parallel=True, {fast})",
                  f"OUTER = dict(cache={cache}, inline='always', {fast}{nrt})",
                  f"UPKEEP = dict(cache={cache})",
                  f"LOOP = dict(cache={cache}, nogil=True, {fast}{nrt})"]  # time loops let other threads run (threads.py)
        return lines

    def text(self, templates):
        plan = self.plan
        lines = self.head()
        for g, group in enumerate(plan.groups):
            lines += self.group_forces(g, group) + self.group_energies(g, group) + self.group_pair_forces(g, group)
        for g, name, sub, _ in self.parts:
            lines += self.group_forces(g, sub, name)
        lines += self.scene_functions()
        for name, template in templates.items():  # (the clock a constant: tier 1 reads H_CLOCK)
            lines += ["", "", "@njit(**LOOP)"] + fused_loop(name, template, bool(self.geometry_slot))
        return "\n".join(lines) + "\n"

    def pieces_text(self, columns, serial_name=None):
        """Tier 2 of a scene with neighbour lists that tier 1 can run (see :func:`build_pieces`): its
        own pair and sphere loops, under the names and with the arguments of the generic pieces
        (:data:`PIECE_SIGNATURES`), which pick a pair loop by the program row's group and
        speed (``columns``: their columns in a row, :data:`demkit.engine.program.G_GROUP` and
        :data:`demkit.engine.program.G_SPEED`). Each chunk of a chunked loop is one call of a serial function,
        ``<loop>_chunk``; the thread pieces (``self.threads``) run the serial module's (``serial_name``)
        chunks on prange."""
        G_GROUP, G_SPEED = columns
        plan = self.plan
        lines = self.head()
        split = {(g, sp): (name, sub) for g, name, sub, sp in self.parts}
        loops = {}  # (group, speed) -> (name, the group or part) of every pair loop a program row may ask for
        for g, group in enumerate(plan.groups):
            for sp, speed in enumerate(SPEEDS):
                if speed is not None and (g, speed) not in split and any(
                        inter.slow != (speed == "slow") for _, inter in group.members):
                    continue  # no member of this speed: the program row is empty, never called
                name, sub = split.get((g, speed), (f"group_{g}", group))
                loops[g, sp] = (name, sub)
        once = {name: sub for name, sub in loops.values()}
        if self.threads:  # the chunks and the loops not chunked are the serial module's
            lines.append(f"from {serial_name} import " + ", ".join(
                f"{name}_chunk" if sub.parallel else f"{name}_forces" for name, sub in once.items()))
            for name, sub in once.items():
                if sub.parallel:
                    lines += self.group_forces(0, sub, name, chunk=False)
        else:
            for name, sub in once.items():
                lines += self.group_forces(0, sub, name)
            for g, group in enumerate(plan.groups):
                lines += self.group_energies(g, group) + self.group_pair_forces(g, group)
            lines += self.sphere_functions()
        arrays = f"{ARRAYS}, force, torque, {LIST_ARRAYS}, scratch, gather, commit"
        chunks = "bounds, chunk_force, chunk_torque, chunk_power"
        lines += ["", "", "@njit(**ENTRY)", f"def piece_pairs_forces({PIECE_SIGNATURES['pairs_forces']}):",
                  '    """The pair loop of the program row\'s group and speed; returns the dissipated power."""']
        lines += piece_prelude("pairs_forces") + [f"    g = program[{G_GROUP}]", f"    speed = program[{G_SPEED}]"]
        speeds = {}  # each loop once, with the speeds whose rows ask for it
        for (g, sp), (name, sub) in loops.items():
            speeds.setdefault(name, (g, sub, []))[2].append(sp)
        for name, (g, sub, sps) in speeds.items():
            call = f"{name}_forces_chunked({arrays}, {chunks})" if sub.parallel else f"{name}_forces({arrays})"
            lines += [f"    if g == {g} and ({' or '.join(f'speed == {sp}' for sp in sps)}):",
                      f"        return {call}"]
        lines += ["    return 0.0",
                  "", "", "piece_pairs_forces_blocked = piece_pairs_forces  # a group's own loop knows it is blocked"]
        if self.threads:
            return "\n".join(lines) + "\n"
        lines += ["", "", "@njit(**ENTRY)", f"def piece_pairs_energies({PIECE_SIGNATURES['pairs_energies']}):",
                  '    """Add the potential energies of the program row\'s group to out[kind]."""']
        lines += piece_prelude("pairs_energies") + [f"    g = program[{G_GROUP}]"]
        for g in range(len(plan.groups)):
            lines += [f"    if g == {g}:", f"        group_{g}_energies({ARRAYS}, {LIST_ARRAYS}, out)"]
        if plan.effects:
            lines += ["", "", "@njit(**ENTRY)", f"def piece_sphere_forces({PIECE_SIGNATURES['sphere_forces']}):"]
            lines += piece_prelude("sphere_forces") + [f"    return sphere_forces({ARRAYS}, force, torque, history, commit)"]
            lines += ["", "", "@njit(**ENTRY)", f"def piece_sphere_energies({PIECE_SIGNATURES['sphere_energies']}):"]
            lines += piece_prelude("sphere_energies") + [f"    sphere_energies({ARRAYS}, history, out)"]
        return "\n".join(lines) + "\n"

    def group_chunk(self, name, group):
        """The owners first..last-1 of a chunked pair loop, their forces into cf/ct (the buffers are
        zero: sum_chunks leaves them so); returns the dissipated power."""
        lines = ["", "", "@njit(**INNER)",
                 f"def {name}_chunk({ARRAYS}, cf, ct, {LIST_ARRAYS}, co, cg, commit, first, last):"]
        lines += self.prelude(group) + ["    power = 0.0"]
        lines += self.loop(group, 4, "first", "last", "cf", "ct", "co", "cg")
        return lines + ["    return power"]


def generate_source(plan, templates, importable, threads=False):
    """Python source of the fused kernel module (see module docstring); ``threads``: the module
    whose chunked loops and per-step passes run on threads."""
    return _Source(plan, importable, threads).text(templates)
