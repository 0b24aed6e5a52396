"""The Leap-to-base transform: the default places the sensor before the user; round trips."""

import numpy as np
import pytest

from cbgo.errors import ConfigError
from cbgo.transform import (
    base_to_leap,
    default_to_base,
    leap_to_base,
    parse_to_base,
)


def test_the_default_maps_leap_axes_to_the_users_view_of_the_table():
    m = default_to_base()
    assert np.allclose(leap_to_base(m, [0, 0, 0]), [1.0, 0.0, 0.0])
    assert np.allclose(leap_to_base(m, [0, 200, 0]), [1.0, 0.0, 0.2])    # up is up
    assert np.allclose(leap_to_base(m, [0, 0, 100]), [1.1, 0.0, 0.0])    # towards the user
    assert np.allclose(leap_to_base(m, [100, 0, 0]), [1.0, 0.1, 0.0])    # the user's right


def test_base_to_leap_inverts_leap_to_base_for_any_yaw():
    m = default_to_base((0.9, -0.2, 0.05), yaw_deg=30)
    p = np.array([12.0, 250.0, -40.0])
    assert np.allclose(base_to_leap(m, leap_to_base(m, p)), p)


def test_a_configured_matrix_must_be_a_scaled_rotation():
    assert np.allclose(parse_to_base(default_to_base().reshape(-1).tolist()), default_to_base())
    with pytest.raises(ConfigError, match="16 numbers"):
        parse_to_base([1.0] * 15)
    with pytest.raises(ConfigError, match="rotation scaled by 1/1000"):
        parse_to_base(np.eye(4).reshape(-1).tolist())
