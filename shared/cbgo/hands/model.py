"""A kinematic hand model that produces contract hands (``cbgo/hands/frame``) from joint angles.

Rules:

- A ``HandShape`` is one person's anatomy (bone lengths, knuckle layout, wrist, widths, side);
  a ``HandPose`` is what the person does with it (24 angles, radians). ``build_hand`` turns
  both, plus a palm position, into every field of a contract hand.
- Local hand frame (a right hand in the reference pose): origin at the palm centre, +x towards
  the little finger, +y out of the back of the hand, +z towards the wrist. The reference pose is
  the palm facing down (normal −y) with the fingers pointing away from the user (direction −z)
  in the Leap frame. A left hand is the mirror image (x → −x) of the right hand built from the
  same shape and pose, so every angle keeps its anatomical meaning on both sides.
- Orientation: ``R = R_y(yaw) · R_x(pitch) · R_z(roll)`` on the local frame. ``pitch > 0`` lifts
  the fingers, ``yaw > 0`` turns them towards the thumb side of a right hand (−x), ``roll > 0``
  turns the palm towards the little-finger side and lowers the thumb; ``roll < 0`` raises the
  thumb side (the recorded thumbs-up is held at about −64°). The mirror keeps these meanings
  on a left hand, so its world rotations are the mirrored ones.
- Fingers (index..pinky): a metacarpal fixed in the palm, then MCP abduction ("spread", > 0
  away from the middle finger; the middle finger's own spread is towards the ring finger) and
  flexion, PIP flexion, DIP flexion. Flexion > 0 curls towards the palm.
- Thumb: a zero-length metacarpal at the CMC joint, as in the Leap SDK (its orientation is the
  thumb's rest orientation, reported in ``rotation``); CMC flexion (across the palm), abduction
  (away from the index finger's plane), axial rotation (opposition); MCP and IP flexion.
- Joint angles are clipped to ``JOINT_LIMITS`` (anatomical ranges of adults); orientation is not.
- Bone frames follow the Leap SDK: x across the bone, y out of the back (nail side), z along
  the bone towards its base; a bone's direction is −z. ``rotation`` is that frame as a
  quaternion ``[qx, qy, qz, qw]`` (for a left hand, the mirrored frame ``M R M``, M = diag(−1,
  1, 1), which keeps it a proper rotation and its −z the true bone direction).
- ``grab_strength`` = mean over index..pinky of clip((MCP + PIP + DIP flexion) / 240°, 0, 1).
  ``pinch_strength`` = clip((80 mm − d) / (80 mm − 25 mm), 0, 1), d the distance from the thumb
  tip to the nearest other fingertip, both scaled by the hand's scale.

The kinematics run on numpy or torch arrays alike (``forward_kinematics(xp, ...)``), so the
calibration can differentiate through exactly the code that builds the frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any

import numpy as np

from cbgo.hands.poses_file import default_shape_parameters
from cbgo.wire import BONE_TYPES, FINGER_TYPES

FINGERS = ("index", "middle", "ring", "pinky")
THUMB_PARAMS = ("cmc_flex", "cmc_abd", "cmc_rot", "mcp", "ip")
FINGER_PARAMS = ("mcp", "spread", "pip", "dip")
ORIENTATION_PARAMS = ("roll", "pitch", "yaw")
PARAM_NAMES: tuple[str, ...] = (
    tuple(f"thumb_{p}" for p in THUMB_PARAMS)
    + tuple(f"{f}_{p}" for f in FINGERS for p in FINGER_PARAMS)
    + ORIENTATION_PARAMS
)
N_PARAMS = len(PARAM_NAMES)
N_JOINT_PARAMS = N_PARAMS - 3

_D = np.pi / 180.0
_FINGER_LIMITS_DEG = {"mcp": (-30.0, 95.0), "spread": (-15.0, 30.0), "pip": (-5.0, 115.0),
                      "dip": (-15.0, 90.0)}
_THUMB_LIMITS_DEG = {"cmc_flex": (-35.0, 70.0), "cmc_abd": (-40.0, 60.0),
                     "cmc_rot": (-50.0, 50.0), "mcp": (-25.0, 75.0), "ip": (-25.0, 90.0)}
JOINT_LIMITS: np.ndarray = np.array(
    [_THUMB_LIMITS_DEG[p] for p in THUMB_PARAMS]
    + [_FINGER_LIMITS_DEG[p] for _ in FINGERS for p in FINGER_PARAMS]) * _D
"""(21, 2) lower/upper limits (rad) of the joint angles, in ``PARAM_NAMES`` order."""

# Sign of "spread" in the local x direction per finger: the index spreads towards the thumb.
_SPREAD_SIGN = np.array([-1.0, 1.0, 1.0, 1.0])

# Adult anatomy (mm), close to the Leap SDK's default hand; the thumb's metacarpal has zero
# length and its "proximal" is the anatomical first metacarpal.
_BONE_LENGTHS = np.array([
    [0.0, 46.0, 32.0, 25.0],
    [68.0, 40.0, 23.0, 17.0],
    [64.0, 45.0, 27.0, 18.0],
    [58.0, 42.0, 26.0, 18.0],
    [53.0, 33.0, 18.0, 16.0],
])
# Thumb CMC, then the MCP knuckles, in the local frame relative to the palm centre.
_KNUCKLES = np.array([
    [-19.0, -9.0, 28.0],
    [-23.0, 0.0, -24.0],
    [-4.0, 1.0, -27.0],
    [14.0, 0.0, -23.0],
    [29.0, -3.0, -15.0],
])
# Where each metacarpal starts (the carpals), which sets its direction in the palm.
_METACARPAL_BASES = np.array([[-12.0, 2.0, 42.0], [-2.0, 2.0, 37.0], [8.0, 2.0, 35.0],
                              [17.0, 1.0, 37.0]])
_WRIST = np.array([0.0, 3.0, 40.0])
_PALM_WIDTH = 85.0
_BONE_WIDTHS = np.array([[20.0, 19.0, 17.5, 16.0], [19.0, 18.0, 16.5, 15.0],
                         [18.5, 17.5, 16.5, 15.0], [18.0, 17.0, 16.0, 14.5],
                         [16.5, 15.5, 14.5, 13.5]])
# The thumb's rest orientation: turned towards the thumb side, dropped towards the palm and
# pronated so that its nail faces sideways, as a relaxed thumb lies.
THUMB_REST_DEG = (38.0, 18.0, 55.0)

GRAB_FULL_CURL = 240.0 * _D
PINCH_OPEN_MM, PINCH_CLOSED_MM = 80.0, 25.0


@dataclass(frozen=True)
class HandShape:
    """One person's hand anatomy, in the local hand frame (mm).

    Attributes:
        side: ``"left"`` or ``"right"``.
        scale: the overall size relative to the default adult hand.
        bone_lengths: (5, 4) lengths, fingers thumb..pinky × bones metacarpal..distal.
        knuckles: (5, 3) thumb CMC joint and index..pinky MCP joints.
        metacarpal_directions: (4, 3) unit directions of the index..pinky metacarpals.
        wrist: (3,) wrist position.
        palm_width: mm.
        bone_widths: (5, 4) mm.
    """

    side: str = "right"
    scale: float = 1.0
    bone_lengths: np.ndarray = field(default_factory=lambda: _BONE_LENGTHS.copy())
    knuckles: np.ndarray = field(default_factory=lambda: _KNUCKLES.copy())
    metacarpal_directions: np.ndarray = field(
        default_factory=lambda: _unit_rows(_KNUCKLES[1:] - _METACARPAL_BASES))
    wrist: np.ndarray = field(default_factory=lambda: _WRIST.copy())
    palm_width: float = _PALM_WIDTH
    bone_widths: np.ndarray = field(default_factory=lambda: _BONE_WIDTHS.copy())

    def __post_init__(self) -> None:
        if self.side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {self.side!r}")
        if not self.scale > 0:
            raise ValueError(f"scale must be positive, got {self.scale!r}")

    @classmethod
    def default(cls, side: str = "right", scale: float = 1.0) -> HandShape:
        """Returns the default adult hand, uniformly scaled (calibrated defaults applied).

        Args:
            side: ``"left"`` or ``"right"``.
            scale: the size relative to the calibrated default hand.
        """
        calibrated = default_shape_parameters()
        s = calibrated["scale"] * scale
        lengths = _BONE_LENGTHS.copy()
        lengths[:, 1:] *= np.asarray(calibrated["phalanx_factors"])[:, None]
        knuckles = _KNUCKLES.copy()
        knuckles[0] = calibrated["thumb_cmc_mm"]
        return cls(side=side, scale=s, bone_lengths=lengths * s, knuckles=knuckles * s,
                   wrist=np.asarray(calibrated["wrist_mm"]) * s, palm_width=_PALM_WIDTH * s,
                   bone_widths=_BONE_WIDTHS * s)

    @classmethod
    def sample(cls, rng: np.random.Generator, scale: float | None = None,
               side: str = "right") -> HandShape:
        """Samples a plausible person's hand: a size and small individual proportions.

        Args:
            rng: the random generator.
            scale: the size; uniform in [0.85, 1.15] when None.
            side: ``"left"`` or ``"right"``.

        Returns:
            A shape whose bone lengths vary ±4 % and knuckles ±1.5 mm around the scaled
            default.
        """
        if scale is None:
            scale = float(rng.uniform(0.85, 1.15))
        base = cls.default(side=side, scale=scale)
        lengths = base.bone_lengths * rng.uniform(0.96, 1.04, size=(5, 4))
        knuckles = base.knuckles + rng.normal(0.0, 1.5, size=(5, 3)).clip(-3.0, 3.0)
        return replace(base, bone_lengths=lengths, knuckles=knuckles)

    def metacarpal_bases(self) -> np.ndarray:
        """Returns (4, 3) metacarpal start points (index..pinky) consistent with the lengths."""
        return self.knuckles[1:] - self.bone_lengths[1:, :1] * self.metacarpal_directions


def _unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass(frozen=True)
class HandPose:
    """Joint angles and palm orientation (radians); see the module rules for the conventions.

    Attributes:
        thumb: (cmc_flex, cmc_abd, cmc_rot, mcp, ip).
        mcp: MCP flexion of index, middle, ring, pinky.
        spread: MCP abduction of index, middle, ring, pinky.
        pip: PIP flexion of index, middle, ring, pinky.
        dip: DIP flexion of index, middle, ring, pinky.
        roll: palm roll relative to the reference pose.
        pitch: palm pitch relative to the reference pose.
        yaw: palm yaw relative to the reference pose.
    """

    thumb: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    mcp: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    spread: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    pip: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    dip: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def to_vector(self) -> np.ndarray:
        """Returns the (24,) parameter vector in ``PARAM_NAMES`` order."""
        fingers = np.stack([self.mcp, self.spread, self.pip, self.dip], -1).reshape(-1)
        return np.concatenate([self.thumb, fingers, [self.roll, self.pitch, self.yaw]]).astype(
            np.float64)

    @classmethod
    def from_vector(cls, v: np.ndarray) -> HandPose:
        """Builds a pose from a (24,) vector in ``PARAM_NAMES`` order."""
        v = np.asarray(v, dtype=np.float64)
        fingers = v[5:21].reshape(4, 4)
        return cls(thumb=tuple(v[:5]), mcp=tuple(fingers[:, 0]), spread=tuple(fingers[:, 1]),
                   pip=tuple(fingers[:, 2]), dip=tuple(fingers[:, 3]), roll=float(v[21]),
                   pitch=float(v[22]), yaw=float(v[23]))

    def clipped(self) -> HandPose:
        """Returns the pose with every joint angle inside ``JOINT_LIMITS``."""
        return HandPose.from_vector(clip_to_limits(self.to_vector()))

    def rotated(self, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> HandPose:
        """Returns the pose with its palm orientation changed by the given angles (rad)."""
        return replace(self, roll=self.roll + roll, pitch=self.pitch + pitch, yaw=self.yaw + yaw)


def clip_to_limits(v: np.ndarray) -> np.ndarray:
    """Clips the joint angles of parameter vectors (..., 24) to ``JOINT_LIMITS``."""
    out = np.array(v, dtype=np.float64, copy=True)
    out[..., :N_JOINT_PARAMS] = np.clip(out[..., :N_JOINT_PARAMS], JOINT_LIMITS[:, 0],
                                        JOINT_LIMITS[:, 1])
    return out


def neutral_pose() -> HandPose:
    """Returns the relaxed, slightly curled open hand used between gestures and in strokes."""
    d = _D
    return HandPose(thumb=(5 * d, 10 * d, 0.0, 10 * d, 10 * d),
                    mcp=(15 * d, 18 * d, 20 * d, 22 * d), spread=(4 * d, 0.0, 3 * d, 6 * d),
                    pip=(20 * d, 22 * d, 24 * d, 26 * d), dip=(8 * d, 9 * d, 10 * d, 10 * d))


def blend(a: HandPose, b: HandPose, t: float) -> HandPose:
    """Interpolates linearly in every angle: ``t = 0`` gives ``a``, ``t = 1`` gives ``b``."""
    return HandPose.from_vector((1.0 - t) * a.to_vector() + t * b.to_vector())


# --------------------------------------------------------------------------- kinematics


def rotation(xp: Any, axis: int, angle: Any) -> Any:
    """Returns rotation matrices (..., 3, 3) about the x (0), y (1) or z (2) axis."""
    c, s = xp.cos(angle), xp.sin(angle)
    o, z = xp.ones_like(angle), xp.zeros_like(angle)
    rows = {0: [[o, z, z], [z, c, -s], [z, s, c]],
            1: [[c, z, s], [z, o, z], [-s, z, c]],
            2: [[c, -s, z], [s, c, z], [z, z, o]]}[axis]
    return xp.stack([xp.stack(r, -1) for r in rows], -2)


def _frame_along(direction: np.ndarray) -> np.ndarray:
    """A Leap bone frame (columns x, y, z) whose −z is ``direction`` and whose y points up."""
    z = -direction / np.linalg.norm(direction, axis=-1, keepdims=True)
    x = np.cross(np.array([0.0, 1.0, 0.0]), z)
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], -1)


@lru_cache(maxsize=1)
def thumb_rest_frame() -> np.ndarray:
    """Returns the (3, 3) local frame of the thumb's zero-length metacarpal (do not mutate)."""
    yaw, droop, pronation = (a * _D for a in THUMB_REST_DEG)
    return (rotation(np, 1, np.float64(yaw)) @ rotation(np, 0, np.float64(-droop))
            @ rotation(np, 2, np.float64(pronation)))


