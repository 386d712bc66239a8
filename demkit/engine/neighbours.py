"""Neighbour lists: cell binning and Verlet half lists with a skin, built in compiled code.

A list of reach r_c + skin holds every pair closer than that (minimum image along periodic axes)
when it is built; it stays complete for the cutoff r_c until some sphere has moved skin/2 from where
it was at the build, which :func:`max_displacement` watches at every force evaluation.

Layout (:class:`demkit.engine.state.PairList`): rows by owner, the partners of particle i at
``partner[start[i]:end[i]]`` (rows come in the order of the cells; ``start[N]`` is the number of
entries). The pair {i, j} is stored once, in the row of the particle with the lower *tag* (tags are persistent: they survive re-sorting), so
a pair always meets its interaction in the same orientation. Per-pair history rows follow the
entries; at a rebuild the non-zero rows are carried to the pair's new entry by tag (a pair that
left the list loses its history, one that enters starts from zero). Lists grow (by 1/8 more than they
need) instead of overflowing; ``bounds`` cuts the owners into chunks of equal pair counts for threads.

Cells are at least one reach wide: 27 neighbouring cells (fewer, de-duplicated, along a periodic
axis with fewer than three cells; clipped along open axes, which span the particles' extent); for
crowded cells (long lists such as dipoles') half a reach wide, 5 x 5 x 5 neighbouring cells. The
build works cell by cell on a cell-sorted copy of the positions folded into the box, adding one
image shift per neighbouring cell, so no pair needs a minimum-image test (except along a periodic
axis with fewer than three cells). A cell's candidates are copied once into a contiguous buffer
that every member of the cell then scans in one vectorised loop: the dipole list of the N = 8000
reference scene builds in 11 ms on one thread instead of 28 ms with a loop per neighbouring column
of cells.

The functions taking a list object allocate (numba reference counting on); every loop runs in a
function compiled without it, on plain arrays (see :mod:`demkit.engine.state`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange, types
from numba.extending import overload

from .motion import fold
from .pair_history import restore_history, saved_history

#: at most this many cells per particle (open scenes whose spheres flew far apart get coarser cells)
MAX_CELLS_PER_PARTICLE = 4
#: a list that outgrows its arrays gets 1/GROWTH more room than it needs
GROWTH = 8
#: at this many particles per reach-wide cell the build uses cells half the reach wide: 5 x 5 x 5
#: of them hold about half the candidates of 3 x 3 x 3 reach-wide ones
DENSE_CELL = 8
#: options of the loops below: no reference counting (they never allocate)
LOOP_OPTIONS = dict(cache=True, _nrt=False, fastmath={"contract", "arcp"}, error_model="numpy")
#: the list builder's entry points, and its helpers: inlined into them by numba (their arithmetic under
#: the same flags). Compiled as functions of their own, each helper was also linked into its caller
#: and optimised again there, four levels deep: rebuild compiled in 14.4-15.9 CPU s, 11.7-13.1 inlined
ENTRY = dict(cache=True, fastmath={"contract", "arcp"}, error_model="numpy")
HELPER = dict(ENTRY, inline="always")


@njit(**LOOP_OPTIONS)
def max_displacement(position, reference):
    """(largest squared displacement since the reference positions, index of that particle)."""
    worst = 0.0
    k = 0
    for i in range(position.shape[0]):
        dx = position[i, 0] - reference[i, 0]
        dy = position[i, 1] - reference[i, 1]
        dz = position[i, 2] - reference[i, 2]
        d2 = dx * dx + dy * dy + dz * dz
        if d2 > worst:
            worst = d2
            k = i
    return worst, k


@njit(cache=True, parallel=True, fastmath={"contract", "arcp"}, error_model="numpy")  # reductions need NRT
def max_displacement_threads(position, reference):
    """:func:`max_displacement` on threads (the largest value on threads, its particle found serially)."""
    worst = 0.0
    for i in prange(position.shape[0]):
        dx = position[i, 0] - reference[i, 0]
        dy = position[i, 1] - reference[i, 1]
        dz = position[i, 2] - reference[i, 2]
        worst = max(worst, dx * dx + dy * dy + dz * dz)
    k = 0
    if worst > 0.0:
        for i in range(position.shape[0]):
            dx = position[i, 0] - reference[i, 0]
            dy = position[i, 1] - reference[i, 1]
            dz = position[i, 2] - reference[i, 2]
            if dx * dx + dy * dy + dz * dz == worst:
                k = i
                break
    return worst, k


@njit(**LOOP_OPTIONS)
def copy_rows(target, source):
    """target[:] = source for (N,3) arrays."""
    for i in range(source.shape[0]):
        target[i, 0] = source[i, 0]
        target[i, 1] = source[i, 1]
        target[i, 2] = source[i, 2]


@njit(**HELPER)
def cell_grid(position, box, periodic, reach, origin, size, ncell):
    """Fill origin, size (3,) and ncell (3,) for cells at least ``reach`` wide (wider when the grid
    would have more than MAX_CELLS_PER_PARTICLE cells per particle)."""
    n = position.shape[0]
    extent = size  # holds the extents until the cell sizes are known
    for a in range(3):
        if periodic[a]:
            origin[a] = 0.0
            extent[a] = box[a]
        else:
            lo = np.inf
            hi = -np.inf
            for i in range(n):
                lo = min(lo, position[i, a])
                hi = max(hi, position[i, a])
            origin[a] = lo
            extent[a] = hi - lo
    width = reach
    while True:
        total = 1
        for a in range(3):
            ncell[a] = max(1, int(extent[a] / width))
            total *= ncell[a]
        if total <= MAX_CELLS_PER_PARTICLE * n + 27:
            break
        width *= 1.5
    for a in range(3):
        size[a] = extent[a] / ncell[a] if extent[a] > 0.0 else width


@njit(cache=True, _nrt=False, inline="always")
def cell_coordinate(x, length, periodic, origin, size, ncell):
    """Cell coordinate of coordinate x along one axis (periodic coordinates folded into the box)."""
    if periodic:
        x -= length * math.floor(x / length)
    k = int((x - origin) / size)
    return min(max(k, 0), ncell - 1)


@njit(**HELPER)
def bin_particles(position, box, periodic, origin, size, ncell, cell, cell_start, members):
    """Counting sort of the particles by cell: members[cell_start[c]:cell_start[c+1]] are in cell c."""
    n = position.shape[0]
    ncells = cell_start.shape[0] - 1
    for c in range(ncells + 1):
        cell_start[c] = 0
    for i in range(n):
        cx = cell_coordinate(position[i, 0], box[0], periodic[0], origin[0], size[0], ncell[0])
        cy = cell_coordinate(position[i, 1], box[1], periodic[1], origin[1], size[1], ncell[1])
        cz = cell_coordinate(position[i, 2], box[2], periodic[2], origin[2], size[2], ncell[2])
        cell[i] = (cx * ncell[1] + cy) * ncell[2] + cz
        cell_start[cell[i] + 1] += 1
    for c in range(ncells):
        cell_start[c + 1] += cell_start[c]
    for i in range(n):  # stable: members of a cell keep index order
        c = cell[i]
        members[cell_start[c]] = i
        cell_start[c] += 1
    for c in range(ncells, 0, -1):
        cell_start[c] = cell_start[c - 1]
    cell_start[0] = 0


@njit(**HELPER)
def neighbour_cells(ncell, periodic, radius, near, shift, counts):
    """near[a, c, :counts[a, c]]: the distinct cell coordinates c-radius .. c+radius along axis a
    (folded along a periodic axis, clipped along an open one); shift[a, c, q] = -1, 0 or +1: the box
    lengths to add to the coordinates of that cell's members to get their image nearest to cell c
    (0 when a periodic axis has fewer than 2 radius + 1 cells: candidates then take the minimum
    image one by one)."""
    for a in range(3):
        for c in range(ncell[a]):
            counts[a, c] = 0
            for o in range(-radius, radius + 1):
                k = c + o
                s = 0
                if periodic[a]:
                    if ncell[a] >= 2 * radius + 1:
                        s = -1 if k < 0 else (1 if k >= ncell[a] else 0)
                    k %= ncell[a]
                elif k < 0 or k >= ncell[a]:
                    continue
                seen = False
                for q in range(counts[a, c]):
                    seen = seen or near[a, c, q] == k
                if not seen:
                    near[a, c, counts[a, c]] = k
                    shift[a, c, counts[a, c]] = s
                    counts[a, c] += 1


@njit(**HELPER)
def sorted_copy(position, tag, box, periodic, members, xs, ts):
    """xs[:, m], ts[m]: position of members[m], folded into the box along periodic axes (rows x,
    y, z), and its tag."""
    for m in range(members.shape[0]):
        j = members[m]
        ts[m] = tag[j]
        for a in range(3):
            x = position[j, a]
            if periodic[a]:
                x -= box[a] * math.floor(x / box[a])
            xs[a, m] = x


@njit(**LOOP_OPTIONS)
def neighbour_ranges(cx, cy, cz, ncell, cell_start, near, shift, counts, box, lo, hi, image):
    """The members of the cells around (cx, cy, cz) as ranges lo[r]:hi[r] of the cell-sorted arrays,
    with the image shift image[r] to add to their coordinates; cells consecutive along z share a
    range. Returns the number of ranges."""
    nr = 0
    for ax in range(counts[0, cx]):
        kx = near[0, cx, ax]
        for ay in range(counts[1, cy]):
            ky = near[1, cy, ay]
            base = (kx * ncell[1] + ky) * ncell[2]
            last = -2
            for az in range(counts[2, cz]):
                kz = near[2, cz, az]
                k = base + kz
                if nr > 0 and kz == last + 1 and shift[2, cz, az] == shift[2, cz, az - 1]:
                    hi[nr - 1] = cell_start[k + 1]
                else:
                    lo[nr] = cell_start[k]
                    hi[nr] = cell_start[k + 1]
                    image[nr, 0] = shift[0, cx, ax] * box[0]
                    image[nr, 1] = shift[1, cy, ay] * box[1]
                    image[nr, 2] = shift[2, cz, az] * box[2]
                    nr += 1
                last = kz
    return nr


@njit(**HELPER)
def sheared_ranges(cx, cy, cz, ncell, cell_start, near, shift, counts, box, radius, le, lo, hi, image):
    """:func:`neighbour_ranges` under Lees-Edwards images (le = [a, b, delta, ahead]): cell by cell (no
    image shifts: the candidates take their sliding image one by one, :func:`sheared_hits`). Along
    the flow axis a, the cells around (cx, cy, cz) as usual for neighbouring cells that do not cross
    the gradient axis b, and around the cell shifted by -s delta for those that cross it s periods (both
    signs where b has too few cells to tell; widened by the sliding covered ahead), each cell once."""
    a = int(le[0])
    b = int(le[1])
    c = 3 - a - b
    delta = le[2]
    own = (cx, cy, cz)
    size = box[a] / ncell[a]
    extra = int(math.ceil(abs(le[3]) / size))  # cells the sliding covered ahead spans
    few_b = ncell[b] < 2 * radius + 1
    nr = 0
    for qb in range(counts[b, own[b]]):
        kb = near[b, own[b], qb]
        sb = shift[b, own[b], qb]
        for qc in range(counts[c, own[c]]):
            kc = near[c, own[c], qc]
            first = nr
            for sigma in range(-1, 2):
                if not (few_b or sigma == sb):
                    continue
                if sigma == 0:
                    width = counts[a, own[a]]
                    begin = 0
                else:
                    width = 2 * radius + 4 + 2 * extra
                    begin = own[a] + int(math.floor(-sigma * delta / size)) - radius - 1 - extra
                for q in range(width):
                    ka = near[a, own[a], q] if sigma == 0 else (begin + q) % ncell[a]
                    kx = ka if a == 0 else (kb if b == 0 else kc)
                    ky = ka if a == 1 else (kb if b == 1 else kc)
                    kz = ka if a == 2 else (kb if b == 2 else kc)
                    k = (kx * ncell[1] + ky) * ncell[2] + kz
                    if cell_start[k] == cell_start[k + 1]:
                        continue
                    seen = False
                    for r in range(first, nr):
                        seen = seen or lo[r] == cell_start[k]
                    if not seen:
                        lo[nr] = cell_start[k]
                        hi[nr] = cell_start[k + 1]
                        image[nr, 0] = 0.0
                        image[nr, 1] = 0.0
                        image[nr, 2] = 0.0
                        nr += 1
    return nr


@njit(**HELPER)
def sheared_hits(xi, yi, zi, ti, k, near_x, near_id, box, periodic, reach2, le):
    """near_id[2, u]: is candidate u's nearest Lees-Edwards image (le = [a, b, delta, ahead]) closer than
    the reach, now or, across the sliding boundary, while delta slides on by ``ahead``, and its tag
    above ti?"""
    a = int(le[0])
    b = int(le[1])
    c = 3 - a - b
    delta = le[2]
    ahead = le[3]
    own = (xi, yi, zi)
    xa, xb, xc = own[a], own[b], own[c]
    ra, rb, rc = near_x[a], near_x[b], near_x[c]
    la = box[a]
    lb = box[b]
    hb = 0.5 * lb
    ila = 1.0 / la
    lc = box[c] if periodic[c] else 0.0
    ilc = 1.0 / lc if lc > 0.0 else 0.0
    # branch-free: vectorised as the plain distance test (branches cost a sheared N = 8000 scene ~8 %)
    for u in range(k):
        db = rb[u] - xb
        shift = (1.0 if db < -hb else 0.0) - (1.0 if db > hb else 0.0)
        db += shift * lb
        da = ra[u] - xa + shift * delta
        da -= la * np.floor(da * ila + 0.5)  # (np.floor: a float, which vectorises; math.floor is an int)
        # the nearest [da, da + shift ahead] comes to 0 or to -+la (a pair not crossing: da itself)
        lo = min(da, da + shift * ahead)
        hi = max(da, da + shift * ahead)
        da = min(max(0.0, max(lo, -hi)), min(max(0.0, max(lo - la, la - hi)), max(0.0, max(lo + la, -la - hi))))
        dc = rc[u] - xc
        dc -= lc * np.floor(dc * ilc + 0.5)
        near_id[2, u] = (da * da + db * db + dc * dc < reach2) & (near_id[1, u] > ti)


@njit(**HELPER)
def sheared_fold(position, box, periodic, le):
    """Positions folded by the sliding images (le = [a, b, delta]): k periods up b, back k L_b and k delta."""
    a = int(le[0])
    b = int(le[1])
    out = position.copy()
    for i in range(out.shape[0]):
        k = math.floor(out[i, b] / box[b])
        out[i, b] -= k * box[b]
        out[i, a] -= k * le[2]
        for q in range(3):
            if periodic[q]:
                out[i, q] -= box[q] * math.floor(out[i, q] / box[q])
    return out


@njit(**LOOP_OPTIONS)
def fill_pairs(ts, xs, members, box, periodic, reach, radius, ncell, cell_start, near, shift, counts, start,
               end, partner, lo, hi, image, near_x, near_id, first_cell, last_cell, base, limit, le):
    """Write the pairs closer than ``reach`` whose owner lies in cells first_cell..last_cell-1 into
    partner[base:limit], the partners of particle i at start[i]:end[i], each pair in the row of its
    lower tag; returns how many entries that takes (those beyond limit - 1 are counted, not
    written: slot limit - 1 is scratch). Works cell by cell on the cell-sorted, folded copy ``xs``
    (rows x, y, z) and tags ``ts``. The candidates of a cell (the members of its neighbouring cells,
    image shift added) are copied once into ``near_x`` (rows x, y, z) and ``near_id`` (rows: index,
    tag, then the hit flags of the member at hand), so that each member of the cell runs one long
    loop the compiler vectorises over all of them (distance and tag test) and one short
    branch-free loop that keeps the hits. Cells are 1/radius of the reach wide (2 radius + 1
    neighbouring cells per axis); a periodic axis with fewer than 2 radius + 1 cells takes the
    minimum image per pair."""
    reach2 = reach * reach
    last = limit - 1
    few = 2 * radius + 1
    lx = box[0] if periodic[0] and ncell[0] < few else 0.0
    ly = box[1] if periodic[1] and ncell[1] < few else 0.0
    lz = box[2] if periodic[2] and ncell[2] < few else 0.0
    hx = 0.5 * lx if lx > 0.0 else np.inf
    hy = 0.5 * ly if ly > 0.0 else np.inf
    hz = 0.5 * lz if lz > 0.0 else np.inf
    minimum_image = lx > 0.0 or ly > 0.0 or lz > 0.0
    sheared = le.shape[0] > 0  # Lees-Edwards: every candidate takes its sliding image (sheared_ranges)
    gradient = int(le[1]) if sheared else 0
    count = base
    for c in range(first_cell, last_cell):
        if cell_start[c] == cell_start[c + 1]:
            continue
        cx = c // (ncell[1] * ncell[2])
        cy = (c // ncell[2]) % ncell[1]
        cz = c % ncell[2]
        # a sheared box's cells whose neighbours along the gradient axis cross no boundary have no
        # sliding image among their candidates: they take the plain path (a third of the build's time)
        crossing = sheared and ncell[gradient] < few
        own_b = cx if gradient == 0 else (cy if gradient == 1 else cz)
        for q in range(counts[gradient, own_b] if sheared and not crossing else 0):
            crossing = crossing or shift[gradient, own_b, q] != 0
        if crossing:
            nr = sheared_ranges(cx, cy, cz, ncell, cell_start, near, shift, counts, box, radius, le, lo, hi, image)
        else:
            nr = neighbour_ranges(cx, cy, cz, ncell, cell_start, near, shift, counts, box, lo, hi, image)
        k = 0
        for r in range(nr):
            for b in range(lo[r], hi[r]):
                near_x[0, k] = xs[0, b] + image[r, 0]
                near_x[1, k] = xs[1, b] + image[r, 1]
                near_x[2, k] = xs[2, b] + image[r, 2]
                near_id[0, k] = members[b]
                near_id[1, k] = ts[b]
                k += 1
        for m in range(cell_start[c], cell_start[c + 1]):
            ti = ts[m]
            xi = xs[0, m]
            yi = xs[1, m]
            zi = xs[2, m]
            if crossing:
                sheared_hits(xs[0, m], xs[1, m], xs[2, m], ti, k, near_x, near_id, box, periodic, reach2, le)
            elif minimum_image:  # two loops: the selects cost the dipole list's build 17-19 ms against 11
                for u in range(k):
                    dx = near_x[0, u] - xi
                    dy = near_x[1, u] - yi
                    dz = near_x[2, u] - zi
                    dx = dx - lx if dx > hx else (dx + lx if dx < -hx else dx)
                    dy = dy - ly if dy > hy else (dy + ly if dy < -hy else dy)
                    dz = dz - lz if dz > hz else (dz + lz if dz < -hz else dz)
                    near_id[2, u] = (dx * dx + dy * dy + dz * dz < reach2) & (near_id[1, u] > ti)
            else:
                for u in range(k):
                    dx = near_x[0, u] - xi
                    dy = near_x[1, u] - yi
                    dz = near_x[2, u] - zi
                    near_id[2, u] = (dx * dx + dy * dy + dz * dz < reach2) & (near_id[1, u] > ti)
            start[members[m]] = count
            if count + k < last:  # without min(): 11.0 against 11.6-12.2 ms for that build
                for u in range(k):  # branch-free: always write, keep when it counts
                    partner[count] = near_id[0, u]
                    count += near_id[2, u]
            else:  # near the end of the region: past it, count without writing
                for u in range(k):
                    partner[min(count, last)] = near_id[0, u]
                    count += near_id[2, u]
            end[members[m]] = count
    return count - base


@njit(**HELPER)
def most_candidates(cell_start, cells_around):
    """At most how many candidates a cell can have: its ``cells_around`` neighbouring cells (itself
    included) times the fullest cell's members, and no more than all the particles (the size of
    fill_pairs' buffers)."""
    fullest = 0
    for c in range(cell_start.shape[0] - 1):
        fullest = max(fullest, cell_start[c + 1] - cell_start[c])
    return min(fullest * cells_around, cell_start[cell_start.shape[0] - 1])


