"""camera-bridge: hand frames from an ordinary webcam, a video file or a folder of images.

Behaviour (the contract is services/camera_bridge/README.md):
- one source per process, ``--camera``: a camera (index or /dev/videoN), a video file played
  at its own rate as a live camera delivers it, or a folder of still images (`sources`);
- each image goes through MediaPipe Hands (`tracker`); each hand becomes a metric contract
  hand in the Leap frame (`geometry`): distance from the camera matrix, axes from the camera's
  placement, the user's left and right from MediaPipe's handedness and the image's mirroring;
- one ``cbgo/hands/frame`` per camera frame (``source`` "leap": a live sensor in the Leap
  frame; ``device`` "camera" unless set), so every downstream service works unchanged;
  ``cbgo/user`` on change and every 2 s, as leap-bridge;
- ``cbgo/camera/preview`` at ``--preview-hz`` (2 by default, 0: never): the image made small
  (``--preview-width``), as JPEG, with the hands' landmarks in image coordinates, so a page can
  show what the camera sees (the web page draws it beside the 3D hand);
- what goes wrong is counted and said clearly, and never stops the stream: no camera or a busy
  one (tried again), no hand in view, more hands than ``--max-hands``, an image too dark,
  a frame that fails; an unreadable video file or image folder is a configuration error at
  start.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cbgo import keys
from cbgo.config import described as _help
from cbgo.errors import ConfigError
from cbgo.runtime import Service, main_for
from cbgo.services.camera_bridge import geometry
from cbgo.services.camera_bridge.smoothing import OneEuro
from cbgo.services.camera_bridge.sources import CameraFrame, open_source
from cbgo.transform import default_to_base, parse_to_base

USER_REPEAT_S = 2.0  # republish the user so that late joiners learn it
NO_HAND_SAY_S = 3.0
"""A hand out of view this long is said once in the log (then again after it came back)."""
VELOCITY_SMOOTHING = 0.5
"""Weight of the newest finite difference in the palm velocity (exponential average)."""
PREVIEW_QUALITY = 70  # JPEG quality of the preview: 320 × 240 in about 10-20 kB
CURL_CHECK = 0.1
"""Fingertips this far (per knuckle span) to one side of the palm say which side the palm
faces, and so the hand's chirality (`side_check`); flatter hands are not checked."""


