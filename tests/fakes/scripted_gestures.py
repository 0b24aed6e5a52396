"""A stand-in for the static- and dynamic-gesture services, for tests (never imported by cbgo).

It knows the scenario the leap-bridge's simulated user performs, regenerates it frame by frame
(the simulated user is deterministic), and recognises each received frame by its exact palm
position: the ground-truth label of that frame becomes a scripted classifier output.

- ``gestures/static``: one message per frame and hand; the label gets ``confidence`` when it is
  a static gesture, else the class ``none`` does; the rest is shared by the other classes.
- ``gestures/dynamic``: one window per stroke: when a run of frames labelled with a dynamic
  gesture ends (the next frame has another label, or no hand), a window over that run with the
  stroke's label at ``confidence``.

`ScriptedClassifier` is the logic (tests use it in memory); run as a script, it is a service
named ``scripted-gestures`` (``python tests/fakes/scripted_gestures.py --scenario FILE``).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

from cbgo import keys
from cbgo.runtime import Service, run
from cbgo.simuser.scenario import load_scenario
from cbgo.simuser.user import SimulatedUser
from cbgo.transform import default_to_base
from cbgo.wire import DYNAMIC_GESTURES, STATIC_GESTURES

STATIC_NAMES = [*STATIC_GESTURES, "none"]
DYNAMIC_NAMES = [*DYNAMIC_GESTURES, "none"]


def vector(names, label, confidence):
    """Returns probs over names: `confidence` on label, the rest shared by the others."""
    rest = (1.0 - confidence) / (len(names) - 1)
    return [confidence if n == label else rest for n in names]


def scenario_labels(scenario, rate_hz, to_base=None):
    """Returns {palm position tuple: label} of every visible frame of a scenario."""
    to_base = default_to_base() if to_base is None else to_base
    user = SimulatedUser(scenario, rate_hz, lambda g: g if isinstance(g, list) else None, to_base)
    return {tuple(f.hands[0]["palm_position"]): f.label for f in user.frames() if f.hands}


class ScriptedClassifier:
    """Turns frames into scripted static and dynamic gesture messages.

    Args:
        labels: {palm position tuple: ground-truth label}.
        confidence: the probability given to the true class.
    """

    def __init__(self, labels, confidence=0.9):
        self.labels, self.confidence = labels, confidence
        self.runs = {}  # side -> [label, t0, t_last, seq]
        self.matched = self.unmatched = 0

    def on_frame(self, frame):
        """Returns [(topic, message)] for one hands/frame message."""
        out, seen = [], set()
        for hand in frame["hands"]:
            key = tuple(hand["palm_position"])
            label = self.labels.get(key)
            if key in self.labels:
                self.matched += 1
            else:
                self.unmatched += 1
            static = label if label in STATIC_GESTURES else "none"
            out.append((keys.GESTURES_STATIC, {
                "v": 1, "ts": frame["ts"], "seq": frame["seq"], "hand_id": hand["id"],
                "side": hand["side"], "names": STATIC_NAMES,
                "probs": vector(STATIC_NAMES, static, self.confidence), "model": "scripted"}))
            out += self._stroke(hand["side"], hand["id"], label, frame)
            seen.add(hand["side"])
        for side in list(self.runs):
            if side not in seen:
                out += self._close(side, self.runs[side][3], frame)
        return out

    def _stroke(self, side, hand_id, label, frame):
        run_ = self.runs.get(side)
        if run_ is not None and run_[0] == label:
            run_[2] = frame["ts"]
            return []
        out = self._close(side, hand_id, frame) if run_ is not None else []
        if label in DYNAMIC_GESTURES:
            self.runs[side] = [label, frame["ts"], frame["ts"], hand_id]
        return out

    def _close(self, side, hand_id, frame):
        label, t0, t1, _ = self.runs.pop(side)
        return [(keys.GESTURES_DYNAMIC, {
            "v": 1, "ts": frame["ts"], "seq": frame["seq"], "hand_id": hand_id, "side": side,
            "names": DYNAMIC_NAMES, "probs": vector(DYNAMIC_NAMES, label, self.confidence),
            "window": [t0, t1], "model": "scripted"})]


@dataclass
class ScriptedSettings:
    scenario: str = field(default="demo", metadata={"help": "the scenario the bridge plays"})
    rate_hz: float = field(default=60.0, metadata={"help": "the bridge's frame rate"})
    confidence: float = field(default=0.9, metadata={"help": "probability of the true class"})


class ScriptedGestures(Service):
    name = "scripted-gestures"
    description = "Scripted static and dynamic gesture messages for a known scenario (tests)."
    settings_class = ScriptedSettings

    def setup(self, ctx):
        labels = scenario_labels(load_scenario(self.settings.scenario), self.settings.rate_hz)
        self.classifier = ScriptedClassifier(labels, self.settings.confidence)
        ctx.subscribe(keys.HANDS_FRAME, self.classifier.on_frame)
        ctx.publishes(keys.GESTURES_STATIC, keys.GESTURES_DYNAMIC)

    def status_extra(self):
        return {"matched": self.classifier.matched, "unmatched": self.classifier.unmatched}


if __name__ == "__main__":
    sys.exit(run(ScriptedGestures, sys.argv[1:]))