@njit(cache=True, _nrt=False, parallel=True, fastmath={"contract", "arcp"}, error_model="numpy")
def fill_threads(ts, xs, members, box, periodic, reach, radius, ncell, cell_start, near, shift, counts, start,
                 end, partner, lo, hi, image, near_x, near_id, cells, region, used, le):
    """fill_pairs for each chunk t of cells cells[t]:cells[t+1] into its region
    partner[region[t]:region[t+1]], chunks on threads; used[t]: entries chunk t needs."""
    for t in prange(cells.shape[0] - 1):
        used[t] = fill_pairs(ts, xs, members, box, periodic, reach, radius, ncell, cell_start, near, shift,
                             counts, start, end, partner, lo[t], hi[t], image[t], near_x[t], near_id[t], cells[t],
                             cells[t + 1], region[t], region[t + 1], le)


@njit(**LOOP_OPTIONS)
def fill_serial(ts, xs, members, box, periodic, reach, radius, ncell, cell_start, near, shift, counts, start,
                end, partner, lo, hi, image, near_x, near_id, cells, region, used, le):
    """fill_threads with the chunks one after the other: the same lists (each chunk fills its own
    region)."""
    for t in range(cells.shape[0] - 1):
        used[t] = fill_pairs(ts, xs, members, box, periodic, reach, radius, ncell, cell_start, near, shift, counts,
                             start, end, partner, lo[t], hi[t], image[t], near_x[t], near_id[t], cells[t],
                             cells[t + 1], region[t], region[t + 1], le)


