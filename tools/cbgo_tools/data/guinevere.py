"""Guinevere's static poses (another Leap Motion, another person) as takes to score.

Why: beside the paper's recordings (older Leap SDK), the HGR set (Leap SDK v2) and Ultraleap's
single Gemini frames, this is one more real sensor and person the model never saw, with a
relaxed hand among the poses: a relaxed, half-open hand that should be answered `none`.

The set: ``guinevre-static2`` in the GitHub repository ``sluyters/QuantumLeap`` (folder
``backend/src/datasets/static/guinevre-static2``; UCLouvain), one person's right hand held
still over a Leap Motion Controller, LeapJS frames at about 55 Hz (``grabAngle`` and
``pinchDistance`` fields: SDK v3/v4 tracking), a folder per pose with files ``POSE-TAKE.json``.
It has no licence file: nothing of it is in this repository; ``cbgo data fetch
guinevere-static`` copies the folder into the cache and ``cbgo data convert guinevere-static``
converts it here. It is **evaluation only**: nothing is fitted, tuned or selected on it.

Which poses are scored, as what (`POSES`), and why the others are not:

- ``point-index`` → ``point``; ``thumb`` → ``thumbsup``; ``flat`` → ``five``;
- ``idle`` → an unknown pose (a relaxed, half-open hand resting over the sensor): right where
  it is rejected (``none``, or top p < 0.5);
- ``grab`` and ``pinch`` are left out: their hands are neither the paper's grab nor its pinch.
  The tracker's own values say so (`describe` prints them): in ``grab`` the thumb and index
  tips touch (median ``pinchStrength`` 0.94) with the other fingers curled and the hand far
  from a fist (median ``grabStrength`` 0.33; the paper's grab is a fist); in ``pinch`` every
  finger but the index is curled, the index often too, with the thumb and index tips 35 mm
  apart (the paper's pinch holds the last three fingers open, an ok sign). Scoring them as
  ours would measure the labels, not the model.

Frames are converted by `cbgo_tools.data.leapjs_frames` (axes, units and bones written down
there) and written as MCAP recordings of ``hands/frame`` (`cbgo.recording`), one per take, named
``LABEL-POSE-TAKE.mcap``; ``cbgo bench static`` scores them when they are in the cache
(`cached_takes`), as ``--takes`` scores a user's own takes (`takes`). A take missing from
a copy is not scored; one that cannot be read is skipped with a line saying why.

Examples::

    cbgo data fetch guinevere-static     # the guinevre-static2 folder, into the cache
    cbgo data convert guinevere-static   # → takes in the cache; prints the line that scores them
    cbgo data convert guinevere-static SRC DST   # another copy of the folder, other takes folder
    cbgo bench static --no-crossval --no-latency # scores the cached takes among its figures
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from cbgo import keys, wire
from cbgo.config import cache_dir
from cbgo.recording import Recorder
from cbgo_tools.data.leapjs_frames import to_frames

POSES = {"point-index": "point", "thumb": "thumbsup", "flat": "five", "idle": "idle"}
"""Guinevere's pose folders → the label a take is scored as (``idle``: an unknown pose)."""
LEFT_OUT = ("grab", "pinch")
"""Poses whose hands are not the paper's gestures of those names (module docstring)."""
DEFAULT_DST = cache_dir() / "guinevere-static-takes"
KEY = f"cbgo/{keys.HANDS_FRAME.suffix}"


def recordings(src: Path) -> list[tuple[str, int, Path]]:
    """Returns (pose, take, file) of every ``POSE-TAKE.json`` under src.

    Raises:
        FileNotFoundError: none there.
    """
    out = []
    for path in sorted(Path(src).rglob("*-*.json")):
        pose, _, take = path.stem.rpartition("-")
        if take.isdigit():
            out.append((pose, int(take), path))
    if not out:
        raise FileNotFoundError(
            f"no LeapJS takes (POSE-TAKE.json) under {src}: copy the guinevre-static2 folder of "
            "github.com/sluyters/QuantumLeap (backend/src/datasets/static/guinevre-static2)")
    return out


