"""Real hand motion: the SHREC'17 / DHG-14/28 depth-camera skeletons as `cbgo/hands/frame` hands.

The data set (De Smedt et al., *SHREC'17 track: 3D hand gesture recognition using a depth and
skeletal dataset*) has 28 people performing 14 gestures with an Intel RealSense camera; each
sequence is a ``skeletons_world.txt`` of 22 joints per frame (x, y, z in metres), at 30 Hz. A
public copy sits in the GitHub repository ``giach68/gesturesCodes``, folder ``datasetShrec``
(with the official ``train_gestures.txt`` / ``test_gestures.txt``). It has no licence, so
nothing of it is committed: fetch it into the cache (``cbgo data fetch shrec17``) or
point the benches at a copy. **Only the people of the official train split are used for
fitting, tuning or selecting anything** (`split_people`); the test split's people are kept for
acceptance checks, and `read_split` refuses to mix them.

Conversion (write-down of every assumption):

- **Axes.** The skeletons' world frame is right-handed with +x to the person's right, +y up and
  +z from the camera towards the person (checked on the data: swipe right moves +x, swipe up
  +y, and fingers curl towards ``(index − pinky) × direction``, the right-hand rule). Those are
  the Leap frame's axes, so the map is a pure translation: ``leap_mm = 1000 · world + offset``.
  The camera looked at the hand from the front, so the hands are seen upright (fingers up, palm
  towards the sensor), not palm-down over a desk sensor; nothing is rotated to pretend
  otherwise.
- **Centring.** ``offset`` puts the median palm position of the train split's swipes at the
  field centre (0, 230, 0) mm (`DEFAULT_OFFSET_MM`, measured by `median_palm`); each person's
  own placement around it is kept, so strokes start wherever that person's hand was.
- **Joints** (0-based): 0 wrist, 1 palm, then base, first, second joint and tip of the thumb
  (2–5), index (6–9), middle (10–13), ring (14–17) and pinky (18–21). Bones: a finger's
  metacarpal runs wrist → base, then base → first (proximal), first → second (intermediate),
  second → tip (distal); the thumb's metacarpal has zero length at its base, as in the Leap SDK.
- **Hand frame.** ``palm_position`` is joint 1; ``direction`` runs from the wrist to the middle
  finger's base; ``palm_normal`` is ``(index base − pinky base) × direction`` (a right hand;
  negated for a left one), made orthogonal to the direction. Velocities are central
  differences. ``grab_strength`` is the mean over index..pinky of the finger's summed bend
  angles / 240° (as `cbgo.hands.model`), ``pinch_strength`` its thumb-tip rule. Every hand of
  the data set is a right hand.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cbgo.config import cache_dir
from cbgo.hands.model import GRAB_FULL_CURL, pinch_strength
from cbgo.services.dynamic_gesture.stroke import Segmenter
from cbgo.wire import BONE_TYPES, FINGER_TYPES, SCHEMA_VERSION
from cbgo_tools.dynamic_gesture.simdata import Labelled, UserData, without_returns

RATE_HZ = 30.0
N_JOINTS = 22
FIELD_CENTRE_MM = np.array([0.0, 230.0, 0.0])
# 1000 × (the train split's median palm position of swipes) mapped to FIELD_CENTRE_MM;
# `median_palm` measures it: ``median_palm(read_split(DIR, "train", SWIPES))``.
DEFAULT_OFFSET_MM = np.array([-427.0, 537.0, -488.0])
GESTURES = {1: "grab", 2: "tap", 3: "expand", 4: "pinch", 5: "rotation_cw", 6: "rotation_ccw",
            7: "swipe_right", 8: "swipe_left", 9: "swipe_up", 10: "swipe_down", 11: "swipe_x",
            12: "swipe_plus", 13: "swipe_v", 14: "shake"}
SWIPES = {7: "swipe_right", 8: "swipe_left", 9: "swipe_up", 10: "swipe_down"}
PALM_JOINT = 1  # joint 0 is the wrist, 1 the palm (the module docstring's "Joints")
FINGER_JOINTS = [(2, 3, 4, 5), (6, 7, 8, 9), (10, 11, 12, 13), (14, 15, 16, 17), (18, 19, 20, 21)]
BONE_WIDTH_MM = (20.0, 18.0, 17.0, 16.0, 15.0)


def default_root() -> Path:
    """Returns where ``cbgo data fetch shrec17`` puts the data set (`cbgo.config.cache_dir`)."""
    return cache_dir() / "shrec17"


@dataclass(frozen=True)
class Sequence:
    """One recorded gesture.

    Attributes:
        gesture: the data set's gesture number (1..14), see `GESTURES`.
        fingers: 1 (one finger) or 2 (whole hand).
        person: the subject number.
        take: the essai number.
        path: the ``skeletons_world.txt`` file.
    """

    gesture: int
    fingers: int
    person: int
    take: int
    path: Path

    @property
    def name(self) -> str:
        """The gesture's name: ours for the swipes, the data set's otherwise."""
        return GESTURES[self.gesture]

    def joints(self) -> np.ndarray:
        """Returns (n, 22, 3) joints in metres, world frame."""
        return read_skeleton(self.path)


def read_skeleton(path: Path) -> np.ndarray:
    """Returns (n, 22, 3) joint positions (m) of one ``skeletons_world.txt``.

    Raises:
        ValueError: a line does not hold 66 numbers.
    """
    data = np.loadtxt(path, ndmin=2)
    if data.shape[1] != N_JOINTS * 3:
        raise ValueError(f"{path}: expected {N_JOINTS * 3} numbers per line, "
                         f"got {data.shape[1]}")
    return data.reshape(-1, N_JOINTS, 3)


def _read_list(path: Path) -> list[tuple[int, int, int, int]]:
    rows = []
    for line in path.read_text().splitlines():
        parts = line.split()
        if len(parts) >= 4:
            rows.append(tuple(int(p) for p in parts[:4]))
    return rows


def split_people(root: Path, split: str) -> set[int]:
    """Returns the people of the official ``train`` or ``test`` split."""
    return {row[2] for row in _read_list(root / f"{split}_gestures.txt")}


def read_split(root: Path, split: str = "train", gestures=None) -> list[Sequence]:
    """Returns the sequences of one official split (its list file), optionally some gestures.

    Raises:
        FileNotFoundError: the folder holds no SHREC'17 copy.
        ValueError: the two splits share a person (they must not).
    """
    if not (root / "train_gestures.txt").is_file():
        raise FileNotFoundError(
            f"no SHREC'17 data in {root}: fetch github.com/giach68/gesturesCodes and point "
            f"--real at its datasetShrec folder, or fetch it: `cbgo data fetch shrec17`")
    if split_people(root, "train") & split_people(root, "test"):
        raise ValueError("the train and test splits share people")
    out = []
    for g, f, person, take in _read_list(root / f"{split}_gestures.txt"):
        if gestures is None or g in gestures:
            path = root / f"gesture_{g}/finger_{f}/subject_{person}/essai_{take}/" \
                          "skeletons_world.txt"
            out.append(Sequence(g, f, person, take, path))
    return out


def median_palm(sequences: list[Sequence]) -> np.ndarray:
    """Returns the median palm position (mm, world frame) over every frame of the sequences."""
    palms = [s.joints()[:, PALM_JOINT] * 1000.0 for s in sequences]
    return np.median(np.concatenate(palms), axis=0)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def _grab(j: np.ndarray) -> np.ndarray:
    """Returns grab strength (n,) from joints (n, 22, 3) in mm."""
    curls = []
    for base, first, second, tip in FINGER_JOINTS[1:]:
        chain = [j[:, 0], j[:, base], j[:, first], j[:, second], j[:, tip]]
        bones = [_unit(b - a) for a, b in zip(chain, chain[1:], strict=False)]
        bend = sum(np.arccos(np.clip((a * b).sum(-1), -1, 1))
                   for a, b in zip(bones, bones[1:], strict=False))
        curls.append(np.clip(bend / GRAB_FULL_CURL, 0.0, 1.0))
    return np.mean(curls, axis=0)


def to_hands(joints_m: np.ndarray, offset_mm=DEFAULT_OFFSET_MM, side: str = "right",
             hand_id: int = 1) -> list[dict]:
    """Returns one contract hand (``cbgo/hands/frame``) per frame of (n, 22, 3) joints (m).

    Args:
        joints_m: the skeleton, world frame, metres.
        offset_mm: added to every position after scaling to mm (see the module docstring).
        side: the hand's side; every SHREC'17 hand is a right hand.
        hand_id: the tracking id to report.
    """
    j = joints_m * 1000.0 + np.asarray(offset_mm, dtype=float)
    direction = _unit(j[:, 10] - j[:, 0])
    normal = np.cross(j[:, 6] - j[:, 18], direction)
    normal = _unit(normal - (normal * direction).sum(-1, keepdims=True) * direction)
    if side == "left":
        normal = -normal
    palm = j[:, PALM_JOINT]
    velocity = np.gradient(palm, 1.0 / RATE_HZ, axis=0) if len(j) > 1 else np.zeros((1, 3))
    grab = _grab(j)
    pinch = pinch_strength(j[:, [5, 9, 13, 17, 21]], 1.0)
    width = np.linalg.norm(j[:, 6] - j[:, 18], axis=-1) * 1.25
    hands = []
    for i in range(len(j)):
        fingers = []
        for f, ftype in enumerate(FINGER_TYPES):
            base, first, second, tip = FINGER_JOINTS[f]
            start = j[i, base] if ftype == "thumb" else j[i, 0]
            chain = [start, j[i, base], j[i, first], j[i, second], j[i, tip]]
            fingers.append({"type": ftype, "bones": [
                {"type": btype, "prev_joint": chain[b].tolist(),
                 "next_joint": chain[b + 1].tolist(), "width": BONE_WIDTH_MM[f]}
                for b, btype in enumerate(BONE_TYPES)]})
        hands.append({
            "id": hand_id, "side": side, "confidence": 1.0,
            "palm_position": j[i, PALM_JOINT].tolist(), "palm_velocity": velocity[i].tolist(),
            "palm_normal": normal[i].tolist(), "direction": direction[i].tolist(),
            "wrist_position": j[i, 0].tolist(), "palm_width": float(width[i]),
            "grab_strength": float(grab[i]), "pinch_strength": float(pinch[i]),
            "fingers": fingers})
    return hands


def frames(seq: Sequence, t0: float = 0.0, offset_mm=DEFAULT_OFFSET_MM, hand_id: int = 1,
           seq0: int = 0) -> list[dict]:
    """Returns the sequence as ``cbgo/hands/frame`` messages at its recorded 30 Hz."""
    hands = to_hands(seq.joints(), offset_mm, hand_id=hand_id)
    return [{"v": SCHEMA_VERSION, "ts": t0 + i / RATE_HZ, "seq": seq0 + i, "source": "replay",
             "device": "shrec17", "hands": [hand]} for i, hand in enumerate(hands)]


# The directions of the swipes in the Leap frame, for labelling which stroke is the gesture.
SWIPE_DIRECTIONS = {"swipe_right": (1.0, 0.0, 0.0), "swipe_left": (-1.0, 0.0, 0.0),
                    "swipe_up": (0.0, 1.0, 0.0), "swipe_down": (0.0, -1.0, 0.0)}
# Gestures made of several straight strokes (an X, a +, a V): their parts are swipes of some
# direction, so they are neither a swipe nor "no gesture"; they are left out of training.
COMPOSITE = {11, 12, 13}
MIN_SWIPE_MM = 40.0


def label_windows(name: str, windows: list) -> list[str]:
    """Returns the truth of each segmenter window of one sequence of gesture `name`.

    In a swipe's sequence the swipe is the stroke that goes farthest in the swipe's direction
    (at least `MIN_SWIPE_MM`); every window of that stroke is the swipe, every other window
    (the preparation, the return, a twitch) is ``none``. Windows of the other gestures
    (grab, tap, pinch, shake, ...) are all ``none``.
    """
    labels = ["none"] * len(windows)
    direction = SWIPE_DIRECTIONS.get(name)
    if direction is None:
        return labels
    reach = {w.stroke: float(w.obs[-1, :3] @ np.asarray(direction))
             for w in windows if w.final}
    if not reach or max(reach.values()) < MIN_SWIPE_MM:
        return labels
    best = max(reach, key=reach.get)
    return [name if w.stroke == best else "none" for w in windows]


# Left out of training and of the false-trigger count: the composites (see `COMPOSITE`), and
# the two rotations, which roll the palm like our rotate and are neither it nor "no gesture".
NOT_TRAINED = COMPOSITE | {5, 6}


def segment(seq: Sequence, segmenter: Segmenter) -> list:
    """Returns the segmenter's windows of one sequence, the hand lost at its end."""
    return recording_windows([(m["ts"], m["hands"]) for m in frames(seq)], segmenter)


