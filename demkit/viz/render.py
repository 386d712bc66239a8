"""Drawing frames with pyvista: spheres to scale coloured by a field (with a colour bar), dipole
arrows, fading trails, the box outline, the walls of a series written with them, a time label.
What to draw is decided in :mod:`.plan`.

pyvista is imported only inside these functions (after the backend probe has chosen the OpenGL
window class), never at ``import demkit``.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

BAR_SPACE = 0.16  # fraction of the window width kept free for the colour bar
#: how far the colour bar's title reaches left of BAR_SPACE (fraction of the window width)
TITLE_OVERHANG = 0.07
#: opacity of the faded spheres around a cluster framed in 3-D (Plan.drawn)
FADED_OPACITY = 0.12
#: opacity of the walls (demkit.io.walls): the spheres behind a wall stay in sight
WALL_OPACITY = 0.25


def load(source):
    """Frames to draw from ``source``: a Trajectory, a SeriesData, a .pvd or its folder, or one
    .vtu frame. Returns an object with time (T,), position (T,N,3), radius and ids (N,) and, when
    the source has them, velocity, dipole, ... (T,N,3), image (T,N,3) and box."""
    from ..io import VECTOR_FIELDS, SeriesData, read_frame, read_series

    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if path.suffix == ".vtu":
            if not path.exists():
                raise ValueError(f"no such frame file: {path}")
            pos, data = read_frame(path)
            fields = {k: data[k][None] for k in VECTOR_FIELDS if k in data}
            ids = data.get("id", np.arange(len(pos)))
            radius = data.get("radius", np.ones(len(pos)))
            image = data["image"][None] if "image" in data else None
            time, box = _beside(path)
            return SeriesData(np.array([time]), pos[None], fields, ids, radius, data.get("mass"), [path],
                              None, image=image, box=box)
        return read_series(path)
    for attr in ("time", "position", "radius", "ids"):
        if not hasattr(source, attr):
            raise TypeError(f"cannot draw a {type(source).__name__}: pass a Trajectory, a series "
                            f"(.pvd file or folder) or a .vtu frame")
    return source


def _beside(path):
    """(time, box) of a .vtu frame from a .pvd beside it that lists it ((NaN, None) when none does)."""
    from ..io import read_pvd
    from ..io.pvd import read_box

    for pvd in sorted(path.parent.glob("*.pvd")):
        try:
            for time, file in read_pvd(pvd):
                if file.resolve() == path.resolve():
                    return time, read_box(pvd)
        except ValueError:
            continue
    return float("nan"), None


class FrameDrawer:
    """An off-screen pyvista plotter that draws frame k of ``plan.frames`` on demand."""

    def __init__(self, plan):
        import pyvista as pv

        self.pv, self.plan, self.frames, self.style = pv, plan, plan.frames, plan.style
        style = plan.style
        n = self.frames.position.shape[1]
        res = style.sphere_resolution or (32 if n <= 100 else 20 if n <= 1000 else 12 if n <= 20000 else 6)
        self.sphere = pv.Sphere(radius=1.0, theta_resolution=res, phi_resolution=res)
        arrow_res = 20 if n <= 1000 else 6
        self.arrow = pv.Arrow(start=(-1.35, 0, 0), direction=(1, 0, 0), scale=2.7, tip_length=0.3,
                              tip_radius=0.14, shaft_radius=0.055, tip_resolution=arrow_res,
                              shaft_resolution=arrow_res)
        self.plotter = pv.Plotter(off_screen=True, window_size=list(style.window_size))
        # edges smoothed by FXAA (a pass over the finished image) instead of multisampling, which
        # costs 2-3x the frame with a software renderer (llvmpipe): 256 spheres at 800x600 took
        # 157-265 ms a frame with 8x multisampling, 77-90 ms with FXAA, which looks the same (measured)
        self.plotter.ren_win.SetMultiSamples(0)
        self.plotter.renderer.UseFXAAOn()
        self.plotter.set_background(style.background)
        self.ink = "black" if pv.Color(style.background).int_rgb[1] > 127 else "white"
        self._actors = {}
        self.drawn = {}  # set by draw
        self._radius = np.broadcast_to(np.asarray(self.frames.radius, dtype=np.float64), (n,))
        outline = plan.framing.outline
        if outline is not None and not plan.isolate and not plan.framing.moving:  # around a cluster in 3-D, its
            # lines would cross it (a deforming box's: drawn with each frame)
            self.plotter.add_mesh(pv.Box(bounds=outline).outline(), color=self.ink, opacity=0.45,
                                  line_width=1, reset_camera=False)
        self._place_camera()

    def _place_camera(self):
        b = self.plan.framing.bounds
        lo, hi = b[0::2], b[1::2]
        centre = (lo + hi) / 2
        p, view, zoom = self.plotter, self.plan.view, self.style.zoom
        # with a colour bar, the framed region is centred in the window's left 84 %
        reserve = BAR_SPACE if self.plan.colouring.bar else 0.0
        p.camera.SetWindowCenter(reserve, 0.0)
        if view == "iso":
            p.camera.focal_point, p.camera.position, p.camera.up = centre, centre + 1.0, (0.0, 0.0, 1.0)
            p.renderer.ResetCamera(*b)  # fits the bounds' enclosing sphere; then fit the points:
            framing = self.plan.framing
            right, up = self._screen_axes()
            pad = framing.reach * np.array([right, -right, up, -up])
            x, y, _ = self._ndc((framing.points[:, None, :] + pad[None]).reshape(-1, 3))
            # NDC x of the window centre is -reserve; the free part spans 1 - reserve either side
            fit = 0.9 / max(np.abs(x + reserve).max() / (1 - reserve), np.abs(y).max())
            p.camera.Zoom(fit * zoom)
            return
        # plane views: parallel projection scaled so the bounds fill the window, with a margin
        normal, up = {"xy": (2, 1), "xz": (1, 2), "yz": (0, 2)}[view]
        across = 3 - normal - up
        width, height = self.style.window_size
        width = width * (1 - reserve)
        half = max((hi[up] - lo[up]) / 2, (hi[across] - lo[across]) / 2 * height / width) * 1.12
        eye = centre.copy()
        sign = -1.0 if view == "xz" else 1.0  # keep the first axis pointing right
        eye[normal] += sign * 10 * (float(np.max(hi - lo)) + half)
        up_vector = np.zeros(3)
        up_vector[up] = 1.0
        p.camera.position, p.camera.focal_point, p.camera.up = eye, centre, up_vector
        p.enable_parallel_projection()
        p.camera.parallel_scale = half / zoom

    def draw(self, k):
        """Draw frame k and return the image, (height, width, 3) uint8."""
        pv, f, plan = self.pv, self.frames, self.plan
        index, faded = plan.drawn(k)
        faded = faded[self._clear_of_overlays(plan.framing.place(f.position[k][faded]), self._radius[faded])]
        self.drawn = {"spheres": index, "faded": faded}  # the spheres of each actor, in glyph order
        colouring = plan.colouring
        centres = self._centres(k, index)
        spheres = centres.glyph(geom=self.sphere, scale="radius", orient=False, factor=1.0) if len(index) else None
        height = self.style.window_size[1]
        size = self._font_size()
        bar = dict(title=colouring.title, vertical=True, position_x=0.85, position_y=0.12, width=0.05,
                   height=0.7, color=self.ink, title_font_size=round(1.4 * size), label_font_size=round(1.2 * size),
                   n_labels=0 if colouring.annotations else colouring.n_labels, fmt="%.3g", fill=False)
        self._show("spheres", spheres, scalars="value", cmap=colouring.cmap, clim=colouring.clim,
                   n_colors=colouring.n_colors, annotations=colouring.annotations,
                   show_scalar_bar=colouring.bar, scalar_bar_args=bar, nan_color="grey",
                   smooth_shading=True)
        context = self._centres(k, faded).glyph(geom=self.sphere, scale="radius", orient=False, factor=1.0) \
            if len(faded) else None
        self._show("faded", context, scalars="value", cmap=colouring.cmap, clim=colouring.clim,
                   n_colors=colouring.n_colors, show_scalar_bar=False, nan_color="grey", opacity=FADED_OPACITY,
                   smooth_shading=True)
        if plan.dipoles:
            centres.point_data["dipole"] = np.asarray(f.dipole[k][index], dtype=np.float64)
            arrows = centres.glyph(geom=self.arrow, orient="dipole", scale="radius", factor=1.0) if len(index) else None
            self._show("arrows", arrows, color="#202020")
        self._show("trails", self._trails(k, index), scalars="colour", rgb=True, line_width=3)
        if plan.framing.moving and not plan.isolate:  # a deforming box: its outline at this frame
            self._show("outline", pv.Box(bounds=plan.framing.outline_at(k)).outline(), color=self.ink, opacity=0.45,
                       line_width=1)
        walls = self._walls(k)
        self._show("walls", walls, color="#8a8a8a", opacity=WALL_OPACITY, smooth_shading=False)
        # their rims as lines: a plane seen edge-on in a plane view is a line, not nothing
        rims = walls.extract_feature_edges(boundary_edges=True, feature_edges=False, manifold_edges=False,
                                           non_manifold_edges=False) if walls is not None else None
        self._show("wall rims", rims, color="#505050", line_width=2)
        if self.style.label:
            text = time_label(f.time, k) if np.isfinite(f.time[k]) else Path(f.files[k]).name
            if "label" not in self._actors:
                self._actors["label"] = self.plotter.add_text(
                    text, position=(size, height - 2.6 * size), font_size=size, color=self.ink)
            else:
                self._actors["label"].SetInput(text)
        self.plotter.renderer.ResetCameraClippingRange()
        self.plotter.render()
        return self.plotter.screenshot(return_img=True)

    def _clear_of_overlays(self, points, radius):
        """Mask of the spheres (centres ``points``, radii ``radius``) whose picture lies in front
        of the camera and clear of the colour bar and the time label."""
        if len(points) == 0:
            return np.zeros(0, dtype=bool)
        width, height = self.style.window_size
        right, up = self._screen_axes()
        x, y, w = self._ndc(points)
        rx = np.abs(self._ndc(points + radius[:, None] * right)[0] - x)
        ry = np.abs(self._ndc(points + radius[:, None] * up)[1] - y)
        keep = w > 0
        if self.plan.colouring.bar:
            keep &= x + rx < 2 * (1 - BAR_SPACE - TITLE_OVERHANG) - 1
        if self.style.label:
            size = self._font_size()
            keep &= ~((x - rx < -1 + 2 * 12 * size / width) & (y + ry > 1 - 2 * 3.2 * size / height))
        return keep

    def _font_size(self):
        """Font size of the time label and the colour bar's labels (grows with the window)."""
        return max(8, round(14 * self.style.window_size[1] / 720))

    def _screen_axes(self):
        """Unit vectors along the picture's right and up directions, in scene coordinates."""
        camera = self.plotter.camera
        forward = np.asarray(camera.GetDirectionOfProjection())
        right = np.cross(forward, np.asarray(camera.GetViewUp(), dtype=float))
        right /= np.linalg.norm(right)
        return right, np.cross(right, forward)

    def _ndc(self, points):
        """Normalised device coordinates x, y (-1..1 across the window) and the homogeneous w
        (> 0: in front of the camera) of ``points`` (P, 3)."""
        width, height = self.style.window_size
        matrix = self.plotter.camera.GetCompositeProjectionTransformMatrix(width / height, -1, 1)
        m = np.array([[matrix.GetElement(i, j) for j in range(4)] for i in range(4)])
        h = np.c_[points, np.ones(len(points))] @ m.T
        return h[:, 0] / h[:, 3], h[:, 1] / h[:, 3], h[:, 3]

    def _centres(self, k, index):
        """Point cloud of the spheres ``index`` of frame k, with their radius and colour value."""
        f = self.frames
        centres = self.pv.PolyData(np.ascontiguousarray(self.plan.framing.place(f.position[k][index]),
                                                        dtype=np.float64))
        centres.point_data["radius"] = self._radius[index]
        centres.point_data["value"] = self.plan.colouring.values(k)[index]
        return centres

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

    def _trails(self, k, index):
        """Line segments through the last ``trail`` time units of the spheres ``index``, fading
        into the background; segments that cross a periodic boundary are left out."""
        plan, f = self.plan, self.frames
        if plan.trail <= 0 or k == 0 or len(index) == 0:
            return None
        first = int(np.searchsorted(f.time, f.time[k] - plan.trail))
        if k - first < 1:
            return None
        pts = plan.framing.place(f.position[first:k + 1][:, index])  # (m, n, 3)
        m, n = pts.shape[:2]
        pts = np.ascontiguousarray(pts.transpose(1, 0, 2))            # (n, m, 3): particle-major
        start = (np.arange(n)[:, None] * m + np.arange(m - 1)[None, :]).ravel()
        keep = np.ones(len(start), dtype=bool)
        box = getattr(f, "box", None)
        if box is not None:
            jump = np.abs(np.diff(pts, axis=1)).reshape(-1, 3) > plan.framing.size / 2
            keep = ~np.any(jump & box.periodic, axis=1)
        start = start[keep]
        if len(start) == 0:
            return None
        age = (f.time[k] - f.time[first:k + 1]) / plan.trail  # 0 (now) .. 1 (oldest)
        bg = np.array(self.pv.Color(self.style.background).int_rgb, dtype=float)
        weight = (1.0 - np.clip(age, 0, 1))[None, :, None]
        own = plan.colouring.rgb(plan.colouring.values(k)[index]).astype(float)
        colours = bg + (own[:, None, :] - bg) * weight  # (n, m, 3)
        lines = np.column_stack([np.full(len(start), 2), start, start + 1]).ravel()
        mesh = self.pv.PolyData(pts.reshape(-1, 3), lines=lines)
        mesh.point_data["colour"] = colours.reshape(-1, 3).astype(np.uint8)
        return mesh

    def _walls(self, k):
        """The walls of frame k, or None: a series' walls file of that frame (written with it), or a
        trajectory's walls where their motion has them at its time (demkit.io.walls)."""
        walls, f = getattr(self.frames, "walls", None), self.frames
        if not walls:
            return None
        if isinstance(walls[0], tuple):  # a Trajectory's (number, wall) pairs
            from ..io.walls import region, surfaces
            lo, hi = region(f.position[k], f.radius, getattr(f, "box", None))
            points, connectivity, offsets, cells = surfaces(walls, float(f.time[k]), lo, hi)
            faces = np.insert(connectivity, np.concatenate([[0], offsets[:-1]]), np.diff(offsets, prepend=0))
            mesh = self.pv.PolyData(points, faces=faces)
            mesh.cell_data["wall"] = cells["wall"]
            return mesh
        return self.pv.read(walls[k]) if walls[k] is not None else None

    def close(self):
        self.plotter.close()


def time_label(times, k):
    """"t = ..." for frame ``k`` of ``times``, with the decimals that tell frames apart (two significant
    digits of their smallest spacing): 0.299998 of frames 0.01 apart reads "t = 0.300"."""
    t = float(times[k])
    steps = np.diff(np.asarray(times, dtype=np.float64))
    steps = steps[np.isfinite(steps) & (steps > 0)]
    if not len(steps) or abs(t) >= 1e7:
        return f"t = {t:.6g}"
    decimals = max(0, math.ceil(-math.log10(float(steps.min())) - 1e-6) + 1)  # (0.00999999 is 0.01)
    return f"t = {round(t, decimals) + 0.0:.{decimals}f}" if decimals <= 12 else f"t = {t:.6g}"  # (+ 0.0: no -0)