def shape_arrays(shapes: list[HandShape] | HandShape) -> dict[str, np.ndarray]:
    """Stacks shapes into the arrays ``forward_kinematics`` takes (leading batch axis if a list)."""
    if isinstance(shapes, HandShape):
        return _one_shape_arrays(shapes)
    parts = [_one_shape_arrays(s) for s in shapes]
    return {k: np.stack([p[k] for p in parts]) for k in parts[0]}


def _one_shape_arrays(shape: HandShape) -> dict[str, np.ndarray]:
    return {"lengths": np.asarray(shape.bone_lengths, dtype=np.float64),
            "knuckles": np.asarray(shape.knuckles, dtype=np.float64),
            "bases": shape.metacarpal_bases(),
            "meta_frames": _frame_along(np.asarray(shape.metacarpal_directions)),
            "wrist": np.asarray(shape.wrist, dtype=np.float64)}


def forward_kinematics(xp: Any, theta: Any, shape: dict[str, Any],
                       thumb_rest: Any) -> dict[str, Any]:
    """Computes local-frame joints and bone frames of right hands from parameter vectors.

    Args:
        xp: the array module, ``numpy`` or ``torch`` (all arrays must belong to it).
        theta: parameter vectors (B, 24), ``PARAM_NAMES`` order (not clipped here).
        shape: ``shape_arrays`` output, unbatched or with the same leading B.
        thumb_rest: ``thumb_rest_frame()`` as an ``xp`` array.

    Returns:
        ``hand_rot`` (B, 3, 3) palm orientation; in the rotated local frame (palm centre at
        the origin): ``joints`` (B, 5, 5, 3) metacarpal start to tip per finger, ``frames``
        (B, 5, 4, 3, 3) bone frames, ``wrist`` (B, 3).
    """
    hand_rot = (rotation(xp, 1, theta[:, 23]) @ rotation(xp, 0, theta[:, 22])
                @ rotation(xp, 2, theta[:, 21]))
    thumb_joints, thumb_frames = _thumb_chain(xp, theta[:, :5], shape, thumb_rest)
    finger_joints, finger_frames = _finger_chains(xp, theta[:, 5:21].reshape(-1, 4, 4), shape)
    joints = xp.concatenate([thumb_joints[:, None], finger_joints], 1)
    frames = xp.concatenate([thumb_frames[:, None], finger_frames], 1)
    rot = hand_rot[:, None, None]
    wrist = shape["wrist"] + xp.zeros_like(theta[:, :3])
    return {"hand_rot": hand_rot,
            "joints": (rot @ joints[..., None])[..., 0],
            "frames": rot @ frames,
            "wrist": (hand_rot @ wrist[..., None])[..., 0]}


