"""Continuous streams: several gestures one after the other, the hand never leaving the field.

What a trial cannot show, a stream does: the moves between gestures (returns, preparations,
holds, slow re-positioning) taken for gestures. Built three ways:

- from one SHREC'17 person's recordings (`person_streams`, `shrec_stream`): swipes and other
  gestures back to back, from their joints (`stream_joints`);
- from LeapJS trials (`trials_stream`): each recording's most seen hand, one tracking id for
  all; with ``returns``, a return move after each swipe (`return_move`), as real people make
  one and the recordings stop before it;
- from a simulated user (`stream_scenario`): swipes and rotates among idle motions (drift,
  wobble, slow re-positioning, slow palm turns) in one long episode.

Between two recordings the hand moves slowly (`junction_s`: `MOVE_MM_S` on average, turning
at most `TURN_DEG_S`, for `MOVE_S` at least), turning rigidly about its palm (`turned_hand`:
a hand turned over is turned, not squeezed through its palm, which would read as a fast
roll), then holds still for `HOLD_S`. `replay_stream` plays a stream through the service's
logic offline (segmenter, return filter, library) and scores it (`scoring.stream_figures`);
`live.run_stream` plays one through the live services.
"""

from __future__ import annotations

import math

import numpy as np

from cbgo.hands.features import hand_basis
from cbgo.services.dynamic_gesture.stroke import GESTURE_P, ReturnFilter, Segmenter, reported
from cbgo.simuser.motion import min_jerk
from cbgo.simuser.scenario import IDLE_MOTIONS, Episode, GestureStep, Scenario
from cbgo.simuser.user import SimulatedUser
from cbgo_tools.data import leapjs, shrec
from cbgo_tools.dynamic_gesture import simdata
from cbgo_tools.dynamic_gesture.scoring import stream_figures, stream_totals
from cbgo_tools.dynamic_gesture.trials import OTHER, Trial, shrec_frames

MOVE_S = 0.6  # the shortest move between two recordings of a stream, s
MOVE_MM_S = 100.0  # its mean palm speed at most (a slow re-positioning), mm/s
TURN_DEG_S = 45.0  # its mean turn rate at most (a slow turn, no rotate), deg/s
HOLD_S = 0.4  # the hand then holds still this long before the next recording, s
RETURN_LENGTH, RETURN_SPEED = 0.95, 0.92
"""With ``returns``, a LeapJS stream's swipe is followed by a return move: back along the swipe
this share of its length, this share of its speed (80th-percentile palm speed): the medians of
the SHREC'17 train split's people (`cbgo bench dynamic --realism DIR`)."""
_MIN_JERK_S = np.linspace(0.0, 1.0, 201)
MIN_JERK_P80 = float(np.percentile(np.gradient(min_jerk(_MIN_JERK_S), _MIN_JERK_S), 80))
"""A minimum-jerk move's 80th-percentile speed over its mean speed."""


def stream_joints(sequences: list[shrec.Sequence]) -> tuple[np.ndarray, list[tuple]]:
    """Returns the joints of sequences played back to back and each one's (name, t0, t1).

    Between two sequences the hand moves slowly (minimum jerk, `MOVE_MM_S` on average and
    turning at most `TURN_DEG_S`, at least `MOVE_S`) from where one ended to where the next
    begins and holds still for `HOLD_S`: it never leaves the field.
    """
    parts, spans, t = [], [], 0.0
    for seq in sequences:
        joints = seq.joints()
        if parts:
            a, b = shrec.to_hands(np.stack([parts[-1][-1], joints[0]]))
            n = int(junction_s(a, b) * shrec.RATE_HZ)
            parts.append(turned_joints(parts[-1][-1], joints[0], a, b,
                                       min_jerk(np.linspace(0, 1, n))))
            parts.append(np.repeat(joints[:1], int(HOLD_S * shrec.RATE_HZ), axis=0))
            t += (len(parts[-1]) + len(parts[-2])) / shrec.RATE_HZ
        parts.append(joints)
        spans.append((seq.name, t, t + len(joints) / shrec.RATE_HZ))
        t += len(joints) / shrec.RATE_HZ
    return np.concatenate(parts), spans


def turned_joints(a: np.ndarray, b: np.ndarray, hand_a: dict, hand_b: dict,
                  shares: np.ndarray) -> np.ndarray:
    """Returns skeleton `a` (joints, 3) taken each of `shares` of the way to skeleton `b`.

    As `blend_hands` does for hand frames (`hand_a` and `hand_b` are the two skeletons' hands;
    `turned_hand`): joints blended in straight lines would squeeze a hand turned over through
    its palm, its normal flipping in a frame or two: a fast roll, read as a rotate that no
    real hand made.
    """
    palms = a[shrec.PALM_JOINT], b[shrec.PALM_JOINT]  # the skeletons' own units
    bases = hand_basis(hand_a), hand_basis(hand_b)
    out = [turned_hand(palms, bases, float(s))[0](a, b) for s in np.asarray(shares, dtype=float)]
    return np.stack(out) if out else np.empty((0, *a.shape))