@njit(**HELPER)
def split_cells(cell_start, cells):
    """Cut the cells into len(cells)-1 consecutive chunks holding equal numbers of particles."""
    chunks = cells.shape[0] - 1
    ncells = cell_start.shape[0] - 1
    n = cell_start[ncells]
    c = 0
    cells[0] = 0
    for t in range(1, chunks):
        target = (n * t) // chunks
        while c < ncells and cell_start[c] < target:
            c += 1
        cells[t] = c
    cells[chunks] = ncells


# A list is built in three parts around its filling, which runs the chunks one after the other
# (fill_serial) or on threads (fill_threads): the same lists either way. One builder takes the choice
# as an argument, so that its body (binning, history carried by tag) compiles once for both (twins
# inlining the same helpers cost 6.5 CPU s more per install): a bool (both fills linked into the builder:
# the fused modules), or the fill itself as a first-class function (:func:`filler`: the generic list upkeep
# and Python; linked into nothing, 2.2 CPU s less for the builder, and a scene that never builds its lists
# on threads never compiles fill_threads).
def fill(how, arguments):
    """fill_threads or fill_serial (the same lists) with the arguments of :func:`fill_arguments`; ``how``:
    threads or not (a bool), or the fill (a first-class function). Compiled code only."""
    raise NotImplementedError("demkit.engine.neighbours.fill runs in compiled code only")


