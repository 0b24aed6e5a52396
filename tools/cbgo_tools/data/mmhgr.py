"""Converts the HGR multi-modal Leap set's XML frames into the cache file the trainer reads.

The set, its layout and the vocabulary mapping are described in
`cbgo.services.static_gesture.mmhgr`, which loads the file this module writes.

Examples::

    cbgo data convert mmhgr SRC              # SRC: the multi_mod_hand_gest_recog folder
    cbgo data convert mmhgr SRC --out FILE   # elsewhere than the cache
    cbgo data convert mmhgr --info           # what the cache file holds
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import numpy as np

from cbgo.config import cache_dir
from cbgo.services.static_gesture.mmhgr import (
    AMBIGUOUS,
    POSE_MAP,
    POSES,
    SESSIONS,
    Frames,
    default_cache,
    load,
)

_FINGER_TAGS = ("Thumb", "Index", "Middle", "Ring", "Pinky")
_POINT_TAGS = ("mcpPosition", "pipPosition", "dipPosition", "TipPosition")
_NUM = r"([-+0-9.eE]+)"
_VEC = re.compile(r"<(\w+) type_id=\"opencv-matrix\">.*?<data>\s*" + r"\s+".join([_NUM] * 3)
                  + r"\s*</data>", re.S)
_SCALAR = re.compile(r"<(Confidence|PinchStrength|GrabStrength|isExtended)>\s*([-+0-9.eE]+)\s*<")
_FILE = re.compile(r"user_(\d+)/(train_pose|test_pose)/(\w+)/frame_(\d+)\.xml$")


def parse_frame(text: str) -> dict | None:
    """Parses one frame file; returns its first hand, or None when the frame has no hand.

    Returns:
        ``{side, palm, normal, direction, joints (5, 4, 3), extended (5,), confidence, grab,
        pinch}``.
    """
    start = text.find("<Hands>")
    end = text.find("</Hands>", start)
    if start < 0 or end < 0:
        return None
    block = text[start:end]
    side = re.search(r"<(Right|Left)>", block)
    if side is None:
        return None
    vectors: dict[str, list] = {}
    finger = None
    for m in re.finditer(r"<(Thumb|Index|Middle|Ring|Pinky)>|" + _VEC.pattern, block, re.S):
        if m.group(1):
            finger = m.group(1)
            continue
        tag = m.group(2)
        vectors[f"{finger}.{tag}" if finger and tag in _POINT_TAGS else tag] = [
            float(m.group(i)) for i in (3, 4, 5)]
    scalars: dict[str, list] = {}
    for m in _SCALAR.finditer(block):
        scalars.setdefault(m.group(1), []).append(float(m.group(2)))
    try:
        joints = [[vectors[f"{f}.{p}"] for p in _POINT_TAGS] for f in _FINGER_TAGS]
        return {"side": side.group(1).lower(), "palm": vectors["Center"],
                "normal": vectors["Normal"], "direction": vectors["Direction"],
                "joints": joints, "extended": scalars["isExtended"][:5],
                "confidence": scalars["Confidence"][0], "grab": scalars["GrabStrength"][0],
                "pinch": scalars["PinchStrength"][0]}
    except (KeyError, IndexError):
        return None




def convert(src: Path, out: Path, progress: bool = True) -> int:
    """Converts every frame file under ``src`` into the cache file ``out`` (atomically).

    Returns:
        The number of frames written (files without a hand are skipped).

    Raises:
        FileNotFoundError: ``src`` holds no ``user_NN/<session>/<pose>/frame_*.xml`` file.
    """
    files = sorted(p for p in Path(src).rglob("frame_*.xml") if _FILE.search(p.as_posix()))
    if not files:
        raise FileNotFoundError(f"no user_NN/<session>/<pose>/frame_*.xml under {src}")
    rows, meta = [], []
    t0 = time.monotonic()
    for n, path in enumerate(files):
        hand = parse_frame(path.read_text(errors="replace"))
        if hand is not None:
            rows.append(hand)
            meta.append(_FILE.search(path.as_posix()).groups())
        if progress and n % 5000 == 0:
            print(f"  {n}/{len(files)} files, {time.monotonic() - t0:.0f} s", file=sys.stderr)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f"tmp-{out.name}")
    np.savez_compressed(
        tmp, joints=np.array([r["joints"] for r in rows], dtype=np.float32),
        palm=np.array([r["palm"] for r in rows], dtype=np.float32),
        normal=np.array([r["normal"] for r in rows], dtype=np.float32),
        direction=np.array([r["direction"] for r in rows], dtype=np.float32),
        side=np.array([r["side"] for r in rows]),
        confidence=np.array([r["confidence"] for r in rows], dtype=np.float32),
        extended=np.array([r["extended"] for r in rows], dtype=bool),
        user=np.array([int(m[0]) for m in meta], dtype=np.int16),
        session=np.array([SESSIONS.index(m[1]) for m in meta], dtype=np.int8),
        pose=np.array([m[2] for m in meta]), frame=np.array([int(m[3]) for m in meta]))
    tmp.replace(out)
    return len(rows)




def _info(frames: Frames) -> None:
    print(f"{len(frames)} frames, {len(np.unique(frames.user))} people, sides "
          f"{dict(zip(*np.unique(frames.side, return_counts=True), strict=True))}")
    for pose in POSES:
        sel = frames.pose == pose
        ext = frames.extended[sel].mean(0)
        role = POSE_MAP.get(pose, "(ambiguous)" if pose in AMBIGUOUS else "(unknown)")
        print(f"  {pose:10s} → {role:12s} {int(sel.sum()):5d} frames; extended T I M R P "
              + " ".join(f"{e:.2f}" for e in ext)
              + f"; confidence {np.median(frames.confidence[sel]):.2f}")
    print("median tracking confidence per person: " + ", ".join(
        f"{u}: {np.median(frames.confidence[frames.user == u]):.2f}"
        for u in np.unique(frames.user)))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the source folder, the output file and ``--info``."""
    parser.add_argument("src", type=Path, nargs="?", default=cache_dir() / "mmhgr",
                        help="the multi_mod_hand_gest_recog folder [the fetched copy: "
                             "cbgo data fetch mmhgr]")
    parser.add_argument("--out", type=Path, default=None, help=f"[{default_cache()}]")
    parser.add_argument("--info", action="store_true",
                        help="print what the cache file (or --out) holds; convert nothing")


def run(args: argparse.Namespace) -> int:
    """Converts SRC into the cache file, or describes the cache file (``--info``)."""
    out = args.out or default_cache()
    if args.info:
        frames = load(out)
        if frames is None:
            print(f"no cache file at {out}; run `cbgo data convert mmhgr SRC` first",
                  file=sys.stderr)
            return 1
        _info(frames)
        return 0
    try:
        n = convert(args.src, out)
    except (OSError, ValueError) as exc:  # no copy there, or an unreadable frame
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {n} frames to {out}")
    return 0
