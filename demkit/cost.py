"""What a run will cost in time, estimated before it runs (``demkit info``).

    est = cost.estimate(scene, integrator, duration, record_every=..., vtk_every=..., animation_frames=...)
    est.per_step, est.stepping, est.outputs, est.total      # seconds, one thread, compilation excluded
    est.parts                                                # {what: seconds per force evaluation}

One force evaluation costs, in serial wall time (the constants measured on this project's 2-core
machine by ``benchmarks/bench_cost_model.py``, ``benchmarks/results/cost_model.json``)::

    N SPHERE + N walls WALL + per mesh wall (N MESH_SPHERE + spheres whose cell lists triangles
      x MESH_QUERY + the triangles their cells list x MESH_TRIANGLE)
      + sum over lists (listed pairs x LISTED_PAIR, DIPOLE_PAIR or EWALD_PAIR)
      + exact-sum pairs x ALL_PAIR + touching pairs x TOUCHING[law] + N wave vectors x RECIPROCAL_VECTOR
      + MESH_CALL + N p^3 MESH_POINT + FFTs (a P3M mesh) + N (FMM_SPHERE + (digits of eps - 3) FMM_SPHERE_PER_DIGIT) (a fast multipole sum)

a step ``integrator.evaluations_per_step`` of them plus STEP. Magnetisable spheres add a solve of
their moments to each evaluation: INDUCTION_CALL + (iterations + 1) field evaluations, each
N INDUCTION_SPHERE + the Dipole's listed (or all) pairs x FIELD_PAIR + its long-range sum, with
SMOOTH_ITERATIONS iterations for a field that changes smoothly and JUMPING_ITERATIONS for a plain
cutoff (demkit.interactions.induction). The listed pairs are counted now
(a k-d tree within reach + skin). Touching pairs change while a scene runs, and they are the most
expensive part of a frictional contact: the estimate follows them through the run as

* spheres falling under gravity onto walls land within t_land = sqrt(2 h / g) of the highest
  (``demkit.guards.fall_heights``) and settle at SETTLED_CONTACTS contacts per sphere (sphere-sphere
  and sphere-wall, measured in a frictional pour): touching pairs grow linearly from now to that
  until t_land. So do the listed pairs of their other loops (dipoles) and of the field of their
  induced moments, to those of a pile at volume fraction SETTLED_FRACTION on the floor
  (:func:`settled_pairs`), and a solve of magnetisable spheres' moments takes PILED_ITERATIONS
  once they touch;
* magnets (dipoles and a contact law, no gravity) gather into chains and rings, about CHAINED_CONTACTS
  per sphere, reached half-way through the run;
* otherwise the pairs touching now.

Outputs: recorded frames (RECORD_FRAME + N RECORD_SPHERE each), VTK frames (VTK_SPHERE per sphere and frame + VTK_FRAME), an animation (ANIMATION_START
+ frames x (ANIMATION_FRAME + N ANIMATION_SPHERE)), the end-of-run notes (:mod:`demkit.notes`: a
k-d tree per frame read, NOTES_SPHERE per sphere).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .interactions.fmm import ALL_PAIR, FMM_SPHERE, FMM_SPHERE_PER_DIGIT, fmm_sphere_seconds  # noqa: F401

#: seconds per sphere and force evaluation: the integrator's passes, the list checks
SPHERE = 1.2e-8
#: seconds per sphere and wall it does not touch (a distance test)
WALL = 3.6e-9
#: seconds per sphere and mesh wall (the calls that find the plane it presents: 47-53 ns measured for
#: spheres outside its grid), more per sphere whose grid cell lists triangles, and per triangle listed
#: (the bounding-sphere and plane tests, the nearest points; memory for large meshes): fitted to the
#: extra cost over a plane wall or a cylinder of spheres on floors and drums of 2 to 50 000 triangles,
#: tier 1, a busy machine (benchmarks/bench_mesh_wall.py, benchmarks/results/mesh_wall.json: 160-455 ns
#: on floors listing 2-18 triangles, 166-422 on drums listing 10-20; the model within +-50 %)
MESH_SPHERE = 5.0e-8
MESH_QUERY = 8.0e-8
MESH_TRIANGLE = 1.5e-8
#: seconds per listed pair of a loop of contact laws only (a distance test)
LISTED_PAIR = 7.2e-9
#: seconds per listed pair of a loop holding dipoles (a dipole force, within reach + skin; 23 ns
#: calibrated, 24.8 ns at the start of benchmarks/scenes/gas600.toml)
DIPOLE_PAIR = 2.4e-8
#: seconds per listed pair of the real-space part of an Ewald sum (vectorised exp and erfc,
#: demkit.interactions.special_functions: 54-57 ns at N = 1000 to 4000, 34 ns at 500, 29 Nov 2026;
#: 62-65 ns with the C library's, 26 Nov; benchmarks/bench_ewald.py)
EWALD_PAIR = 5.5e-8
#: seconds per sphere and wave vector of the reciprocal part of an Ewald sum (5.6-6.1 ns, the same)
RECIPROCAL_VECTOR = 5.8e-9
#: seconds per sphere and B-spline point of a P3M mesh sum (spreading and gathering; the FFTs as
#: demkit.interactions.p3m.FFT_SECONDS per mesh point and log2 of the mesh size)
MESH_POINT = 7.0e-9
#: seconds of a P3M mesh sum's fixed work per evaluation (numba's object mode, scipy's FFT set-up,
#: numpy temporaries: measured 1 ms with 100 spheres on a 25^3 mesh, where the model above says 0.6 ms)
MESH_CALL = 1.0e-3
# FMM_SPHERE, FMM_SPHERE_PER_DIGIT (seconds per sphere of a fast multipole sum) and ALL_PAIR (per pair of
# the exact all-pairs sum of dipoles) are the FMM's own figures, which it chooses its crossover with
# (imported above from demkit.interactions.fmm)
#: seconds per touching pair (or sphere on a wall), by contact law and friction (at rest and shaken:
#: 13/22/93/73-104 ns on a squeezed lattice; a settled frictional pour measures ~150 ns)
TOUCHING = {("KelvinVoigt", False): 1.3e-8, ("Hertz", False): 2.2e-8,
            ("KelvinVoigt", True): 1.2e-7, ("Hertz", True): 1.2e-7}
#: seconds per step beyond its force evaluations (the step loop, the guards; the paper's two-sphere
#: scene measures 0.07-0.1 us a step in all)
STEP = 5.0e-8
#: seconds of an induced-moment solve's fixed work, per sphere and field evaluation, per pair of its
#: field (benchmarks/bench_induction.py: 11-16 ns a listed pair at N = 1000 and 8000 with the blocked
#: field loop, on a machine where the dipole force loop takes 15-19 ns a pair)
INDUCTION_CALL = 2.0e-6
INDUCTION_SPHERE = 3.0e-8
FIELD_PAIR = 1.3e-8
#: conjugate-gradient iterations per solve at the default tolerance 1e-6 in a run: the field smooth
#: in time (all pairs, a switched cutoff, a long-range sum: the extrapolated start; 4.2-4.5 measured on
#: the reference scene), or jumping as pairs cross a plain cutoff (6.2-6.3)
SMOOTH_ITERATIONS, JUMPING_ITERATIONS = 4.0, 6.0
#: seconds per recorded frame, and per sphere in it (the paper's scene: 0.9 us a frame of 2 spheres)
RECORD_FRAME = 1.0e-6
RECORD_SPHERE = 5.0e-9
#: contacts per sphere of a settled pour (sphere-sphere pairs and walls; 2.3 + 0.23 measured with
#: 3000 spheres in a 20 x 20 box)
SETTLED_CONTACTS = 2.5
#: contacts per sphere of magnets gathered into chains and rings
CHAINED_CONTACTS = 1.0
#: volume fraction of a settled pour's pile: its listed pairs (dipoles, the induced moments' field)
#: are counted on spheres spread evenly through a pile this dense on the floor (measured: a 300-sphere
#: magnetisable pour into an 8 x 8 box, 3369 listed dipole pairs at the start, 12738 settled; the
#: model counts 12.1-13.0 thousand)
SETTLED_FRACTION = 0.6
#: conjugate-gradient iterations per solve of magnetisable spheres piled up and touching (5.0-7.0
#: measured in that pour once settled, against 0.8-4.7 while falling)
PILED_ITERATIONS = 6.0
#: VTK series: seconds per sphere and frame, and per frame (meshio .vtu, benchmarks/results/vtk.json)
VTK_SPHERE = 9.0e-7
VTK_FRAME = 5.0e-4
#: animation: starting the renderer, and per frame and sphere drawn (measured: 400 spheres 0.29 s a
#: frame, 3000 spheres 0.55 s)
ANIMATION_START = 3.0
ANIMATION_FRAME = 0.25
ANIMATION_SPHERE = 1.0e-7
#: end-of-run notes: seconds per sphere of a frame read (a k-d tree; all pairs at once up to
#: demkit.notes.FEW spheres, negligible)
NOTES_SPHERE = 2.0e-6


@dataclass
class Estimate:
    """Seconds of one thread: per step, for the stepping, for the outputs, in all; ``parts``: the
    seconds per force evaluation of each part; ``touching``: touching pairs now and on average."""

    per_step: float
    stepping: float
    outputs: float
    parts: dict = field(default_factory=dict)
    touching: tuple = (0, 0.0)
    note: str = ""
    #: seconds per step the touching pairs (and in a pour the listed pairs) add on average beyond
    #: those of now (what a timing of the first steps misses), and what they are
    later: float = 0.0
    later_what: str = ""

    @property
    def total(self):
        return self.stepping + self.outputs


def pair_counts(scene, tree=None):
    """[(group, reach, pairs)]: the pairs each pair loop of ``scene`` visits per force evaluation,
    all pairs or those within reach + skin now (a k-d tree of the centres, built here unless given:
    :func:`centres_tree`)."""
    p = scene.particles
    n = len(p)
    out = []
    for group in scene.plan.groups:
        if group.kind == "all":
            out.append((group, math.inf, n * (n - 1) // 2))
            continue
        tree = tree if tree is not None else centres_tree(scene)
        # counted, not listed (a set of every pair took ~150 bytes per pair): ordered pairs with i = j
        within = int(tree.count_neighbors(tree, group.reach + scene.skin))
        out.append((group, group.reach, (within - n) // 2))
    return out


def centres_tree(scene):
    """A k-d tree of the sphere centres (periodic only when every axis is)."""
    from scipy.spatial import cKDTree
    p, box = scene.particles, scene.box
    if box is not None and box.periodic.all():
        return cKDTree(np.mod(p.position, box.size), boxsize=box.size)
    return cKDTree(p.position)


def touching_now(scene, tree=None):
    """Sphere pairs closer than twice the mean radius, and spheres overlapping a wall, now (``tree``:
    :func:`centres_tree`, built here unless given)."""
    from .interactions.wall import Wall
    p = scene.particles
    if len(p) < 2:
        pairs = 0
    else:
        tree = tree if tree is not None else centres_tree(scene)
        pairs = (int(tree.count_neighbors(tree, 2.0 * float(np.mean(p.radius)))) - len(p)) // 2
    walls = sum(int(np.sum(w.heights(p.position, scene.time) < p.radius)) for w in scene.effects if isinstance(w, Wall))
    return pairs + walls


def _contact_law(scene):
    laws = [inter for inter in scene.interactions if inter.contact_reach]
    return laws[0] if laws else None


def estimate(scene, integrator, duration, record_every=None, vtk_every=None, animation_frames=0, tree=None):
    """The :class:`Estimate` of running ``scene`` with ``integrator`` for ``duration`` (module
    docstring), recording every ``record_every`` (None: start and end), writing VTK frames every
    ``vtk_every`` (None: none) and an animation of ``animation_frames`` frames (0: none); ``tree``:
    :func:`centres_tree`, built here unless given."""
    from . import notes
    from .guards import fall_heights
    from .interactions.mesh import MeshWall
    from .interactions.wall import Wall
    p = scene.particles
    n = len(p)
    steps = max(1, round(duration / integrator.dt))
    walls = sum(isinstance(e, Wall) for e in scene.effects)
    parts = {"spheres": n * SPHERE, "walls": n * walls * WALL}
    meshes = [e for e in scene.effects if isinstance(e, MeshWall)]
    if meshes:  # what each sphere's query of each mesh visits now
        listed = [w.listed(p.position, scene.time) for w in meshes]
        parts["mesh walls"] = sum(n * MESH_SPHERE + MESH_QUERY * int(np.count_nonzero(c)) + MESH_TRIANGLE * int(c.sum())
                                  for c in listed)
    tree = tree if tree is not None else centres_tree(scene)  # one tree for the listed and touching pairs
    law = _contact_law(scene)
    heights, g, _ = fall_heights(scene) if law is not None else (None, 0.0, "")
    pour = heights is not None and g > 0.0
    land = math.sqrt(2.0 * float(np.max(heights)) / g) if pour else 0.0
    counts = pair_counts(scene, tree)
    # a pour: each list's pairs (and the induction's iterations) grow from now to the settled pile's
    pile = dict(settled_pairs(scene, heights)) if pour else {}
    ramp = (lambda now, end: _ramp_mean(now, end, land, duration)) if pour else (lambda now, end: float(now))
    growth = 0.0  # seconds per force evaluation the pairs add on average beyond those listed now
    for group, reach, count in counts:
        contact_only = all(inter.contact_reach for _, inter in group.members)
        if group.kind == "all":
            key, each = "exact sum", ALL_PAIR
        elif contact_only:
            key, each = "listed pairs", LISTED_PAIR
        elif any(getattr(inter, "tuned", None) is not None for _, inter in group.members):
            key, each = "listed Ewald pairs", EWALD_PAIR
        else:
            key, each = "listed dipole pairs", DIPOLE_PAIR
        mean_count = ramp(count, max(count, pile.get(id(group), count))) if not contact_only else count
        parts[key] = parts.get(key, 0.0) + mean_count * each
        growth += (mean_count - count) * each
    long_range = 0.0
    for tuned in scene.long_range:
        name, seconds = _long_range_seconds(tuned, n)
        parts[name] = parts.get(name, 0.0) + seconds
        long_range += seconds
    if scene.induction is not None:
        now_solve = _induction_seconds(scene, counts, long_range)
        parts["induction solve"] = (ramp(now_solve, _induction_seconds(scene, counts, long_range, pile))
                                    if pour else now_solve)
        growth += parts["induction solve"] - now_solve
    now = touching_now(scene, tree) if law is not None else 0
    mean, note, later = float(now), "", 0.0
    if law is not None:
        if pour:
            settled = max(float(now), SETTLED_CONTACTS * n)
            mean = _ramp_mean(now, settled, land, duration)
            note = f"spheres settling under gravity within t = {land:.3g}"
        elif p.dipole is not None and any(not i.contact_reach for i in scene.interactions):
            chained = max(float(now), CHAINED_CONTACTS * n)
            mean = 0.5 * (now + chained)
            note = "magnets gathering into chains"
        friction = getattr(law, "friction", None) is not None  # plug-in laws: priced as a Hertz law
        per_touch = TOUCHING.get((type(law).__name__, friction), TOUCHING[("Hertz", friction)])
        parts["touching pairs"] = mean * per_touch
        later = integrator.evaluations_per_step * ((mean - now) * per_touch + growth)
    force = sum(parts.values())
    per_step = integrator.evaluations_per_step * force + STEP
    stepping = steps * per_step
    outputs = 0.0
    if vtk_every:
        outputs += (duration / vtk_every + 1) * (n * VTK_SPHERE + VTK_FRAME)
    if animation_frames:
        outputs += ANIMATION_START + animation_frames * (ANIMATION_FRAME + n * ANIMATION_SPHERE)
    frames = (duration / record_every + 1) if record_every else 2
    outputs += frames * (RECORD_FRAME + n * RECORD_SPHERE)
    if steps >= notes.STEPS_PER_FRAME and n > notes.FEW:
        read = min(frames, steps / notes.STEPS_PER_FRAME, notes.SPHERE_FRAMES / n)
        outputs += read * n * NOTES_SPHERE
    later_what = f"the ~{mean - now:,.0f} more touching pairs"
    if growth > 0.0:
        later_what += " and the listed pairs of the settling pile" + (
            " (with the solve of the induced moments)" if scene.induction is not None else "")
    return Estimate(per_step=per_step, stepping=stepping, outputs=outputs, parts=parts, touching=(now, mean),
                    note=note, later=later, later_what=later_what)


def _induction_seconds(scene, counts, long_range, settled=None):
    """Seconds of one solve of the induced moments (module docstring), with the listed pairs
    ``counts`` (:func:`pair_counts`), or those of the settled pile ``settled`` (:func:`settled_pairs`)."""
    solver, n = scene.induction, len(scene.particles)
    pairs = 0
    if solver.group is not None:
        group = scene.plan.groups[solver.group]
        pairs = next(count for g, _, count in counts if g is group)
        if settled is not None:
            pairs = max(pairs, settled.get(id(group), pairs))
    jumps = solver.tuned is None and solver.kind == "list" and solver.inv_width == 0.0
    iterations = JUMPING_ITERATIONS if jumps else SMOOTH_ITERATIONS
    if settled is not None:
        iterations = max(iterations, PILED_ITERATIONS)
    return INDUCTION_CALL + (iterations + 1.0) * (n * INDUCTION_SPHERE + pairs * FIELD_PAIR + long_range)


def settled_pairs(scene, heights):
    """[(id of group, pairs)]: the pairs each listed loop of a pour would visit once its spheres
    settled, counted on a pile: the spheres spread evenly (a fixed seed) through a layer on the floor
    under the whole span of their positions across gravity, as thick as N spheres at volume fraction
    SETTLED_FRACTION make it. ``heights``: how far each can fall (:func:`demkit.guards.fall_heights`)."""
    from scipy.spatial import cKDTree
    p = scene.particles
    n = len(p)
    from .guards import gravity
    g = gravity(scene)
    up = -g / np.linalg.norm(g)
    across = np.linalg.svd(np.eye(3) - np.outer(up, up))[0][:, :2]  # two axes across gravity
    height = p.position @ up
    floor = float(np.min(height - heights)) - float(np.min(p.radius))  # the floor's level along up
    flat = p.position @ across
    low, high = flat.min(axis=0) - p.radius.max(), flat.max(axis=0) + p.radius.max()
    area = float(np.prod(high - low))
    volume = float(np.sum(4.0 / 3.0 * math.pi * p.radius ** 3))
    thick = volume / (SETTLED_FRACTION * area) if area > 0.0 else 0.0
    rng = np.random.default_rng(0)
    pile = (low + (high - low) * rng.random((n, 2))) @ across.T + \
        np.outer(floor + p.radius.max() + thick * rng.random(n), up)
    tree = cKDTree(pile)
    return [(id(group), (int(tree.count_neighbors(tree, group.reach + scene.skin)) - n) // 2)
            for group in scene.plan.groups if group.kind != "all"]


def _long_range_seconds(tuned, n):
    """(part name, seconds of one evaluation) of a long-range sum (scene.long_range) over n spheres."""
    from .interactions.ewald import TunedEwald
    from .interactions.p3m import TunedP3M, _fft_seconds
    if isinstance(tuned, TunedEwald):
        return "reciprocal sum", n * tuned.wave_vectors * RECIPROCAL_VECTOR
    if isinstance(tuned, TunedP3M):
        return "mesh sum", MESH_CALL + n * tuned.order ** 3 * MESH_POINT + _fft_seconds(tuned.mesh)
    return "fast multipole sum", n * fmm_sphere_seconds(tuned.settings.accuracy)



def _ramp_mean(start, end, ramp, duration):
    """Mean over [0, duration] of a value growing linearly from start to end over [0, ramp], then end."""
    if ramp <= 0.0:
        return float(end)
    if duration <= ramp:
        return start + (end - start) * duration / (2.0 * ramp)
    return (end * duration - (end - start) * ramp / 2.0) / duration
