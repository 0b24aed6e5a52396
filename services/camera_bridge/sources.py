"""Where images come from: a live camera, a video file, or a folder of still images.

One option, ``--camera SPEC``, picks the source (`open_source`):

- a device index (``0``) or a device path (``/dev/video0``): frames as the camera delivers
  them. A camera that is missing or busy is not fatal: the source says so (a clear, counted
  warning) and tries again every `RETRY_S`, so plugging it in or closing the other program
  is enough;
- a video file: played at its own frame rate as a live camera would deliver it: each frame
  is due at ``start + n / fps``; when processing falls behind, the frames already past are
  skipped (counted), as a camera's driver drops frames nobody read. After the end, frames
  with no image keep coming at the video's rate (``--loop`` starts over), like a camera that
  sees nobody;
- a folder of images (``.jpg``, ``.jpeg``, ``.png``, ``.bmp``, ``.webp``), played in name
  order, each one held for ``--hold-s`` at ``--rate-hz`` and followed by ``--gap-s`` with no
  image (a hand that leaves the view between poses). A still image is the same scene on every
  frame of its hold, so the bridge reads it once (`CameraFrame.still`).

An unreadable video file or a folder with no readable image is a configuration error at start,
named with its path.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cbgo.errors import ConfigError

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".webp")
RETRY_S = 2.0
"""How often a missing or busy camera is tried again."""
DEFAULT_VIDEO_FPS = 30.0
"""The rate assumed for a video file that does not state one."""
_DEVICE = re.compile(r"^(?:/dev/video)?(\d+)$")


@dataclass
class CameraFrame:
    """One image as the camera delivered it.

    Attributes:
        captured: when it was captured (Unix seconds).
        image: BGR uint8 (H, W, 3), or None: the camera saw nothing (after a video's end, in
            a folder's gaps).
        still: for a still image, its index in the folder: the same index is the same scene.
        name: what it shows (the file name of a still image), for logs and benchmarks.
    """

    captured: float
    image: np.ndarray | None
    still: int | None = None
    name: str = ""


class SourceStatus:
    """What a source tells the status: frames read and dropped, and its state."""

    def __init__(self) -> None:
        self.read = 0
        self.dropped = 0
        self.unreadable = 0
        self.state = "starting"

    def as_dict(self) -> dict:
        """Returns the counters as plain data."""
        return {"read": self.read, "dropped": self.dropped, "unreadable": self.unreadable,
                "state": self.state}


def _cv2():
    from cbgo.services.camera_bridge.tracker import import_mediapipe

    import_mediapipe()  # the same install hint when the extra is missing
    import cv2

    return cv2


def open_source(spec: str, hold_s: float = 2.0, gap_s: float = 0.0, rate_hz: float = 30.0,
                loop: bool = False, warn=None):
    """Returns the source ``--camera SPEC`` names (see the module rules).

    Args:
        spec: a device index or path, a video file or a folder of images.
        hold_s: folder: how long each image is shown.
        gap_s: folder: how long no image is shown after each.
        rate_hz: folder: the frame rate.
        loop: video or folder: start over at the end.
        warn: ``warn(kind, message)`` for a counted warning (a missing or busy camera).

    Raises:
        ConfigError: a file or folder that cannot be played, named with the fix.
    """
    match = _DEVICE.match(spec.strip())
    if match:
        return DeviceSource(int(match.group(1)), warn or (lambda kind, message: None))
    path = Path(spec).expanduser()
    if path.is_dir():
        return FolderSource(path, hold_s, gap_s, rate_hz, loop)
    if path.is_file():
        return VideoSource(path, loop)
    raise ConfigError(f"--camera {spec!r} is neither a camera (an index such as 0, or "
                      "/dev/video0), nor a video file, nor a folder of images")


class DeviceSource:
    """A live camera, by index: ``/dev/video<index>`` on Linux."""

    kind = "device"

    def __init__(self, index: int, warn):
        self.index, self.warn = index, warn
        self.name = f"/dev/video{index}"
        self.status = SourceStatus()
        self.fps: float | None = None

    def _open(self):
        cv2 = _cv2()
        device = Path(self.name)
        if not device.exists():
            self.status.state = "no camera"
            self.warn("no-camera", f"no camera at {self.name}: plug one in, or pass --camera "
                      "with one that exists (ls /dev/video*; in Docker: devices: "
                      f"[{self.name}]), a video file or a folder of images; trying again "
                      f"every {RETRY_S:.0f} s")
            return None
        capture = cv2.VideoCapture(self.index)
        ok = capture.isOpened() and capture.read()[0]
        if not ok:
            capture.release()
            self.status.state = "busy"
            self.warn("camera-busy", f"camera {self.name} cannot be read: another program may "
                      f"be using it (fuser {self.name}), or this user may lack access (the "
                      f"'video' group); trying again every {RETRY_S:.0f} s")
            return None
        self.fps = capture.get(cv2.CAP_PROP_FPS) or None
        self.status.state = "live"
        return capture

    def frames(self, stop: threading.Event) -> Iterator[CameraFrame]:
        """Yields frames as the camera delivers them; reopens it when it fails."""
        while not stop.is_set():
            capture = self._open()
            if capture is None:
                stop.wait(RETRY_S)
                continue
            try:
                while not stop.is_set():
                    ok, image = capture.read()
                    if not ok:
                        self.status.state = "lost"
                        self.warn("camera-lost", f"camera {self.name} stopped delivering "
                                  "frames (unplugged, or taken by another program); reopening")
                        break
                    self.status.read += 1
                    yield CameraFrame(time.time(), image)
            finally:
                capture.release()


class VideoSource:
    """A video file played at its own frame rate, as a live camera would deliver it.

    Raises:
        ConfigError: the file cannot be opened or decoded.
    """

    kind = "video"

    def __init__(self, path: Path, loop: bool = False):
        cv2 = _cv2()
        self.path, self.loop, self.name = path, loop, path.name
        self.status = SourceStatus()
        capture = cv2.VideoCapture(str(path))
        ok = capture.isOpened() and capture.read()[0]
        fps = capture.get(cv2.CAP_PROP_FPS) if ok else 0.0
        capture.release()
        if not ok:
            raise ConfigError(f"cannot read the video {path}: not a video OpenCV can decode "
                              "(try converting it: ffmpeg -i FILE -c:v libx264 out.mp4), or "
                              "not a video at all")
        self.fps = fps if 1.0 <= fps <= 240.0 else DEFAULT_VIDEO_FPS

    def frames(self, stop: threading.Event) -> Iterator[CameraFrame]:
        """Yields the due frames on the video's clock, skipping those already past."""
        cv2 = _cv2()
        start, n = time.time(), 0
        while not stop.is_set():
            capture = cv2.VideoCapture(str(self.path))
            self.status.state = "playing"
            try:
                while not stop.is_set():
                    due = int((time.time() - start) * self.fps)
                    while n < due:  # a live camera drops what nobody read in time
                        if not capture.grab():
                            break
                        n += 1
                        self.status.dropped += 1
                    ok, image = capture.read()
                    if not ok:
                        break
                    captured = start + n / self.fps
                    n += 1
                    self.status.read += 1
                    stop.wait(max(0.0, captured - time.time()))
                    yield CameraFrame(captured, image)
            finally:
                capture.release()
            if not self.loop:
                break
        self.status.state = "finished"
        yield from _empty_frames(stop, start + n / self.fps, self.fps)


class FolderSource:
    """Still images played in name order, each held for ``hold_s`` at ``rate_hz``.

    Raises:
        ConfigError: no image in the folder can be read.
    """

    kind = "folder"

    def __init__(self, folder: Path, hold_s: float, gap_s: float, rate_hz: float,
                 loop: bool = False):
        cv2 = _cv2()
        self.folder, self.hold_s, self.gap_s, self.loop = folder, hold_s, gap_s, loop
        self.fps = rate_hz
        self.name = folder.name
        self.status = SourceStatus()
        self.images: list[tuple[str, np.ndarray]] = []
        for path in sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES):
            image = cv2.imread(str(path))
            if image is None:
                self.status.unreadable += 1
                continue
            self.images.append((path.name, image))
        if not self.images:
            raise ConfigError(f"no readable image in {folder} (looked for "
                              f"{', '.join(IMAGE_SUFFIXES)})")

    def frames(self, stop: threading.Event) -> Iterator[CameraFrame]:
        """Yields each image for its hold, then its gap, on absolute deadlines."""
        dt = 1.0 / self.fps
        start, n = time.time(), 0
        per_image, per_gap = round(self.hold_s * self.fps), round(self.gap_s * self.fps)
        while not stop.is_set():
            for index, (name, image) in enumerate(self.images):
                self.status.state = f"showing {name}"
                for k in range(per_image + per_gap):
                    captured = start + n * dt
                    n += 1
                    stop.wait(max(0.0, captured - time.time()))
                    if stop.is_set():
                        return
                    self.status.read += 1
                    yield (CameraFrame(captured, image, index, name) if k < per_image
                           else CameraFrame(captured, None, name=name))
            if not self.loop:
                break
        self.status.state = "finished"
        yield from _empty_frames(stop, start + n * dt, self.fps)


def _empty_frames(stop: threading.Event, t: float, fps: float) -> Iterator[CameraFrame]:
    """Frames with no image at ``fps`` from ``t`` on: a camera that sees nobody."""
    while not stop.is_set():
        stop.wait(max(0.0, t - time.time()))
        if stop.is_set():
            return
        yield CameraFrame(t, None)
        t += 1.0 / fps
