"""Hands that change pose (`motion.py`): each hand followed by its id, its fingers and answer
compared with a window before; through the service, a hand changing pose is answered none
while it changes, and a held one keeps its answer however its fingers flicker."""

import numpy as np
import pytest

from cbgo import keys
from cbgo.errors import ConfigError
from cbgo.examples import example
from cbgo.hands import features as F
from cbgo.hands.model import HandPose, HandShape, build_hand
from cbgo.hands.poses import gesture_mean
from cbgo.services.static_gesture import invariant, motion
from cbgo.services.static_gesture.main import StaticGesture, StaticGestureSettings
from cbgo.testing import FakeBus

SHAPE = HandShape.default(side="right")


def hand(pose_vector, hand_id=1):
    return build_hand(SHAPE, HandPose.from_vector(pose_vector), [0.0, 220.0, 0.0],
                      hand_id=hand_id)


def blend(a, b, share):
    return gesture_mean(a).to_vector() + share * (gesture_mean(b).to_vector()
                                                  - gesture_mean(a).to_vector())


def bends_of(hands):
    return invariant.bends(F.hands_features(hands, to_recorded_side=True))


SURE = np.array([[0.9, 0.1]])


def moved_of(tracker, hands, ts, probs=SURE):
    """Measures one frame whose hands all read ``probs``: the fingers' motion only."""
    return tracker.measure(hands, ts, bends_of(hands), np.repeat(probs, len(hands), 0))[0]


def test_the_share_kept_falls_from_the_still_line_to_the_moving_line():
    moved = np.array([0.0, 10.0, 15.0, 20.0, 40.0, np.nan])
    assert motion.keep_share(moved, 10.0, 20.0) == pytest.approx([1, 1, 0.5, 0, 0, 1])
    assert motion.keep_share(moved, 10.0, 0.0) == pytest.approx(np.ones(6))  # off


def test_only_a_hand_whose_answer_changed_is_faded_for_its_motion():
    moved = np.array([15.0, 15.0, 15.0, 40.0, 40.0])
    changed = np.array([0.0, 0.19, 0.2, 1.0, np.nan])  # NaN: nothing to compare the answer with
    assert motion.keep_share(moved, 10.0, 20.0, changed, 0.2) == pytest.approx([1, 1, 0.5, 0, 1])
    assert motion.keep_share(moved, 10.0, 20.0, changed, 0.0) == pytest.approx([.5, .5, .5, 0, 1])


def test_the_answer_change_is_the_total_variation_distance():
    assert motion.answer_change([0.9, 0.1, 0.0], [0.9, 0.1, 0.0]) == 0.0
    assert motion.answer_change([0.9, 0.1, 0.0], [0.1, 0.1, 0.8]) == pytest.approx(0.8)
    assert motion.answer_change([[1.0, 0.0]], [[0.0, 1.0]]) == pytest.approx([1.0])


def test_the_answer_is_compared_with_the_same_frame_as_the_fingers():
    tracker = motion.FingerMotion(window_s=0.1)
    five = [hand(blend("five", "five", 0))]
    answers_then = [[0.9, 0.1], [0.5, 0.5], [0.1, 0.9]]
    got = [tracker.measure(five, 1.0 + i * 0.05, bends_of(five), np.array([p]))
           for i, p in enumerate(answers_then)]
    assert np.isnan(got[0][1]).all()  # its first frame: nothing to compare with
    assert got[1][1] == pytest.approx([0.4])  # 0.05 s old: against its first frame
    assert got[2][1] == pytest.approx([0.8])  # against the frame 0.1 s back
    reloaded = tracker.measure(five, 1.2, bends_of(five), np.array([[0.2, 0.3, 0.5]]))
    assert not np.isnan(reloaded[0]).any() and np.isnan(reloaded[1]).all()  # another vocabulary


def test_each_hand_is_compared_with_its_own_frame_a_window_before():
    tracker = motion.FingerMotion(window_s=0.1)
    moved = []
    for i in range(30):  # 10 ms apart: hand 1 holds five, hand 2 closes from five to a fist
        hands = [hand(blend("five", "five", 0)), hand(blend("five", "grab", i / 29), 2)]
        moved.append(moved_of(tracker, hands, 100.0 + i * 0.01))
    moved = np.array(moved)
    assert np.isnan(moved[0]).all() and not np.isnan(moved[1:]).any()  # first frames: nothing
    assert moved[1:, 0].max() < 1e-6 and moved[10:, 1].min() > 5.0  # the held hand stays still
    # younger than the window: against the hand's first frame, so the closing hand already moves
    assert 0 < moved[1, 1] < moved[5, 1] < moved[9, 1]
    assert moved[9, 1] == pytest.approx(invariant.finger_change(
        bends_of([hand(blend("five", "grab", 0))]), bends_of([hand(blend("five", "grab",
                                                                            9 / 29))]))[0])
    # the same change over 0.1 s, whatever the frame rate
    assert moved[20, 1] == pytest.approx(invariant.finger_change(
        bends_of([hand(blend("five", "grab", 10 / 29))]), bends_of([hand(blend("five", "grab",
                                                                              20 / 29))]))[0])


def test_a_hand_gone_for_long_or_time_going_back_starts_afresh():
    tracker = motion.FingerMotion(window_s=0.1, forget_s=1.0)
    five, grab = [hand(blend("five", "five", 0))], [hand(blend("grab", "grab", 0))]
    moved_of(tracker, five, 10.0)
    assert moved_of(tracker, grab, 10.2)[0] > 20.0  # it closed
    other = [hand(blend("five", "five", 0), hand_id=9)]
    moved_of(tracker, other, 11.5)  # hand 1 unseen for 1.3 s: forgotten
    assert list(tracker.tracks) == ["right/9"]
    assert np.isnan(moved_of(tracker, grab, 11.6)[0])
    assert np.isnan(moved_of(tracker, five, 5.0)[0])  # a replay restarted


