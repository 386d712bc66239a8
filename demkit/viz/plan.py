"""What a picture shows, decided before anything renders: which spheres (``subset``), their
colours (``color_by``, ``cmap``, ``clim``) and what the camera frames (``frame``, ``bounds``).

Everything here is numpy/scipy: bad arguments raise ValueError before a renderer starts.
"""
from __future__ import annotations

import numpy as np

from ..clustering import clusters, contacts

#: colours for ``color_by="id"`` (cycled), RGB 0..255
PALETTE = np.array([[31, 119, 180], [214, 39, 40], [44, 160, 44], [255, 127, 14], [148, 103, 189],
                    [140, 86, 75], [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207]],
                   dtype=np.uint8)
#: colours of the largest clusters for ``color_by="cluster"``; smaller ones are light grey
CLUSTER_COLOURS = np.delete(PALETTE, 7, axis=0)
OTHERS = np.array([205, 205, 205], dtype=np.uint8)
FRAMES = ("auto", "all", "cluster", "box")
VECTORS = ("velocity", "angular_velocity", "force", "torque")
#: "auto" frames the largest cluster when it holds more than this fraction of the spheres drawn
#: and everything drawn spans more than CLUSTER_SPREAD times its size
CLUSTER_SHARE, CLUSTER_SPREAD = 0.5, 1.5
#: "auto" frames the box when the spheres drawn span at least this fraction of it along every axis
#: (else the spheres, drawn with the box's outline: a pile at the bottom of a tall box fills the picture)
BOX_FILL = 0.5


def check_bounds(bounds):
    """``bounds`` as a (6,) float array (xmin, xmax, ymin, ymax, zmin, zmax), or None."""
    if bounds is None:
        return None
    try:
        b = np.array(bounds, dtype=np.float64)
    except (TypeError, ValueError):
        b = None
    if b is None or b.shape != (6,) or not np.all(np.isfinite(b)):
        raise ValueError(f"bounds must be 6 finite numbers (xmin, xmax, ymin, ymax, zmin, zmax), got {bounds!r}")
    if np.any(b[0::2] >= b[1::2]):
        raise ValueError(f"bounds must have min < max along x, y and z, got {b.tolist()}")
    return b


def check_zoom(zoom):
    try:
        zoom = float(zoom)
    except (TypeError, ValueError):
        raise ValueError(f"zoom must be a positive number, got {zoom!r}") from None
    if not np.isfinite(zoom) or zoom <= 0:
        raise ValueError(f"zoom must be a positive number (2: twice as close), got {zoom}")
    return zoom


def check_frame(frame):
    if isinstance(frame, (int, np.integer)) and not isinstance(frame, bool):
        raise ValueError(f"frame chooses what the camera fits ({', '.join(map(repr, FRAMES))}); "
                         f"the frame to draw is frame_index={frame}")
    if frame not in FRAMES:
        raise ValueError(f"frame must be one of {', '.join(map(repr, FRAMES))}, got {frame!r}")
    return frame


def _as_mask(value, n, what):
    """A boolean (n,) mask from sphere indices or a boolean mask."""
    value = np.asarray(value)
    if value.dtype == bool:
        if value.shape != (n,):
            raise ValueError(f"{what}: a boolean mask needs one entry per sphere ({n}), got shape {value.shape}")
        return value
    if value.ndim <= 1 and (value.dtype.kind in "iu" or value.size == 0):
        index = value.astype(np.int64).ravel()
        bad = index[(index < -n) | (index >= n)]
        if len(bad):
            raise ValueError(f"{what}: sphere indices {bad[:5].tolist()} are out of range for {n} spheres")
        mask = np.zeros(n, dtype=bool)
        mask[index] = True
        return mask
    raise ValueError(f"{what} must be sphere indices, a boolean mask of {n} entries or a callable "
                     f"(frames, k) -> mask; got a {value.dtype} array of shape {value.shape}")


