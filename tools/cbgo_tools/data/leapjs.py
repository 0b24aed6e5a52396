"""Real Leap Motion recordings in LeapJS's JSON frame format (the Guinevere set) as hand frames.

A second real data set beside SHREC'17 (`shrec`): a different sensor (a Leap Motion
Controller, LeapJS / SDK v2-v4 frames at 100-120 Hz) and different people. The **Guinevere**
set (UCLouvain; 4 people, 23 dynamic gestures, 4 takes each; a public copy in the GitHub
repository ``sluyters/QuantumLeap``, folder ``backend/src/datasets/dynamic/guinevere``) holds
swipes in the four directions with the palm or the index finger, palm rotations and hand
gestures that are no swipe (tap, pinch, thumbs, hand opening). It has no licence file, so
nothing of it is committed: fetch that folder into the cache (``cbgo data fetch guinevere``) and
point ``cbgo bench dynamic --real DIR`` at it. It is used for **evaluation only**: nothing
is fitted, tuned or selected on it.

Conversion (every assumption written down):

- **Frames.** As `cbgo_tools.data.leapjs_frames` converts LeapJS frames (axes, units, time and bones
  are written down there): nothing is moved or turned.
- **Labels.** A file ``NAME-TAKE.json`` in a person's folder; ``NAME`` may carry a variant
  after ``#`` (``swipe_left#palm``, ``swipe_up#index``). The swipes map to ours; ``turn_*``
  (a palm turned like a key) is left out of the swipe scores, as SHREC'17's rotations are;
  every other gesture is a hard "no gesture" case.

**Both hands: ``leapmotion-all``.** Both sets above are right hands. The same repository's
history holds another LeapJS set, ``leapmotion-all`` (commit ``bec964af``, folder
``backend/src/datasets/dynamic/leapmotion-all``; no licence file either), in which 16 people
each made a "previous" and a "next" gesture of their own choosing, with the right hand or the
left. Its labels are commands, not directions, so `swipe_of` reads each recording's swipe from
the palm path of the hand that moves most along x, by a rule written down once
(`SWIPE_RULE`): one tracking id throughout, at least 0.3 s and 100 mm along x, at most 0.8 of
that across (y or z), and it ends at least 0.4 of its x range from where it started (a hand
that swipes and comes back all the way could have meant either move). 20 of its 32 recordings
pass, 12 people: 10 left-hand and 10 right-hand swipes.

- ``cbgo data convert leapmotion-all [SRC [DST]]`` writes them as a set of
  the layout above, each recording whole (every hand it holds, as a sensor reports them), for
  ``cbgo bench dynamic --real DST``;
- ``... --left-only`` writes only the left-hand ones, left-hand frames only: real left
  hands alone.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cbgo.config import cache_dir
from cbgo_tools.data.leapjs_frames import to_frames, vector


@dataclass(frozen=True)
class SwipeRule:
    """When a ``leapmotion-all`` recording is a swipe along x, and which (`swipe_of`)."""

    min_s: float = 0.3  # the moving hand is seen this long at least
    min_span_mm: float = 100.0  # its palm's range along x
    across_max: float = 0.8  # its range along y and along z, at most this share of x's
    away_min: float = 0.4  # first to last frame along x, at least this share of x's range


SWIPE_RULE = SwipeRule()

SWIPES = ("swipe_right", "swipe_left", "swipe_up", "swipe_down")
NOT_SCORED = ("turn_clockwise", "turn_counter_clockwise")
# Moves along one direction with another hand shape (an opening hand) or a curved path: no
# swipe of the set, yet swipe-shaped, so they are reported apart (and kept out of streams).
SWIPE_LIKE = ("open_hand_", "C_swipe_")


@dataclass(frozen=True)
class Recording:
    """One recorded gesture.

    Attributes:
        gesture: the data set's gesture name without its variant (``swipe_left``).
        variant: what follows ``#`` in the file name ("" if nothing).
        person: the person's folder name.
        take: the take number.
        path: the JSON file.
    """

    gesture: str
    variant: str
    person: str
    take: int
    path: Path

    def frames(self) -> list[dict]:
        """Returns the recording as ``cbgo/hands/frame`` messages (see the module docstring)."""
        return to_frames(json.loads(self.path.read_text()))


def read_set(root: Path) -> list[Recording]:
    """Returns every recording under `root` (a folder of person folders, at any depth).

    Raises:
        FileNotFoundError: no recording there.
    """
    out = []
    for path in sorted(Path(root).rglob("*-*.json")):
        stem, _, take = path.stem.rpartition("-")
        if not take.isdigit():
            continue
        gesture, _, variant = stem.partition("#")
        out.append(Recording(gesture, variant, path.parent.name, int(take), path))
    if not out:
        raise FileNotFoundError(
            f"no LeapJS recordings (NAME-TAKE.json) under {root}: fetch the Guinevere set of "
            f"github.com/sluyters/QuantumLeap (cbgo data fetch guinevere, then use "
            f"{cache_dir() / 'guinevere'}), or write leapmotion-all's swipes there (cbgo data "
            f"fetch leapmotion-all; cbgo data convert leapmotion-all SRC {root})")
    return out


def left_hand_only(recording: dict) -> dict:
    """Returns a parsed LeapJS recording with its right hands (and their fingers) removed."""
    frames = []
    for frame in recording["data"]:
        hands = [h for h in frame["hands"] if h.get("type") == "left"]
        ids = {h["id"] for h in hands}
        frames.append({**frame, "hands": hands,
                       "pointables": [p for p in frame.get("pointables", [])
                                      if p.get("handId") in ids]})
    return {**recording, "data": frames}


def swipe_of(recording: dict, rule: SwipeRule = SWIPE_RULE) -> tuple[str, str] | None:
    """Returns (side, swipe_left or swipe_right) of a parsed LeapJS recording, or None.

    The hand is the side whose palm ranges farthest along x; the swipe is where that palm
    went from its first frame to its last, when the recording passes `rule`.

    Raises:
        KeyError, ValueError: a hand's field is missing or malformed.
    """
    tracks: dict[str, list[tuple[float, int, list[float]]]] = {}
    for frame in recording["data"]:
        for hand in frame["hands"]:
            tracks.setdefault(hand["type"], []).append(
                (float(frame["timestamp"]) / 1e6, int(hand["id"]), vector(hand["palmPosition"])))
    if not tracks:
        return None
    side, track = max(tracks.items(), key=lambda kv: np.ptp([p[0] for _, _, p in kv[1]]))
    times = [t for t, _, _ in track]
    palms = np.array([p for _, _, p in track])
    span = np.ptp(palms, axis=0)
    away = float(palms[-1, 0] - palms[0, 0])
    if (len({hand_id for _, hand_id, _ in track}) > 1 or times[-1] - times[0] < rule.min_s
            or span[0] < rule.min_span_mm or max(span[1], span[2]) > rule.across_max * span[0]
            or abs(away) < rule.away_min * span[0]):
        return None
    return side, "swipe_right" if away > 0 else "swipe_left"


def arrange_swipes(src: Path, dst: Path, sides: tuple[str, ...] = ("left", "right")) -> int:
    """Writes the swipes (`swipe_of`) of a ``leapmotion-all`` folder as a set `read_set` reads.

    ``dst/participant-P/swipe_X-T.json``: a swipe of `sides` only; whole with both sides,
    else the left hand's frames only. Returns how many it wrote.

    Raises:
        OSError: `src` holds no recording, or one is unreadable.
        ValueError, KeyError: a recording is not LeapJS JSON.
    """
    paths = sorted(Path(src).glob("*/participant-*.json"))
    if not paths:
        raise FileNotFoundError(f"no participant-P-T.json recordings under {src}/<command>/: "
                                "copy the leapmotion-all folder there")
    written = 0
    for path in paths:
        recording = json.loads(path.read_text())
        swipe = swipe_of(recording)
        if swipe is None or swipe[0] not in sides:
            continue
        person, _, take = path.stem.rpartition("-")
        out = Path(dst) / person / f"{swipe[1]}-{take}.json"
        if out.exists():
            raise ValueError(f"two recordings of {person} would both be {out.name}")
        out.parent.mkdir(parents=True, exist_ok=True)
        whole = set(sides) == {"left", "right"}
        out.write_text(json.dumps(recording if whole else left_hand_only(recording)))
        written += 1
    return written


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the source folder, where the set goes, and ``--left-only``."""
    parser.add_argument("src", type=Path, nargs="?", default=cache_dir() / "leapmotion-all",
                        help="the leapmotion-all folder (precedent/, suivant/) [the fetched copy]")
    parser.add_argument("dst", type=Path, nargs="?", default=None,
                        help="where to write the set [leapmotion-swipes, or leapmotion-left "
                             "with --left-only, in the cache]")
    parser.add_argument("--left-only", action="store_true",
                        help="only the left-hand swipes, left-hand frames only")


def run(args: argparse.Namespace) -> int:
    """Writes the swipes as a set for ``cbgo bench dynamic --real``."""
    sides = ("left",) if args.left_only else ("left", "right")
    dst = args.dst or cache_dir() / ("leapmotion-left" if args.left_only else "leapmotion-swipes")
    try:
        count = arrange_swipes(args.src, dst, sides)
    except (OSError, ValueError, KeyError) as exc:  # missing, unreadable or not LeapJS JSON
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {count} {'swipes' if len(sides) == 2 else 'left-hand swipes'} under "
          f"{dst}; cbgo bench dynamic --real {dst} --per-class 0")
    return 0