def test_a_source_whose_time_stands_still_keeps_a_bounded_history():
    tracker = motion.FingerMotion()
    five = [hand(blend("five", "five", 0))]
    assert np.isnan(moved_of(tracker, five, 7.0)[0])
    for _ in range(3 * motion.MAX_FRAMES_KEPT):
        assert moved_of(tracker, five, 7.0)[0] == 0.0  # against its first frame
    assert len(tracker.tracks["right/1"]) == motion.MAX_FRAMES_KEPT


def service(**settings):
    return FakeBus(StaticGesture(StaticGestureSettings(**settings)))


def answers(bus, poses, rate_hz=60.0):
    """Feeds one hand through `poses` (one per frame); returns (winner, p) per frame."""
    out = []
    for i, pose in enumerate(poses):
        msg = example("hands/frame", hands=[hand(pose)], seq=i, ts=50.0 + i / rate_hz)
        (_, m), = bus.feed(keys.HANDS_FRAME, msg)
        k = int(np.argmax(m["probs"]))
        out.append((m["names"][k], m["probs"][k]))
    return out


def test_through_the_service_a_hand_changing_pose_is_none_and_a_held_one_keeps_its_answer():
    # a point held 0.5 s, a 0.3 s change into a fist, the fist held 0.5 s (60 Hz)
    change = [blend("point", "grab", s * s * (3 - 2 * s)) for s in np.linspace(0, 1, 18)]
    poses = [blend("point", "point", 0)] * 30 + change + [blend("grab", "grab", 0)] * 30
    bus = service()
    got = answers(bus, poses)
    assert {name for name, _ in got[:30]} == {"point"}
    assert {name for name, _ in got[-20:]} == {"grab"}  # a window after the change, held again
    middle = slice(30 + 8, 30 + 15)  # the change's fast part
    assert {name for name, _ in got[middle]} == {"none"}
    assert bus.query("status", None)[1]["hands_moving"] >= 7
    # read frame by frame (the rule off), the same frames are gestures
    off = answers(service(moving_deg=0.0), poses)
    assert {name for name, _ in off[middle]} == {"point", "grab"}
    assert off[:30] == got[:30] and off[-20:] == got[-20:]  # held poses: the same answers


def test_a_hand_found_while_it_changes_pose_is_none_before_it_is_a_window_old():
    # the tracker finds the hand a third into a point closing into a fist (0.3 s, 60 Hz)
    change = [blend("point", "grab", s * s * (3 - 2 * s)) for s in np.linspace(0, 1, 18)]
    poses = change[6:] + [blend("grab", "grab", 0)] * 30
    got, off = answers(service(), poses), answers(service(moving_deg=0.0), poses)
    young = int(motion.WINDOW_S * 60)  # frames with nothing a window back
    flips = [i for i in range(1, young) if off[i][0] != off[i - 1][0]]
    assert flips and off[flips[0]][0] == "grab"  # read alone: point, then grab, while young
    assert got[flips[0]][0] == "none"  # against its first frame: a pose forming
    assert got[0] == off[0] and got[-20:] == off[-20:]  # its first frame and the held fist


def test_a_change_of_one_finger_is_none_where_its_reading_flips():
    # two to three in 0.3 s: the ring finger alone moves, 3 of the 19 angles
    change = [blend("two", "three", s * s * (3 - 2 * s)) for s in np.linspace(0, 1, 18)]
    poses = [blend("two", "two", 0)] * 30 + change + [blend("three", "three", 0)] * 30
    bus = service()
    got, off = answers(bus, poses), answers(service(moving_deg=0.0), poses)
    flips = [i for i in range(1, len(off)) if off[i][0] != off[i - 1][0]]
    assert [off[i][0] for i in flips] == ["three"]  # read frame by frame: two, then three
    assert got[flips[0]][0] == "none" and got[flips[0] + 1][0] == "none"
    assert got[:30] == off[:30] and got[-10:] == off[-10:]  # the held poses: the same answers
    assert bus.query("status", None)[1]["hands_moving"] >= 5


def test_a_held_pose_whose_fingers_flicker_keeps_its_answer():
    # a grab whose fingers open 15 % and back every 0.1 s (a tracker's flicker): the fingers
    # move, the reading stays grab, so the answer is kept; on finger motion alone it is not
    poses = [blend("grab", "five", 0.15 if (i // 6) % 2 else 0.0) for i in range(60)]
    bus = service()
    assert {name for name, _ in answers(bus, poses)} == {"grab"}
    assert bus.query("status", None)[1]["hands_moving"] == 0
    assert "none" in {name for name, _ in answers(service(changed_tv=0.0), poses)}


@pytest.mark.parametrize("tv", [-0.1, 1.5])
def test_an_answer_change_line_outside_0_1_is_a_configuration_error(tv):
    with pytest.raises(ConfigError, match="changed_tv"):
        StaticGestureSettings(changed_tv=tv)


@pytest.mark.parametrize(("still", "moving"), [(20.0, 10.0), (-1.0, 10.0), (10.0, 10.0)])
def test_lines_out_of_order_are_a_configuration_error(still, moving):
    with pytest.raises(ConfigError, match="still_deg"):
        StaticGestureSettings(still_deg=still, moving_deg=moving)