def subset_mask(frames, subset):
    """A function k -> (N,) bool: the spheres drawn in frame k."""
    n = frames.position.shape[1]
    if subset is None:
        every = np.ones(n, dtype=bool)
        return lambda k: every
    if isinstance(subset, str):
        if subset != "cluster":
            raise ValueError(f"subset must be 'cluster', sphere indices, a boolean mask or a callable, "
                             f"got {subset!r}")
        box = getattr(frames, "box", None)
        return lambda k: clusters(frames.position[k], frames.radius, box, time=frames.time[k]) == 0
    if callable(subset):
        return lambda k: _as_mask(subset(frames, k), n, "subset(frames, k)")
    fixed = _as_mask(subset, n, "subset")
    if not fixed.any():
        raise ValueError("subset selects no sphere")
    return lambda k: fixed


class Colouring:
    """Colour values of the spheres: ``values(k)`` (N,) floats mapped through ``cmap`` (a
    matplotlib colormap of ``n_colors`` colours, or 256) over ``clim`` (default: the range over
    the spheres ``mask(k)`` of the frames ``shown``; cluster categories: over ``drawn(k)``);
    ``title`` for the colour bar, ``bar`` whether to show one with ``n_labels`` labels,
    ``annotations`` {value: label} for categorical fields."""

    def __init__(self, frames, color_by, cmap, clim, shown, mask, drawn):
        import matplotlib

        self.frames = frames
        n = frames.position.shape[1]
        self._cache = {}
        if color_by is None:
            color_by = "speed" if n > len(PALETTE) and getattr(frames, "velocity", None) is not None else "id"
        self.bar, self.annotations, self.n_colors, self.n_labels = True, None, 256, 5
        if isinstance(color_by, str):
            self.title, self._compute = self._field(color_by)
        else:
            self.title, self._compute = "value", self._array(color_by)
        self.name = color_by if isinstance(color_by, str) else "array"
        if self.name == "id":  # categorical, no colour bar
            self.cmap = (matplotlib.colors.ListedColormap(PALETTE / 255.0) if cmap is None
                         else matplotlib.colormaps[cmap].resampled(len(PALETTE)))
            self.clim, self.n_colors, self.bar = (-0.5, len(PALETTE) - 0.5), len(PALETTE), False
            return
        if self.name == "cluster":
            self._categories(shown, drawn, cmap)
            return
        self.cmap = matplotlib.colormaps[cmap or ("coolwarm" if self.name == "dipole" else "viridis")]
        self.clim = self._range(shown, mask) if clim is None else self._check_clim(clim)
        if self.name == "contacts" and clim is None:  # whole numbers at the colour bar's labels
            step = max(1, int(np.ceil(self.clim[1] / 5)))
            self.n_labels = int(np.ceil(self.clim[1] / step)) + 1
            self.clim = (0.0, float(step * (self.n_labels - 1)))

    def values(self, k):
        """(N,) colour values of frame k (cached)."""
        if k not in self._cache:
            self._cache[k] = np.asarray(self._compute(k), dtype=np.float64)
        return self._cache[k]

    def rgb(self, values):
        """(N,3) uint8 colours of ``values`` (as the colour map draws them)."""
        lo, hi = self.clim
        x = np.clip((values - lo) / (hi - lo), 0.0, 1.0)
        if self.n_colors < 256:
            x = (np.minimum(np.floor(x * self.n_colors), self.n_colors - 1) + 0.5) / self.n_colors
        colours = self.cmap(np.where(np.isfinite(x), x, 0.0))[:, :3] * 255
        colours[~np.isfinite(x)] = 128
        return colours.astype(np.uint8)

    # ---- fields ----------------------------------------------------------------------------
    def _field(self, name):
        f = self.frames
        n = f.position.shape[1]
        box = getattr(f, "box", None)

        def magnitude(array):
            return lambda k: np.linalg.norm(array[k], axis=1)

        if name == "id":
            return "id", lambda k: np.arange(n) % len(PALETTE)
        if name == "speed" and getattr(f, "velocity", None) is not None:
            return "speed", magnitude(f.velocity)
        if name == "contacts":
            return "contacts", lambda k: contacts(f.position[k], f.radius, box, time=f.time[k])
        if name == "cluster":
            return "cluster (1: largest)", lambda k: clusters(f.position[k], f.radius, box, time=f.time[k])
        if name == "radius":
            return "radius", lambda k: np.broadcast_to(f.radius, (n,))
        if name == "mass" and getattr(f, "mass", None) is not None:
            return "mass", lambda k: np.broadcast_to(f.mass, (n,))
        if name == "dipole" and getattr(f, "dipole", None) is not None:
            def mz(k):
                m = f.dipole[k]
                norm = np.linalg.norm(m, axis=1)
                with np.errstate(invalid="ignore", divide="ignore"):
                    return np.where(norm > 0, m[:, 2] / norm, np.nan)
            return "dipole m_z/m", mz
        if name in VECTORS and getattr(f, name, None) is not None:
            return f"{name} (magnitude)", magnitude(getattr(f, name))
        have = ["id", "cluster", "contacts", "radius"]
        have += ["speed"] * (getattr(f, "velocity", None) is not None) + ["mass"] * (getattr(f, "mass", None) is not None)
        have += [v for v in ("dipole",) + VECTORS if getattr(f, v, None) is not None]
        raise ValueError(f"cannot colour by {name!r}: this source has {', '.join(have)} "
                         f"(or pass an (N,) or (T, N) array of values)")

    def _array(self, values):
        f = self.frames
        shape = (len(f.time), f.position.shape[1])
        try:
            array = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"color_by must be a field name or an array of numbers, got {values!r}") from None
        if array.shape == shape[1:]:
            return lambda k: array
        if array.shape == shape:
            return lambda k: array[k]
        raise ValueError(f"a color_by array must have shape (N,) = {shape[1:]} or (T, N) = {shape}, "
                         f"got {array.shape}")

    def _range(self, shown, mask):
        if self.name == "dipole":
            return (-1.0, 1.0)
        values = np.concatenate([self.values(k)[mask(k)] for k in shown])
        values = values[np.isfinite(values)]
        if len(values) == 0:
            return (0.0, 1.0)
        lo, hi = float(values.min()), float(values.max())
        if hi - lo > 1e-12 * max(abs(lo), abs(hi)):
            return (lo, hi)
        pad = 0.05 * abs(lo) if lo != 0 else 0.5  # one value: a range around it, not below 0 if it is not
        low = max(lo - pad, 0.0) if lo >= 0 else lo - pad
        return (low, low + 2 * pad)

    @staticmethod
    def _check_clim(clim):
        try:
            lo, hi = (float(c) for c in clim)
        except (TypeError, ValueError):
            raise ValueError(f"clim must be two numbers (low, high), got {clim!r}") from None
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ValueError(f"clim must be two finite numbers with low < high, got {clim!r}")
        return (lo, hi)

    def _categories(self, shown, mask, cmap):
        """Clusters 1..K in distinct colours, smaller ones (beyond the palette) in light grey."""
        import matplotlib

        count = int(max(self.values(k)[mask(k)].max(initial=0) for k in shown)) + 1
        kinds = min(count, len(CLUSTER_COLOURS) + 1)
        if cmap is None:
            colours = CLUSTER_COLOURS[:kinds] if count <= len(CLUSTER_COLOURS) else \
                np.vstack([CLUSTER_COLOURS, OTHERS])
            self.cmap = matplotlib.colors.ListedColormap(colours / 255.0)
        else:
            self.cmap = matplotlib.colormaps[cmap].resampled(kinds)
        compute = self._compute
        self._compute = lambda k: np.minimum(compute(k), kinds - 1)
        self._cache.clear()
        self.clim, self.n_colors = (-0.5, kinds - 0.5), kinds
        self.annotations = {float(c): str(c + 1) for c in range(kinds)}
        if count > kinds:
            self.annotations[float(kinds - 1)] = f"{kinds}+"


