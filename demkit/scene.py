"""Scene: particles in a box (or open space) and the chosen interactions, fused into compiled kernels.

Only what the interactions declare is allocated: no dipole arrays without a dipole interaction
(or user-given moments), no angular velocity unless something produces torque (or the user gave
spins), no history unless an interaction keeps some, no image counts or periodic arithmetic in
open space, no neighbour lists for a handful of spheres, no threads for small scenes.

Interactions are grouped by reach (:class:`demkit.engine.plan.Group`): those of equal finite reach
share a neighbour list with a skin (contacts reach 2 R_max, dipoles their cutoff); interactions
without a cutoff loop over all pairs i < j; a scene of at most :data:`ALL_PAIRS_MAX` spheres in
open space loops over all pairs for everything (one fused loop, the fastest for a few spheres).
"""
from __future__ import annotations

import hashlib
import inspect
import math

import numba
import numpy as np

from . import checks, deformed, sheared
from .box import Box
from .diagnostics import SceneDiagnostics, energy_dict  # noqa: F401 (demkit.scene.energy_dict, as before)
from .engine import generic, generic_modules, neighbours
from .engine import program as layout
from .engine.kernels import _Source
from .engine.modules import build_module, build_pieces
from .engine.plan import BLOCK, GATHER_ROWS, Group, Plan, energy_kinds, importable
from .engine.motion import empty_vectors
from .engine.notice import compile_estimate, compile_notice
from .engine.shear import list_frame, wrap_sheared
from .engine.state import (DEEP_OVERLAP_FRACTION, SORTS, STATE_FIELDS, PairListTuple, StateTuple, TupleStateModule,
                           make_pair_list, make_state, new_pair_list, touch_getters)
from .engine.templates import TEMPLATES
from .engine.threads import PARALLEL_MIN, THREADS_FROM_SECONDS, estimated_force_seconds
from .interactions import induction
from .interactions.base import PairInteraction, check_repeats
from .interactions.dipole import Dipole
from .interactions.induction import Induction, InducedMoments
from .interactions.langevin import flow_values
from .interactions.sphere import SphereInteraction
from .interactions.wall_motion import SERVO_STATE
from .particles import Particles

#: initial overlap, as a fraction of the smaller radius, above which a start is rejected (the
#: same limit stops a run, see demkit.engine.state.DEEP_OVERLAP_FRACTION)
MAX_INITIAL_OVERLAP = DEEP_OVERLAP_FRACTION
#: open scenes with at most this many spheres loop over all pairs (no neighbour lists)
ALL_PAIRS_MAX = 64
#: default skin of the neighbour lists, as a fraction of the mean diameter
DEFAULT_SKIN = 0.3
#: scenes with neighbour lists and at least this many spheres are re-sorted by cell (sort_every=None)
SORT_MIN = 1000
#: steps between re-sorts by default (done at the first list rebuild after that many steps)
SORT_EVERY = 1000
#: per-particle arrays of the state (kept in the internal order when the scene is sorted)
PARTICLE_FIELDS = ("position", "velocity", "angular_velocity", "dipole", "radius", "mass", "inertia", "image")
#: an all-pairs history larger than this many bytes is refused (give the interaction a cutoff)
MAX_ALL_PAIRS_HISTORY = 2**31


