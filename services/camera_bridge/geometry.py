"""From MediaPipe's 21 hand landmarks to a metric contract hand in the Leap frame.

Pure numpy: nothing here reads a camera or runs a model, so every rule is unit-tested.

1. **Distance** (`solve_translation`). MediaPipe gives each hand twice: image landmarks (pixels)
   and "world" landmarks (metres, centred on the hand, axes along the camera's: x right, y down,
   z away). The world shape placed at translation ``t`` must project onto the image landmarks
   through the camera matrix ``K``; with the world axes taken as the camera's, the pinhole
   equations are linear in ``t`` (two per landmark), solved by least squares. On the
   development photos, OpenCV's ``solvePnP`` (which also fits a rotation) finds the world axes
   within 1-8° of the camera's and a translation within 1 cm of this one
   (``tests/unit/camera_bridge/test_geometry.py`` holds both to each other on a photo).
   ``K`` comes from a calibration file or from a stated horizontal field of view
   (`camera_matrix`, `DEFAULT_FOV_DEG`).
2. **Axes** (`CameraPose`). Camera coordinates (mm; x right, y down, z along the optical axis)
   are turned into the Leap frame (origin at a virtual sensor's top centre, +y up, +z towards
   the user, +x to the user's right) by the camera's placement:

   - ``front`` (default): the camera faces the user across the desk (a webcam on a screen or
     on the robot's side): optical axis = Leap +z, image right = the user's left (−x),
     image down = −y;
   - ``side``: the camera looks the way the user looks (head-mounted, over the shoulder):
     optical axis = Leap −z, image right = the user's right (+x), image down = −y;

   then tilted down by ``pitch_deg`` and placed at ``position_mm`` in the Leap frame. Left
   and right stay the user's in both: the image is never flipped, the axes are.
3. **The hand** (`leap_hand`). The 21 landmarks are the wrist, the thumb's CMC, MCP, IP and
   tip, and each finger's MCP, PIP, DIP and tip. The Leap hand has more, derived from the
   kinematic hand model of `cbgo.hands.model` (the anatomy the simulated users and the static
   model share): in the palm's own frame (origin the middle finger's MCP, axes along wrist →
   middle MCP, across index MCP → pinky MCP, and their normal) the model's palm centre, wrist,
   metacarpal bases of index..pinky, palm direction and palm normal have fixed coordinates per
   side (`reference_palm`); the camera hand gets the same ones, scaled by its knuckle span
   (index MCP to pinky MCP). The knuckles, not MediaPipe's wrist, anchor the palm because the
   two skeletons agree on them: measured on the development photos and the open-palm video,
   MediaPipe's wrist → middle-MCP is 1.4-1.6 times the model's (its wrist landmark lies at the
   wrist crease, the Leap's wrist point inside the palm), its knuckle span 1.1-1.4 times and
   its middle finger 1.0-1.25 times (`tests/unit/camera_bridge/test_geometry.py` keeps the
   derivation exact on model hands). Bones: each finger's metacarpal runs from its derived
   base to its MCP, then
   MCP → PIP → DIP → tip. The thumb's metacarpal has zero length at the CMC landmark (as the
   Leap SDK's), and its proximal, intermediate and distal bones are CMC → MCP → IP → tip.
   Widths scale the model's. ``grab_strength`` and ``pinch_strength`` follow the model's
   definitions (mean finger curl over 240°; thumb tip to the nearest fingertip, 80 → 25 mm).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from cbgo.hands.model import (
    GRAB_FULL_CURL,
    HandShape,
    build_hand,
    neutral_pose,
    pinch_strength,
)
from cbgo.wire import BONE_TYPES, FINGER_TYPES

N_LANDMARKS = 21
WRIST, THUMB_CMC = 0, 1
INDEX_MCP, MIDDLE_MCP, PINKY_MCP = 5, 9, 17
FINGER_MCPS = (5, 9, 13, 17)
"""Landmark of each finger's MCP (index..pinky); its PIP, DIP and tip follow."""