@overload(fill, inline="always")
def _fill(how, arguments):
    if isinstance(how, types.Boolean):
        def direct(how, arguments):
            if how:
                fill_threads(*arguments)
            else:
                fill_serial(*arguments)
        return direct

    def called(how, arguments):
        how(*arguments)
    return called


def fill_signature(pair_list, box, periodic):
    """The argument types of fill_serial/fill_threads (:func:`fill_arguments`) for a pair list, box and
    periodic flags of these numba types: start_build's arrays (tests/test_nbody.py checks them) and the
    list's."""
    i1, i2, i3 = (types.Array(types.int64, d, "C") for d in (1, 2, 3))
    f1, f2, f3 = (types.Array(types.float64, d, "C") for d in (1, 2, 3))
    f = dict(pair_list.field_dict)
    return (i1, f2, i1, box, periodic, types.float64, types.int64, i1, i1, i3, i3, i2, f["start"], f["end"],
            f["partner"], i2, i2, f3, f3, i3, i1, i1, i1, f1)


_FILLERS = {}


def filler(pair_list, box, periodic, threads=False):
    """fill_threads (``threads``) or fill_serial compiled for lists of these numba types, as a first-class
    function: what :func:`rebuild` takes as ``how`` from the generic list upkeep and from Python."""
    key = (pair_list, box, periodic, bool(threads))
    if key not in _FILLERS:
        from numba.core.types.function_type import CompileResultWAP
        signature = fill_signature(pair_list, box, periodic)
        function = fill_threads if threads else fill_serial
        function.compile(signature)
        _FILLERS[key] = CompileResultWAP(function.overloads[signature])
    return _FILLERS[key]