@dataclass
class CameraBridgeSettings:
    """Settings of the camera-bridge (flags ``--camera`` ... or env ``CBGO_CAMERA`` ...)."""

    camera: str = field(default="0", metadata=_help(
        "the source: a camera index or /dev/videoN, a video file (played at its own rate), "
        "or a folder of images (played in name order, each held --hold-s)"))
    placement: str = field(default="front", metadata=_help(
        "where the camera looks from: front (facing the user across the desk) or side (the "
        "way the user looks: head-mounted, over the shoulder)"))
    camera_position: list[float] | None = field(default=None, metadata=_help(
        "the camera's centre in the Leap frame, mm (x,y,z); default front 0,200,-450, "
        "side 0,450,350"))
    camera_pitch_deg: float | None = field(default=None, metadata=_help(
        "tilt of the camera below the horizontal, degrees; default front 0, side 30"))
    fov_deg: float = field(default=geometry.DEFAULT_FOV_DEG, metadata=_help(
        "horizontal field of view, degrees, used without --calibration (sets the distance)"))
    calibration: str | None = field(default=None, metadata=_help(
        "camera calibration, JSON or YAML: camera_matrix (3x3), image_size [w, h], "
        "optional dist_coeffs (OpenCV's order)"))
    smooth: bool = field(default=True, metadata=_help(
        "filter the landmarks over time (One-Euro): steady when still, quick when moving"))
    mirrored: bool = field(default=False, metadata=_help(
        "the images are mirrored (a selfie view): MediaPipe's handedness is taken as is"))
    max_hands: int = field(default=1, metadata=_help(
        "hands published per frame (the most confident); more in view are counted and said"))
    model_complexity: int = field(default=1, metadata=_help(
        "MediaPipe's hand landmark model: 0 (faster) or 1 (more accurate)"))
    min_detection: float = field(default=0.5, metadata=_help(
        "MediaPipe's palm detection threshold, 0..1"))
    min_brightness: float = field(default=20.0, metadata=_help(
        "mean grey level (0-255) under which an image with no hand is reported too dark"))
    hold_s: float = field(default=2.0, metadata=_help("folder: seconds each image is shown"))
    gap_s: float = field(default=0.0, metadata=_help(
        "folder: seconds with no image after each (a hand leaving the view)"))
    rate_hz: float = field(default=30.0, metadata=_help("folder: frame rate, Hz (1-120)"))
    loop: bool = field(default=False, metadata=_help("video or folder: start over at the end"))
    user: str = field(default="user1", metadata=_help("operator id published on cbgo/user"))
    device: str = field(default="camera", metadata=_help("device label in frames"))
    sensor_position: list[float] = field(default_factory=lambda: [1.0, 0.0, 0.0], metadata=_help(
        "the Leap frame's origin in the robot base frame, m (x,y,z)"))
    sensor_yaw_deg: float = field(default=0.0, metadata=_help(
        "Leap frame rotation about the vertical, degrees (0: user faces the robot along -x)"))
    to_base: list[float] | None = field(default=None, metadata=_help(
        "full Leap(mm)->base(m) transform, 16 numbers row-major; overrides sensor_*"))
    preview_hz: float = field(default=2.0, metadata=_help(
        "camera images a second on cbgo/camera/preview, with the landmarks (0: none; at most "
        "10)"))
    preview_width: int = field(default=320, metadata=_help(
        "width of the preview images, pixels (80-1280; the height keeps the aspect)"))
    wait_for: list[str] = field(default_factory=list, metadata=_help(
        "services whose liveliness to wait for before reading the source (a video or a "
        "folder then starts when its readers are up)"))

    def __post_init__(self):
        if self.placement not in geometry.PLACEMENTS:
            raise ConfigError(f"placement {self.placement!r} is not one of "
                              f"{', '.join(geometry.PLACEMENTS)}")
        if self.camera_position is not None and len(self.camera_position) != 3:
            raise ConfigError("camera_position needs 3 numbers (mm)")
        if not 10.0 <= self.fov_deg <= 170.0:
            raise ConfigError(f"fov_deg={self.fov_deg} must be within 10-170°")
        if not 1 <= self.max_hands <= 16:
            raise ConfigError(f"max_hands={self.max_hands} must be within 1-16")
        if self.model_complexity not in (0, 1):
            raise ConfigError("model_complexity must be 0 or 1")
        if not 0.0 < self.min_detection < 1.0:
            raise ConfigError(f"min_detection={self.min_detection} must be within 0-1")
        if not 0.0 <= self.min_brightness <= 255.0:
            raise ConfigError(f"min_brightness={self.min_brightness} must be within 0-255")
        if not 1.0 <= self.rate_hz <= 120.0:
            raise ConfigError(f"rate_hz={self.rate_hz} must be within 1-120 Hz")
        if self.hold_s <= 0.0 or self.gap_s < 0.0:
            raise ConfigError("hold_s must be > 0 and gap_s >= 0")
        if len(self.sensor_position) != 3:
            raise ConfigError("sensor_position needs 3 numbers (m)")
        if not 0.0 <= self.preview_hz <= 10.0:
            raise ConfigError(f"preview_hz={self.preview_hz} must be within 0-10 (0: none)")
        if not 80 <= self.preview_width <= 1280:
            raise ConfigError(f"preview_width={self.preview_width} must be within 80-1280 px")

    def camera_pose(self) -> geometry.CameraPose:
        """Returns where the camera is and which way it looks."""
        position = self.camera_position or geometry.DEFAULT_POSITION_MM[self.placement]
        pitch = (geometry.DEFAULT_PITCH_DEG[self.placement] if self.camera_pitch_deg is None
                 else self.camera_pitch_deg)
        return geometry.CameraPose(self.placement, tuple(position), pitch)

    def transform(self) -> np.ndarray:
        """Returns the 4×4 Leap(mm)→base(m) transform these settings describe."""
        if self.to_base is not None:
            return parse_to_base(self.to_base)
        return default_to_base(self.sensor_position, self.sensor_yaw_deg)