def turned_hand(palms: tuple, bases: tuple, s: float):
    """Returns how points of hand a and hand b lie a fraction `s` of the way from a to b.

    The palm moves in a straight line from ``palms[0]`` to ``palms[1]`` and the hand turns
    rigidly about it at an even rate, from palm frame ``bases[0]`` to ``bases[1]`` (rows:
    direction, normal, side; `partial_rotation`), while every point changes linearly in the
    palm's frame.

    Returns:
        (point, basis, palm): ``point(pa, pb)`` maps a point of a and the same point of b, (3,)
        or (n, 3), to where it lies; the palm frame and the palm position there.
    """
    (palm_a, palm_b), (basis_a, basis_b) = [np.asarray(v, float) for v in palms], bases
    basis = (partial_rotation(basis_b.T @ basis_a, s) @ basis_a.T).T
    palm = (1 - s) * palm_a + s * palm_b

    def point(pa, pb) -> np.ndarray:
        local = ((1 - s) * (np.asarray(pa, float) - palm_a) @ basis_a.T
                 + s * (np.asarray(pb, float) - palm_b) @ basis_b.T)
        return palm + local @ basis

    return point, basis, palm


def partial_rotation(rot: np.ndarray, s: float) -> np.ndarray:
    """Returns the rotation a fraction `s` of the way along rotation matrix `rot` (same axis)."""
    angle = math.acos(float(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0)))
    if angle < 1e-9:
        return np.eye(3)
    # The axis is the eigenvector of eigenvalue 1; its sign from the skew part (any sign at π).
    axis = np.linalg.eigh((rot + rot.T) / 2.0)[1][:, -1]
    skew = np.array([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])
    axis = axis if float(axis @ skew) >= 0.0 else -axis
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    t = s * angle
    return np.eye(3) + math.sin(t) * k + (1.0 - math.cos(t)) * (k @ k)


def _unit(v) -> list[float]:
    v = np.asarray(v, dtype=float)
    return (v / max(float(np.linalg.norm(v)), 1e-9)).tolist()


def blend_hands(a: dict, b: dict, s: float) -> dict:
    """Returns hand `a` taken a fraction `s` of the way to hand `b`.

    The palm moves in a straight line and the hand turns rigidly about it at an even rate
    (the rotation from `a`'s palm frame to `b`'s), while the joints change linearly in the
    palm's frame (`turned_hand`): a hand turned over is turned, not squeezed through its palm
    with its normal flipping in a frame or two (a fast roll, a rotate). Velocity, grab and
    pinch change linearly; the id is `a`'s.
    """
    def lerp(x, y):
        return np.asarray(x, dtype=float) * (1 - s) + np.asarray(y, dtype=float) * s

    turned, basis, palm = turned_hand((a["palm_position"], b["palm_position"]),
                                      (hand_basis(a), hand_basis(b)), s)

    def point(pa, pb) -> list[float]:
        return turned(pa, pb).tolist()

    fingers = [{"type": fa["type"], "bones": [
        {**ba, "prev_joint": point(ba["prev_joint"], bb["prev_joint"]),
         "next_joint": point(ba["next_joint"], bb["next_joint"])}
        for ba, bb in zip(fa["bones"], fb["bones"], strict=True)]}
        for fa, fb in zip(a["fingers"], b["fingers"], strict=True)]
    return {**a, "palm_position": palm.tolist(),
            "wrist_position": point(a["wrist_position"], b["wrist_position"]),
            "palm_velocity": lerp(a["palm_velocity"], b["palm_velocity"]).tolist(),
            "palm_normal": _unit(basis[1]), "direction": _unit(basis[0]),
            "grab_strength": float(lerp(a["grab_strength"], b["grab_strength"])),
            "pinch_strength": float(lerp(a["pinch_strength"], b["pinch_strength"])),
            "fingers": fingers}


def junction_s(a: dict, b: dict) -> float:
    """Returns how long a stream's hand takes from hand `a` to hand `b` between two recordings.

    At `MOVE_MM_S` on average and turning the palm at most `TURN_DEG_S` on average, at least
    `MOVE_S`: a slow re-positioning, not a gesture (a palm turned 90° in 0.6 s is a rotate).
    """
    distance = float(np.linalg.norm(np.subtract(a["palm_position"], b["palm_position"])))
    turn = math.degrees(math.acos(float(np.clip(np.dot(a["palm_normal"], b["palm_normal"]),
                                                -1.0, 1.0))))
    return max(MOVE_S, distance / MOVE_MM_S, turn / TURN_DEG_S)


