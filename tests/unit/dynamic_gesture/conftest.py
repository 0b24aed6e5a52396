"""Synthetic hand trajectories for the dynamic-gesture tests (contract-valid hands).

The helpers are handed to tests as the `synth` fixture (test modules do not import each other).
"""

import copy
import math
import types

import numpy as np
import pytest

from cbgo.examples import example
from cbgo.services.dynamic_gesture.stroke import DEFAULT_CENTRE_MM

CENTRE = np.array(DEFAULT_CENTRE_MM)


def hand(pos, roll=0.0, hand_id=1, side="right", grab=0.0):
    """A contract hand at `pos` (mm) whose palm is rolled by `roll` (rad) about -z."""
    out = copy.deepcopy(example("hands/frame")["hands"][0])
    out.update(id=hand_id, side=side, palm_position=[float(v) for v in pos],
               palm_normal=[math.sin(roll), -math.cos(roll), 0.0], direction=[0.0, 0.0, -1.0],
               grab_strength=grab)
    return out


def frame(t, hands, seq=0):
    """A contract hands/frame message at time t."""
    msg = copy.deepcopy(example("hands/frame"))
    msg.update(ts=float(t), seq=seq, hands=hands)
    return msg


def min_jerk(s):
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s**2)


def trajectory(segments, rate=60.0, start=CENTRE, tremor=0.0, seed=0):
    """Frames (t, pos, roll) from segments: ('hold', s), ('move', s, dxyz), ('roll', s, rad),
    ('moveroll', s, dxyz, rad)."""
    rng = np.random.default_rng(seed)
    pos, roll, t, out = np.asarray(start, float), 0.0, 0.0, []
    for seg in segments:
        n = max(1, int(round(seg[1] * rate)))
        for i in range(1, n + 1):
            s = min_jerk(i / n)
            if seg[0] == "move":
                p, r = pos + s * np.asarray(seg[2], float), roll
            elif seg[0] == "roll":
                p, r = pos, roll + s * seg[2]
            elif seg[0] == "moveroll":  # ('moveroll', s, dxyz, rad): both at once
                p, r = pos + s * np.asarray(seg[2], float), roll + s * seg[3]
            else:
                p, r = pos, roll
            out.append((t, p + rng.normal(0, tremor, 3), r))
            t += 1.0 / rate
        if seg[0] in ("move", "moveroll"):
            pos = pos + np.asarray(seg[2], float)
        if seg[0] in ("roll", "moveroll"):
            roll += seg[-1]
    return out


def feed(segmenter, traj, hand_id=1, side="right"):
    """Feeds a trajectory to a segmenter; returns every window."""
    windows = []
    for t, p, r in traj:
        windows += segmenter.update(t, [hand(p, r, hand_id, side)])
    return windows


def jumped(traj, at_s, offset):
    """The trajectory with the tracker's palm landing `offset` mm away from `at_s` on."""
    return [(t, p + (np.asarray(offset, float) if t >= at_s else 0.0), r) for t, p, r in traj]


@pytest.fixture
def synth():
    """The helpers above: hand, frame, trajectory, jumped, feed, CENTRE."""
    return types.SimpleNamespace(hand=hand, frame=frame, trajectory=trajectory, jumped=jumped,
                                 feed=feed, CENTRE=CENTRE)