@dataclass
class Calibration:
    """A camera matrix measured at one image size, and the lens distortion."""

    matrix: np.ndarray
    image_size: tuple[int, int]
    distortion: np.ndarray | None = None


def load_calibration(path: str) -> Calibration:
    """Reads a calibration file (JSON or YAML; see the ``calibration`` setting).

    Raises:
        ConfigError: missing, unreadable, or not a camera matrix.
    """
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text())
        matrix = np.asarray(data["camera_matrix"], dtype=float).reshape(3, 3)
        width, height = (int(v) for v in data["image_size"])
        dist = data.get("dist_coeffs")
        distortion = None if dist is None else np.asarray(dist, dtype=float).reshape(-1)
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as e:
        raise ConfigError(f"cannot read the calibration {path}: {e!r}; it needs camera_matrix "
                          "(3x3), image_size [w, h] and optionally dist_coeffs") from None
    if not (np.all(np.isfinite(matrix)) and matrix[0, 0] > 0 and matrix[1, 1] > 0
            and width > 0 and height > 0):
        raise ConfigError(f"calibration {path}: the camera matrix needs positive focal lengths")
    return Calibration(matrix, (width, height), distortion)


class Lens:
    """The camera matrix for each image size, and undistortion of landmarks."""

    def __init__(self, fov_deg: float, calibration: Calibration | None):
        self.fov_deg, self.calibration = fov_deg, calibration
        self._matrices: dict[tuple[int, int], np.ndarray] = {}

    def matrix(self, width: int, height: int) -> np.ndarray:
        """Returns the camera matrix of an image of this size."""
        size = (width, height)
        if size not in self._matrices:
            cal = self.calibration
            self._matrices[size] = (geometry.camera_matrix(width, height, self.fov_deg)
                                    if cal is None else
                                    geometry.scale_matrix(cal.matrix, cal.image_size, size))
        return self._matrices[size]

    def undistort(self, image_px: np.ndarray, K: np.ndarray) -> np.ndarray:
        """Returns landmarks where a distortion-free lens would show them."""
        if self.calibration is None or self.calibration.distortion is None:
            return image_px
        import cv2

        points = cv2.undistortPoints(image_px.reshape(-1, 1, 2).astype(np.float64), K,
                                     self.calibration.distortion, P=K)
        return points.reshape(-1, 2)


class Track:
    """One hand seen on successive frames: its id, its landmark filter and palm velocity."""

    def __init__(self, hand_id: int, palm: np.ndarray, t: float, smooth: bool = True):
        self.id, self.palm, self.t = hand_id, palm, t
        self.velocity = np.zeros(3)
        self.smooth = OneEuro() if smooth else (lambda points, _t: points)

    def update(self, palm: np.ndarray, t: float) -> np.ndarray:
        """Moves the track to a new palm position; returns the smoothed velocity (mm/s)."""
        dt = t - self.t
        if dt > 1e-4:
            step = (palm - self.palm) / dt
            self.velocity = VELOCITY_SMOOTHING * step + (1 - VELOCITY_SMOOTHING) * self.velocity
        self.palm, self.t = palm, t
        return self.velocity


def swap_side(label: str) -> str:
    """Returns the other side of a MediaPipe label, in contract spelling."""
    return "left" if label.lower() == "right" else "right"


