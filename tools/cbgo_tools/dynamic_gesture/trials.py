"""Trials: one recording, or one simulated appearance of the hand, to play with its truth.

A trial is one episode: the hand appears, does what the recording holds (a preparation, the
gesture, whatever return follows) and leaves. Three sources:

- the SHREC'17 depth-camera skeletons (`cbgo_tools.data.shrec`, 30 Hz; a ``datasetShrec``
  folder): its swipes, and its other gestures (grab, tap, expand, pinch, shake: `OTHER`) as
  trials whose truth is ``none``;
- Leap Motion recordings in LeapJS's JSON frames (`cbgo_tools.data.leapjs`: the Guinevere set,
  about 115 Hz, or the swipes converted from ``leapmotion-all``; a folder of person folders of
  ``NAME-TAKE.json``);
- GestureMidAir's fingertip paths (`cbgo_tools.data.gesturemidair`, about 60 Hz), carried by
  an open hand: slow, short swipes, a person drawing a line in the air;
- simulated users (`simulated_trials`): each performs every dynamic gesture once per
  appearance of the hand, rotate included.

`mirrored_trial` plays a trial as the other hand makes it (x → −x, sides swapped:
`cbgo.hands.model.mirrored_hand`), a swipe_left scored as a swipe_right: both real sets hold
right hands only, so this is how the left-hand path is measured on real motion.

People: the SHREC'17 train split's people are the only ones that fitting, tuning and selection
may look at; its test split is reserved for acceptance checks (`real_trials`' ``split``), as are
GestureMidAir's test people. GestureMidAir's train people and the LeapJS sets are development
data that nothing is fitted on: they judge a change made for other people.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cbgo.hands.model import mirrored_hand
from cbgo.services.dynamic_gesture.classifier import MIRROR
from cbgo.simuser.scenario import IDLE_MOTIONS, Episode, Scenario
from cbgo.simuser.user import SimulatedUser
from cbgo.wire import DYNAMIC_GESTURES
from cbgo_tools.data import gesturemidair, leapjs, shrec
from cbgo_tools.dynamic_gesture import simdata

OTHER = (1, 2, 3, 4, 14)  # grab, tap, expand, pinch, shake: no dynamic gesture of ours


@dataclass(frozen=True)
class Trial:
    """One trial to play: its truth and how to get its hand frames.

    Attributes:
        truth: the gesture performed, or "none" for a gesture that is no dynamic gesture of
            ours.
        gesture: the data set's name of the gesture.
        person: who performed it.
        recording: a `shrec.Sequence`, a `leapjs.Recording`, or (time, hands) frames (a
            simulated user's, a mirrored trial's).
        style: a simulated user's stroke size and speed (`simdata.StyleRanges.quarter`).
    """

    truth: str
    gesture: str
    person: str
    recording: object
    style: str = ""

    def row(self, **answers) -> dict:
        """Returns a scored row: who did what (and in which style), and the answers."""
        return {"truth": self.truth, "person": self.person, "gesture": self.gesture,
                **({"style": self.style} if self.style else {}), **answers}

    def frames(self) -> list[tuple[float, list[dict]]]:
        """Returns (time from the first frame, hands) per recorded frame."""
        if isinstance(self.recording, shrec.Sequence):
            return shrec_frames(self.recording.joints())
        if isinstance(self.recording, list):  # frames already (`simulated_trials`, mirrored)
            return self.recording
        return [(m["ts"], m["hands"]) for m in self.recording.frames()]


def shrec_trial(seq: shrec.Sequence) -> Trial:
    """Returns a SHREC'17 sequence as a trial."""
    return Trial(shrec.SWIPES.get(seq.gesture, "none"), seq.name, str(seq.person), seq)


def leapjs_trial(recording: leapjs.Recording) -> Trial:
    """Returns a LeapJS recording as a trial (its palm turns are not scored: `leapjs`)."""
    truth = recording.gesture if recording.gesture in leapjs.SWIPES else "none"
    name = recording.gesture + (f"#{recording.variant}" if recording.variant else "")
    return Trial(truth, name, recording.person, recording)


def gesturemidair_trial(drawing: gesturemidair.Drawing) -> Trial:
    """Returns a GestureMidAir swipe, carried by an open hand (`gesturemidair.hand_frames`)."""
    return Trial(gesturemidair.SWIPES[drawing.gesture], drawing.gesture, drawing.person,
                 gesturemidair.hand_frames(drawing.samples()))


def shrec_frames(joints: np.ndarray) -> list[tuple[float, list[dict]]]:
    """Returns (n, 22, 3) SHREC'17 joints as (time, hands) frames at its 30 Hz."""
    return [(i / shrec.RATE_HZ, [hand]) for i, hand in enumerate(shrec.to_hands(joints))]


