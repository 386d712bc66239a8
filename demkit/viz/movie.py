"""Encoding rendered frames: GIF with Pillow, MP4 (H.264) with imageio-ffmpeg's bundled ffmpeg.

An animation is written to ``<name>.partial.<suffix>`` beside the output and renamed to the output
only when it is complete: an interrupted or failed render (:meth:`MovieWriter.abort`) removes the
partial file and leaves any existing file of the output's name as it was.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

FORMATS = (".gif", ".mp4")


def check_path(path):
    """The output Path, ValueError unless it ends in .gif or .mp4 and can be written in its folder."""
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise ValueError(f"animations are written as .gif or .mp4, got {path}")
    if not path.parent.is_dir():
        raise ValueError(f"folder {path.parent} does not exist")
    from ..outputs import check_writable
    return check_writable(path, "animation")  # before rendering, not after


class MovieWriter:
    """Collects frames (H,W,3 uint8 arrays) and writes them to ``path`` at ``fps`` frames/s."""

    def __init__(self, path, fps):
        if not np.isfinite(fps) or fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        self.path, self.fps = check_path(path), float(fps)
        self.partial = self.path.with_name(f"{self.path.stem}.partial{self.path.suffix}")
        self.gif = self.path.suffix.lower() == ".gif"
        self._frames, self._ffmpeg = [], None
        if not self.gif:
            try:
                import imageio_ffmpeg  # noqa: F401
            except ImportError:
                raise RuntimeError("writing .mp4 needs the imageio-ffmpeg package "
                                   "(pip install imageio-ffmpeg), or write a .gif") from None

    def add(self, image):
        image = np.ascontiguousarray(image[..., :3], dtype=np.uint8)
        if self.gif:
            from PIL import Image

            # 255 colours by Pillow's median cut: 28-84 ms an 800x600 frame; its fast octree (3-5 ms) draws
            # visible contour bands across the shaded spheres (docs/progress.md)
            self._frames.append(Image.fromarray(image).quantize(colors=255, method=Image.Quantize.MEDIANCUT,
                                                                dither=Image.Dither.NONE))
            return
        if self._ffmpeg is None:
            import imageio_ffmpeg

            height, width = image.shape[:2]
            self._ffmpeg = imageio_ffmpeg.write_frames(
                str(self.partial), (width, height), fps=self.fps, codec="libx264",
                pix_fmt_out="yuv420p", quality=7, macro_block_size=2,
                ffmpeg_log_level="error")
            self._ffmpeg.send(None)
        self._ffmpeg.send(image)

    def close(self):
        """Write the file (GIF) or finish the stream (MP4), then give it the output's name; returns
        the path. Interrupted or failed here, it removes the partial file and raises again."""
        try:
            if self.gif and self._frames:
                first, rest = self._frames[0], self._frames[1:]
                first.save(self.partial, save_all=True, append_images=rest, loop=0,
                           duration=max(20, int(round(1000.0 / self.fps))), disposal=1, optimize=False)
            elif self._ffmpeg is not None:
                self._ffmpeg.close()
                self._ffmpeg = None
            if self.partial.exists():
                with open(self.partial, "rb+") as fh:
                    os.fsync(fh.fileno())
                os.replace(self.partial, self.path)
        except BaseException:
            self.abort()
            raise
        return self.path

    def abort(self):
        """Stop without writing the output: end ffmpeg, drop the frames, remove the partial file."""
        self._frames = []
        if self._ffmpeg is not None:
            ffmpeg, self._ffmpeg = self._ffmpeg, None
            try:
                ffmpeg.close()
            except Exception:  # ffmpeg already gone (killed, broken pipe): nothing to finish
                pass
        self.partial.unlink(missing_ok=True)
