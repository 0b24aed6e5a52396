"""The vendored real Leap Motion recordings (``cbgo/data/leap_static_features.npz``).

Rules: this is TRAINING data (see ``cbgo/data/README.md`` for its origin and licence). The
evaluation split of the project lives outside the package and is never read here.
"""

from __future__ import annotations

import hashlib
from importlib import resources

import numpy as np

REAL_FEATURES_FILE = "leap_static_features.npz"


def _resource():
    return resources.files("cbgo.data") / REAL_FEATURES_FILE


def load_real_features() -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Loads the real recordings as features.

    Returns:
        ``(X, y, names)``: X float64 (N, 57) in the ``cbgo.hands.features`` order, y int64
        (N,) indices into ``names``, names the gesture names (grab, pinch, point, two, three,
        four, five, thumbsup).
    """
    with resources.as_file(_resource()) as path, np.load(path) as data:
        return (data["X"].astype(np.float64), data["y"].astype(np.int64),
                tuple(str(n) for n in data["names"]))


def real_features_sha256() -> str:
    """Returns the SHA-256 of the vendored file (recorded in ``poses.json``)."""
    return hashlib.sha256(_resource().read_bytes()).hexdigest()