def _min_jerk(a: dict, b: dict, seconds: float, t: float, rate_hz: float) -> list[tuple]:
    """Returns the frames of a minimum-jerk move from hand `a` to hand `b` after time `t`."""
    n = max(1, int(seconds * rate_hz))
    return [(t + i / rate_hz, [blend_hands(a, b, float(min_jerk(i / n)))])
            for i in range(1, n + 1)]


def shifted_hand(hand: dict, offset) -> dict:
    """Returns a hand moved by `offset` (mm): palm, wrist and every joint."""
    def moved(p) -> list[float]:
        return (np.asarray(p, dtype=float) + offset).tolist()

    fingers = [{"type": f["type"], "bones": [
        {**b, "prev_joint": moved(b["prev_joint"]), "next_joint": moved(b["next_joint"])}
        for b in f["bones"]]} for f in hand["fingers"]]
    return {**hand, "palm_position": moved(hand["palm_position"]),
            "wrist_position": moved(hand["wrist_position"]), "fingers": fingers}


def return_move(hands: list[tuple[float, dict]]) -> tuple[dict, float]:
    """Returns where a swipe recording's return move ends, and how long it takes.

    Back along the recording's displacement `RETURN_LENGTH` of its length, with an
    80th-percentile speed `RETURN_SPEED` of the recording's (minimum jerk).
    """
    palms = np.array([h["palm_position"] for _, h in hands], dtype=float)
    times = np.array([tt for tt, _ in hands], dtype=float)
    speeds = np.linalg.norm(np.diff(palms, axis=0), axis=1) / np.maximum(np.diff(times), 1e-3)
    offset = -RETURN_LENGTH * (palms[-1] - palms[0])
    speed = RETURN_SPEED * float(np.percentile(speeds, 80)) if len(speeds) else 0.0
    seconds = MIN_JERK_P80 * float(np.linalg.norm(offset)) / max(speed, 1e-3)
    return shifted_hand(hands[-1][1], offset), max(MOVE_S / 2, seconds)


def _main_hand(frames: list[tuple[float, list[dict]]]) -> list[tuple[float, dict]]:
    """Returns (time, hand) of the recording's most seen hand, in the frames that have it."""
    ids = [h["id"] for _, hands in frames for h in hands]
    main = max(set(ids), key=ids.count)
    return [(t, h) for t, hands in frames for h in hands if h["id"] == main]


def trials_stream(trials: list[Trial], rate_hz: float = 60.0, returns: bool = False
                  ) -> tuple[list[tuple], list[tuple]]:
    """Returns recordings played back to back as one stream: frames and (name, t0, t1) spans.

    Each recording's most seen hand, one tracking id for all: between two recordings the hand
    moves (`blend_hands`, minimum jerk) from where one ended to where the next begins, at
    `MOVE_MM_S` on average and turning at most `TURN_DEG_S`, at least `MOVE_S`, then holds
    still for `HOLD_S`: it never leaves the field. A span's name is the trial's truth. With
    ``returns``, each swipe is followed by a return move (`return_move`), as real people make
    one and LeapJS recordings stop before it; the return is outside every span.
    """
    frames, spans, t = [], [], 0.0
    for trial in trials:
        hands = _main_hand(trial.frames())
        if frames:
            a, b = frames[-1][1][0], hands[0][1]
            frames += _min_jerk(a, b, junction_s(a, b), t, rate_hz)
            hold = int(HOLD_S * rate_hz)
            t = frames[-1][0]
            frames += [(t + i / rate_hz, [b]) for i in range(1, hold + 1)]
            t = frames[-1][0] + 1.0 / rate_hz
        t_first = hands[0][0]
        frames += [(t + tt - t_first, [hand]) for tt, hand in hands]
        spans.append((trial.truth, t, frames[-1][0]))
        t = frames[-1][0] + 1.0 / rate_hz
        if returns and trial.truth != "none" and len(hands) > 1:
            back, seconds = return_move(hands)
            frames += _min_jerk(frames[-1][1][0], back, seconds, frames[-1][0], rate_hz)
            t = frames[-1][0] + 1.0 / rate_hz
    return [(tt, [{**h, "id": 1} for h in hs]) for tt, hs in frames], spans


def shrec_stream(sequences: list[shrec.Sequence]) -> tuple[list[tuple], list[tuple]]:
    """Returns SHREC'17 sequences as one stream: (time, hands) frames and (name, t0, t1) spans."""
    joints, spans = stream_joints(sequences)
    return shrec_frames(joints), spans


