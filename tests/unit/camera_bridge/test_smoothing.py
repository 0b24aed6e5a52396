"""The One-Euro filter of camera-bridge's landmarks: less jitter when still, little lag moving."""

import numpy as np

from cbgo.services.camera_bridge.smoothing import OneEuro


def run(filter_, path, dt=1 / 30):
    return np.array([filter_(p, k * dt) for k, p in enumerate(path)])


def test_the_first_frame_passes_through_and_a_repeated_time_changes_nothing():
    f = OneEuro()
    first = np.array([[1.0, 2.0, 3.0]])
    assert np.array_equal(f(first, 1.0), first)
    assert np.array_equal(f(first + 50.0, 1.0), first)


def test_a_still_hands_jitter_shrinks():
    rng = np.random.default_rng(0)
    noisy = rng.normal(0.0, 5.0, (300, 21, 3)) + [0.0, 200.0, 0.0]
    out = run(OneEuro(), noisy)
    raw_step = np.linalg.norm(np.diff(noisy, axis=0), axis=-1).mean()
    step = np.linalg.norm(np.diff(out, axis=0), axis=-1).mean()
    assert step < raw_step / 3


def test_a_fast_swipe_is_followed_closely_and_a_slow_one_more_smoothly():
    t = np.arange(60) / 30
    def lag(speed):
        path = np.zeros((60, 1, 3))
        path[:, 0, 0] = speed * t
        return abs(run(OneEuro(), path)[-1, 0, 0] - path[-1, 0, 0])
    assert lag(800.0) < 25.0  # mm behind a 0.8 m/s swipe after 2 s
    assert lag(800.0) / 800.0 < lag(50.0) / 50.0  # relatively less lag when fast
