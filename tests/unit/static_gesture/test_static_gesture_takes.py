"""Scoring recorded takes (`takes.py`, `cbgo bench static --takes`): real MCAP recordings of
simulated hands, the shipped model."""

import argparse
import json

import numpy as np
import pytest

from cbgo import keys, wire
from cbgo.errors import RecordingError
from cbgo.hands import features as F
from cbgo.hands.model import HandPose, HandShape, build_hand
from cbgo.hands.poses import gesture_mean, gesture_pose
from cbgo.recording import Recorder
from cbgo.services.static_gesture.classifier import StaticClassifier, default_model_path
from cbgo_tools.static_gesture import bench, takes

T0 = 1_700_000_000_000_000_000


def half_open(rng):
    """A hand halfway between five and grab: no gesture of the vocabulary."""
    del rng
    return HandPose.from_vector(0.5 * (gesture_mean("five").to_vector()
                                       + gesture_mean("grab").to_vector()))


def record_take(path, gesture, frames=12, seed=0, bad=0, prefix="cbgo"):
    """Records `frames` hands/frame messages of one simulated right hand holding `gesture`."""
    rng = np.random.default_rng(seed)
    shape = HandShape.sample(rng, side="right")
    pose = half_open if gesture == "half-open" else (lambda r: gesture_pose(gesture, r))
    with Recorder(path) as rec:
        for i in range(frames):
            hand = build_hand(shape, pose(rng), np.array([0.0, 200.0, 0.0]))
            hand["id"] = 7
            ns = T0 + i * 10_000_000
            msg = keys.HANDS_FRAME.message(ts=ns / 1e9, seq=i, source="simulated", device="sim",
                                           hands=[hand])
            rec.write(f"{prefix}/hands/frame", wire.encode(msg), ns)
        for i in range(bad):  # breaks the contract: a hand without fingers
            msg = keys.HANDS_FRAME.message(ts=T0 / 1e9, seq=100 + i, hands=[{"id": 1}])
            rec.write(f"{prefix}/hands/frame", wire.encode(msg), T0 + (100 + i) * 10_000_000)
        rec.write(f"{prefix}/gaze", b"\x80", T0)  # another key: not read
    return path


@pytest.fixture(scope="module")
def shipped():
    return StaticClassifier.load(default_model_path(), samples=8)


def test_a_take_of_a_gesture_counts_the_frames_answered_with_it(tmp_path, shipped):
    five = record_take(tmp_path / "five.mcap", "five", bad=2)
    right, = takes.score_takes(shipped, [f"five={five}"])
    assert (right.hands, right.skipped, right.unknown) == (12, 2, False)
    assert right.share >= 0.9 and right.answers.most_common(1)[0][0] == "five"
    # the same frames named as another gesture are wrong, and as no gesture, not rejected
    wrong, = takes.score_takes(shipped, [f"grab={five}"])
    assert wrong.share <= 0.1
    unknown, = takes.score_takes(shipped, [f"horns={five}"])
    assert unknown.unknown and unknown.share <= 0.1


def test_a_take_of_a_pose_outside_the_vocabulary_is_right_when_rejected(tmp_path, shipped):
    scores = takes.score_takes(shipped, [
        f"none={record_take(tmp_path / 'half.mcap', 'half-open', seed=3)}",
        f"grab={record_take(tmp_path / 'grab.mcap', 'grab', seed=4, prefix='lab/cbgo')}"])
    assert [s.unknown for s in scores] == [True, False]
    assert scores[0].share >= 0.9 and scores[0].answers.most_common(1)[0][0] == "none"
    assert scores[1].hands == 12  # a recording under another prefix is read as well
    fig = takes.summary(scores)
    assert fig["hands"] == 24 and fig["known"] == scores[1].share
    assert fig["unknown_rejected"] == scores[0].share


@pytest.mark.parametrize("spec", ["five.mcap", "=x.mcap", "five=", ""])
def test_a_malformed_take_is_named(spec):
    with pytest.raises(ValueError, match="LABEL=FILE"):
        takes.parse_take(spec)


def test_the_bench_scores_takes_and_says_what_is_wrong(tmp_path, capsys):
    five = record_take(tmp_path / "five.mcap", "five", frames=20)
    parser = argparse.ArgumentParser()
    bench.add_arguments(parser)
    out = tmp_path / "fig.json"
    assert bench.run(parser.parse_args(["--takes", f"five={five}", "--json", str(out)])) == 0
    printed = capsys.readouterr().out
    assert "five" in printed and "known gestures, frames right" in printed
    assert "fingers moved in 0.15 s" in printed  # 20 frames 10 ms apart: the last 5 measured
    fig = json.loads(out.read_text())
    assert fig["takes"]["per_take"][0]["hands"] == 20 and fig["takes"]["known"] >= 0.9
    assert set(fig["takes"]["per_take"][0]["finger_motion"]) == {"50", "95", "99"}
    assert bench.run(parser.parse_args(["--takes", f"five={tmp_path / 'no.mcap'}"])) == 2
    assert "no such file" in capsys.readouterr().out
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap")
    assert bench.run(parser.parse_args(["--takes", f"five={tmp_path / 'junk.mcap'}"])) == 2