DEFAULT_FOV_DEG = 60.0
"""Horizontal field of view assumed without a calibration file: the middle of common webcams'
(55-78°). A wrong one scales the distance: 10° off moves a hand at 45 cm by about 8 cm."""

PLACEMENTS = ("front", "side")
_CAMERA_AXES = {
    # columns: where the camera's x (image right), y (image down), z (optical axis) point
    "front": np.array([[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]),
    "side": np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]),
}
DEFAULT_POSITION_MM = {"front": (0.0, 200.0, -450.0), "side": (0.0, 450.0, 350.0)}
"""Default camera position in the Leap frame per placement: a hand 45 cm in front of a level
front camera, or 40 cm in front of a side camera tilted 30° down (`DEFAULT_PITCH_DEG`), sits
where a Leap sees a hand: about 20-25 cm above the sensor, over its centre."""
DEFAULT_PITCH_DEG = {"front": 0.0, "side": 30.0}


def camera_matrix(width: int, height: int, fov_deg: float = DEFAULT_FOV_DEG) -> np.ndarray:
    """Returns the 3×3 pinhole matrix of an image with this horizontal field of view.

    Square pixels, the principal point at the image's centre.
    """
    if not 1.0 < fov_deg < 179.0:
        raise ValueError(f"field of view {fov_deg}° must be within 1-179°")
    f = (width / 2.0) / np.tan(np.radians(fov_deg) / 2.0)
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])


def scale_matrix(K: np.ndarray, calibrated_size: tuple[int, int],
                 size: tuple[int, int]) -> np.ndarray:
    """Returns a camera matrix calibrated at one image size, for another (same aspect)."""
    sx, sy = size[0] / calibrated_size[0], size[1] / calibrated_size[1]
    return np.diag([sx, sy, 1.0]) @ K


