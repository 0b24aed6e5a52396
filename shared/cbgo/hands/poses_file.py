"""Reading ``poses.json``, the calibrated hand data (``cbgo train hands`` writes it).

Its own module because both the hand model (`cbgo.hands.model`: the default hand's shape) and
the gesture poses (`cbgo.hands.poses`) read it; neither imports the other for it.
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

from cbgo.wire import STATIC_GESTURES

POSES_FILE = "poses.json"


@lru_cache(maxsize=1)
def load_poses() -> dict:
    """Returns the parsed ``poses.json`` (cached)."""
    text = (resources.files("cbgo.hands") / POSES_FILE).read_text()
    data = json.loads(text)
    missing = set(STATIC_GESTURES) - set(data["gestures"])
    if missing:
        raise ValueError(f"poses.json lacks {sorted(missing)}; rerun `cbgo train hands` "
                         "(the offline tools of a cbgo checkout)")
    return data


def default_shape_parameters() -> dict:
    """Returns the calibrated default hand: ``poses.json``'s "shape" section.

    Keys: scale, wrist_mm, phalanx_factors (thumb..pinky), thumb_cmc_mm (millimetres at
    scale 1).
    """
    return load_poses()["shape"]
