"""Gesture evidence from classifier probabilities over time, triggers, the gesture vector g.

The paper accumulates evidence for each gesture over an episode; a gesture whose evidence passes
the threshold E_t *triggers*, and at that moment the probability vector of all gestures is saved.
At the end of the episode the saved vectors are combined into g by an element-wise maximum.

Evidence model (one number per source, hand side and gesture name):

- Static evidence is a leaky integral of the gesture's probability over *time*, not over
  messages, so it does not depend on the frame rate: between observations it decays as
  ``exp(-dt/τ)``, and a message that observes probability ``p`` for ``c`` seconds moves it
  towards ``p``::

      e ← e · exp(-Δ/τ) + p · (1 − exp(-c/τ))      (Δ: time since the last update, c ≤ Δ)

  For a constant probability ``p`` the evidence rises as ``p·(1 − exp(−t/τ))``: it is the
  probability smoothed over the last τ seconds, so E_t reads as a probability (default 0.6:
  a gesture held at p = 0.9 triggers after 0.33 s with τ = 0.3 s; one at p ≤ 0.6 never does).
- Static messages (one per frame and hand) each cover the time since the previous static
  message of the same hand side, at most ``max_gap_s`` (a longer gap is a loss of tracking, not
  an observation). The first message of a side covers nothing.
- Dynamic messages (one per evaluated stroke window ``[t_start, t_end]``) are each a judgement
  of a whole stroke, not a slice of time: a dynamic classifier may evaluate a growing window
  several times while a stroke runs and once more at its end (whose end need not be later), or
  slide a fixed window. So a window is not integrated with the previous ones; it *sets* the
  evidence to at least its probability, discounted for short windows::

      e ← max(e · exp(-Δ/τ_d), p · (1 − exp(-(t_end − t_start)/τ_d)))

  With the default τ_d = 0.15 s a 0.45 s window at p = 0.9 gives evidence 0.86 at once (strong
  evidence, as a classified stroke is), while a 0.15 s window needs p ≥ 0.95 to pass E_t = 0.6:
  the early windows of a stroke, which lean to "no gesture" anyway, count little.
- Sources are integrated separately and merged by name only in the vectors; a side (left or
  right hand) is integrated separately, so a hand that loses tracking and comes back with a new
  id keeps its evidence.
- Classes named like ``none`` / ``no_gesture`` ("no gesture") never trigger and are not part of
  g.
- A gesture triggers once per episode (default). With ``rearm`` it may trigger again after all
  of its evidence fell below ``release × E_t`` (the gesture was released and performed again).

The snapshot saved at a trigger is the *current* probability of every gesture: the latest
static vector of each side if it is at most ``max_gap_s`` old, and the latest dynamic window of
each side up to ``dynamic_hold_s`` after the window's end (a stroke's classification stays
current a little after it); several are merged by name with the maximum.
A dynamic trigger's vector also takes in the later windows of its stroke (same side and start),
by the maximum: they judge the same stroke with more of it seen, so they are saved for it too.

This module is pure (numbers and dicts): no Zenoh, no clock of its own. Times are seconds on
the frames' clock.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

from cbgo.config import described as _help
from cbgo.errors import ConfigError
from cbgo.wire import DYNAMIC_GESTURES, NO_GESTURE_NAMES, STATIC_GESTURES

NONE_NAMES = NO_GESTURE_NAMES


@dataclass
class EvidenceSettings:
    """Parameters of the evidence model (see the module docstring).

    Declared once, here: the episode service takes them as its ``--evidence.*`` settings.
    """

    threshold: float = field(default=0.6, metadata=_help(
        "evidence threshold E_t at which a gesture triggers (0-1]"))
    static_tau_s: float = field(default=0.3, metadata=_help(
        "time constant of static gesture evidence, s"))
    dynamic_tau_s: float = field(default=0.15, metadata=_help(
        "time constant of dynamic gesture evidence, s"))
    max_gap_s: float = field(default=0.1, metadata=_help(
        "longest time one static message counts for, s"))
    dynamic_hold_s: float = field(default=0.5, metadata=_help(
        "how long a dynamic window stays in the current probability vector, s"))
    rearm: bool = field(default=False, metadata=_help(
        "let a gesture trigger again in the same episode once its evidence fell below "
        "release x E_t (default: once per episode)"))
    release: float = field(default=0.5, metadata=_help(
        "with rearm: a gesture re-arms once its evidence is below this fraction of E_t"))
    none_names: tuple[str, ...] = field(default=NONE_NAMES, metadata=_help(
        "class names that mean 'no gesture' (never trigger, not in g)"))

    def __post_init__(self):
        self.none_names = tuple(self.none_names)
        if not 0.0 < self.threshold <= 1.0:
            raise ConfigError(f"threshold={self.threshold} must be within (0, 1]")
        for name in ("static_tau_s", "dynamic_tau_s", "max_gap_s"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name}={getattr(self, name)} must be positive")
        if self.dynamic_hold_s < 0:
            raise ConfigError(f"dynamic_hold_s={self.dynamic_hold_s} must not be negative")
        if not 0.0 < self.release < 1.0:
            raise ConfigError(f"release={self.release} must be within (0, 1)")


@dataclass
class Trigger:
    """One gesture passing E_t.

    Attributes:
        gesture: the gesture name.
        ts: when (the observation's time: frame time, or a window's end).
        prob: the gesture's probability in the observation that triggered it.
        side: the hand side it was observed on.
        source: ``static`` or ``dynamic``.
        snapshot: the current probability of every gesture (the saved vector).
        window: the dynamic window that triggered it, or None.
    """

    gesture: str
    ts: float
    prob: float
    side: str
    source: str
    snapshot: dict[str, float]
    window: tuple[float, float] | None = None


@dataclass
class _Track:
    value: float = 0.0
    t: float = -math.inf


@dataclass
class Evidence:
    """The evidence of one episode; feed it observations in arrival order.

    Args:
        settings: the model parameters.
    """

    settings: EvidenceSettings = field(default_factory=EvidenceSettings)

    def __post_init__(self):
        self.tracks: dict[tuple[str, str, str], _Track] = {}
        self.names: dict[str, None] = {}  # every gesture name seen, in first-seen order
        self.triggers: list[Trigger] = []
        self._armed: dict[str, bool] = {}
        self._static: dict[str, tuple[float, dict[str, float]]] = {}
        self._dynamic: dict[str, tuple[float, dict[str, float]]] = {}

    def is_gesture(self, name: str) -> bool:
        """Returns False for the "no gesture" classes."""
        return name not in self.settings.none_names

    def static(self, t: float, side: str, names: Iterable[str], probs: Iterable[float]
               ) -> list[Trigger]:
        """Integrates one static message (one frame, one hand); returns new triggers."""
        vector = dict(zip(names, map(float, probs), strict=True))
        last = self._static.get(side)
        covered = 0.0 if last is None else min(max(t - last[0], 0.0), self.settings.max_gap_s)
        self._static[side] = (t, vector)
        tau = self.settings.static_tau_s
        gain = 1.0 - math.exp(-covered / tau)
        return self._update("static", side, t, vector, tau,
                            lambda decayed, p: decayed + p * gain)

    def dynamic(self, window: tuple[float, float], side: str, names: Iterable[str],
                probs: Iterable[float]) -> list[Trigger]:
        """Takes one dynamic window message; returns new triggers."""
        t0, t1 = float(window[0]), float(window[1])
        vector = dict(zip(names, map(float, probs), strict=True))
        self._dynamic[side] = (t1, vector)  # the newest evaluation is the current one
        self._refine(side, t0, vector)
        weight = 1.0 - math.exp(-max(t1 - t0, 0.0) / self.settings.dynamic_tau_s)
        return self._update("dynamic", side, t1, vector, self.settings.dynamic_tau_s,
                            lambda decayed, p: max(decayed, p * weight), (t0, t1))

    def _refine(self, side: str, t0: float, vector: dict[str, float]) -> None:
        """Saves a later window of a stroke that triggered into that trigger's vector (max).

        The windows of one stroke share its start and judge the same stroke with more of it
        seen, so each is a vector saved for the trigger: were only the window that crossed
        E_t saved, an early, unsure window of a real swipe could lose to a sure preparation or
        return in g.
        """
        for trigger in self.triggers:
            if (trigger.source == "dynamic" and trigger.side == side
                    and trigger.window is not None and trigger.window[0] == t0):
                for name, p in vector.items():
                    if self.is_gesture(name):
                        trigger.snapshot[name] = max(trigger.snapshot.get(name, 0.0), p)

    def _update(self, source: str, side: str, t: float, vector: dict[str, float], tau: float,
                combine, window: tuple[float, float] | None = None) -> list[Trigger]:
        crossed = []
        for name, p in vector.items():
            if not self.is_gesture(name):
                continue
            self.names.setdefault(name, None)
            track = self.tracks.setdefault((source, side, name), _Track())
            decayed = track.value * math.exp(-max(t - track.t, 0.0) / tau)
            track.value, track.t = combine(decayed, p), max(track.t, t)
            self._update_arming(name, t)
            if track.value >= self.settings.threshold and self._armed.get(name, True):
                self._armed[name] = False
                crossed.append((name, p))
        new = [Trigger(name, t, p, side, source, self.current(t), window)
               for name, p in crossed]
        self.triggers.extend(new)
        return new

    def _update_arming(self, name: str, t: float) -> None:
        if self.settings.rearm and not self._armed.get(name, True):
            if self.value(name, t) < self.settings.release * self.settings.threshold:
                self._armed[name] = True

    def value(self, name: str, t: float) -> float:
        """Returns a gesture's evidence at time t (the maximum over sources and sides)."""
        best = 0.0
        for (source, _side, n), track in self.tracks.items():
            if n == name:
                tau = (self.settings.static_tau_s if source == "static"
                       else self.settings.dynamic_tau_s)
                best = max(best, track.value * math.exp(-max(t - track.t, 0.0) / tau))
        return best

    def current(self, t: float) -> dict[str, float]:
        """Returns the current probability of every gesture seen, merged by name (max)."""
        out = dict.fromkeys(self.names, 0.0)
        recent = [v for ts, v in self._static.values() if t - ts <= self.settings.max_gap_s]
        recent += [v for ts, v in self._dynamic.values()
                   if t - ts <= self.settings.dynamic_hold_s]
        for vector in recent:
            for name, p in vector.items():
                if self.is_gesture(name):
                    out[name] = max(out.get(name, 0.0), p)
        return out


def _vocabulary_order(name: str) -> tuple[int, int, str]:
    known = STATIC_GESTURES + DYNAMIC_GESTURES
    return (0, known.index(name), "") if name in known else (1, 0, name)


def gesture_vector(snapshots: Iterable[dict[str, float]], names: Iterable[str]
                   ) -> tuple[list[str], list[float]]:
    """Returns g: the element-wise maximum of the saved vectors (the paper's equation).

    Args:
        snapshots: the probability vectors saved at the triggers (C of them, maybe none).
        names: every gesture name to report (those not in any snapshot get 0).

    Returns:
        (names, probs) in vocabulary order: the static gestures, the dynamic ones, then any
        other names alphabetically.
    """
    snapshots = list(snapshots)
    ordered = sorted(set(names).union(*[s.keys() for s in snapshots]), key=_vocabulary_order)
    probs = [max((s.get(n, 0.0) for s in snapshots), default=0.0) for n in ordered]
    return ordered, [min(1.0, max(0.0, p)) for p in probs]