def build_from_python(pl, position, tag, box, periodic, le):
    """Fill the list ``pl`` from Python, on one thread (:func:`rebuild` given the serial :func:`filler`; the
    tags ``tag`` also as ``before``: no history to carry)."""
    import numba
    rebuild(pl, position, tag, tag, box, periodic, le,
            filler(numba.typeof(pl), numba.typeof(box), numba.typeof(periodic)))


@njit(**ENTRY)
def build(pl, position, tag, box, periodic, le, how):
    """Fill ``pl.start``/``pl.end``/``pl.partner`` with every pair closer than ``pl.reach``, the cells cut
    into len(pl.bounds) - 1 chunks filled one after the other (or on threads), each in its own region
    of ``partner`` (grown, and the regions resized, when one overflows)."""
    work = start_build(pl, position, tag, box, periodic, le)
    fill(how, fill_arguments(pl, box, periodic, work, le))
    if grown(pl, work):
        fill(how, fill_arguments(pl, box, periodic, work, le))
    finish_build(pl, work)


@njit(**ENTRY)
def start_build(pl, position, tag, box, periodic, le):
    """Bin the particles into cells and cut the cells into chunks: the working arrays of a build.
    Compiled once for both builders (not inlined into each): with lists built on threads too, the
    two rebuilds compiled in 26-27 CPU s instead of 32, at ~2 s more for the serial one alone. Under
    Lees-Edwards images (le = [a, b, delta], else empty) the cells hold the positions folded with them."""
    if le.shape[0] > 0:
        position = sheared_fold(position, box, periodic, le)
    n = position.shape[0]
    origin = np.empty(3)
    size = np.empty(3)
    ncell = np.empty(3, dtype=np.int64)
    radius = 1
    while True:  # (one call site: the grid's code inlined once)
        cell_grid(position, box, periodic, pl.reach / radius, origin, size, ncell)
        if radius == 2 or n < DENSE_CELL * ncell[0] * ncell[1] * ncell[2]:
            break
        radius = 2  # crowded cells: halve them, 2 cells of reach
    cell = np.empty(n, dtype=np.int64)
    cell_start = np.empty(ncell[0] * ncell[1] * ncell[2] + 1, dtype=np.int64)
    members = np.empty(n, dtype=np.int64)
    bin_particles(position, box, periodic, origin, size, ncell, cell, cell_start, members)
    widest = max(ncell[0], ncell[1], ncell[2])
    side = 2 * radius + 1
    near = np.empty((3, widest, side), dtype=np.int64)
    shift = np.empty((3, widest, side), dtype=np.int64)
    counts = np.empty((3, widest), dtype=np.int64)
    neighbour_cells(ncell, periodic, radius, near, shift, counts)
    xs = np.empty((3, n))
    ts = np.empty(n, dtype=np.int64)
    sorted_copy(position, tag, box, periodic, members, xs, ts)
    chunks = pl.bounds.shape[0] - 1
    cells = np.empty(chunks + 1, dtype=np.int64)
    split_cells(cell_start, cells)
    around = side**3  # (sheared_ranges: wider along the flow axis)
    if le.shape[0] > 0:
        extra = int(math.ceil(abs(le[3]) / (box[int(le[0])] / ncell[int(le[0])]))) + 1  # (one more than it uses)
        around = side * side * (side + 2 * (2 * radius + 4 + 2 * extra))
    lo = np.empty((chunks, around), dtype=np.int64)
    hi = np.empty((chunks, around), dtype=np.int64)
    image = np.empty((chunks, around, 3))
    most = most_candidates(cell_start, around)
    near_x = np.empty((chunks, 3, most))
    near_id = np.empty((chunks, 3, most), dtype=np.int64)
    used = np.zeros(chunks, dtype=np.int64)
    region = np.empty(chunks + 1, dtype=np.int64)
    for t in range(chunks + 1):  # regions in proportion to the particles of each chunk
        region[t] = (pl.partner.shape[0] * (cell_start[cells[t]] if t < chunks else n)) // max(n, 1)
    region[chunks] = pl.partner.shape[0]
    return (ts, xs, members, radius, ncell, cell_start, near, shift, counts, lo, hi, image, near_x, near_id, cells,
            region, used)