def _batched(a: Any, ndim: int) -> Any:
    """Adds a leading batch axis to a shape array that has none (one shape for all hands)."""
    return a if a.ndim == ndim else a[None]


def _advance(xp: Any, start: Any, frame: Any, length: Any) -> Any:
    """Moves ``length`` along the frame's −z from ``start``."""
    return start - frame[..., :, 2] * length[..., None]


def _finger_chains(xp: Any, angles: Any, shape: dict[str, Any]) -> tuple[Any, Any]:
    """Index..pinky chains: joints (B, 4, 5, 3) and frames (B, 4, 4, 3, 3)."""
    mcp, spread, pip, dip = (angles[..., i] for i in range(4))
    sign = xp.stack([xp.ones_like(mcp[:, 0]) * float(s) for s in _SPREAD_SIGN], -1)
    # Adding zeros of the batch's size broadcasts a shared shape to every hand.
    meta = _batched(shape["meta_frames"], 4) + xp.zeros_like(angles)[..., None, :3]
    prox = meta @ rotation(xp, 1, -sign * spread) @ rotation(xp, 0, -mcp)
    inter = prox @ rotation(xp, 0, -pip)
    dist = inter @ rotation(xp, 0, -dip)
    lengths = _batched(shape["lengths"], 3)
    knuckles = _batched(shape["knuckles"], 3)
    base = _batched(shape["bases"], 3) + xp.zeros_like(prox[..., 0])
    knuckle = knuckles[:, 1:] + xp.zeros_like(prox[..., 0])
    pip_joint = _advance(xp, knuckle, prox, lengths[:, 1:, 1])
    dip_joint = _advance(xp, pip_joint, inter, lengths[:, 1:, 2])
    tip = _advance(xp, dip_joint, dist, lengths[:, 1:, 3])
    joints = xp.stack([base, knuckle, pip_joint, dip_joint, tip], 2)
    frames = xp.stack([meta, prox, inter, dist], 2)
    return joints, frames


