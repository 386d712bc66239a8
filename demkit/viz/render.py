"""Drawing frames with pyvista: spheres to scale, dipole arrows, fading trails, a time label.

pyvista is imported only inside these functions (after the backend probe has chosen the OpenGL
window class), never at ``import demkit``.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

#: one colour per particle (cycled), RGB 0..255
PALETTE = np.array([[31, 119, 180], [214, 39, 40], [44, 160, 44], [255, 127, 14], [148, 103, 189],
                    [140, 86, 75], [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207]],
                   dtype=np.uint8)


def load(source):
    """Frames to draw from ``source``: a Trajectory, a SeriesData, a .pvd or its folder, or one
    .vtu frame. Returns an object with time (T,), position (T,N,3), dipole (T,N,3) or None,
    radius and ids (N,)."""
    from ..io import SeriesData, read_frame, read_series

    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if path.suffix == ".vtu":
            if not path.exists():
                raise ValueError(f"no such frame file: {path}")
            pos, data = read_frame(path)
            fields = {k: data[k][None] for k in ("dipole",) if k in data}
            ids = data.get("id", np.arange(len(pos)))
            radius = data.get("radius", np.ones(len(pos)))
            return SeriesData(np.array([_frame_time(path)]), pos[None], fields, ids, radius,
                              data.get("mass"), [path], None)
        return read_series(path)
    for attr in ("time", "position", "radius", "ids"):
        if not hasattr(source, attr):
            raise TypeError(f"cannot draw a {type(source).__name__}: pass a Trajectory, a series "
                            f"(.pvd file or folder) or a .vtu frame")
    return source


def default_trail(frames, shown):
    """A quarter of the time from the first frame to the last shown (none above 1000 particles)."""
    if frames.position.shape[1] > 1000:
        return 0.0
    if len(shown) == 1:
        return 0.25 * float(frames.time[shown[0]] - frames.time[0])
    return 0.25 * float(frames.time[shown[-1]] - frames.time[shown[0]])


def _frame_time(path):
    """The time of a .vtu frame from a .pvd beside it that lists it (NaN when none does)."""
    from ..io import read_pvd

    for pvd in sorted(path.parent.glob("*.pvd")):
        try:
            for time, file in read_pvd(pvd):
                if file.resolve() == path.resolve():
                    return time
        except ValueError:
            continue
    return float("nan")


class Style:
    """How frames look. trail: length of the fading trails in time units (0: none);
    window_size: pixels (width, height); background: colour; arrows: draw dipole arrows;
    view: 'auto', 'xy', 'xz', 'yz' or 'iso'; label: show the time."""

    def __init__(self, trail=None, window_size=(960, 720), background="white", arrows=True,
                 view="auto", label=True, sphere_resolution=None):
        self.trail, self.window_size, self.background = trail, tuple(window_size), background
        self.arrows, self.view, self.label = arrows, view, label
        self.sphere_resolution = sphere_resolution
        if view not in ("auto", "xy", "xz", "yz", "iso"):
            raise ValueError(f"view must be 'auto', 'xy', 'xz', 'yz' or 'iso', got {view!r}")
        if trail is not None and (not np.isfinite(trail) or trail < 0):
            raise ValueError(f"trail must be a non-negative time (0: no trails), got {trail}")


class FrameDrawer:
    """An off-screen pyvista plotter that draws frame k of ``frames`` on demand."""

    def __init__(self, frames, style, shown):
        import pyvista as pv

        self.pv, self.frames, self.style = pv, frames, style
        n = frames.position.shape[1]
        self.colours = PALETTE[np.arange(n) % len(PALETTE)]
        self.trail = style.trail if style.trail is not None else default_trail(frames, shown)
        res = style.sphere_resolution or (32 if n <= 100 else 20 if n <= 1000 else 12 if n <= 20000 else 6)
        self.sphere = pv.Sphere(radius=1.0, theta_resolution=res, phi_resolution=res)
        arrow_res = 20 if n <= 1000 else 6
        self.arrow = pv.Arrow(start=(-1.35, 0, 0), direction=(1, 0, 0), scale=2.7, tip_length=0.3,
                              tip_radius=0.14, shaft_radius=0.055, tip_resolution=arrow_res,
                              shaft_resolution=arrow_res)
        self.plotter = pv.Plotter(off_screen=True, window_size=list(style.window_size))
        if n > 1000:  # multisampling costs ~4x with a software renderer (llvmpipe): measured
            self.plotter.ren_win.SetMultiSamples(0)
        self.plotter.set_background(style.background)
        self._actors = {}
        self._place_camera(shown)

    def _place_camera(self, shown):
        first = shown[0]
        if self.trail > 0:
            first = int(np.searchsorted(self.frames.time, self.frames.time[shown[0]] - self.trail))
        pos = self.frames.position[first:shown[-1] + 1].reshape(-1, 3)
        rmax = float(np.max(self.frames.radius))
        reach = rmax * (1.4 if self.style.arrows and getattr(self.frames, "dipole", None) is not None else 1.0)
        lo, hi = pos.min(axis=0) - reach, pos.max(axis=0) + reach
        view = self.style.view
        if view == "auto":
            extent = np.ptp(pos, axis=0)  # of the centres
            flat = int(np.argmin(extent))
            view = ("yz", "xz", "xy")[flat] if extent[flat] <= 0.5 * rmax else "iso"
        p = self.plotter
        if view == "iso":
            # an invisible box spanning everything shown fixes the camera for the whole animation
            box = self.pv.Box(bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
            p.add_mesh(box, opacity=0.0, name="bounds")
            p.view_isometric()
            p.reset_camera()
            return
        # plane views: parallel projection scaled so the bounds fill the window, with a margin
        normal, up = {"xy": (2, 1), "xz": (1, 2), "yz": (0, 2)}[view]
        across = 3 - normal - up
        centre = (lo + hi) / 2
        width, height = self.style.window_size
        half = max((hi[up] - lo[up]) / 2, (hi[across] - lo[across]) / 2 * height / width) * 1.06
        eye = centre.copy()
        sign = -1.0 if view == "xz" else 1.0  # keep the first axis pointing right
        depth = float(np.max(hi - lo)) + half
        eye[normal] += sign * 10 * depth
        up_vector = np.zeros(3)
        up_vector[up] = 1.0
        p.camera.position, p.camera.focal_point, p.camera.up = eye, centre, up_vector
        p.enable_parallel_projection()
        p.camera.parallel_scale = half
        p.camera.clipping_range = (8 * depth, 12 * depth)

    def draw(self, k):
        """Draw frame k and return the image, (height, width, 3) uint8."""
        pv, f = self.pv, self.frames
        centres = pv.PolyData(np.ascontiguousarray(f.position[k], dtype=np.float64))
        centres.point_data["radius"] = np.asarray(f.radius, dtype=np.float64)
        centres.point_data["colour"] = self.colours
        self._show("spheres", centres.glyph(geom=self.sphere, scale="radius", orient=False, factor=1.0),
                   scalars="colour", rgb=True, smooth_shading=True)
        dipole = getattr(f, "dipole", None)
        if self.style.arrows and dipole is not None:
            centres.point_data["dipole"] = np.asarray(dipole[k], dtype=np.float64)
            self._show("arrows", centres.glyph(geom=self.arrow, orient="dipole", scale="radius", factor=1.0),
                       color="#202020")
        self._show("trails", self._trails(k), scalars="colour", rgb=True, line_width=3)
        if self.style.label:
            text = f"t = {f.time[k]:.6g}" if np.isfinite(f.time[k]) else Path(f.files[k]).name
            if "label" not in self._actors:
                colour = "black" if pv.Color(self.style.background).int_rgb[1] > 127 else "white"
                height = self.style.window_size[1]
                size = max(8, round(14 * height / 720))
                self._actors["label"] = self.plotter.add_text(
                    text, position=(size, height - 2.6 * size), font_size=size, color=colour)
            else:
                self._actors["label"].SetInput(text)
        self.plotter.render()
        return self.plotter.screenshot(return_img=True)

    def _show(self, name, mesh, **options):
        """Show ``mesh`` as actor ``name``: added on first use, then its data replaced in place
        (one render per frame instead of one per added actor). None hides the actor."""
        actor = self._actors.get(name)
        if mesh is None:
            if actor is not None:
                actor[1].SetVisibility(False)
            return
        if actor is None:
            self._actors[name] = (mesh, self.plotter.add_mesh(mesh, reset_camera=False, **options))
        else:
            actor[0].copy_from(mesh, deep=False)
            actor[1].SetVisibility(True)

    def _trails(self, k):
        """Poly-lines through the last ``trail`` time units, fading into the background."""
        if self.trail <= 0 or k == 0:
            return None
        f = self.frames
        first = int(np.searchsorted(f.time, f.time[k] - self.trail))
        if k - first < 1:
            return None
        pts = f.position[first:k + 1]                      # (m, N, 3)
        m, n = pts.shape[:2]
        age = (f.time[k] - f.time[first:k + 1]) / self.trail  # 0 (now) .. 1 (oldest)
        bg = np.array(self.pv.Color(self.style.background).int_rgb, dtype=float)
        weight = (1.0 - np.clip(age, 0, 1))[None, :, None]
        colours = bg + (self.colours[:, None, :].astype(float) - bg) * weight  # (N, m, 3)
        lines = np.hstack([np.full((n, 1), m), np.arange(n * m).reshape(n, m)]).ravel()
        mesh = self.pv.PolyData(np.ascontiguousarray(pts.transpose(1, 0, 2).reshape(-1, 3)), lines=lines)
        mesh.point_data["colour"] = colours.reshape(-1, 3).astype(np.uint8)
        return mesh

    def close(self):
        self.plotter.close()
