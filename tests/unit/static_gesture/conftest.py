"""Fixtures: tiny models trained in a second, written where a test wants them."""

import numpy as np
import pytest

from cbgo.services.static_gesture import train
from cbgo.wire import STATIC_GESTURES


def tiny_model(base, seed=0, names=(*STATIC_GESTURES, "none")):
    """Trains a small, rough model on random rows (shape and metadata are what matter)."""
    rng = np.random.default_rng(seed)
    y = np.repeat(np.arange(len(names)), 8)
    x = rng.normal(0.0, 1.0, (len(y), 57)) + y[:, None]
    data = train.Dataset(x, y, list(names), np.full(len(y), "real"))
    trained = train.fit(data, train.TrainOptions(hidden=[4], epochs=1, seed=seed))
    return train.save_model(base, trained)


@pytest.fixture
def make_model(tmp_path):
    """Returns a function writing a tiny model (a name in tmp_path, or a path).

    The function returns (pt, json, model id).
    """
    return lambda where="m", **kw: tiny_model(tmp_path / where, **kw)
