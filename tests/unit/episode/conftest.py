"""An in-memory driver for the episode service: frames, gesture messages, gaze and time."""

import importlib.util
import sys
from pathlib import Path

import pytest

from cbgo import keys
from cbgo.examples import open_hand
from cbgo.services.episode.main import Episode, EpisodeSettings
from cbgo.testing import FakeBus
from cbgo.transform import default_to_base
from cbgo.wire import DYNAMIC_GESTURES, STATIC_GESTURES

STATIC_NAMES = [*STATIC_GESTURES, "none"]
DYNAMIC_NAMES = [*DYNAMIC_GESTURES, "none"]
T0 = 1000.0  # the frames' clock at the driver's time 0


def probs(names, label, p):
    """A probability vector: p on label, the rest shared by the others."""
    rest = (1.0 - p) / (len(names) - 1)
    return [p if n == label else rest for n in names]


class Drive:
    """Feeds the episode service through FakeBus on a simulated clock.

    `now` is the driver's time (s): the service's local clock, and the frames' ts minus T0.
    """

    def __init__(self, rate_hz=60.0, **settings):
        self.svc = Episode(EpisodeSettings(**settings))
        self.now = 0.0
        self.svc.clock = lambda: self.now
        self.svc.wall = lambda: T0 + self.now
        self.bus = FakeBus(self.svc)
        self.period = 1.0 / rate_hz
        self.seq = 0
        self.to_base = default_to_base().reshape(-1).tolist()

    def frame(self, hands=None, to_base=True):
        """Advances one frame period and publishes a frame (default: one open hand)."""
        self.now += self.period
        hands = [open_hand()] if hands is None else hands
        msg = {"v": 1, "ts": T0 + self.now, "seq": self.seq, "source": "simulated",
               "device": "test", "hands": hands}
        if to_base:
            msg["to_base"] = self.to_base if to_base is True else to_base
        self.seq += 1
        return self.bus.feed(keys.HANDS_FRAME, msg) + self.bus.tick(self.period)

    def static(self, label, p=0.9, seq=None, side="right", names=STATIC_NAMES):
        """Publishes a static message about the last frame (or frame `seq`)."""
        return self.bus.feed(keys.GESTURES_STATIC, {
            "v": 1, "ts": T0 + self.now, "seq": self.seq - 1 if seq is None else seq,
            "hand_id": 1, "side": side, "names": list(names), "probs": probs(names, label, p),
            "model": "test"})

    def dynamic(self, label, t_start, t_end, p=0.9, side="right", names=DYNAMIC_NAMES):
        """Publishes a dynamic window [t_start, t_end] (driver times)."""
        return self.bus.feed(keys.GESTURES_DYNAMIC, {
            "v": 1, "ts": T0 + self.now, "seq": self.seq, "hand_id": 1, "side": side,
            "names": list(names), "probs": probs(names, label, p),
            "window": [T0 + t_start, T0 + t_end], "model": "test"})

    def gaze(self, point):
        return self.bus.feed(keys.GAZE, {"v": 1, "ts": T0 + self.now, "point": list(point),
                                         "source": "simulated"})

    def hold(self, seconds, label=None, p=0.9, hand=None):
        """Frames with a hand for `seconds`, each followed by a static message of label."""
        out = []
        for _ in range(round(seconds / self.period)):
            out += self.frame([hand or open_hand()])
            if label is not None:
                out += self.static(label, p)
        return out

    def empty(self, seconds):
        """Frames without a hand for `seconds`."""
        out = []
        for _ in range(round(seconds / self.period)):
            out += self.frame([])
        return out

    def tick(self, seconds):
        """Advances the clock without frames (the timer runs)."""
        self.now += seconds
        return self.bus.tick(seconds)

    def of(self, suffix, kind=None):
        return [m for k, m in self.bus.published
                if k == suffix and (kind is None or m.get("kind") == kind)]

    @property
    def summaries(self):
        return self.of("episode/summary")


@pytest.fixture
def drive():
    """Returns the Drive class: ``d = drive(debounce_s=0.1)``."""
    return Drive


@pytest.fixture(scope="session")
def scripted():
    """The test-side scripted classifier module (tests/fakes/scripted_gestures.py)."""
    path = Path(__file__).parents[2] / "fakes" / "scripted_gestures.py"
    spec = importlib.util.spec_from_file_location("scripted_gestures", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["scripted_gestures"] = module
    spec.loader.exec_module(module)
    return module
