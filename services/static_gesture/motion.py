"""Hands that change pose: answered ``none`` while their fingers move and their answer changes.

Why: a static gesture is a held pose. A hand on its way from one gesture to another passes
through shapes that a frame-by-frame classifier reads as gestures with confidence (a
half-raised ring finger is a two or a three), and a transition should be answered ``none``.
What tells them apart is time: the fingers of a held pose stay put, those of a
changing one move, and the reading of a changing hand changes with them. So the service
follows each hand by its side and tracking id and compares it with the hand's latest frame at
least `WINDOW_S` older (or its first, below), two ways:

- its fingers (`invariant.finger_change`: degrees, the root mean square change of the 19 joint
  angles, the same however the hand is turned);
- its answer (`answer_change`: the total variation distance between the two frames'
  probabilities, 0 the same answer, 1 a wholly different one).

A hand whose answer changed by less than ``changed_tv`` keeps it, however its fingers move: a
tracker's flicker on a held pose moves the fingers without changing what the pose reads as.
Otherwise, below ``still_deg`` the answer is kept; from there to ``moving_deg`` the gestures
fade into ``none`` in proportion (`openset.fade_into_none`, the open-set rule's fading);
beyond, the hand is ``none``.

The lines are chosen on the HGR set's held poses (development data) and hands made moving
between two of a person's gestures (`crossval.timed_transitions`); ``cbgo bench static --folds
25 --no-latency`` measures what they cost held poses and take out of changing ones
(docs/design/static_gesture.md, "Hands that change pose"). A hand seen for less than
`WINDOW_S` is compared with its first frame: a hand often comes into view while it forms its
pose, and those first frames are a pose forming too (`crossval.appearing_transitions` measures
them). A held pose's fingers move about as much over a shorter gap as over the window (tracker
noise, not drift: `WINDOW_S`), so the rule costs held poses no more there. Its very first frame
has nothing to compare with and keeps its answer. A hand not seen for `FORGET_S`
is forgotten; frame times that go backwards (a replay restarted) start the hand afresh.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from cbgo.services.static_gesture import invariant

WINDOW_S = 0.15
"""How far back a hand's fingers are compared, seconds of frame time: longer than a tracker's
flicker, shorter than a change of pose (0.25–0.6 s), and longer than 0.1 s, which catches less
of a change. The HGR set's held poses move about as much between kept frames a few tracker
frames apart as many apart, noise rather than drift, so the cost measured on its gaps of about
0.1–0.2 s holds for this window (``cbgo bench static --folds 25 --no-latency`` prints it)."""
FORGET_S = 1.0
"""A hand not seen for this long (frame time) is forgotten."""
MAX_FRAMES_KEPT = 256
"""Frames kept per hand at most: a source whose time stands still cannot grow the memory."""
STILL_DEG = 5.0
"""Finger motion (degrees, `invariant.finger_change`) up to which a hand keeps its answer."""
MOVING_DEG = 10.0
"""Finger motion (degrees) from which a hand whose answer changed is wholly ``none``."""
CHANGED_TV = 0.3
"""How much of a hand's answer must have changed (`answer_change`) for its finger motion to
count: a held pose's flicker rarely changes what it reads as, a changing hand's answer does.
Chosen on the HGR set's held-out people (development data): the lowest line at which no gesture
loses more than 2 % of its held frames answered right (``cbgo bench static --folds 25
--no-latency`` prints each line's cost and the gesture that loses most)."""


def answer_change(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Returns the total variation distance between two rows of probabilities (..., K): 0-1."""
    return 0.5 * np.abs(np.asarray(after) - np.asarray(before)).sum(-1)


def keep_share(moved: np.ndarray, still_deg: float, moving_deg: float,
               changed: np.ndarray | None = None, changed_tv: float = 0.0) -> np.ndarray:
    """Returns the share of its gestures' probability each hand keeps for its finger motion.

    1 up to ``still_deg``, falling in proportion to 0 at ``moving_deg``; 1 where the motion is
    unknown (NaN). ``moving_deg`` 0 turns the rule off. With ``changed`` (`answer_change`),
    only the hands whose answer changed by at least ``changed_tv`` are faded (NaN: unknown,
    kept).
    """
    moved = np.nan_to_num(np.asarray(moved, dtype=np.float64), nan=0.0)
    if moving_deg <= 0:
        return np.ones(len(moved))
    keep = np.clip((moving_deg - moved) / (moving_deg - still_deg), 0.0, 1.0)
    if changed is None:
        return keep
    changed = np.nan_to_num(np.asarray(changed, dtype=np.float64), nan=-1.0)
    return np.where(changed >= changed_tv, keep, 1.0)


class FingerMotion:
    """Follows hands over frames and measures how far each one's fingers and answer just moved."""

    def __init__(self, window_s: float = WINDOW_S, forget_s: float = FORGET_S):
        self.window_s, self.forget_s = window_s, forget_s
        self.tracks: dict[str, deque] = {}  # "side/id" -> (ts, bends, probs) oldest first
        self.now = -np.inf

    def measure(self, hands: list[dict], ts: float, bends: np.ndarray, probs: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Returns, per hand of one frame, how far it moved in the last `window_s`.

        Args:
            hands: the frame's contract hands (``side`` and ``id`` name each one's track).
            ts: the frame's time, seconds.
            bends: (N, 19) `invariant.bends` of the hands.
            probs: (N, K) the hands' answers before any fading.

        Returns:
            ``(moved, changed)``: degrees (`invariant.finger_change`) and the answer's change
            (`answer_change`), against the hand's latest frame at least `window_s` older, or
            its first while it is younger; NaN for a hand's first frame (and ``changed`` NaN
            too where the model's vocabulary changed in between).
        """
        if ts < self.now:  # a replay restarted, or another source: history means nothing
            self.tracks.clear()
        self.now = ts
        moved, changed = np.full(len(hands), np.nan), np.full(len(hands), np.nan)
        for k, hand in enumerate(hands):
            track = self.tracks.setdefault(f"{hand['side']}/{hand['id']}",
                                           deque(maxlen=MAX_FRAMES_KEPT))
            while len(track) > 1 and track[1][0] <= ts - self.window_s:
                track.popleft()  # keep only the newest frame old enough to compare with
            if track:  # that frame, or the hand's first while it is younger than the window
                _, bends_then, probs_then = track[0]
                moved[k] = invariant.finger_change(bends_then, bends[k])
                if probs_then.shape == probs[k].shape:  # a reloaded model may name others
                    changed[k] = answer_change(probs_then, probs[k])
            track.append((ts, bends[k], probs[k].copy()))
        self._forget(ts)
        return moved, changed

    def _forget(self, ts: float) -> None:
        gone = [name for name, track in self.tracks.items() if track[-1][0] < ts - self.forget_s]
        for name in gone:
            del self.tracks[name]
