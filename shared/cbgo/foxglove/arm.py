"""The Panda / FR3 arm's links from its joint angles: forward kinematics, for drawing.

The Franka arms (Panda and FR3 share these numbers) are described by Craig's modified
Denavit-Hartenberg parameters (`DH`: a, d, alpha per joint; Franka's documentation, "Robot and
interface specifications"); each joint's frame is Rx(alpha) Tx(a) Rz(q) Tz(d) of the one before.
The flange is `FLANGE_D` further along the last axis and the TCP of the Franka Hand
`HAND_TCP_D` beyond it. `link_points` gives the base, every joint frame's origin, the flange
and the TCP in the base frame: a viewer draws the links between consecutive points. The web
page's scene.js carries the same table (`PANDA_DH`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

# (a, d, alpha) of joints 1..7, m and rad: Franka's published modified DH parameters
DH = ((0.0, 0.333, 0.0), (0.0, 0.0, -math.pi / 2), (0.0, 0.316, math.pi / 2),
      (0.0825, 0.0, math.pi / 2), (-0.0825, 0.384, -math.pi / 2), (0.0, 0.0, math.pi / 2),
      (0.088, 0.0, math.pi / 2))
FLANGE_D = 0.107  # m from joint 7's frame to the flange, along its z
HAND_TCP_D = 0.1034  # m from the flange to the Franka Hand's TCP (between the fingertips)


def _dh(a: float, d: float, alpha: float, q: float) -> np.ndarray:
    ca, sa, cq, sq = math.cos(alpha), math.sin(alpha), math.cos(q), math.sin(q)
    return np.array([[cq, -sq, 0.0, a],
                     [sq * ca, cq * ca, -sa, -d * sa],
                     [sq * sa, cq * sa, ca, d * ca],
                     [0.0, 0.0, 0.0, 1.0]])


def link_points(joints: Sequence[float]) -> list[tuple[float, float, float]]:
    """Returns the base, the origins of joint frames 1..7, the flange and the TCP (base frame, m).

    Raises:
        ValueError: not seven joint angles.
    """
    if len(joints) != len(DH):
        raise ValueError(f"expected {len(DH)} joint angles, got {len(joints)}")
    frame = np.eye(4)
    points = [(0.0, 0.0, 0.0)]
    for (a, d, alpha), q in zip(DH, joints, strict=True):
        frame = frame @ _dh(a, d, alpha, float(q))
        points.append(tuple(float(v) for v in frame[:3, 3]))
    for along in (FLANGE_D, FLANGE_D + HAND_TCP_D):
        points.append(tuple(float(v) for v in (frame @ np.array([0.0, 0.0, along, 1.0]))[:3]))
    return points