class Scene(SceneDiagnostics):
    """Particles, an optional box and pair interactions.

    Parameters
    ----------
    particles : Particles
    interactions : list of PairInteraction and SphereInteraction (e.g. ``[Dipole(prefactor=1/3),
        KelvinVoigt(1.0, 0.1)]``), each given once; two of a class that is not ``repeatable`` (two
        Gravity, two Dipole) are refused, their forces would merely add up
    box : :class:`demkit.Box` or None (open space)
    skin : extra reach of the neighbour lists (length); default 0.3 mean diameters. Lists are
        rebuilt when a sphere has moved skin/2.
    parallel : None (default: a scene of at least 2000 spheres whose force evaluation is
        estimated at 0.5 ms or more may use threads, and each run measures whether they pay, see
        :mod:`demkit.engine.threads`), True (always threads) or False (never). Threads follow ``NUMBA_NUM_THREADS`` / ``numba.set_num_threads``; the pair loops
        of such a scene are cut into ``numba.config.NUMBA_NUM_THREADS`` fixed chunks, so results
        do not depend on how many threads run them, nor on whether threads run them at all.
    sort_every : re-order the spheres by cell every this many steps (at the next list rebuild) for
        memory locality; None: every 1000 steps in scenes with lists and at least 1000 spheres, 0:
        never. Invisible to the user: ``particles`` keeps its order, compiled code works on its
        own copies, synchronised at the start and end of every run and for every diagnostic.
    tier : None (default: the generic module, tier 1, and the scene's own code, tier 2, compiled in
        the background once a run makes it pay; ``DEMKIT_TIER=1`` or ``2`` sets this default), 1 (the
        generic module only) or 2 (the scene's own time loops from the start); the same bits on
        either. Diagnostics always run on tier 1 where it can run the scene (docs/engine.md).
    """

    def __init__(self, particles, interactions, box=None, skin=None, parallel=None, sort_every=None, tier=None):
        if not isinstance(particles, Particles):
            raise TypeError(f"particles must be a demkit.Particles, got {type(particles).__name__}")
        if isinstance(interactions, (PairInteraction, SphereInteraction)):
            interactions = [interactions]
        interactions = list(interactions)
        for inter in interactions:
            if not isinstance(inter, (PairInteraction, SphereInteraction)):
                raise TypeError(f"interactions must be PairInteraction or SphereInteraction objects (Wall, Gravity, "
                                f"UniformField, ...), got {inter!r}")
        check_repeats(interactions)
        effects = [inter for inter in interactions if isinstance(inter, SphereInteraction)]
        interactions = [inter for inter in interactions if isinstance(inter, PairInteraction)]
        if box is not None and not isinstance(box, Box):
            raise TypeError(f"box must be a demkit.Box or None, got {type(box).__name__}")
        dipoles = [inter for inter in interactions if isinstance(inter, Dipole)]
        polarisabilities = induction.prepare(particles, dipoles, effects)  # None: no magnetisable spheres
        if box is not None and box.shear is not None:  # what Lees-Edwards images do not cover yet, refused
            sheared.check_scene(box, interactions, effects)
        if box is not None and getattr(box, "deform", None) is not None:  # ... nor the affine remap
            deformed.check_scene(box, interactions, effects)
            if len(box.deform.history):  # a servo's changes of rates belong to the scene that made them
                raise ValueError("this box's servo has driven another scene (box.deform.history holds its changes of "
                                 "rates, which that scene's frames need): give each scene its own dk.Box")
        # long-range sums are tuned to the spheres and the box: the scene keeps a tuned copy
        interactions = [inter.tuned_for(particles, box) if getattr(inter, "long_range", None) is not None else inter
                        for inter in interactions]
        for effect in effects:
            effect.bind(interactions)
        if parallel not in (None, True, False):
            raise ValueError(f"parallel must be None (automatic), True or False, got {parallel!r}")
        self.particles = particles
        self.has_fixed = particles.fixed is not None and bool(particles.fixed.any())
        self.interactions = tuple(interactions)
        self.effects = tuple(effects)
        self.box = box
        for inter in self.interactions + self.effects:
            inter.check(particles)
        #: the long-range sums tuned to this scene (dipolar Ewald: Dipole(long_range=Ewald(...)))
        self.long_range = tuple(inter.tuned for inter in self.interactions if getattr(inter, "tuned", None))
        if any(inter.torque or "angular_velocity" in inter.reads for inter in self.interactions + self.effects):
            particles.require("angular_velocity")
        self.periodic = tuple(bool(f) for f in box.periodic) if box is not None else (False,) * 3
        if any(self.periodic):
            particles.require("image")
        self.skin = self._skin(skin)
        # (an interaction a long-range sum covers whole has no pair loop, and no reach)
        self.reaches = [inter.cutoff(particles) if getattr(inter, "pair_loop", True) else 0.0
                        for inter in self.interactions]
        self._check_geometry()
        machine = max(1, int(numba.config.NUMBA_NUM_THREADS))
        #: rough serial time of one force evaluation (s), which decides chunks with parallel=None
        self.force_seconds = estimated_force_seconds(particles, self.reaches, self.skin, box)
        big = len(particles) >= PARALLEL_MIN and self.force_seconds >= THREADS_FROM_SECONDS
        wanted = big if parallel is None else parallel
        #: how threads are chosen: None (measured while running), True (always), False (never)
        self.threads_requested = parallel
        #: the pair loops are cut into this many fixed chunks (the machine's thread count when the
        #: scene may run on threads, else 1), whoever runs them: the same bits on any thread count
        self.chunks = machine if wanted and machine > 1 else 1
        self.parallel = self.chunks > 1  # may run on threads
        self._thread_kernels = None
        self.tier_requested = _tier(tier)
        #: the tier came from DEMKIT_TIER, a default: 1 then means tier 1 wherever it can run the scene
        self.tier_from_environment = tier is None and self.tier_requested is not None
        self.plan = self._plan()
        #: the induced-moment solve (demkit.interactions.induction.InducedMoments), or None
        self.induction = self._induction(polarisabilities)
        self.plan.induction = self.induction
        self._sorting(sort_every)
        self._check_memory()
        self.energy_kinds = energy_kinds(self.plan.energy_sources)
        n = len(particles)
        self.force = np.zeros((n, 3))
        self.torque = np.zeros((n, 3))
        self.accum = np.zeros(1)  # accum[0]: work dissipated so far
        self.clock = np.zeros(1)  # clock[0]: the time the forces are evaluated at (see `time`)
        self._synced = None  # digest of the user's arrays when they last matched the kernels' (see push)
        self.stepping = False  # inside a Simulation.run: the arrays are the kernels' (push has nothing to do)
        self.stepped_by = None  # the Simulation whose run or resume last left the state as it is
        with compile_notice(lambda: compile_estimate(self.plan, "scene", getattr(self, "tier", 2))):  # a line on stderr when not cached yet
            self.state = self._make_state()
            if self.induction is not None:
                self._first_induction()
            #: the module of forces(), energy() and every call made from Python: tier 1 whenever it
            #: can run the scene (tier 2 then only runs time loops: nothing else of it is compiled)
            if self.box is not None and (self.box.shear or self.deform_slot is not None) and not self.on_tier_1_possible:
                raise ValueError(f"a sheared or deforming box needs a scene the generic module runs: "
                                 f"{self.program_refusal}")
            self.kernels = self._kernels(threads=False, tier=1 if self.on_tier_1_possible else None)
            self._loop_kernels = None
            self.validate()
        # the lists are built (and a sorted scene sorted by cell) at the first push, by the first
        # run or diagnostic: their code then compiles with the rest of the scene's, under one
        # compile notice; periodic coordinates are wrapped now (demkit's own compiled helper)
        if self._wrap() and self.plan.sorted:  # the kernels' arrays are copies, still in the user's order
            self.particles.position[...] = self.arrays["position"]
            self.particles.image[...] = self.arrays["image"]

    @property
    def on_tier_1_possible(self):
        """Can the generic module (tier 1) run this scene (shipped interactions only)?"""
        return self.program is not None and self.program_refusal is None

    @property
    def loop_kernels(self):
        """The module whose time loops runs of this scene's tier call (``kernels`` on tier 1)."""
        if self._loop_kernels is None:
            self._loop_kernels = self._kernels(threads=False) if self.tier == 2 else self.kernels
        return self._loop_kernels

    @property
    def thread_kernels(self):
        """The module whose loops run on numba's threads, of the scene's tier (the same arithmetic as
        ``loop_kernels``; compiled when first asked for)."""
        if self._thread_kernels is None:
            self._thread_kernels = self._kernels(threads=True)
        return self._thread_kernels

    def fused_source(self, threads=False):
        """The text of this scene's fused module (tier 2; generated, not compiled): what code the
        scene's combination of interactions needs, and only that."""
        from .engine.modules import fused_source
        return fused_source(self.plan, TEMPLATES, threads)

    def _kernels(self, threads, tier=None):
        """The compiled module of this scene's tier, or of ``tier`` (the thread module with ``threads``).
        Tier 2 of a scene that the program describes, with neighbour lists or functions of your own,
        is the generic time loops calling the scene's own pieces (:func:`demkit.engine.modules.build_pieces`);
        else its fused module (through named tuples over the arrays of a structref state)."""
        tier = tier or self.tier
        if tier == 1 or self._pieces_tier_2():
            pieces = build_pieces(self.plan, self.program_columns, threads) if tier == 2 else None
            return generic_modules.build_generic(threads, generic_modules.needs_of(self.program), pieces,
                                         generic_modules.family_of(self.program), own_energies=not self.on_tier_1_possible,
                                         own=self._adapters())
        module = build_module(self.plan, TEMPLATES, threads=threads)
        return TupleStateModule(module, self) if self.structured and not self.plan.growing else module

    #: where a program row holds its group and speed (read by the scene's own pieces)
    program_columns = (layout.G_GROUP, layout.G_SPEED)

    @property
    def structured(self):
        """Is the state a structref (lists, or the generic module), not named tuples (a fused open module)?"""
        return self.plan.growing or self.on_tier_1_possible or self._pieces_tier_2()

    def _pair_list(self, fields):
        """A structref pair list with neighbour lists (compiled code grows it), else a named tuple."""
        return make_pair_list(*fields) if self.plan.growing else PairListTuple(*fields)

    def _adapters(self):
        """The adapters of the scene's functions of your own on tier 1 (demkit.engine.own_laws), or None."""
        if not self.on_tier_1_possible:
            return None
        from .engine.own_laws import build_adapters
        tables = {e for e, effect in enumerate(self.plan.effects) if np.size(effect.table_values())}
        return build_adapters(self.plan, tables)

    def _pieces_tier_2(self):
        """Is this scene's tier 2 its own pieces called by the generic loops (not a fused module)?
        With neighbour lists, and in open space when it solves induced moments: the solve, the
        same code on either tier, takes most of each step (six magnetisable spheres: the pieces ran
        at 0.93 of a fused module's speed, which compiles in 35-40 CPU s against their 11)."""
        if self.program is None:
            return False
        own = self.program_refusal is not None or bool(set(generic.OWN_CALLS) & set(generic_modules.needs_of(self.program)))
        if own:  # functions of your own: their own pieces on disk, or a fused module in memory
            return importable(self.plan)
        return self.plan.growing or self.induction is not None

    def _choose_tier(self):
        """1 when the generic module can run this scene and tier 2 is not asked for, else 2."""
        if self.program is None or self.program_refusal is not None:
            if self.tier_requested == 1 and not self.tier_from_environment:
                raise ValueError(f"tier=1: the generic module cannot run this scene ({self.program_refusal}); "
                                 f"use tier=None or 2")
            return 2
        return 2 if self.tier_requested == 2 else 1

    def _sorting(self, sort_every):
        plan, n = self.plan, len(self.particles)
        can = plan.growing and not any(g.kind == "all" and g.width for g in plan.groups)
        if sort_every is None:
            every = SORT_EVERY if can and n >= SORT_MIN else 0
        else:
            every = int(sort_every)
            if every < 0 or every != sort_every:
                raise ValueError(f"sort_every must be a whole number of steps >= 0 (0: never), got {sort_every!r}")
            if every and not can:
                raise ValueError("sort_every needs neighbour lists and no all-pairs history (this scene has none "
                                 "to sort by, or keeps history by particle index)")
        plan.sorted = every > 0
        self.sort_every = every

    # ---- set-up ----------------------------------------------------------------------------
    def _induction(self, alpha):
        """The scene's induced-moment solve over the group that holds its Dipole (None without
        magnetisable spheres)."""
        if alpha is None:
            return None
        dipole = next(inter for inter in self.interactions if isinstance(inter, Dipole))
        group = kind = None
        for g, members in enumerate(self.plan.groups):
            if any(inter is dipole for _, inter in members.members):
                group, kind = g, members.kind
        solver = InducedMoments(dipole, kind, self.box, self.effects, alpha, dipole.induction or Induction())
        solver.group = group
        return solver

    def _first_induction(self):
        """Solve the induced moments of the starting positions (in the user's order, over a half list
        of their own: the kernels' lists are built at the first push); ValueError if it fails."""
        solver, p = self.induction, self.particles
        n = len(p)
        index = np.arange(n, dtype=np.int64)
        position = p.position.copy()  # wrapped into the box (the kernels wrap theirs later)
        for axis in np.flatnonzero(self.periodic):
            position[:, axis] = np.mod(position[:, axis], self.box.size[axis])
        pairs = new_pair_list(solver.cutoff if solver.kind == "list" else 0.0, n, 0, 1)
        if solver.kind == "list":
            neighbours.build_from_python(pairs, position, index, self.arrays["box"], self.arrays["periodic"],
                                         self._shear_frame())
        code = induction.induce(position, p.dipole, index, self.arrays["box"], self.arrays["periodic"], self.params,
                                self.induction_slot, pairs.start, pairs.end, pairs.partner, np.zeros((n, 0)), 0,
                                False, self._shear_frame())
        if code:
            raise ValueError(f"at the starting positions {solver.failure(code)}")
        if self.arrays["dipole"] is not p.dipole:
            self.arrays["dipole"][...] = p.dipole

    def induce(self):
        """Solve the induced moments at the current positions (after the user moved spheres; runs and
        diagnostics do it themselves). ValueError if the solve fails."""
        if self.induction is None:
            return
        self.push()
        code = self.kernels.induce_of(self.state)
        self.pull()
        if code:
            raise ValueError(self.induction.failure(code))

    def memory_estimate(self, frames=0, stages=0):
        """Bytes this scene's arrays, neighbour lists and a record of ``frames`` frames need
        (:func:`demkit.memory.estimate`; the lists' pairs from the spheres' density within the box,
        or within their bounding box extended by the reach)."""
        from . import memory
        p, plan = self.particles, self.plan
        n = len(p)
        lists, history = [], 0
        for group in plan.groups:
            if group.kind == "list" and n:
                lo, hi = p.position.min(axis=0), p.position.max(axis=0)
                radius = float(np.mean(p.radius))
                reach = group.reach + self.skin
                span = hi - lo + reach
                if self.box is not None:
                    periodic = np.array(self.periodic)
                    span[periodic] = self.box.size[periodic]
                count = min(memory.pairs_per_sphere(n, reach, radius, float(np.prod(span))),
                            memory.pairs_per_sphere(n, reach, radius))
                lists.append((count, group.width))
            elif group.kind != "list":
                history += group.width
        threads = self.chunks if any(g.parallel for g in plan.groups) else 1
        return memory.estimate(n, dipoles=p.dipole is not None, spins=p.angular_velocity is not None,
                               periodic=any(self.periodic), fixed=self.has_fixed, sorted_copies=plan.sorted,
                               threads=threads, stages=stages, sphere_history=plan.effect_width, lists=lists,
                               all_pairs_history=history, frames=frames)

    def _check_memory(self):
        """Refuse (ValueError) a scene whose arrays and neighbour lists would not fit in the memory
        available, before they are allocated."""
        from . import memory
        parts = self.memory_estimate()
        memory.refuse_above(parts["total"], f"a Scene of {len(self.particles):,} spheres needs",
                            "fewer spheres, or shorter cutoffs (smaller neighbour lists)", parts=memory.describe(parts))

    def _skin(self, skin):
        if skin is None:
            return DEFAULT_SKIN * 2.0 * float(np.mean(self.particles.radius))
        return checks.positive("skin", skin)

    def _check_geometry(self):
        p = self.particles
        contact = 2.0 * float(np.max(p.radius))
        if self.box is not None:
            checks.resolvable(f"the box {self.box}", self.box.size, p.radius)
        checks.resolvable("the spheres' positions", np.ptp(p.position, axis=0), p.radius)
        for inter, reach in zip(self.interactions, self.reaches):
            if ("dipole" in inter.reads and inter.cutoff_distance is not None and reach < contact
                    and getattr(inter, "tuned", None) is None):  # an Ewald sum's real space may end short of it
                raise ValueError(f"{type(inter).__name__} cutoff {reach:.6g} is shorter than the contact reach "
                                 f"{contact:.6g} (twice the largest radius): touching spheres would not interact")
            if self.box is not None:
                self.box.check_reach(reach, type(inter).__name__)
        if self.box is not None:
            outside = self.box.outside(p.position)
            if len(outside):
                k = int(outside[0])
                raise ValueError(f"particle {p.ids[k]} at {p.position[k].tolist()} is outside the box {self.box} "
                                 f"along an open (non-periodic) axis ({len(outside)} particles are)")

    def _plan(self):
        """Group the interactions by reach (see the module docstring)."""
        n = len(self.particles)
        members = [(k, inter) for k, inter in enumerate(self.interactions) if getattr(inter, "pair_loop", True)]
        if n <= ALL_PAIRS_MAX and not any(self.periodic):
            groups = [Group(members, "all", math.inf)] if members else []
        else:
            by_reach = {}
            for k, inter in members:
                by_reach.setdefault(self.reaches[k], []).append((k, inter))
            groups = [Group(m, "all" if math.isinf(r) else "list", r) for r, m in sorted(by_reach.items())]
        chunked = any(g.kind == "list" for g in groups) or self.parallel
        for group in groups:
            # chunked loops in every scene with lists, whatever its size or thread count, so that
            # neither changes the compiled code (a scene of 1 chunk runs them as one loop)
            group.parallel = chunked and n > 1
            if group.kind == "all" and group.width:
                size = n * (n - 1) // 2 * group.width * 8
                if size > MAX_ALL_PAIRS_HISTORY:
                    raise ValueError(f"{[type(i).__name__ for _, i in group.members]} keep history for every pair "
                                     f"of {n} spheres ({size / 2**30:.1f} GiB) because they have no cutoff: "
                                     f"give them a cutoff_distance")
        return Plan(self.interactions, groups, self.periodic, any(g.kind == "list" for g in groups),
                    effects=self.effects, sums=self.long_range, shear=self.box.shear if self.box is not None else None)

    def _make_state(self):
        p, plan = self.particles, self.plan
        n = len(p)
        growing = plan.growing
        slots = _Source(plan, True)
        self.program, self.program_refusal = layout.program_of(plan, slots, self.energy_kinds)
        self.tier = self._choose_tier()  # before the lists: the tier decides the state's form
        lists = []
        for group in plan.groups:
            bounds = np.zeros(self.chunks + 1, dtype=np.int64)
            if group.kind == "list":  # a parallel group's lists are also built in chunks side by side
                lists.append(new_pair_list(group.reach + self.skin, n, group.width, self.chunks))
                continue
            neighbours.triangle_bounds(n, bounds)
            history = np.zeros((n * (n - 1) // 2 if group.width else 0, group.width))
            fields = (math.inf, np.zeros(n + 1, dtype=np.int64), np.zeros(n, dtype=np.int64),
                      np.zeros(0, dtype=np.int32), history, bounds)
            lists.append(self._pair_list(fields))
        lists = self.padded(lists)
        threads = self.chunks if any(g.parallel for g in plan.groups) else 0
        omega = p.angular_velocity if p.angular_velocity is not None else empty_vectors()
        dipole = p.dipole if p.dipole is not None else empty_vectors()
        image = p.image if p.image is not None else empty_vectors(np.int64)
        params = [inter.parameter_values() for inter in self.interactions + self.effects]
        cut2 = [inter.cutoff_distance ** 2 if inter.cutoff_distance is not None else math.inf
                for inter in self.interactions]
        tables = [np.asarray(e.table_values(), dtype=np.float64).ravel() for e in self.effects]
        tables += [np.asarray(e.geometry_values(), dtype=np.float64).ravel() for e in self.effects]
        tables += [np.asarray(e.table_values(), dtype=np.float64).ravel() for e in self.long_range]
        if self.induction is not None:  # its table last (its first value: the solver's key, see checkpoint)
            tables.append(self.induction.table_values())
        # (the order kernels._Source gives their slots)
        self.params = np.concatenate(params + [np.array(cut2)] + tables) if params else np.zeros(0)
        self.induction_slot = len(self.params) - len(tables[-1]) if self.induction is not None else None
        self.shear_slot = slots.shear_slot  # Lees-Edwards: [a, b, gammadot L_b, offset at the lists' build], last
        reach = max([g.reach + self.skin for g in plan.groups if g.kind == "list"], default=0.0)  # the longest list's
        if self.shear_slot is not None:
            self.params = np.concatenate([self.params, sheared.shear_block(self.box, reach, self.skin)])
        self.deform_slot = None  # a deforming box: [rates, sizes at 0, sizes at the lists' build, list reach], last
        if self.box is not None and getattr(self.box, "deform", None) is not None:
            self.deform_slot = len(self.params)
            self.params = np.concatenate([self.params, deformed.deform_block(self.box, 0.0, reach)])
            if self.program is not None:  # the time loops keep the clock; end_step remaps (demkit.engine.deform)
                self.program[0, layout.H_DEFORM], self.program[0, layout.H_CLOCK] = self.deform_slot, 1
        self.geometry_slots = dict(slots.geometry_slot)
        for e, slot in slots.geometry_slot.items():  # walls read their state (a servo's) from their block
            self.effects[e].block = self.params[slot:slot + np.size(self.effects[e].geometry_values())]
        if self.induction is not None:
            self.induction.bind(self.params, self.induction_slot)
        # slots of parameters named "dt": the integrator's time step, set by each run
        self.time_step_slots, slot = [], 0
        for inter in self.interactions + self.effects:
            self.time_step_slots += [slot + m for m, name in enumerate(inter.parameters) if name == "dt"]
            if "flow_rate" in inter.parameters:  # a bath: its drag relative to a sheared box's flow (or none)
                k = slot + inter.parameters.index("flow_rate")
                self.params[k:k + 4] = flow_values(self.box)
            slot += len(inter.parameters)
        own = (lambda a: a.copy()) if plan.sorted else (lambda a: a)  # sorted: the kernels' own order
        mass, inertia = own(p.mass), own(p.inertia)
        if self.has_fixed:  # fixed spheres: infinite mass and inertia in the kernels' copies
            mass, inertia = np.where(p.fixed, np.inf, p.mass), np.where(p.fixed, np.inf, p.inertia)
        fields = dict(
            position=own(p.position), velocity=own(p.velocity), angular_velocity=own(omega), dipole=own(dipole),
            radius=own(p.radius), mass=mass, inertia=inertia, tag=np.arange(n, dtype=np.int64),
            image=own(image),
            force=self.force, torque=self.torque, accum=self.accum, clock=self.clock, params=self.params,
            box=self.box.size.copy() if self.box is not None else np.zeros(3),
            periodic=np.array(self.periodic), reference=np.full((n, 3), np.inf) if growing else empty_vectors(),
            skin=self.skin, status=np.zeros(4, dtype=np.int64),
            counters=np.array([0, 0, 0, 0, self.sort_every, 1, 0], dtype=np.int64),
            lists=lists, thread_force=np.zeros((max(threads - 1, 0), n, 3)),
            thread_torque=np.zeros((max(threads - 1, 0), n, 3)),
            thread_power=np.zeros(max(threads, 1)), scratch=np.zeros((max(threads, 1), 9, BLOCK)),
            gather=np.zeros((max(threads, 1), GATHER_ROWS, BLOCK + 1)),
            sphere_history=np.zeros((n, plan.effect_width)), stage=np.zeros((0, 0, 3)),
            program=self.program if self.program is not None else np.zeros((1, layout.COLUMNS), dtype=np.int64))
        self.arrays = fields
        return self._state_object()

    def padded(self, lists):
        """The scene's lists followed by empty ones up to demkit.engine.program.MAX_GROUPS: every state has
        as many, so that one compiled generic module serves every scene."""
        lists = list(lists)
        while len(lists) < layout.MAX_GROUPS:
            fields = (0.0, np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int32),
                      np.zeros((0, 0)), np.zeros(2, dtype=np.int64))
            lists.append(self._pair_list(fields))
        return tuple(lists)

    def _state_object(self):
        """The named state the kernels take, over the arrays in ``self.arrays``."""
        values = [self.arrays[name] for name in STATE_FIELDS]
        if not self.structured:
            return StateTuple(*values)
        if not self.plan.growing:  # open space on the generic module: structref lists over the same arrays
            values[STATE_FIELDS.index("lists")] = tuple(make_pair_list(*pl) for pl in self.arrays["lists"])
        state = make_state(*values)
        if self.plan.growing:
            touch_getters(state)
        return state

    # ---- state -----------------------------------------------------------------------------
    def _pairs(self):
        """(user array, kernel array) of each per-particle field present. An array the user replaced
        (``particles.velocity = ...``) is checked and copied into the kernels' array, which the
        attribute then names again (unsorted scenes share their arrays with ``particles``)."""
        p = self.particles
        for name in PARTICLE_FIELDS:
            if self.has_fixed and name in ("mass", "inertia"):
                continue  # kept apart (infinite for fixed spheres), see push
            user, own = getattr(p, name), self.arrays[name]
            if user is None:
                if own.size:
                    raise ValueError(f"particles.{name} was removed, but this scene needs it")
                continue
            if not self.plan.sorted and user is not own:
                value = np.asarray(user, dtype=own.dtype)
                if value.shape != own.shape:
                    raise ValueError(f"particles.{name} must keep the shape {own.shape}, got {value.shape}")
                if not np.isfinite(value).all():
                    raise ValueError(f"particles.{name} contains NaN or inf")
                own[...] = value
                setattr(p, name, own)
                user = own
            elif user.shape != own.shape:
                raise ValueError(f"particles.{name} must keep the shape {own.shape}, got {user.shape}")
            yield user, own

    def digest(self):
        """A fingerprint of the user's particle arrays (values and identity), O(N): equal digests
        mean nothing was changed (or replaced) in between."""
        h = hashlib.blake2b(digest_size=16)
        p = self.particles
        for name in PARTICLE_FIELDS + ("fixed", "ids"):
            value = getattr(p, name, None)
            h.update(f"{name}:{id(value)}:".encode())
            if value is not None:
                h.update(memoryview(np.ascontiguousarray(value)).cast("B"))
        return h.digest()

    @property
    def in_sync(self):
        """True when the user's particle arrays are exactly as the kernels last left them (after a
        run, a diagnostic or :meth:`demkit.Simulation.resume`): then :meth:`push` has nothing to do
        and a run can continue without re-checking or re-preparing anything."""
        return self._synced is not None and self._synced == self.digest()

    def push(self):
        """Copy the user's particle arrays into the kernels' order (when sorted; unsorted scenes share
        them), then bring the lists up to date and wrap periodic coordinates. Does nothing when the
        user changed nothing since the kernels last synchronised (:attr:`in_sync`): wrapping or
        rebuilding at another moment than an uninterrupted run would changes its last bits."""
        if self.stepping or self.in_sync:
            return
        tag = self.arrays["tag"]
        for user, own in self._pairs():
            if self.plan.sorted:
                own[:] = user[tag]
        if self.has_fixed:
            p = self.particles
            fixed = p.fixed[tag]
            self.arrays["mass"][:] = np.where(fixed, np.inf, p.mass[tag])
            self.arrays["inertia"][:] = np.where(fixed, np.inf, p.inertia[tag])
        # lists up to date, periodic coordinates wrapped: called from here rather than through a
        # compiled prepare(s), which would re-optimise the whole list builder it links (~3 CPU s
        # of every new scene with lists); maintain_lists is compiled for the time loops anyway
        if self.plan.lists:
            self.kernels.maintain_lists(self.state, False)
        self._wrap()
        if self.plan.sorted and self.counters[SORTS] == 0:  # the kernels' order is the cells' from the first push on
            self.kernels.sort_particles(self.state)
        self.pull()

    def _wrap(self):
        """Periodic coordinates into the box (images counted, the list reference moved along);
        returns whether the box has periodic axes."""
        if not any(self.periodic):
            return False
        a = self.arrays
        if self.shear_slot is not None:  # the sliding images at the scene's clock
            wrap_sheared(a["position"], a["velocity"], a["reference"], a["image"], a["box"], a["periodic"], a["params"],
                         self.shear_slot, float(self.clock[0]))
        else:
            neighbours.wrap(a["position"], a["reference"], a["image"], a["box"], a["periodic"])
        return True

    def pull(self):
        """Copy the kernels' arrays back into the user's particle arrays (no-op unless sorted)."""
        if self.plan.sorted:
            tag = self.arrays["tag"]
            for user, own in self._pairs():
                user[tag] = own
        if not self.stepping:  # within a run the fingerprint is taken once, at its end
            self._synced = self.digest()

    def to_user_order(self, values):
        """Per-particle values (kernel order) in the order of ``particles``."""
        if not self.plan.sorted:
            return values
        out = np.empty_like(values)
        out[self.arrays["tag"]] = values
        return out

    @property
    def dissipated(self):
        """Work dissipated by the interactions since the scene was made."""
        return float(self.accum[0])

    @property
    def time(self):
        """The time of the state: moving walls stand where they are at this time when the forces,
        energies and contacts are evaluated. A Simulation sets it (steps taken times dt) and its runs
        move it on; a new scene starts at 0."""
        return float(self.clock[0])

    @time.setter
    def time(self, value):
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f"Scene time must be finite, got {value}")
        self.clock[0] = value
        if getattr(self, "deform_slot", None) is not None:  # a deforming box at that time, the positions remapped
            synced = not self.stepping and self.in_sync
            if deformed.remap(self.arrays, self.box, value):
                if self.plan.sorted:
                    self.particles.position[self.arrays["tag"]] = self.arrays["position"]
                if synced:
                    self._synced = self.digest()

    @property
    def counters(self):
        return self.arrays["counters"]

    @property
    def status(self):
        return self.arrays["status"]

    def close_pairs(self, reach):
        """(P, 2) particle indices of the pairs closer than ``reach`` (minimum image), via a cell list."""
        p = self.particles
        if not self.plan.lists and len(p) <= ALL_PAIRS_MAX:  # all pairs directly: no cell list (nor its
            # compilation: 6 s once per install) for scenes without lists; scenes with lists compile
            # the cell list for their kernels anyway
            i, j = np.triu_indices(len(p), k=1)
            d = self.separations(np.column_stack([i, j]))
            close = np.einsum("ij,ij->i", d, d) < reach * reach
            return np.column_stack([i[close], j[close]]).astype(np.int64)
        pl = new_pair_list(reach, len(p), 0, 1)
        index = np.arange(len(p), dtype=np.int64)
        neighbours.build_from_python(pl, p.position, index, self.arrays["box"], self.arrays["periodic"],
                                     self._shear_frame())
        return neighbours.pairs_of(pl, index)

    def _shear_frame(self):
        """A sheared box's sliding images at the scene's clock ([a, b, delta, 0]: what the list builder and the
        induced moments' field read), else none, passed as the time loops pass it (an empty array), so that
        the rebuild they compiled serves here too (3 CPU-s otherwise)."""
        if self.shear_slot is None:
            return np.zeros(0)
        return list_frame(self.params, self.shear_slot, self.arrays["box"], float(self.clock[0]), 0.0)

    def separations(self, pairs):
        """Centre-to-centre vectors x_j - x_i (minimum image) of index pairs (P, 2)."""
        d = self.particles.position[pairs[:, 1]] - self.particles.position[pairs[:, 0]]
        return self.box.minimum_image(d, self.time) if self.box is not None else d

    def validate(self):
        """Raise ValueError for non-finite state, coincident or deeply overlapping spheres, spheres
        outside the box or behind (deep inside) a wall. O(N): overlaps are found with a cell list."""
        p = self.particles
        p.check_finite()
        p.check_fixed()
        if self.box is not None:
            self._check_geometry()
        for effect in self.effects:  # walls: no sphere behind or deep inside one, where it stands now
            effect.check(p, self.time) if getattr(effect, "plane_contact", False) else effect.check(p)
            if getattr(effect, "servo", None) is not None:
                effect.servo.target(effect, self.box)  # (a stress needs the wall's area)
            if self.box is not None and hasattr(effect, "check_box"):
                effect.check_box(self.box)
        if len(p) < 2:
            return
        pairs = self.close_pairs(2.0 * float(np.max(p.radius)))
        if len(pairs) == 0:
            return
        i, j = pairs[:, 0], pairs[:, 1]
        r = np.linalg.norm(self.separations(pairs), axis=1)
        overlap = (p.radius[i] + p.radius[j] - r) / np.minimum(p.radius[i], p.radius[j])
        k = int(np.argmax(overlap))
        if r[k] == 0.0:
            raise ValueError(f"particles {p.ids[i[k]]} and {p.ids[j[k]]} are coincident "
                             f"(both at {p.position[i[k]].tolist()})")
        if overlap[k] > MAX_INITIAL_OVERLAP:
            raise ValueError(
                f"particles {p.ids[i[k]]} and {p.ids[j[k]]} overlap deeply: centre distance {r[k]:.6g} "
                f"with radii {p.radius[i[k]]:.6g} and {p.radius[j[k]]:.6g} (overlap {overlap[k]:.3g} of the "
                f"smaller radius; at most {MAX_INITIAL_OVERLAP} is accepted at the start)")

    def reserve_stages(self, count):
        """Give the kernels ``count`` (N,3) arrays of integrator working storage (``s.stage``; RK4
        keeps 9), or none for ``count`` = 0: only a scene stepped by such an integrator holds them."""
        stage = self.arrays["stage"]
        n = len(self.particles)
        if stage.shape[0] == count and (count == 0 or stage.shape[1] == n):
            return
        self.arrays["stage"] = np.zeros((count, n if count else 0, 3))
        self.state = self._state_object()

    @property
    def heat_baths(self):
        """The effects that exchange energy with a heat bath (thermostats; SphereInteraction.stochastic)."""
        return [effect for effect in self.effects if effect.stochastic]

    def history_keepers(self):
        """The interactions and effects of the scene that keep per-contact (or per-sphere) history."""
        return [inter for inter in self.interactions + self.effects if inter.history_size]

    def set_time_step(self, dt):
        """Hand the integrator's time step to the interactions that need it (parameter "dt") and to the
        servo-controlled walls, with their servos' targets as they are now (changed between runs: staged
        loading)."""
        self.params[self.time_step_slots] = dt
        for e, state in self.servo_slots():
            wall = self.effects[e]
            wall.servo.write(wall.block[wall.servo_after:], wall, self.box)  # (a view of params)
            self.params[state.stop] = dt

    def servo_slots(self):
        """(effect index, slice of params) of each servo-controlled wall's state (offset, speed, push,
        stiffness: demkit.interactions.wall_motion.SERVO_STATE); its time step follows the slice."""
        slots = []
        for e, effect in enumerate(self.effects):
            if getattr(effect, "servo", None) is not None:
                start = self.geometry_slots[e] + effect.servo_after + SERVO_STATE
                slots.append((e, slice(start, start + 4)))
        return slots

    def max_time_step(self):
        """Largest safe time step over all interactions (math.inf when none limits it). Contacts whose
        limit depends on the impact speed (Hertz: 2 max|v| by default, no limit at rest) take in a
        sheared box 2 max|v| + |gammadot L_b|: the flow drives spheres into the images sliding by at
        gammadot L_b, even when they start at rest."""
        members = self.interactions + self.effects
        shear = getattr(self.box, "shear", None)
        if shear is None:
            return min([inter.max_time_step(self.particles) for inter in members] + [math.inf])
        v = self.particles.velocity
        speed = (2.0 * float(np.max(np.linalg.norm(v, axis=1))) if len(v) else 0.0) + abs(shear.jump(self.box.size))
        return min([inter.max_time_step(self.particles, speed=speed)
                    if "speed" in inspect.signature(inter.max_time_step).parameters
                    else inter.max_time_step(self.particles) for inter in members] + [math.inf])

    # ---- diagnostics ---------------------------------------------------------------------
    def check_layers(self):
        """ValueError when the spheres left the layer of a slab sum (demkit.interactions.slab): its
        forces and energies would hold copies of the layer too close."""
        for tuned in self.long_range:
            if tuned.layer is not None:
                tuned.layer.check(self.particles.position, self.particles.ids)

    def _list(self, g):
        return self.state.lists[g] if self.plan.growing else self.arrays["lists"][g]

    def __repr__(self):
        where = f", {self.box}" if self.box is not None else ""
        return f"Scene({len(self.particles)} particles, {list(self.interactions)}{where})"


def _tier(tier):
    """The tier asked for (None, 1 or 2), from the argument or else DEMKIT_TIER."""
    import os
    if tier is None:
        tier = os.environ.get("DEMKIT_TIER") or None
        if tier is not None and tier not in ("1", "2"):
            raise ValueError(f"DEMKIT_TIER must be 1 or 2 (or unset), got {tier!r}")
    if tier is None:
        return None
    if tier not in (1, 2, "1", "2") or isinstance(tier, bool):
        raise ValueError(f"tier must be None (automatic), 1 (the generic module) or 2 (the fused module), got {tier!r}")
    return int(tier)
