"""The transform between the Leap frame (mm) and the robot base frame (m).

Leap frame: origin at the sensor's top centre, +y up, +z towards the user, +x to the user's
right. Robot base frame: +z up, table top at z = 0. The default puts the sensor on the table in
front of the robot, where the user stands, looking up: the user faces the robot across the
table (towards -x of the base), so Leap +z (towards the user) is base +x, Leap +y is base +z and
Leap +x (the user's right) is base +y.

This module is the only place that converts between the two frames; other services read the
matrix from the frames' ``to_base`` field.
"""

from __future__ import annotations

import numpy as np

from cbgo.errors import ConfigError

# Where the sensor sits in the robot base frame by default (m): 1 m in front of the robot
# base, on the table top, centred.
DEFAULT_SENSOR_POSITION = (1.0, 0.0, 0.0)

# Columns: the Leap x, y, z axes expressed in the base frame (default orientation).
_LEAP_AXES_IN_BASE = np.array([[0.0, 0.0, 1.0],
                               [1.0, 0.0, 0.0],
                               [0.0, 1.0, 0.0]])


def default_to_base(sensor_position=DEFAULT_SENSOR_POSITION, yaw_deg: float = 0.0) -> np.ndarray:
    """Returns the 4×4 Leap(mm)→base(m) transform of a sensor at `sensor_position` (m).

    Args:
        sensor_position: the sensor's top centre in the base frame, metres.
        yaw_deg: rotation of the sensor about the vertical axis (0: the user faces -x).
    """
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    yaw = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    matrix = np.eye(4)
    matrix[:3, :3] = yaw @ _LEAP_AXES_IN_BASE / 1000.0  # mm -> m
    matrix[:3, 3] = sensor_position
    return matrix


def parse_to_base(values: list[float]) -> np.ndarray:
    """Returns a 4×4 transform from 16 row-major numbers, checking it is rigid (plus mm→m).

    Raises:
        ConfigError: not 16 numbers, not finite, or the rotation part is not a rotation × 1/1000.
    """
    if len(values) != 16:
        raise ConfigError(f"to_base needs 16 numbers (row-major 4x4), got {len(values)}")
    matrix = np.asarray(values, dtype=float).reshape(4, 4)
    if not np.all(np.isfinite(matrix)):
        raise ConfigError("to_base has non-finite numbers")
    rotation = matrix[:3, :3] * 1000.0
    if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-3) or not np.allclose(
            matrix[3], [0, 0, 0, 1]):
        raise ConfigError("to_base must be a rotation scaled by 1/1000 (mm -> m) plus a "
                          "translation, with last row 0 0 0 1")
    return matrix


def leap_to_base(matrix: np.ndarray, point_mm) -> np.ndarray:
    """Returns a Leap-frame point (mm) in the base frame (m)."""
    return matrix[:3, :3] @ np.asarray(point_mm, dtype=float) + matrix[:3, 3]


def base_to_leap(matrix: np.ndarray, point_m) -> np.ndarray:
    """Returns a base-frame point (m) in the Leap frame (mm)."""
    rotation = matrix[:3, :3]
    # rotation is R/1000 with R orthonormal, so its inverse is R.T * 1000 = rotation.T * 1e6.
    return (rotation.T * 1e6) @ (np.asarray(point_m, dtype=float) - matrix[:3, 3])