@njit(**HELPER)
def fill_arguments(pl, box, periodic, work, le):
    """The arguments of fill_serial/fill_threads."""
    ts, xs, members, radius, ncell, cell_start, near, shift, counts, lo, hi, image, near_x, near_id, cells, region, \
        used = work
    return (ts, xs, members, box, periodic, pl.reach, radius, ncell, cell_start, near, shift, counts, pl.start,
            pl.end, pl.partner, lo, hi, image, near_x, near_id, cells, region, used, le)


@njit(**HELPER)
def grown(pl, work):
    """Did a chunk fill its region? Then make room for what each chunk needs, and 1/GROWTH more
    (``pl.partner`` replaced, the regions resized): the list is to be filled again."""
    region, used = work[15], work[16]
    chunks = used.shape[0]
    full = False
    for t in range(chunks):
        full = full or used[t] >= region[t + 1] - region[t]
    if full:
        region[0] = 0
        for t in range(chunks):
            region[t + 1] = region[t] + used[t] + used[t] // GROWTH + 16
        pl.partner = np.empty(region[chunks], dtype=np.int32)
    return full


@njit(**HELPER)
def finish_build(pl, work):
    """Record the number of entries (rows may leave gaps between the chunks' regions)."""
    used = work[16]
    total = 0
    for t in range(used.shape[0]):
        total += used[t]
    pl.start[pl.start.shape[0] - 1] = total


