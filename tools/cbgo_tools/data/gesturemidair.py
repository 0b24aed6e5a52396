"""GestureMidAir: Leap Motion fingertip paths of 13 people, the swipes carried by an open hand.

The set (``giach68/gesturesCodes``, folder ``datasetNew``; no licence file, so nothing of it is
committed: ``cbgo data fetch gesturemidair``) holds one take per person of 26 mid-air
gestures drawn with the index finger over a Leap Motion Controller: ``left-swipe`` and
``right-swipe``, and 24 shapes (circle, check, star, ...). Each ``PERSON/GESTURE.csv`` line is
``x y z t``: the index fingertip in mm in the Leap frame (+x right, +y up, +z towards the
user) and the time in ms. The people draw a line in the air: slow (peak speed 220-980 mm/s)
and short (100-390 mm) beside SHREC'17's swipes.

Split (``train_gestures.txt`` / ``test_gestures.txt`` list the people): the five **train**
people (andrea, chiara, claudio, elena, elenaf) are development data; the **test** people and
``davide`` (in neither list) are reserved for acceptance checks: `read_split` refuses to read
them unless asked by name (``split="test"``), and the benches print that they must never be
tuned on.

How a fingertip path becomes hand frames (`hand_frames`), every assumption written down:

- **An open hand carries it.** The calibrated mean ``five`` pose of a default right hand
  (`cbgo.hands.poses.gesture_mean`, palm down, fingers forward) is moved rigidly so that its
  index fingertip is on the path: the palm follows the fingertip's path translated, which is
  what a person drawing with a stiff hand does. The palm does not roll.
- **Time** is the file's, from its first sample (about 60 Hz); a sample whose time does not
  advance is dropped.
- **Rest before and after.** The files start and end at the stroke's ends; the hand is held
  still at the first point for `REST_S` before and at the last point for `REST_S` after (a
  person rests before drawing and after), at the file's median frame interval. The hand then
  leaves.
- **Truth.** ``left-swipe`` is ``swipe_left`` and ``right-swipe`` ``swipe_right``; the other 24
  shapes are drawn figures, not scored here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cbgo.config import cache_dir
from cbgo.hands.model import HandShape, build_hands
from cbgo.hands.poses import gesture_mean

SWIPES = {"left-swipe": "swipe_left", "right-swipe": "swipe_right"}
REST_S = 0.4


def default_root() -> Path:
    """Returns where ``cbgo data fetch gesturemidair`` puts the set."""
    return cache_dir() / "gesturemidair"


def is_set(root: Path) -> bool:
    """True when `root` looks like GestureMidAir's ``datasetNew`` folder."""
    return (root / "train_gestures.txt").is_file() and any(root.glob("*/left-swipe.csv"))


@dataclass(frozen=True)
class Drawing:
    """One drawn gesture: who drew what, and the file."""

    gesture: str
    person: str
    path: Path

    def samples(self) -> np.ndarray:
        """Returns (n, 4) rows ``x y z t_s`` (mm, seconds from the first), time advancing."""
        return read_samples(self.path)


def read_samples(path: Path) -> np.ndarray:
    """Returns a file's (n, 4) samples, time in s from the first; repeated times dropped.

    Raises:
        ValueError: a line does not hold 4 numbers, or fewer than 2 samples.
    """
    data = np.loadtxt(path, ndmin=2)
    if data.shape[1] != 4 or len(data) < 2:
        raise ValueError(f"{path}: expected lines of 'x y z t_ms', at least 2")
    t = (data[:, 3] - data[0, 3]) / 1000.0
    keep = np.concatenate([[True], np.diff(t) > 0])
    out = data[keep].copy()
    out[:, 3] = t[keep]
    return out


def split_people(root: Path, split: str) -> list[str]:
    """Returns the people of the ``train`` or ``test`` list."""
    return (root / f"{split}_gestures.txt").read_text().split()


def read_split(root: Path, split: str = "train", swipes_only: bool = True) -> list[Drawing]:
    """Returns the drawn gestures of a split's people (the swipes only by default).

    Raises:
        FileNotFoundError: not the set's folder.
    """
    if not is_set(root):
        raise FileNotFoundError(f"no GestureMidAir datasetNew folder at {root}: cbgo data fetch "
                                f"gesturemidair (then use {default_root()})")
    out = []
    for person in split_people(root, split):
        for path in sorted((root / person).glob("*.csv")):
            if swipes_only and path.stem not in SWIPES:
                continue
            out.append(Drawing(path.stem, person, path))
    return out


def _index_tip(hand: dict) -> np.ndarray:
    index = next(f for f in hand["fingers"] if f["type"] == "index")
    return np.asarray(index["bones"][-1]["next_joint"], dtype=float)


def hand_frames(samples: np.ndarray, hand_id: int = 1) -> list[tuple[float, list[dict]]]:
    """Returns (time, [hand]) frames of an open right hand whose index tip draws `samples`."""
    tips, t = samples[:, :3], samples[:, 3]
    dt = float(np.median(np.diff(t)))
    rest = max(1, round(REST_S / dt))
    before = t[0] - dt * np.arange(rest, 0, -1)
    after = t[-1] + dt * np.arange(1, rest + 1)
    times = np.concatenate([before, t, after]) - before[0]
    path = np.concatenate([np.repeat(tips[:1], rest, 0), tips, np.repeat(tips[-1:], rest, 0)])
    shape, pose = HandShape.default("right"), gesture_mean("five")
    reference = build_hands([shape], [pose], np.zeros((1, 3)))[0]
    palms = path - _index_tip(reference)
    velocities = np.gradient(palms, times, axis=0)
    hands = build_hands([shape] * len(palms), [pose] * len(palms), palms, velocities,
                        [hand_id] * len(palms))
    return [(float(ti), [h]) for ti, h in zip(times, hands, strict=True)]
