"""Off-screen rendering without a display, chosen by a probe in a child process.

VTK (>= 9.4 wheels) picks its OpenGL window class at run time from the environment variable
``VTK_DEFAULT_OPENGL_WINDOW``: ``vtkXOpenGLRenderWindow`` needs an X server,
``vtkEGLRenderWindow`` renders through EGL (on a machine without a GPU, Mesa's llvmpipe via
``libEGL_mesa``), ``vtkOSOpenGLRenderWindow`` through ``libOSMesa``. A missing or broken library
can abort or segfault the process, so each candidate is first tried in a child Python process that
renders a small sphere; the first that yields a non-blank image is set for this process. When none
works, :class:`RenderingUnavailable` (a RuntimeError) says what was tried and what to install.

A probe that succeeded is written to the environment (:data:`PROBED_VARIABLE`), so the processes this
one starts (a sweep's workers, a script run by the tests) trust it instead of probing again: each
probe is a child Python that imports VTK and renders, 2-3 s.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys

WINDOW_VARIABLE = "VTK_DEFAULT_OPENGL_WINDOW"
#: candidate window classes, tried in order after the display's own (when there is a display)
HEADLESS_WINDOWS = ("vtkEGLRenderWindow", "vtkOSOpenGLRenderWindow")
#: set by a successful probe for this process and the processes it starts: "window|renderer|variable"
PROBED_VARIABLE = "DEMKIT_RENDERING_PROBED"
PROBE_TIMEOUT = 120.0  # seconds for one probe (first VTK import can be slow on a cold disk)

PROBE_CODE = r"""
import pyvista as pv
plotter = pv.Plotter(off_screen=True, window_size=(64, 64))
plotter.add_mesh(pv.Sphere(), color="red")
image = plotter.screenshot(return_img=True)
window = plotter.ren_win.GetClassName()
renderer = ""
for line in plotter.ren_win.ReportCapabilities().splitlines():
    if "renderer string" in line:
        renderer = line.split(":", 1)[1].strip()
plotter.close()
print("DEMKIT-PROBE", window, float(image.std()), renderer, sep="|")
"""


class RenderingUnavailable(RuntimeError):
    """Off-screen rendering is impossible here (no working OpenGL: EGL, OSMesa or X)."""


_chosen = None  # dict describing the working backend, once probed


def _has_display():
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def candidates():
    """Window classes to try, in order (None: VTK's own default). A user's explicit
    VTK_DEFAULT_OPENGL_WINDOW is the only candidate."""
    if os.environ.get(WINDOW_VARIABLE):
        return [os.environ[WINDOW_VARIABLE]]
    if not sys.platform.startswith("linux"):
        return [None]
    return ([None] if _has_display() else []) + list(HEADLESS_WINDOWS)


def probe(window):
    """Render a test image in a child process with ``window`` (a VTK window class or None).

    Returns (ok, detail): detail is a dict (window, renderer) when ok, else a reason string.
    """
    env = dict(os.environ)
    env.pop(WINDOW_VARIABLE, None)
    if window:
        env[WINDOW_VARIABLE] = window
    try:
        done = subprocess.run([sys.executable, "-c", PROBE_CODE], env=env, capture_output=True,
                              text=True, timeout=PROBE_TIMEOUT)
    except subprocess.TimeoutExpired:
        return False, f"no image after {PROBE_TIMEOUT:.0f} s"
    line = next((l for l in done.stdout.splitlines() if l.startswith("DEMKIT-PROBE|")), None)
    if done.returncode == 0 and line:
        _, klass, std, renderer = line.split("|", 3)
        if float(std) > 0:
            return True, {"window": klass, "renderer": renderer, "variable": window}
        return False, "the test image was blank"
    if done.returncode < 0:
        try:
            why = f"crashed with {signal.Signals(-done.returncode).name}"
        except ValueError:
            why = f"killed by signal {-done.returncode}"
    else:
        why = f"exited with status {done.returncode}"
    tail = [l for l in done.stderr.strip().splitlines() if l.strip()][-2:]
    return False, why + (": " + " / ".join(t.strip()[-200:] for t in tail) if tail else "")


def ensure_rendering():
    """Make sure off-screen rendering works in this process, choosing the OpenGL window class.

    Returns a dict: window (VTK class), renderer (OpenGL renderer string), variable (value set
    for VTK_DEFAULT_OPENGL_WINDOW or None). Probes once per process. Raises RenderingUnavailable.
    """
    global _chosen
    if _chosen is None:
        _chosen = _inherited()
    if _chosen is not None:
        return dict(_chosen)
    failures = []
    for window in candidates():
        ok, detail = probe(window)
        if ok:
            if window:
                os.environ[WINDOW_VARIABLE] = window
            os.environ[PROBED_VARIABLE] = "|".join((detail["window"], detail["renderer"], window or ""))
            _chosen = detail
            return dict(detail)
        failures.append(f"{window or 'VTK default window'}: {detail}")
    raise RenderingUnavailable(
        "demkit.viz cannot render off-screen on this machine. Tried "
        + "; ".join(failures)
        + ". To render without a display install Mesa's EGL (Debian/Ubuntu: apt-get install libegl1 "
          "libgl1-mesa-dri) or OSMesa (apt-get install libosmesa6), or run under xvfb-run. The VTK "
          "series themselves need no rendering: open the .pvd in ParaView.")


def _inherited():
    """The probe of a parent process (PROBED_VARIABLE), if it chose what this environment would try
    first (the same VTK_DEFAULT_OPENGL_WINDOW, or none with the same display); else None."""
    text = os.environ.get(PROBED_VARIABLE, "")
    if text.count("|") != 2:
        return None
    klass, renderer, variable = text.split("|")
    first = candidates()[0] if candidates() else None
    if variable and os.environ.get(WINDOW_VARIABLE) in (None, "", variable):
        os.environ[WINDOW_VARIABLE] = variable
        return {"window": klass, "renderer": renderer, "variable": variable}
    if not variable and first is None:  # VTK's default window (a display), and there still is one
        return {"window": klass, "renderer": renderer, "variable": None}
    return None


def rendering_info():
    """Describe the rendering backend (probing if needed): dict, or raises RenderingUnavailable."""
    return ensure_rendering()
