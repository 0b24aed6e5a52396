"""Offscreen rendering of the simulated world to PNG (headless: ``MUJOCO_GL=egl`` or osmesa).

Rules:
- one `mujoco.Renderer` per (model, width, height), created on first use, on the thread that
  renders (an OpenGL context belongs to its thread); a new world closes the old renderers;
- shadows and reflections are off by default (they cost most of a software-rendered frame);
- PNG encoding is plain zlib, no imaging library needed.
"""

from __future__ import annotations

import struct
import zlib

import mujoco
import numpy as np

from cbgo.services.mujoco_sim.build import CAMERAS

MAX_SIZE = 1920


class RenderError(Exception):
    """The image cannot be rendered (unknown camera, size, no OpenGL)."""


def encode_png(rgb: np.ndarray) -> bytes:
    """Returns the PNG bytes of an (H, W, 3) uint8 image."""
    height, width, _ = rgb.shape
    raw = np.concatenate([np.zeros((height, 1), np.uint8), rgb.reshape(height, -1)], axis=1)

    def chunk(kind: bytes, body: bytes) -> bytes:
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + chunk(b"IEND", b""))


class Camera:
    """Renders PNG images of one model's data from its named cameras.

    Args:
        shadows: render shadows and reflections (slow without a GPU).
    """

    def __init__(self, shadows: bool = False):
        self.shadows = shadows
        self._model: mujoco.MjModel | None = None
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}

    def close(self) -> None:
        """Frees the OpenGL contexts."""
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()

    def _renderer(self, model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
        if model is not self._model:
            self.close()
            self._model = model
        key = (width, height)
        if key not in self._renderers:
            try:
                self._renderers[key] = mujoco.Renderer(model, height, width)
            except Exception as e:  # noqa: BLE001 - any GL failure is reported as one
                raise RenderError(f"cannot render ({type(e).__name__}: {e}); set MUJOCO_GL=egl "
                                  "or MUJOCO_GL=osmesa for headless rendering") from e
        return self._renderers[key]

    def png(self, model: mujoco.MjModel, data: mujoco.MjData, camera: str, width: int,
            height: int) -> bytes:
        """Returns a PNG of the world seen from a named camera.

        Raises:
            RenderError: unknown camera, bad size, or no OpenGL context.
        """
        if camera not in CAMERAS:
            raise RenderError(f"unknown camera {camera!r} (cameras: {', '.join(CAMERAS)})")
        if not (16 <= width <= MAX_SIZE and 16 <= height <= MAX_SIZE):
            raise RenderError(f"image size {width}x{height} is outside 16..{MAX_SIZE} pixels")
        renderer = self._renderer(model, width, height)
        renderer.update_scene(data, camera=camera)
        flags = renderer.scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = self.shadows
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = self.shadows
        return encode_png(renderer.render())