@njit(**HELPER)
def balance(start, end, bounds):
    """Cut the owners (by index) into len(bounds)-1 consecutive chunks holding equal numbers of pairs."""
    n = end.shape[0]
    chunks = bounds.shape[0] - 1
    total = start[n]  # the number of entries
    i = 0
    done = 0
    bounds[0] = 0
    for t in range(1, chunks):
        target = (total * t) // chunks
        while i < n and done < target:
            done += end[i] - start[i]
            i += 1
        bounds[t] = i
    bounds[chunks] = n


@njit(**ENTRY)
def rebuild(pl, position, tag, before, box, periodic, le, how):
    """Rebuild one list, carrying its per-pair history by tag: ``before`` are the tags the particles
    had when the list was last built (``tag`` itself, unless they were re-ordered since: the sort
    permutes the particles first and then rebuilds every list with this one compiled function).
    ``le``: [a, b, delta, ...] of Lees-Edwards images (demkit.engine.shear.list_frame), or empty;
    ``how``: the fill (see :func:`fill`), a first-class function from :func:`filler` (the generic list
    upkeep's ``calls``; from Python: :func:`build_from_python`), or whether to fill on threads, a bool and not a
    literal (numba compiles a function once per *literal* argument value: a fused module passes
    ``np.bool_(LISTS_ON_THREADS)``). The generic upkeep calls this function as a first-class function: each
    function that calls it directly has its whole body linked in and optimised again (1.2-1.3 CPU s a
    caller)."""
    if pl.history.shape[1] > 0:
        owners, partners, rows = saved_history(pl, before)
        build(pl, position, tag, box, periodic, le, how)
        restore_history(pl, tag, owners, partners, rows)
    else:
        build(pl, position, tag, box, periodic, le, how)
    balance(pl.start, pl.end, pl.bounds)