class Framing:
    """Where the spheres are drawn and what the camera fits: the spheres drawn in the frames
    ``span`` (indices, increasing).

    kind : 'all', 'cluster', 'box' or 'bounds' (after 'auto' was resolved); bounds (6,) the region
    to fit; extent (3,) of the framed sphere centres; points (P,3) and reach: what perspective
    views fit (points padded by reach); shift (3,) or None: along periodic axes,
    positions are drawn wrapped into [shift, shift + L) (set when the framed cluster straddles the
    box edge, to draw it in one piece); outline (6,) or None: the box to outline.
    """

    def __init__(self, frames, frame, bounds, mask, span, reach, subset=None):
        self.frames = frames
        self.box = getattr(frames, "box", None)
        self.shift = None
        ref = span[-1]  # the last frame shown: where 'auto' and 'cluster' look
        #: a deforming box (its outline drawn at each frame's lengths); the box's lengths as framed: a deforming
        #: box's largest over the frames shown
        self.moving = self.box is not None and getattr(self.box, "deform", None) is not None
        self.size = None if self.box is None else np.max(self.box.size_at(np.asarray(frames.time, dtype=np.float64)[
            list(span)]), axis=0) if self.moving else self.box.size
        members = mask(ref)
        if bounds is not None:
            frame = "bounds"
        elif frame == "auto":
            frame = self._auto(ref, members, subset)
        if frame == "box" and self.box is None:
            raise ValueError("frame='box' needs a source with a box (this one has none): "
                             "use frame='all', 'cluster' or bounds=")
        # the spheres the camera aims at (among those drawn): the cluster's, or all
        members = self._cluster(ref, members) if frame == "cluster" else np.ones_like(members)
        self.kind, self.members = frame, members
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for j in span:  # running extremes: no copy of all frames
            pos = self.place(frames.position[j][members & mask(j)])
            if len(pos):
                lo, hi = np.minimum(lo, pos.min(axis=0)), np.maximum(hi, pos.max(axis=0))
        if not np.all(np.isfinite(lo)):
            raise ValueError("the subset selects no sphere in the frames shown")
        self.extent = hi - lo
        if frame == "bounds":
            self.bounds = bounds
        elif frame == "box":
            self.bounds = np.ravel(np.column_stack([np.zeros(3), self.size]))
        else:
            self.bounds = np.ravel(np.column_stack([lo - reach, hi + reach]))
        # points to fit in perspective views: the bounds' corners, or a sample of the framed centres
        # (first, middle and last frame of the span) to be padded by ``reach``
        self.points = np.array(np.meshgrid(*self.bounds.reshape(3, 2), indexing="ij")).reshape(3, -1).T
        self.reach = 0.0
        if frame in ("all", "cluster"):
            sample = []
            for j in {span[0], span[len(span) // 2], ref}:
                pos = self.place(frames.position[j][members & mask(j)])
                sample.append(pos[::max(1, len(pos) // 2000)])
            self.points, self.reach = np.concatenate(sample), reach
        self.outline = None
        if self.box is not None:
            corner = np.zeros(3) if self.shift is None else self.shift
            self.outline = np.ravel(np.column_stack([corner, corner + self.size]))

    def outline_at(self, k):
        """The box's outline at frame k (a deforming box's lengths then), as pyvista bounds."""
        corner = np.zeros(3) if self.shift is None else self.shift
        return np.ravel(np.column_stack([corner, corner + self.box.size_at(float(self.frames.time[k]))]))

    def place(self, position):
        """Positions (..., 3) as drawn (re-wrapped about ``shift`` along periodic axes)."""
        if self.shift is None:
            return position
        position = np.array(position, dtype=np.float64)
        for a in np.flatnonzero(self.box.periodic):
            position[..., a] = self.shift[a] + np.mod(position[..., a] - self.shift[a], self.size[a])
        return position

    def _largest(self, k, members):
        """Mask of the largest cluster among the spheres ``members`` of frame k."""
        index = np.flatnonzero(members)
        if len(index) == 0:
            raise ValueError("the subset selects no sphere in the last frame shown")
        radius = np.broadcast_to(self.frames.radius, members.shape)[index]
        label = clusters(self.frames.position[k][index], radius, self.box, time=self.frames.time[k])
        largest = np.zeros_like(members)
        largest[index[label == 0]] = True
        return largest

    def _auto(self, k, members, subset):
        """'box' with a box and no subset when the spheres fill most of it (BOX_FILL); else 'cluster'
        when the largest cluster holds most spheres drawn and the rest would shrink it (or there is
        no rest); else 'all'."""
        if self.box is not None and subset is None:
            pos = self.frames.position[k][members]
            span = np.ptp(pos, axis=0) + 2.0 * float(np.max(self.frames.radius)) if len(pos) else np.zeros(3)
            if np.all(span >= BOX_FILL * self.size):
                return "box"
            return "all"
        largest = self._cluster(k, members)
        size, n = int(largest.sum()), int(members.sum())
        pos, r = self.place(self.frames.position[k]), float(np.max(self.frames.radius))
        extent_all = np.ptp(pos[members], axis=0).max() + 2 * r
        extent_cluster = np.ptp(pos[largest], axis=0).max() + 2 * r
        if size >= 2 and size > CLUSTER_SHARE * n and (size == n or extent_all > CLUSTER_SPREAD * extent_cluster):
            return "cluster"
        self.shift = None
        return "all"

    def _cluster(self, k, members):
        largest = self._largest(k, members)
        if self.box is not None and np.any(self.box.periodic):
            # along periodic axes where the cluster straddles the edge, centre the drawn cell on it
            pos = self.frames.position[k][largest]
            shift = np.zeros(3)
            for a in np.flatnonzero(self.box.periodic):
                size = self.size[a]
                angle = 2 * np.pi * pos[:, a] / size
                centre = size * np.arctan2(np.sin(angle).mean(), np.cos(angle).mean()) / (2 * np.pi)
                moved = np.mod(pos[:, a] - (centre - size / 2), size)
                if np.ptp(moved) < np.ptp(np.mod(pos[:, a], size)) - 1e-9 * size:
                    shift[a] = centre - size / 2
            if np.any(shift != 0):
                self.shift = shift
        return largest


class Style:
    """How frames look (see :func:`demkit.viz.snapshot` for the meaning of each argument)."""

    def __init__(self, trail=None, window_size=(960, 720), background="white", arrows=True,
                 view="auto", label=True, frame="auto", bounds=None, zoom=1.0, color_by=None,
                 cmap=None, clim=None, subset=None, sphere_resolution=None, color_label=None):
        if view not in ("auto", "xy", "xz", "yz", "iso"):
            raise ValueError(f"view must be 'auto', 'xy', 'xz', 'yz' or 'iso', got {view!r}")
        if trail is not None and (not np.isfinite(trail) or trail < 0):
            raise ValueError(f"trail must be a non-negative time (0: no trails), got {trail}")
        if cmap is not None:
            import matplotlib

            if cmap not in matplotlib.colormaps:
                raise ValueError(f"unknown colour map {cmap!r}: use a matplotlib name such as 'viridis', "
                                 f"'plasma', 'coolwarm', 'tab10'")
        self.trail, self.window_size, self.background = trail, tuple(window_size), background
        self.arrows, self.view, self.label = arrows, view, label
        self.frame, self.bounds, self.zoom = check_frame(frame), check_bounds(bounds), check_zoom(zoom)
        if color_label is not None and not isinstance(color_label, str):
            raise ValueError(f"color_label must be a string, got {color_label!r}")
        self.color_by, self.cmap, self.clim, self.subset = color_by, cmap, clim, subset
        self.color_label = color_label
        self.sphere_resolution = sphere_resolution


#: above this many spheres, default trails are as long as the typical sphere takes to move
#: TRAIL_RADII radii (a quarter of the time shown packs a box of moving spheres with lines)
TRAIL_FEW, TRAIL_RADII = 10, 3.0


def default_trail(frames, shown):
    """A quarter of the time from the first frame to the last shown; above TRAIL_FEW spheres at
    most the time the median sphere takes to move TRAIL_RADII radii at its mean speed over the
    frames shown (speeds from the velocities, else from the steps between frames); none above
    1000 spheres."""
    n = frames.position.shape[1]
    if n > 1000:
        return 0.0
    span = float(frames.time[shown[-1]] - frames.time[shown[0] if len(shown) > 1 else 0])
    quarter = 0.25 * span
    if n <= TRAIL_FEW or quarter <= 0:
        return quarter
    first = shown[0] if len(shown) > 1 else 0
    velocity = getattr(frames, "velocity", None)
    if velocity is not None:
        speed = np.linalg.norm(velocity[first:shown[-1] + 1], axis=2).mean(axis=0)
    else:
        d = np.diff(frames.position[first:shown[-1] + 1], axis=0)
        box = getattr(frames, "box", None)
        if box is not None and (box.shear is not None or getattr(box, "deform", None) is not None):  # each step's
            # sliding images or box lengths, at its end
            d = np.stack([box.minimum_image(dk, t) for dk, t in zip(d, frames.time[first + 1:shown[-1] + 1])])
        elif box is not None:
            d = box.minimum_image(d)
        speed = (np.linalg.norm(d, axis=2) / np.diff(frames.time[first:shown[-1] + 1])[:, None]).mean(axis=0)
    typical = float(np.median(speed)) if len(speed) else 0.0
    if not np.isfinite(typical) or typical <= 0:
        return quarter
    return min(quarter, TRAIL_RADII * float(np.median(frames.radius)) / typical)


class Plan:
    """Everything decided for drawing frames ``shown`` of ``frames`` in ``style``: mask(k),
    colouring, framing, trail (time units), view ('xy', 'xz', 'yz' or 'iso')."""

    def __init__(self, frames, style, shown):
        self.frames, self.style, self.shown = frames, style, np.asarray(shown)
        self.trail = style.trail if style.trail is not None else default_trail(frames, shown)
        self.mask = subset_mask(frames, style.subset)
        span = self.shown  # the frames the camera fits: those shown and, with trails, those before
        if self.trail > 0:
            first = int(np.searchsorted(frames.time, frames.time[shown[0]] - self.trail))
            span = np.arange(first, shown[-1] + 1)
        rmax = float(np.max(frames.radius))
        self.dipoles = style.arrows and getattr(frames, "dipole", None) is not None
        reach = rmax * (1.4 if self.dipoles else 1.0)
        self.framing = Framing(frames, style.frame, style.bounds, self.mask, span, reach, style.subset)
        self.colouring = Colouring(frames, style.color_by, style.cmap, style.clim, shown, self.in_view,
                                   self.mask)
        if style.color_label is not None:
            self.colouring.title = style.color_label
        self.view = style.view
        if self.view == "auto":  # a plane view when the framed centres lie in a plane
            flat = int(np.argmin(self.framing.extent))
            self.view = ("yz", "xz", "xy")[flat] if self.framing.extent[flat] <= 0.5 * rmax else "iso"
        # a cluster framed in 3-D is drawn whole and unobstructed: the other spheres only where they
        # lie within its framed region, faded (see drawn); in a plane nothing can hide it
        self.isolate = self.framing.kind == "cluster" and self._in_depth(shown[-1], rmax)

    def _in_depth(self, k, rmax):
        """Do the spheres drawn in frame k spread along the line of sight (more than a diameter)?"""
        pos = self.frames.position[k][self.mask(k)]
        if self.view == "iso":
            return bool(np.ptp(pos, axis=0).min() > 2 * rmax) if len(pos) else False
        normal = {"xy": 2, "xz": 1, "yz": 0}[self.view]
        return bool(np.ptp(pos[:, normal]) > 2 * rmax) if len(pos) else False

    def drawn(self, k):
        """(solid, faded): indices of the spheres drawn in frame k as usual and of those drawn
        faded (see-through context). Only a cluster framed in 3-D has faded ones: its own spheres
        are solid, the others within the framed region faded, the others not drawn."""
        mask = self.mask(k)
        if not self.isolate:
            return np.flatnonzero(mask), np.zeros(0, dtype=np.int64)
        members = mask & self.framing.members
        pos = self.framing.place(self.frames.position[k])
        b = self.framing.bounds
        near = mask & ~members & np.all((pos >= b[0::2]) & (pos <= b[1::2]), axis=1)
        return np.flatnonzero(members), np.flatnonzero(near)

    def in_view(self, k):
        """Mask of the spheres drawn in frame k that the framing aims at (the default colour range
        is taken over these, so spheres far outside the picture do not set it)."""
        framing = self.framing
        if framing.kind == "cluster":
            return self.mask(k) & framing.members
        if framing.kind in ("box", "bounds"):
            pos = framing.place(self.frames.position[k])
            b = framing.bounds
            return self.mask(k) & np.all((pos >= b[0::2]) & (pos <= b[1::2]), axis=1)
        return self.mask(k)