def recording_windows(frames: list[tuple], segmenter: Segmenter) -> list:
    """Returns the segmenter's windows of (time, hands) frames, the hand lost at the end."""
    out = [w for t, hands in frames for w in segmenter.update(t, hands)]
    return out + segmenter.update(frames[-1][0] + 1.0, [])


def sequence_windows(sequences: list[Sequence], config=None) -> list[tuple]:
    """Returns (sequence, windows, truths) of each sequence not in `NOT_TRAINED`."""
    out = []
    for seq in sequences:
        if seq.gesture not in NOT_TRAINED:
            windows = segment(seq, Segmenter(config))
            out.append((seq, windows, label_windows(seq.name, windows)))
    return out


def people_data(recordings: list[tuple], return_s: float) -> list[UserData]:
    """Returns one `simdata.UserData` per person: their windows as training sees them.

    Returns are dropped as the service drops them; in a swipe's recording, the strokes other
    than the swipe that move half as far as it (at least `MIN_SWIPE_MM`) are left out (a
    return the filter let through is as swipe-shaped as the swipe: calling it "none" would
    teach that swipes are nothing); shorter ones, preparations and twitches, are "none".
    """
    people: dict[int, UserData] = {}
    for seq, windows, truths in recordings:
        data = people.setdefault(seq.person, UserData(f"shrec{seq.person}", {"source": "shrec17"}))
        kept = without_returns([Labelled(w, t) for w, t in zip(windows, truths, strict=True)],
                               return_s)
        if seq.name in SWIPE_DIRECTIONS:
            swipe = [float(np.linalg.norm(lw.window.obs[-1, :3])) for lw in kept
                     if lw.truth != "none" and lw.window.final]
            limit = max(MIN_SWIPE_MM, 0.5 * max(swipe, default=0.0))
            kept = [lw for lw in kept if lw.truth != "none"
                    or float(np.linalg.norm(lw.window.obs[-1, :3])) < limit]
        data.windows += kept
    return [people[p] for p in sorted(people)]