def user_side(label: str, mirrored: bool) -> str:
    """Returns the user's side of a hand MediaPipe labelled on a (mirrored or not) image.

    MediaPipe's label assumes a mirrored image (a selfie view): on a camera's own, unmirrored
    image its "Right" is the user's left hand, whichever way the camera looks.
    """
    return label.lower() if mirrored else swap_side(label)


def shape_side(world_m: np.ndarray) -> str | None:
    """Returns the side whose hand has this 3-D shape as the image shows it, or None (flat).

    The fingertips lie on the palm's side of the palm; in the palm's frame (`geometry.
    palm_axes`) that is +normal for a right hand's shape and −normal for a left one's (the
    model hand, `geometry.reference_palm`).
    """
    w = world_m
    axes, span = geometry.palm_axes(w[geometry.WRIST], w[geometry.INDEX_MCP],
                                    w[geometry.MIDDLE_MCP], w[geometry.PINKY_MCP])
    tips = np.array([w[m + 3] - w[m] for m in geometry.FINGER_MCPS])
    curl = float((tips @ axes[2]).mean() / span)
    if abs(curl) < CURL_CHECK:
        return None
    right_palm_sign = np.sign(geometry.reference_palm("right").normal[2])
    return "right" if np.sign(curl) == right_palm_sign else "left"


class FrameTimes:
    """Processing time per camera frame (ms), over a window, for the status."""

    def __init__(self, window: int = 600):
        self.ms: deque[float] = deque(maxlen=window)

    def add(self, seconds: float) -> None:
        """Records one frame's processing time."""
        self.ms.append(seconds * 1e3)

    def summary(self) -> dict:
        """Returns p50, p95 and max (ms) over the window."""
        if not self.ms:
            return {}
        a = np.asarray(self.ms)
        return {"p50_ms": float(np.percentile(a, 50)), "p95_ms": float(np.percentile(a, 95)),
                "max_ms": float(a.max()), "frames": len(a)}