def _thumb_chain(xp: Any, angles: Any, shape: dict[str, Any], rest: Any) -> tuple[Any, Any]:
    """Thumb chain: joints (B, 5, 3) and frames (B, 4, 3, 3)."""
    flex, abd, rot, mcp, ip = (angles[:, i] for i in range(5))
    rest = rest + xp.zeros_like(angles)[:, :3, None]
    prox = rest @ rotation(xp, 0, -flex) @ rotation(xp, 1, abd) @ rotation(xp, 2, rot)
    inter = prox @ rotation(xp, 0, -mcp)
    dist = inter @ rotation(xp, 0, -ip)
    lengths = _batched(shape["lengths"], 3)
    cmc = _batched(shape["knuckles"], 3)[:, 0] + xp.zeros_like(angles)[:, :3]
    mcp_joint = _advance(xp, cmc, prox, lengths[:, 0, 1])
    ip_joint = _advance(xp, mcp_joint, inter, lengths[:, 0, 2])
    tip = _advance(xp, ip_joint, dist, lengths[:, 0, 3])
    joints = xp.stack([cmc, cmc, mcp_joint, ip_joint, tip], 1)
    return joints, xp.stack([rest, prox, inter, dist], 1)


# --------------------------------------------------------------------------- contract hands

_MIRROR = np.diag([-1.0, 1.0, 1.0])