def person_streams(sequences: list[shrec.Sequence], count: int, rng: np.random.Generator,
                   length: int = 10) -> list[tuple[list[tuple], list[tuple]]]:
    """Returns `count` SHREC'17 streams of one person's swipes and other gestures (`OTHER`)."""
    own = [s for s in sequences if s.gesture in shrec.SWIPES or s.gesture in OTHER]
    return [shrec_stream([own[i] for i in rng.permutation(len(own))[:length]])
            for _ in range(count if own else 0)]


def stream_sets(device: str, trials: list[Trial], sequences: list[shrec.Sequence],
                streams: int, seed: int, returns: bool = False
                ) -> list[tuple[list[tuple], list[tuple]]]:
    """Returns `streams` continuous streams, one person each, of 10 recordings in random order.

    SHREC'17: its swipes and other gestures (`stream_joints`). LeapJS: its swipes and the
    gestures that are no swipe (tap, pinch, thumbs), not the moves along one direction with
    another hand shape or path (`leapjs.SWIPE_LIKE`), whose truth is neither; with
    ``returns``, each swipe followed by a return move (`trials_stream`).
    """
    rng = np.random.default_rng(seed)
    if device == "shrec17":
        people = sorted({s.person for s in sequences})
    else:
        people = sorted({t.person for t in trials})
    out = []
    for person in rng.choice(people, min(streams, len(people)), replace=False) if people else []:
        if device == "shrec17":
            out += person_streams([s for s in sequences if s.person == person], 1, rng)
        else:
            own = [t for t in trials if t.person == person
                   and not t.gesture.startswith(leapjs.SWIPE_LIKE)]
            out.append(trials_stream([own[i] for i in rng.permutation(len(own))[:10]],
                                     returns=returns))
    return out


def split_spans(spans: list[tuple], t0: float = 0.0) -> tuple[list[tuple], list[tuple]]:
    """Returns a stream's (name, t0, t1) spans as its swipes and its other gestures, + t0."""
    swipe_names = set(shrec.SWIPES.values())
    shifted = [(name, t0 + a, t0 + b) for name, a, b in spans]
    return ([s for s in shifted if s[0] in swipe_names],
            [s for s in shifted if s[0] not in swipe_names])


def stream_scenario(seed: int, ranges, swipes: int = 8) -> Scenario:
    """One long episode without the hand leaving: swipes and rotates among idle motions."""
    rng = np.random.default_rng(seed)
    style, (lo, hi) = ranges.draw(rng, f"user{seed}")
    steps = [GestureStep(str(g)) for g in rng.choice(list(shrec.SWIPE_DIRECTIONS), swipes)]
    steps += [GestureStep("rotate", angle_deg=float(rng.uniform(lo, hi))) for _ in range(2)]
    steps += [GestureStep(str(m)) for m in rng.choice(IDLE_MOTIONS, swipes)]
    order = rng.permutation(len(steps))
    return Scenario(episodes=[Episode(gestures=[steps[i] for i in order], pause_s=0.3)],
                    users={f"user{seed}": style}, name=f"stream{seed}", seed=seed)


def score_stream(classifier, scenario: Scenario, config) -> dict:
    """Plays a scenario through the service's logic; returns recall and false triggers."""
    frames = list(SimulatedUser(scenario, 60.0).frames())
    times = np.array([f.t for f in frames])
    strokes = simdata.true_strokes(times, [f.label for f in frames])
    return replay_stream(classifier, [(f.t, f.hands) for f in frames], strokes, [], config)


def replay_stream(classifier, frames: list[tuple], strokes: list[tuple], others: list[tuple],
                  config) -> dict:
    """Plays (time, hands) frames through the service's logic offline; returns its figures.

    The segmenter, the return filter and the classifier as the service runs them, without the
    wire; a window is reported as a gesture when its top gesture has p ≥ `GESTURE_P`.
    `strokes` and `others` are as `stream_figures` takes them.
    """
    segmenter = Segmenter(config)
    windows = [w for t, hands in frames for w in segmenter.update(t, hands)]
    reports = []
    for window, probs in reported(windows, ReturnFilter(segmenter.config.return_s),
                                  classifier.classify):
        top = int(np.argmax(probs[:-1]))
        if probs[top] >= GESTURE_P:
            reports.append((classifier.names[top], window.t_start, window.t_end, window.stroke))
    return stream_figures(reports, strokes, frames[-1][0] - frames[0][0], others)


def replay_played(classifier, played: list[tuple], config) -> dict:
    """Returns the totals of (frames, spans) streams (`stream_sets`) replayed offline."""
    return stream_totals([replay_stream(classifier, frames, *split_spans(spans), config)
                          for frames, spans in played])


def synthetic_streams(classifier, users: int, seed: int, config, ranges) -> dict:
    """Returns the totals of `users` simulated users' streams (`stream_scenario`), offline."""
    return stream_totals([score_stream(classifier, stream_scenario(seed + i, ranges), config)
                          for i in range(users)])