class CameraBridge(Service):
    """Hands from a camera."""

    name = "camera-bridge"
    description = ("Publishes cbgo/hands/frame from an ordinary webcam, a video file or a folder "
                   "of images (MediaPipe Hands), as leap-bridge does from a Leap; also "
                   "cbgo/user.")
    settings_class = CameraBridgeSettings

    def __init__(self, settings: CameraBridgeSettings):
        super().__init__(settings)
        self.to_base = settings.transform()
        self.pose = settings.camera_pose()
        self.seq = 0
        self.times = FrameTimes()
        self.problems: dict[str, int] = {"no_hand": 0, "too_dark": 0, "extra_hands": 0,
                                         "failed": 0, "camera": 0}
        self.side_check = {"checked": 0, "disagreed": 0}
        self._tracks: dict[str, Track] = {}
        self._next_id = 1
        self._still: tuple[int | None, list] = (None, [])
        self._last_user: tuple[str | None, float] = (None, 0.0)
        self._hand_gone_since: float | None = None
        self._no_hand_said = False
        self._thread: threading.Thread | None = None
        self._landmarks: list[tuple[str, np.ndarray]] = []  # (side, 21 × 2 px) of the last image
        self._last_preview = -1e9

    def setup(self, ctx) -> None:
        """Opens the source and the tracker, declares outputs, starts the camera thread."""
        from cbgo.services.camera_bridge.tracker import HandTracker

        s = self.settings
        self.ctx = ctx
        self.lens = Lens(s.fov_deg, load_calibration(s.calibration) if s.calibration else None)
        self.source = open_source(s.camera, s.hold_s, s.gap_s, s.rate_hz, s.loop,
                                  warn=self._camera_problem)
        self.tracker = HandTracker(max_hands=s.max_hands + 1,
                                   model_complexity=s.model_complexity,
                                   still_images=self.source.kind == "folder",
                                   min_detection=s.min_detection)
        ctx.publishes(keys.HANDS_FRAME, keys.USER, keys.CAMERA_PREVIEW)
        self._thread = threading.Thread(target=self._run, name="camera", daemon=True)
        self._thread.start()

    def _camera_problem(self, kind: str, message: str) -> None:
        self.problems["camera"] += 1
        self.ctx.rejects.warning(kind, message)

    # ------------------------------------------------------------ camera thread

    def _run(self) -> None:
        for name in self.settings.wait_for:
            self.ctx.log.info("waiting for %s", name)
            while not self.ctx.wait_for_service(name, 1.0):
                if self.ctx.stopping.is_set():
                    return
        for frame in self.source.frames(self.ctx.stopping):
            if self.ctx.stopping.is_set():
                return
            try:
                hands = self.hands_of(frame)
            except Exception as e:  # noqa: BLE001 - one bad frame never stops the stream
                self.problems["failed"] += 1
                self.ctx.counters.error("frame", repr(e))
                self.ctx.rejects.warning("frame-failed", f"a camera frame failed: {e!r}")
                hands = []
            self._publish(hands, frame.captured)
            self._preview(frame)

    def hands_of(self, frame: CameraFrame) -> list[dict]:
        """Returns the contract hands one camera frame shows (and says what went wrong)."""
        if frame.image is None:  # the camera sees nobody: every hand has left
            self._tracks.clear()
            self._still = (None, [])
            self._landmarks = []
            return []
        if frame.still is not None:
            if frame.still == self._still[0]:
                return self._restamped(self._still[1], frame.captured)
            self._tracks.clear()  # another image, another scene
        import cv2

        started = time.perf_counter()
        detections = self.tracker.detect(cv2.cvtColor(frame.image, cv2.COLOR_BGR2RGB))
        hands = self._hands(detections, frame)
        self.times.add(time.perf_counter() - started)
        if frame.still is not None:
            self._still = (frame.still, hands)
        return hands

    def _restamped(self, hands: list[dict], t: float) -> list[dict]:
        """The hands of a still image again: same ids, at rest."""
        for hand in hands:
            self._tracks[hand["side"]].update(np.asarray(hand["palm_position"]), t)
        return [{**hand, "palm_velocity": [0.0, 0.0, 0.0]} for hand in hands]

    def _hands(self, detections: list, frame: CameraFrame) -> list[dict]:
        self._landmarks = []
        if not detections:
            self._no_hand(frame)
            return []
        self._hand_gone_since, self._no_hand_said = None, False
        limit = self.settings.max_hands
        if len(detections) > limit:
            self.problems["extra_hands"] += 1
            self.ctx.rejects.warning("extra-hands", f"{len(detections)} hands in view: "
                                     f"publishing the {limit} most confident; keep only the "
                                     "gesturing hand in view (or raise --max-hands)")
        height, width = frame.image.shape[:2]
        K = self.lens.matrix(width, height)
        hands, seen = [], set()
        for detection in detections[:limit]:
            side = user_side(detection.label, self.settings.mirrored)
            if side in seen:
                continue  # MediaPipe gave one side twice: keep the more confident
            seen.add(side)
            self._landmarks.append((side, detection.image_px))
            self._check_side(detection, side)
            hands.append(self._hand(detection, side, K, frame.captured))
        for gone in set(self._tracks) - seen:
            del self._tracks[gone]
        return hands

    def _hand(self, detection, side: str, K: np.ndarray, t: float) -> dict:
        image_px = self.lens.undistort(detection.image_px, K)
        shift = geometry.solve_translation(detection.world_m, image_px, K)
        points = self.pose.to_leap((detection.world_m + shift) * 1000.0)
        track = self._tracks.get(side)
        if track is None:
            track = self._tracks[side] = Track(self._next_id, points[geometry.WRIST], t,
                                               self.settings.smooth)
            self._next_id += 1
        hand = geometry.leap_hand(track.smooth(points, t), side, track.id, detection.score)
        hand["palm_velocity"] = track.update(np.asarray(hand["palm_position"]), t).tolist()
        return hand

    def _check_side(self, detection, side: str) -> None:
        """Counts frames whose hand shape contradicts MediaPipe's label (see `shape_side`)."""
        shown = shape_side(detection.world_m)
        if shown is None:
            return
        self.side_check["checked"] += 1
        # the image shows the mirror of the labelled hand (MediaPipe assumes a selfie view)
        if shown == detection.label.lower():
            self.side_check["disagreed"] += 1
            self.ctx.rejects.warning("side-check", f"MediaPipe called a {shown} hand's shape "
                                     f"{detection.label}: the side may be wrong on this frame")

    def _no_hand(self, frame: CameraFrame) -> None:
        self._tracks.clear()
        grey = float(frame.image[::8, ::8].mean())
        if grey < self.settings.min_brightness:
            self.problems["too_dark"] += 1
            self.ctx.rejects.warning("too-dark", f"the image is too dark to find a hand (mean "
                                     f"grey {grey:.0f} < {self.settings.min_brightness:.0f} of "
                                     "255): light the hand, or lower --min-brightness")
            return
        self.problems["no_hand"] += 1
        now = frame.captured
        if self._hand_gone_since is None:
            self._hand_gone_since = now
        elif not self._no_hand_said and now - self._hand_gone_since >= NO_HAND_SAY_S:
            self._no_hand_said = True
            self.ctx.log.info("no hand in view for %.0f s (%s): hold one hand up in the "
                              "camera's view, fingers up, about 30-60 cm away", NO_HAND_SAY_S,
                              frame.name or self.source.name)

    def _publish(self, hands: list[dict], captured: float) -> None:
        self.ctx.publish(keys.HANDS_FRAME, keys.HANDS_FRAME.message(
            ts=captured, seq=self.seq, source="leap", device=self.settings.device,
            hands=hands, to_base=self.to_base.reshape(-1).tolist()))
        self.seq += 1
        user, (last_user, last_time) = self.settings.user, self._last_user
        if user != last_user or captured - last_time >= USER_REPEAT_S:
            self.ctx.publish(keys.USER, keys.USER.message(ts=captured, user=user))
            self._last_user = (user, captured)

    def _preview(self, frame: CameraFrame) -> None:
        """Publishes the image, small, with the landmarks, when one is due (`preview_hz`)."""
        s = self.settings
        if (s.preview_hz <= 0.0 or frame.image is None
                or frame.captured - self._last_preview < 1.0 / s.preview_hz):
            return
        import cv2

        height, width = frame.image.shape[:2]
        size = (s.preview_width, max(1, round(height * s.preview_width / width)))
        ok, jpeg = cv2.imencode(".jpg", cv2.resize(frame.image, size,
                                                   interpolation=cv2.INTER_AREA),
                                [cv2.IMWRITE_JPEG_QUALITY, PREVIEW_QUALITY])
        if not ok:
            return
        self._last_preview = frame.captured
        hands = [{"side": side, "points": np.round(px / [width, height], 4).tolist()}
                 for side, px in self._landmarks]
        self.ctx.publish(keys.CAMERA_PREVIEW, keys.CAMERA_PREVIEW.message(
            ts=frame.captured, seq=self.seq - 1, width=size[0], height=size[1],
            jpeg=jpeg.tobytes(), hands=hands))

    def status_extra(self) -> dict:
        """Adds the source, per-frame time, problems and the handedness check."""
        return {"camera": self.settings.camera, "source": self.source.kind,
                "frames": self.seq, "reading": self.source.status.as_dict(),
                "frame_time": self.times.summary(), "problems": dict(self.problems),
                "side_check": dict(self.side_check)}

    def shutdown(self) -> None:
        """Stops the camera thread (the runtime has set `stopping`)."""
        if self._thread is not None:
            self._thread.join(timeout=1.0)


main = main_for(CameraBridge)


if __name__ == "__main__":
    main()