def quaternions(m: np.ndarray) -> np.ndarray:
    """Returns quaternions ``[qx, qy, qz, qw]`` (..., 4), ``qw >= 0``, of rotations (..., 3, 3).

    Each of the four rows below is the quaternion times 4·q_k for one component k; the row
    whose q_k is largest is the numerically stable one for that matrix (Shepperd's method).
    """
    m = np.asarray(m, dtype=np.float64)
    d0, d1, d2 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    s01, s02, s12 = m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0], \
        m[..., 1, 2] + m[..., 2, 1]
    a21, a02, a10 = m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], \
        m[..., 1, 0] - m[..., 0, 1]
    rows = np.stack([
        np.stack([1 + d0 - d1 - d2, s01, s02, a21], -1),
        np.stack([s01, 1 - d0 + d1 - d2, s12, a02], -1),
        np.stack([s02, s12, 1 - d0 - d1 + d2, a10], -1),
        np.stack([a21, a02, a10, 1 + d0 + d1 + d2], -1),
    ], -2)
    best = np.argmax(np.stack([1 + d0 - d1 - d2, 1 - d0 + d1 - d2, 1 - d0 - d1 + d2,
                               1 + d0 + d1 + d2], -1), -1)
    q = np.take_along_axis(rows, best[..., None, None], -2)[..., 0, :]
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return q * np.where(q[..., 3:] < 0, -1.0, 1.0)