def solve_translation(world_m: np.ndarray, image_px: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Returns the translation (m) that puts the world landmarks where the image shows them.

    Args:
        world_m: (N, 3) hand-centred landmarks, camera axes, metres.
        image_px: (N, 2) the same landmarks in the (undistorted) image, pixels.
        K: the 3×3 camera matrix.

    Each landmark gives ``fx (X + tx) = (u − cx)(Z + tz)`` and the same in y: linear in t.
    """
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    du, dv = image_px[:, 0] - cx, image_px[:, 1] - cy
    n = len(world_m)
    A = np.zeros((2 * n, 3))
    A[:n, 0], A[:n, 2] = fx, -du
    A[n:, 1], A[n:, 2] = fy, -dv
    b = np.concatenate([du * world_m[:, 2] - fx * world_m[:, 0],
                        dv * world_m[:, 2] - fy * world_m[:, 1]])
    return np.linalg.lstsq(A, b, rcond=None)[0]


def reprojection_px(world_m: np.ndarray, t: np.ndarray, image_px: np.ndarray,
                    K: np.ndarray) -> float:
    """Returns the mean distance (pixels) from the placed landmarks' projections to the image's.

    How well one rigid hand explains the image.
    """
    p = (world_m + t) @ K.T
    return float(np.linalg.norm(p[:, :2] / p[:, 2:] - image_px, axis=1).mean())


@dataclass(frozen=True)
class CameraPose:
    """Where the camera is in the Leap frame, and which way it looks.

    Attributes:
        placement: ``front`` or ``side`` (see the module rules).
        position_mm: the camera's centre in the Leap frame.
        pitch_deg: tilt of the optical axis below the horizontal.
    """

    placement: str = "front"
    position_mm: tuple[float, float, float] = DEFAULT_POSITION_MM["front"]
    pitch_deg: float = 0.0

    def __post_init__(self) -> None:
        if self.placement not in PLACEMENTS:
            raise ValueError(f"placement {self.placement!r} is not one of {PLACEMENTS}")

    def rotation(self) -> np.ndarray:
        """Returns the 3×3 rotation from camera axes to Leap axes."""
        p = np.radians(self.pitch_deg)
        tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(p), np.sin(p)],
                         [0.0, -np.sin(p), np.cos(p)]])
        return _CAMERA_AXES[self.placement] @ tilt

    def to_leap(self, points_camera_mm: np.ndarray) -> np.ndarray:
        """Returns (..., 3) camera-frame points (mm) in the Leap frame (mm)."""
        return points_camera_mm @ self.rotation().T + np.asarray(self.position_mm)

    def user_side(self, image_x: float, width: float) -> str:
        """Returns which of the user's sides an image column is on (for messages)."""
        right_of_centre = image_x > width / 2.0
        return ("left" if right_of_centre else "right") if self.placement == "front" else (
            "right" if right_of_centre else "left")


def palm_axes(wrist: np.ndarray, index_mcp: np.ndarray, middle_mcp: np.ndarray,
              pinky_mcp: np.ndarray) -> tuple[np.ndarray, float]:
    """Returns the palm's frame (3×3, rows: along, across, normal) and its knuckle span (mm).

    Along: wrist → middle MCP; across: index MCP → pinky MCP made orthogonal to it; the third
    axis completes a right-handed frame (so it leaves the palm on one side of a right hand and
    the other of a left: `reference_palm` is per side).
    """
    along = middle_mcp - wrist
    along = along / np.linalg.norm(along)
    knuckles = pinky_mcp - index_mcp
    across = knuckles - (knuckles @ along) * along
    across = across / np.linalg.norm(across)
    return np.stack([along, across, np.cross(along, across)]), float(np.linalg.norm(knuckles))


@dataclass(frozen=True)
class PalmReference:
    """The model hand's palm in its own frame (`palm_axes`), per unit of knuckle span.

    Attributes:
        palm: (3,) palm centre, from the middle MCP.
        wrist: (3,) the wrist, from the middle MCP.
        bases: (4, 3) metacarpal bases of index..pinky, from the middle MCP.
        direction: (3,) unit palm direction.
        normal: (3,) unit palm normal.
        palm_width: palm width per unit span.
        bone_widths: (5, 4) bone widths per unit span.
        span: the model's knuckle span at scale 1 (mm).
    """

    palm: np.ndarray
    wrist: np.ndarray
    bases: np.ndarray
    direction: np.ndarray
    normal: np.ndarray
    palm_width: float
    bone_widths: np.ndarray
    span: float


@lru_cache(maxsize=2)
def reference_palm(side: str) -> PalmReference:
    """Returns the model hand's palm (`cbgo.hands.model`, calibrated default) for one side."""
    shape = HandShape.default(side=side)
    hand = build_hand(shape, neutral_pose(), (0.0, 200.0, 0.0))
    joints = np.array([[b["prev_joint"] for b in f["bones"]] + [f["bones"][-1]["next_joint"]]
                       for f in hand["fingers"]])  # (5, 5): base, then each bone's end
    wrist, origin = np.asarray(hand["wrist_position"]), joints[2, 1]
    axes, span = palm_axes(wrist, joints[1, 1], origin, joints[4, 1])
    return PalmReference(
        palm=axes @ (np.asarray(hand["palm_position"]) - origin) / span,
        wrist=axes @ (wrist - origin) / span,
        bases=(joints[1:, 0] - origin) @ axes.T / span,
        direction=axes @ np.asarray(hand["direction"]),
        normal=axes @ np.asarray(hand["palm_normal"]),
        palm_width=shape.palm_width / span,
        bone_widths=shape.bone_widths / span,
        span=span / shape.scale)


def finger_joints(points: np.ndarray, side: str) -> tuple[np.ndarray, dict]:
    """Returns the five fingers' joints and the palm's fields, from 21 landmarks (Leap, mm).

    The joints are (5, 5, 3): each finger's metacarpal base, then the end of each bone.
    """
    ref = reference_palm(side)
    origin = points[MIDDLE_MCP]
    axes, span = palm_axes(points[WRIST], points[INDEX_MCP], origin, points[PINKY_MCP])
    joints = np.empty((5, 5, 3))
    cmc = points[THUMB_CMC]
    joints[0] = [cmc, cmc, points[2], points[3], points[4]]
    for f, mcp in enumerate(FINGER_MCPS, start=1):
        base = origin + span * ref.bases[f - 1] @ axes
        joints[f] = [base, *points[mcp:mcp + 4]]
    direction = ref.direction @ axes
    normal = ref.normal @ axes
    normal = normal - (normal @ direction) * direction
    palm = {"palm_position": origin + span * ref.palm @ axes,
            "wrist_position": origin + span * ref.wrist @ axes,
            "direction": direction / np.linalg.norm(direction),
            "palm_normal": normal / np.linalg.norm(normal),
            "palm_width": ref.palm_width * span, "bone_widths": ref.bone_widths * span,
            "scale": span / ref.span}
    return joints, palm


def grab_strength(joints: np.ndarray) -> float:
    """Returns the mean curl of index..pinky over the model's full curl (240°).

    A finger's curl is the sum of the angles between its successive bones, metacarpal to
    distal, clipped to [0, 1] of the full curl.
    """
    bones = np.diff(joints[1:], axis=1)  # (4, 4, 3)
    bones = bones / np.linalg.norm(bones, axis=-1, keepdims=True)
    cosines = np.clip((bones[:, :-1] * bones[:, 1:]).sum(-1), -1.0, 1.0)
    curl = np.arccos(cosines).sum(-1)
    return float(np.clip(curl / GRAB_FULL_CURL, 0.0, 1.0).mean())


def leap_hand(points_leap_mm: np.ndarray, side: str, hand_id: int, confidence: float,
              velocity_mm_s: np.ndarray | None = None) -> dict:
    """Returns a contract hand (``cbgo/hands/frame``) from 21 landmarks in the Leap frame.

    Args:
        points_leap_mm: (21, 3) MediaPipe's landmarks, metric, in the Leap frame.
        side: the user's ``left`` or ``right`` hand.
        hand_id: the tracking id.
        confidence: 0..1.
        velocity_mm_s: the palm velocity, zeros when None.
    """
    joints, palm = finger_joints(np.asarray(points_leap_mm, dtype=np.float64), side)
    fingers = [{"type": ftype, "bones": [
        {"type": btype, "prev_joint": joints[f, b].tolist(),
         "next_joint": joints[f, b + 1].tolist(), "width": float(palm["bone_widths"][f, b])}
        for b, btype in enumerate(BONE_TYPES)]} for f, ftype in enumerate(FINGER_TYPES)]
    velocity = np.zeros(3) if velocity_mm_s is None else np.asarray(velocity_mm_s, float)
    return {
        "id": int(hand_id), "side": side, "confidence": float(np.clip(confidence, 0.0, 1.0)),
        "palm_position": palm["palm_position"].tolist(), "palm_velocity": velocity.tolist(),
        "palm_normal": palm["palm_normal"].tolist(), "direction": palm["direction"].tolist(),
        "wrist_position": palm["wrist_position"].tolist(),
        "palm_width": float(palm["palm_width"]),
        "grab_strength": grab_strength(joints),
        "pinch_strength": float(pinch_strength(joints[:, 4], palm["scale"])),
        "fingers": fingers,
    }


def landmarks_from_hand(hand: dict) -> np.ndarray:
    """Returns the 21 MediaPipe-style landmarks (Leap frame, mm) of a contract hand.

    The inverse of `leap_hand` on the joints MediaPipe has: used to put a model hand through
    the camera path (tests, feature comparisons).
    """
    fingers = hand["fingers"]
    thumb = fingers[0]["bones"]
    points = [hand["wrist_position"], thumb[1]["prev_joint"], thumb[1]["next_joint"],
              thumb[2]["next_joint"], thumb[3]["next_joint"]]
    for finger in fingers[1:]:
        bones = finger["bones"]
        points += [bones[1]["prev_joint"], bones[1]["next_joint"], bones[2]["next_joint"],
                   bones[3]["next_joint"]]
    return np.asarray(points, dtype=np.float64)
