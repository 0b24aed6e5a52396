"""PNG encoding and offscreen rendering (headless EGL; skipped where there is no OpenGL)."""

import struct
import zlib

import numpy as np
import pytest

from cbgo.services.mujoco_sim import scenes
from cbgo.services.mujoco_sim.render import Camera, RenderError, encode_png


def _decode_png(data: bytes) -> np.ndarray:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, {}
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        assert struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])[0] == (
            zlib.crc32(kind + body) & 0xFFFFFFFF)
        chunks[kind] = chunks.get(kind, b"") + body
        pos += 12 + length
    width, height = struct.unpack(">II", chunks[b"IHDR"][:8])
    raw = np.frombuffer(zlib.decompress(chunks[b"IDAT"]), np.uint8).reshape(height, -1)
    assert np.all(raw[:, 0] == 0)  # filter type "none" on every row
    return raw[:, 1:].reshape(height, width, 3)


def test_a_png_round_trips_its_pixels():
    image = np.random.default_rng(0).integers(0, 256, (7, 5, 3), dtype=np.uint8)
    assert np.array_equal(_decode_png(encode_png(image)), image)


def test_a_named_camera_renders_the_scene(fixed_scene):
    loaded = scenes.load(fixed_scene)
    camera = Camera()
    try:
        png = camera.png(loaded.sim.model, loaded.sim.data, "workspace", 96, 64)
    except RenderError as e:
        pytest.skip(f"no headless OpenGL (MUJOCO_GL=egl) here: {e}")
    finally:
        camera.close()
    image = _decode_png(png)
    assert image.shape == (64, 96, 3) and image.std() > 10  # a picture, not a blank frame
    with pytest.raises(RenderError, match="unknown camera 'nowhere'"):
        camera.png(loaded.sim.model, loaded.sim.data, "nowhere", 96, 64)