@njit(**LOOP_OPTIONS)
def wrap(position, reference, image, box, periodic):
    """Bring periodic coordinates into [0, L), counting images and moving the reference along."""
    for a in range(3):
        if not periodic[a]:
            continue
        length = box[a]
        for i in range(position.shape[0]):
            x = position[i, a]
            if x < 0.0 or x >= length:
                folded, k = fold(x, length)
                position[i, a] = folded
                image[i, a] += k
                if reference.shape[0] > 0:
                    reference[i, a] -= k * length


@njit(**LOOP_OPTIONS)
def triangle_bounds(n, bounds):
    """Cut the rows i of the all-pairs triangle (n - 1 - i pairs each) into equal shares."""
    chunks = bounds.shape[0] - 1
    total = n * (n - 1) // 2
    i = 0
    done = 0
    bounds[0] = 0
    for t in range(1, chunks):
        target = (total * t) // chunks
        while i < n and done < target:
            done += n - 1 - i
            i += 1
        bounds[t] = i
    bounds[chunks] = n


def entry_owners(pl):
    """(owner, entry) of each list entry, row by row: two (P,) arrays."""
    start, end = pl.start[:-1], pl.end
    counts = end - start
    owners = np.repeat(np.arange(len(end)), counts)
    first = np.repeat(np.cumsum(counts) - counts, counts)  # where each owner's entries begin, row by row
    return owners, start[owners] + np.arange(len(owners)) - first


def pairs_of(pl, tag):
    """(P, 2) array of the listed pairs as tags (owner first), row by row: for diagnostics and tests."""
    owners, entries = entry_owners(pl)
    return np.stack([tag[owners], tag[pl.partner[entries]]], axis=1)



@njit(cache=True)
def cell_order(position, box, periodic, width):
    """Permutation of the particles by cell (cells at least ``width`` wide, x slowest): particle
    order[k] goes to place k. (A Z-order curve was tried: a million-sphere contact loop ran 37 ns a
    sphere instead of 26; in x-major order a loop's partners lie in three planes of cells that it
    walks through as streams.)"""
    n = position.shape[0]
    origin = np.empty(3)
    size = np.empty(3)
    ncell = np.empty(3, dtype=np.int64)
    cell_grid(position, box, periodic, width, origin, size, ncell)
    cell = np.empty(n, dtype=np.int64)
    cell_start = np.empty(ncell[0] * ncell[1] * ncell[2] + 1, dtype=np.int64)
    order = np.empty(n, dtype=np.int64)
    bin_particles(position, box, periodic, origin, size, ncell, cell, cell_start, order)
    return order


@njit(cache=True)
def permute_rows(a, order):
    """a[k] = a[order[k]] for the rows of an (N, W) array."""
    tmp = a.copy()
    for k in range(order.shape[0]):
        for c in range(a.shape[1]):
            a[k, c] = tmp[order[k], c]


@njit(**LOOP_OPTIONS)
def permute_vectors(a, order, tmp):
    """a[k] = a[order[k]] for the rows of an (N,3) array (skips an absent (0,3) field)."""
    if a.shape[0] == 0:
        return
    for k in range(order.shape[0]):
        for c in range(3):
            tmp[k, c] = a[order[k], c]
    for k in range(order.shape[0]):
        for c in range(3):
            a[k, c] = tmp[k, c]


@njit(**LOOP_OPTIONS)
def permute_scalars(a, order, tmp):
    """a[k] = a[order[k]] for an (N,) array."""
    for k in range(order.shape[0]):
        tmp[k] = a[order[k]]
    for k in range(order.shape[0]):
        a[k] = tmp[k]