def grab_strength(theta: np.ndarray) -> np.ndarray:
    """Returns the grab strength (...,) of parameter vectors (..., 24); see the module rules."""
    fingers = theta[..., 5:21].reshape(*theta.shape[:-1], 4, 4)
    curl = fingers[..., 0] + fingers[..., 2] + fingers[..., 3]
    return np.clip(curl / GRAB_FULL_CURL, 0.0, 1.0).mean(-1)


def pinch_strength(tips: np.ndarray, scale: np.ndarray | float) -> np.ndarray:
    """Returns the pinch strength (...,) from fingertips (..., 5, 3) and the hand scale."""
    nearest = np.linalg.norm(tips[..., 1:, :] - tips[..., :1, :], axis=-1).min(-1)
    scale = np.asarray(scale, dtype=np.float64)
    span = (PINCH_OPEN_MM - PINCH_CLOSED_MM) * scale
    return np.clip((PINCH_OPEN_MM * scale - nearest) / span, 0.0, 1.0)


def build_hands(shapes: list[HandShape], poses: list[HandPose],
                palm_positions_mm: np.ndarray,
                palm_velocities_mm_s: np.ndarray | None = None,
                hand_ids: list[int] | None = None,
                confidence: float = 1.0) -> list[dict]:
    """Builds several contract hands at once (one kinematics pass); see ``build_hand``.

    Args:
        shapes: one shape per hand.
        poses: one pose per hand (joint angles are clipped to the limits).
        palm_positions_mm: (N, 3) palm centres in the Leap frame.
        palm_velocities_mm_s: (N, 3), zeros when None.
        hand_ids: tracking ids, 1..N when None.
        confidence: the reported tracking confidence.

    Returns:
        Hand dicts that pass ``cbgo.wire.HAND``.
    """
    n = len(poses)
    theta = clip_to_limits(np.stack([p.to_vector() for p in poses]))
    fk = forward_kinematics(np, theta, shape_arrays(list(shapes)), thumb_rest_frame())
    left = np.array([s.side == "left" for s in shapes])
    mirror = np.ones((n, 3))
    mirror[left, 0] = -1.0  # x → −x about the palm centre
    palms = np.asarray(palm_positions_mm, dtype=np.float64).reshape(n, 3)
    joints = fk["joints"] * mirror[:, None, None] + palms[:, None, None]
    frames = np.where(left[:, None, None, None, None], _MIRROR @ fk["frames"] @ _MIRROR,
                      fk["frames"])
    hand_frames = np.where(left[:, None, None], _MIRROR @ fk["hand_rot"] @ _MIRROR,
                           fk["hand_rot"])
    geometry = {
        "joints": joints, "quats": quaternions(frames),
        "wrist": fk["wrist"] * mirror + palms, "palms": palms,
        "normal": -hand_frames[..., 1], "direction": -hand_frames[..., 2],
        "velocity": (np.zeros((n, 3)) if palm_velocities_mm_s is None
                     else np.asarray(palm_velocities_mm_s, dtype=np.float64).reshape(n, 3)),
        "grab": grab_strength(theta),
        "pinch": pinch_strength(joints[:, :, 4], np.array([s.scale for s in shapes])),
    }
    ids = list(range(1, n + 1)) if hand_ids is None else hand_ids
    return [_hand_dict(geometry, i, shapes[i], ids[i], confidence) for i in range(n)]