def test_a_missing_file_is_refused_before_scoring(tmp_path, shipped):
    with pytest.raises(RecordingError, match="no such file"):
        takes.score_takes(shipped, [f"five={tmp_path / 'absent.mcap'}"])


def test_finger_motion_follows_each_hand_by_its_id_over_the_window():
    # Two hands 10 ms apart for 0.3 s: hand 1 holds five, hand 2 closes from five to a fist.
    shape = HandShape.sample(np.random.default_rng(1), side="right")
    five, grab = gesture_mean("five").to_vector(), gesture_mean("grab").to_vector()
    palm = np.array([0.0, 200.0, 0.0])
    hands, stamps = [], []
    for i in range(30):
        held = build_hand(shape, HandPose.from_vector(five), palm)
        closing = build_hand(shape, HandPose.from_vector(five + (grab - five) * i / 29), palm)
        held["id"], closing["id"] = 1, 2
        hands += [held, closing]
        stamps += [i * 0.01] * 2
    x = F.hands_features(hands, to_recorded_side=True)
    probs = np.tile([0.9, 0.1], (60, 1))
    share = np.arange(30) / 29
    probs[1::2] = np.stack([1 - share, share], 1)  # the closing hand's answer turns with it
    moved, changed = takes.finger_motion(hands, stamps, x, probs, window_s=0.1)
    moved, changed = moved.reshape(30, 2), changed.reshape(30, 2)
    assert np.isnan(moved[0]).all() and not np.isnan(moved[1:]).any()  # the first frame alone
    assert moved[1:, 0].max() < 1e-6 and moved[10:, 1].min() > 5.0
    assert 0 < moved[1, 1] < moved[9, 1]  # younger than 0.1 s: against the first frame
    assert np.isnan(changed[0]).all()
    assert changed[1:, 0] == pytest.approx(0.0)
    assert changed[1:10, 1] == pytest.approx(np.arange(1, 10) / 29)
    # against the newest frame at least 0.1 s back: 10 frames, or 11 where the sum rounds
    assert ((changed[10:, 1] > 10 / 29 - 1e-9) & (changed[10:, 1] < 11 / 29 + 1e-9)).all()
    alone = takes.finger_motion(hands[1::2], stamps[1::2], x[1::2], probs[1::2], window_s=1.0)
    assert np.isnan(alone[0][0]) and changed[9, 1] == pytest.approx(alone[1][9])  # 0.09 s old


def test_a_take_is_scored_as_the_service_answers_a_hand_whose_fingers_move(tmp_path, shipped,
                                                                           capsys):
    # a point held 0.3 s, then closed into a fist over 0.3 s (60 Hz): read frame by frame the
    # change is point then grab; as the service answers, its fast part is none
    shape = HandShape.default(side="right")
    point, grab = gesture_mean("point").to_vector(), gesture_mean("grab").to_vector()
    shares = [0.0] * 18 + [s * s * (3 - 2 * s) for s in np.linspace(0, 1, 18)]
    path = tmp_path / "change.mcap"
    with Recorder(path) as rec:
        for i, share in enumerate(shares):
            hand = build_hand(shape, HandPose.from_vector(point + share * (grab - point)),
                              np.array([0.0, 220.0, 0.0]), hand_id=3)
            ns = T0 + int(i * 1e9 / 60)
            rec.write("cbgo/hands/frame", wire.encode(keys.HANDS_FRAME.message(
                ts=ns / 1e9, seq=i, source="simulated", device="sim", hands=[hand])), ns)
    score, = takes.score_takes(shipped, [f"none={path}"])
    assert score.answers["none"] >= 7 and score.answers["point"] >= 18
    # read alone, the change's hands are gestures: the rule's rejections are what it adds
    assert score.rule_rejected >= 5
    assert score.right == score.right_alone + score.rule_rejected  # a none take: rejected = right
    fig = takes.figures([score])
    assert fig["per_take"][0]["rule_rejected"] == score.rule_rejected
    takes.print_figures(fig, shipped.model_id)
    assert f"rejected {score.rule_rejected} that read as a gesture alone" in capsys.readouterr().out