def describe(recording: dict) -> dict:
    """Returns the tracker's own view of a take: median strengths and the usual finger flags.

    Hands without those values are passed over (`to_frames` counts the unreadable ones).
    """
    grab, pinch, flags = [], [], {}
    for frame in recording["data"]:
        for hand in frame.get("hands") or []:
            try:
                strengths = float(hand["grabStrength"]), float(hand["pinchStrength"])
                own = sorted((p for p in frame.get("pointables") or []
                              if p.get("handId") == hand["id"]), key=lambda p: p["type"])
            except (KeyError, TypeError, ValueError):
                continue
            grab.append(strengths[0])
            pinch.append(strengths[1])
            pattern = "".join("1" if p.get("extended") else "0" for p in own)
            flags[pattern] = flags.get(pattern, 0) + 1
    common = max(flags, key=flags.get) if flags else ""
    return {"hands": len(grab), "grab_strength": float(np.median(grab)) if grab else None,
            "pinch_strength": float(np.median(pinch)) if pinch else None,
            "extended": common, "extended_share": flags.get(common, 0) / max(len(grab), 1)}


def write_take(frames: list[dict], path: Path, start_ns: int = 1_700_000_000_000_000_000) -> int:
    """Writes hands/frame messages as an MCAP recording; returns the messages written."""
    with Recorder(path, prefix="cbgo", keys=[KEY],
                  metadata={"source": "guinevre-static2 (sluyters/QuantumLeap)"}) as rec:
        for frame in frames:
            t_ns = start_ns + int(frame["ts"] * 1e9)
            rec.write(KEY, wire.encode({**frame, "ts": t_ns / 1e9}), t_ns)
    return len(frames)


def convert(src: Path, dst: Path) -> list[str]:
    """Writes the scored poses' takes under dst; returns their ``LABEL=FILE`` arguments."""
    dst.mkdir(parents=True, exist_ok=True)
    specs = []
    for pose, take, path in recordings(src):
        if pose not in POSES and pose not in LEFT_OUT:
            print(f"  {path.name}: left out (a pose this converter does not know)")
            continue
        try:
            recording = json.loads(path.read_text())
            rejected: Counter = Counter()
            frames = to_frames(recording, rejected)
            seen = _tracker_line(describe(recording))
        except (OSError, ValueError, KeyError, TypeError) as e:
            print(f"  {path.name}: skipped, unreadable ({type(e).__name__}: {e})"[:200])
            continue
        if pose in LEFT_OUT:
            print(f"  {path.name}: left out, not the paper's {pose}; {seen}")
            continue
        out = dst / f"{POSES[pose]}-{pose}-{take}.mcap"
        bad = (f"; left out as unreadable: {', '.join(f'{n} {why}' for why, n in rejected.items())}"
               if rejected else "")
        print(f"  {path.name} → {out.name}: {write_take(frames, out)} frames; {seen}{bad}")
        specs.append(f"{POSES[pose]}={out}")
    return specs


def _tracker_line(seen: dict) -> str:
    if not seen["hands"]:
        return "no hand"
    return (f"{seen['hands']} hands, tracker: grab {seen['grab_strength']:.2f}, pinch "
            f"{seen['pinch_strength']:.2f}, fingers extended (thumb..pinky) {seen['extended']} "
            f"in {seen['extended_share']:.0%}")


def cached_takes(directory: Path = DEFAULT_DST) -> list[str]:
    """Returns the ``LABEL=FILE`` arguments of the takes `convert` wrote there ([] if none)."""
    paths = sorted(Path(directory).glob("*-*-*.mcap")) if Path(directory).is_dir() else []
    return [f"{path.name.split('-', 1)[0]}={path}" for path in paths]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the source folder and where the takes go."""
    parser.add_argument("src", type=Path, nargs="?", default=cache_dir() / "guinevere-static",
                        help="the guinevre-static2 folder [the fetched copy]")
    parser.add_argument("dst", type=Path, nargs="?", default=DEFAULT_DST,
                        help=f"where to write the takes [{DEFAULT_DST}]")


def run(args: argparse.Namespace) -> int:
    """Writes the takes and prints the command that scores them."""
    try:
        specs = convert(args.src, args.dst)
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if not specs:
        print("error: no take of a scored pose could be read", file=sys.stderr)
        return 2
    print(f"wrote {len(specs)} takes under {args.dst}; score them with:\n"
          f"cbgo bench static --takes {' '.join(specs)}")
    return 0
