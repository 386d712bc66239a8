"""Clusters and contacts of spheres in one frame (scipy cKDTree; periodic boxes via its boxsize).

    labels = clusters(position, radius, box)     # 0 = the largest cluster, 1 = the next, ...
    count = contacts(position, radius, box)      # touching neighbours of each sphere
"""
from __future__ import annotations

import numpy as np

#: spheres whose surfaces are closer than this many mean radii belong to one cluster
CLUSTER_GAP = 0.1
#: spheres touch when their centre distance is below (r_i + r_j) * (1 + CONTACT_TOLERANCE)
CONTACT_TOLERANCE = 0.01


def _wrapped(position, box, time=None):
    """Positions brought into [0, L) along the periodic axes of ``box`` (a deforming box's at ``time``) and
    the cKDTree boxsize."""
    if box is None or not np.any(box.periodic):
        return position, None
    if getattr(box, "deform", None) is not None and time is None:
        raise ValueError("close pairs in a deforming box need the frame's time (time=...): its lengths change")
    lengths = box.size_at(float(time)) if time is not None else box.size
    position = position.copy()
    size = np.where(box.periodic, lengths, 0.0)  # 0: not periodic, for cKDTree
    for a in np.flatnonzero(box.periodic):
        x = np.mod(position[:, a], lengths[a])
        x[x >= lengths[a]] = 0.0  # np.mod of a tiny negative number can give L itself
        position[:, a] = x
    return position, size


def _sliding_copies(points, box, time, boxsize):
    """A sheared box's wrapped points with their copies one period up and down the gradient axis b,
    shifted along the flow axis a by +-delta(time) (the sliding images), all moved up b by L_b; the
    tree's boxsize with 3 L_b along b; the index of each point's original. Pairs through the copies
    are every pair through the sliding boundary (and some that are not, which the distance drops)."""
    a, b = box.shear.axes
    size = box.size
    delta = box.shear.offset(size, time)
    copies = []
    for k in (0, 1, -1):
        c = points.copy()
        c[:, b] += (k + 1) * size[b]
        c[:, a] = np.mod(c[:, a] + k * delta, size[a])
        c[c[:, a] >= size[a], a] = 0.0
        copies.append(c)
    boxsize = boxsize.copy()
    boxsize[b] = 3.0 * size[b]
    return np.concatenate(copies), boxsize, np.tile(np.arange(len(points)), 3)


def close_pairs(position, radius, box=None, scale=1.0, extra=0.0, distances=False, time=None):
    """(P, 2) index pairs i < j whose centre distance is below (r_i + r_j) * scale + extra,
    using the minimum image along periodic axes of ``box`` (a sheared box's sliding images at
    ``time``, which it needs); with ``distances``, also their (P,) centre distances."""
    from scipy.spatial import cKDTree

    position = np.asarray(position, dtype=np.float64)
    radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (len(position),))
    if len(position) < 2:
        none = np.zeros((0, 2), dtype=np.int64)
        return (none, np.zeros(0)) if distances else none
    points, boxsize = _wrapped(position, box, time)
    sheared = box is not None and box.shear is not None
    if sheared and time is None:
        raise ValueError("close pairs in a sheared box need the frame's time (time=...): its images slide")
    tree_points, tree_box, owner = _sliding_copies(points, box, time, boxsize) if sheared else (points, boxsize, None)
    tree = cKDTree(tree_points, boxsize=tree_box)
    pairs = tree.query_pairs(2.0 * float(radius.max()) * scale + extra, output_type="ndarray")
    if sheared and len(pairs):
        pairs = np.sort(owner[pairs], axis=1)
        pairs = np.unique(pairs[pairs[:, 0] != pairs[:, 1]], axis=0)
    if len(pairs) == 0:
        pairs = pairs.reshape(0, 2)
        return (pairs, np.zeros(0)) if distances else pairs
    d = points[pairs[:, 1]] - points[pairs[:, 0]]
    if boxsize is not None:
        d = box.minimum_image(d, time)
    r = np.linalg.norm(d, axis=1)
    keep = r < (radius[pairs[:, 0]] + radius[pairs[:, 1]]) * scale + extra
    return (pairs[keep], r[keep]) if distances else pairs[keep]


def clusters(position, radius, box=None, gap=None, time=None):
    """Cluster label of every sphere, (N,) int: 0 for the largest cluster, 1 for the next, ...

    Two spheres are connected when the gap between their surfaces is below ``gap`` (length;
    default CLUSTER_GAP mean radii); clusters are the connected groups (a lone sphere is one). A
    sheared box needs the frame's ``time``.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(position)
    radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (n,))
    gap = CLUSTER_GAP * float(np.mean(radius)) if gap is None else float(gap)
    pairs = close_pairs(position, radius, box, extra=gap, time=time)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    size = np.bincount(label)
    rank = np.empty(len(size), dtype=np.int64)
    rank[np.argsort(-size, kind="stable")] = np.arange(len(size))
    return rank[label]


def contacts(position, radius, box=None, tolerance=CONTACT_TOLERANCE, time=None):
    """Number of touching neighbours of every sphere, (N,) int: centre distance below
    (r_i + r_j) * (1 + tolerance) (a sheared box: at ``time``)."""
    pairs = close_pairs(position, radius, box, scale=1.0 + tolerance, time=time)
    return np.bincount(pairs.ravel(), minlength=len(position))


def rings_and_chains(labels, counts):
    """Sizes of the clusters that are plain rings (at least 3 spheres, each touching exactly two
    others) and plain chains (an open line: two ends touching one sphere, the rest two), from the
    cluster labels of :func:`clusters` and the touching neighbours of :func:`contacts`:
    (rings, chains), two lists of sizes in label order."""
    rings, chains = [], []
    for c in range(int(labels.max()) + 1 if len(labels) else 0):
        k = counts[labels == c]
        if len(k) >= 3 and np.all(k == 2):
            rings.append(len(k))
        elif len(k) >= 2 and k.max() <= 2 and np.sum(k == 1) == 2:
            chains.append(len(k))
    return rings, chains