def mirrored_trial(trial: Trial) -> Trial:
    """Returns a trial as the other hand makes it.

    Its frames mirrored (x → −x, sides swapped), a swipe_left becoming a swipe_right
    (`classifier.MIRROR`).
    """
    frames, _ = mirrored_stream(trial.frames(), [])
    return Trial(MIRROR.get(trial.truth, trial.truth), f"{trial.gesture} mirrored", trial.person,
                 frames)


def mirrored_stream(frames: list[tuple], spans: list[tuple]) -> tuple[list[tuple], list[tuple]]:
    """Returns a stream's frames and (name, t0, t1) spans as the other hand makes them."""
    return ([(t, [mirrored_hand(h) for h in hands]) for t, hands in frames],
            [(MIRROR.get(name, name), t0, t1) for name, t0, t1 in spans])


def mirrored_set(trials: list[Trial], streams: list[tuple], where: str
                 ) -> tuple[list[Trial], list[tuple], str]:
    """Returns trials, streams and their description as the other hand makes them."""
    return ([mirrored_trial(t) for t in trials], [mirrored_stream(*s) for s in streams],
            where + ", mirrored into the other hand")


def pick_trials(trials: list[Trial], per_class: int, seed: int, others: int | None = None
                ) -> list[Trial]:
    """Returns `per_class` trials of each swipe and `others` of the other gestures, people mixed.

    0 or less: every trial of its kind; `others` None: as many as `per_class`, and 0 none.
    """
    if per_class <= 0 and (others is None or others < 0):
        return list(trials)  # every trial, in the data set's order
    rng = np.random.default_rng(seed)
    out = []
    for truth in [*shrec.SWIPES.values(), "none"]:
        wanted = others if truth == "none" and others is not None else per_class
        if truth == "none" and wanted == 0:
            continue
        pool = [t for t in trials if t.truth == truth]
        if wanted <= 0:
            out += pool
        else:
            out += [pool[i] for i in rng.choice(len(pool), min(wanted, len(pool)),
                                                replace=False)]
    return out


def real_trials(root: Path, split: str) -> tuple[str, list[Trial], list[shrec.Sequence]]:
    """Returns the data set's device name, its trials and (SHREC'17 only) its sequences.

    A folder of GestureMidAir (`gesturemidair.is_set`) is that set (its `split`'s people), one
    with SHREC'17's split lists is SHREC'17; anything else is read as LeapJS
    recordings.

    Raises:
        FileNotFoundError: neither data set is there.
    """
    if gesturemidair.is_set(root):
        return "gesturemidair", [gesturemidair_trial(d)
                                 for d in gesturemidair.read_split(root, split)], []
    if (root / "train_gestures.txt").is_file():
        sequences = shrec.read_split(root, split)
        return "shrec17", [shrec_trial(s) for s in sequences
                           if s.gesture in shrec.SWIPES or s.gesture in OTHER], sequences
    recordings = leapjs.read_set(root)
    return "leapjs", [leapjs_trial(r) for r in recordings
                      if r.gesture not in leapjs.NOT_SCORED], []


def simulated_trials(users: int, seed: int, ranges: simdata.StyleRanges) -> list[Trial]:
    """Returns one trial per gesture of `users` simulated users, each its own episode.

    Each user performs every dynamic gesture once, in random order, one per appearance of the
    hand (enter, an idle motion or none, the gesture from anywhere in the field with its
    preparation and return, leave), in the user's style drawn from `ranges`.
    """
    trials = []
    for user_seed in range(seed, seed + users):
        scenario = simdata.user_scenario(user_seed, ranges, 1, statics=False)
        person, style = next(iter(scenario.users.items()))
        steps = scenario.episodes[0].gestures
        idle = [s for s in steps if s.gesture in IDLE_MOTIONS]
        for i, step in enumerate(s for s in steps if s.gesture in DYNAMIC_GESTURES):
            before = idle[i % 2:i % 2 + 1]  # every other trial starts with an idle motion
            episode = Episode(gestures=[*before, step], pause_s=0.3)
            one = Scenario(episodes=[episode], users=scenario.users,
                           name=f"{person}-{step.gesture}", seed=user_seed * 10 + i)
            frames = [(f.t, f.hands) for f in SimulatedUser(one, 60.0).frames() if f.hands]
            t0 = frames[0][0]
            trials.append(Trial(str(step.gesture), str(step.gesture), person,
                                [(t - t0, hands) for t, hands in frames], ranges.quarter(style)))
    return trials