def _hand_dict(g: dict[str, np.ndarray], i: int, shape: HandShape, hand_id: int,
               confidence: float) -> dict:
    fingers = []
    for f, ftype in enumerate(FINGER_TYPES):
        bones = [{"type": btype,
                  "prev_joint": g["joints"][i, f, b].tolist(),
                  "next_joint": g["joints"][i, f, b + 1].tolist(),
                  "width": float(shape.bone_widths[f, b]),
                  "rotation": g["quats"][i, f, b].tolist()}
                 for b, btype in enumerate(BONE_TYPES)]
        fingers.append({"type": ftype, "bones": bones})
    return {
        "id": int(hand_id), "side": shape.side, "confidence": float(confidence),
        "palm_position": g["palms"][i].tolist(), "palm_velocity": g["velocity"][i].tolist(),
        "palm_normal": g["normal"][i].tolist(), "direction": g["direction"][i].tolist(),
        "wrist_position": g["wrist"][i].tolist(), "palm_width": float(shape.palm_width),
        "grab_strength": float(g["grab"][i]), "pinch_strength": float(g["pinch"][i]),
        "fingers": fingers,
    }


def build_hand(shape: HandShape, pose: HandPose, palm_position_mm: Any,
               palm_velocity_mm_s: Any = (0.0, 0.0, 0.0), hand_id: int = 1,
               confidence: float = 1.0) -> dict:
    """Builds one contract hand (every field of ``cbgo/hands/frame``'s hand).

    Args:
        shape: the person's hand.
        pose: joint angles and palm orientation (joint angles are clipped to the limits).
        palm_position_mm: the palm centre [x, y, z] in the Leap frame.
        palm_velocity_mm_s: the palm velocity to report.
        hand_id: the tracking id.
        confidence: the reported tracking confidence, 0..1.

    Returns:
        A hand dict that passes ``cbgo.wire.HAND``.
    """
    return build_hands([shape], [pose], np.asarray(palm_position_mm, dtype=np.float64)[None],
                       np.asarray(palm_velocity_mm_s, dtype=np.float64)[None], [hand_id],
                       confidence)[0]


MIRROR_VECTORS = ("palm_position", "palm_velocity", "palm_normal", "direction", "wrist_position")


def mirrored_hand(hand: dict) -> dict:
    """Returns a contract hand mirrored across the body's midline (x → −x).

    The other hand doing the mirror image of the same thing, as this module builds a left hand
    from a right. Positions and directions are negated in x, the side is swapped, and a bone's
    ``rotation`` becomes ``M R M`` (quaternion ``[qx, −qy, −qz, qw]``). Used to measure how the
    services serve left hands on recordings of right ones (``cbgo bench dynamic --real DIR
    --mirror``).
    """

    def flip(v: list) -> list:
        return [-float(v[0]), float(v[1]), float(v[2])]

    out = {**hand, "side": "left" if hand["side"] == "right" else "right"}
    out.update({k: flip(hand[k]) for k in MIRROR_VECTORS if k in hand})
    out["fingers"] = [{**finger, "bones": [
        {**bone, "prev_joint": flip(bone["prev_joint"]), "next_joint": flip(bone["next_joint"]),
         **({"rotation": [bone["rotation"][0], -bone["rotation"][1], -bone["rotation"][2],
                          bone["rotation"][3]]} if "rotation" in bone else {})}
        for bone in finger["bones"]]} for finger in hand["fingers"]]
    return out
