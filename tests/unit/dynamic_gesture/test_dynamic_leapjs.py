"""The LeapJS converter (the Guinevere set) on recordings laid out like LeapJS's own frames."""

import json
from argparse import Namespace

import numpy as np
import pytest

from cbgo import keys, wire
from cbgo.services.dynamic_gesture.stroke import Segmenter
from cbgo_tools.data import leapjs
from cbgo_tools.data import leapjs_frames as hands_leapjs
from cbgo_tools.dynamic_gesture import streams
from cbgo_tools.dynamic_gesture.trials import leapjs_trial


def leapjs_hand(palm, hand_id=7, side="right"):
    """One LeapJS hand over a desk sensor, palm down, fingers away from the user, and its
    five pointables (carp → mcp → pip → dip → btip along −z)."""
    palm = np.asarray(palm, dtype=float)
    hand = {"id": hand_id, "type": side, "confidence": 0.9,
            "palmPosition": palm.tolist(), "palmVelocity": [0.0, 0.0, 0.0],
            "palmNormal": [0.0, -1.0, 0.0], "direction": [0.0, 0.0, -1.0],
            "wrist": (palm + [0, 0, 50]).tolist(), "palmWidth": 82.0,
            "grabStrength": 0.0, "pinchStrength": 0.1}
    pointables = []
    for finger in range(5):
        base = palm + [-40.0 + 20.0 * finger, 0.0, 40.0]
        joints = {name: (base + [0.0, 0.0, -25.0 * j]).tolist()
                  for j, name in enumerate(hands_leapjs.JOINTS)}
        pointables.append({"handId": hand_id, "type": finger, "width": 17.0, **joints})
    return hand, pointables


def recording(palms, hz=115.0):
    frames = []
    for i, palm in enumerate(palms):
        hand, pointables = leapjs_hand(palm)
        frames.append({"id": 1000 + i, "timestamp": 5_000_000 + round(i * 1e6 / hz),
                       "hands": [hand], "pointables": pointables})
    return {"frames": len(frames), "data": frames}


def swipe_palms(dx=220.0, n=115):
    s = np.linspace(0, 1, n)[:, None]
    s = s**3 * (10 - 15 * s + 6 * s**2)
    move = np.array([0.0, 200.0, 0.0]) + s * [dx, 0.0, 0.0]
    still = np.repeat(move[:1], 40, axis=0)
    return np.concatenate([still, move, np.repeat(move[-1:], 30, axis=0)])


@pytest.fixture
def dataset(tmp_path):
    """Two people's folders: a swipe right with the palm, a tap, and a file that is no take."""
    for person in ("01", "02"):
        (tmp_path / person).mkdir()
        (tmp_path / person / "swipe_right#palm-1.json").write_text(
            json.dumps(recording(swipe_palms())))
        (tmp_path / person / "tap-2.json").write_text(json.dumps(recording(swipe_palms(0.0))))
    (tmp_path / "info.json").write_text("{}")
    return tmp_path


def test_every_converted_frame_fits_the_contract(dataset):
    rec = leapjs.read_set(dataset)[0]
    for msg in rec.frames():
        wire.validate(msg, wire.schema_for(keys.HANDS_FRAME.suffix))


def test_positions_stay_in_the_leap_frame_and_time_is_the_device_clock_in_seconds(dataset):
    frames = leapjs.read_set(dataset)[0].frames()
    first, last = frames[0]["hands"][0], frames[-1]["hands"][0]
    assert np.allclose(np.subtract(last["palm_position"], first["palm_position"]),
                       [220.0, 0.0, 0.0])
    assert frames[0]["ts"] == 0.0
    assert frames[115]["ts"] == pytest.approx(1.0, abs=1e-5)
    assert first["palm_normal"] == [0.0, -1.0, 0.0] and first["side"] == "right"


def test_bones_run_carp_mcp_pip_dip_tip_with_the_fingers_in_order(dataset):
    hand = leapjs.read_set(dataset)[0].frames()[0]["hands"][0]
    assert [f["type"] for f in hand["fingers"]] == ["thumb", "index", "middle", "ring", "pinky"]
    index = hand["fingers"][1]["bones"]
    assert [b["type"] for b in index] == ["metacarpal", "proximal", "intermediate", "distal"]
    for a, b in zip(index, index[1:], strict=False):
        assert a["next_joint"] == b["prev_joint"]
    assert index[0]["prev_joint"][2] - index[-1]["next_joint"][2] == pytest.approx(100.0)


def test_names_variants_people_and_takes_come_from_the_file_names(dataset):
    recs = leapjs.read_set(dataset)
    assert {(r.gesture, r.variant, r.person, r.take) for r in recs} == {
        ("swipe_right", "palm", "01", 1), ("tap", "", "01", 2),
        ("swipe_right", "palm", "02", 1), ("tap", "", "02", 2)}
    trials = [leapjs_trial(r) for r in recs]
    assert {(t.truth, t.gesture) for t in trials} == {("swipe_right", "swipe_right#palm"),
                                                     ("none", "tap")}


def test_an_empty_folder_names_where_to_get_the_data(tmp_path):
    with pytest.raises(FileNotFoundError, match="sluyters/QuantumLeap"):
        leapjs.read_set(tmp_path)


def test_the_segmenter_cuts_one_swipe_out_of_a_converted_recording(dataset):
    rec = next(r for r in leapjs.read_set(dataset) if r.gesture == "swipe_right")
    segmenter, windows = Segmenter(), []
    for msg in rec.frames():
        windows += segmenter.update(msg["ts"], msg["hands"])
    finals = [w for w in windows if w.final]
    assert len(finals) == 1
    assert finals[0].obs[-1, 0] > 150.0  # the stroke goes right


def test_a_trial_plays_its_frames_at_their_recorded_times(dataset):
    rec = leapjs.read_set(dataset)[0]
    frames = leapjs_trial(rec).frames()
    assert len(frames) == len(rec.frames())
    assert frames[-1][0] == pytest.approx((len(frames) - 1) / 115.0, abs=1e-5)


def test_a_stream_plays_recordings_back_to_back_with_the_hand_never_leaving(dataset):
    trials = [leapjs_trial(r) for r in leapjs.read_set(dataset)]
    frames, spans = streams.trials_stream(trials)
    assert [name for name, _, _ in spans] == [t.truth for t in trials]
    times = [t for t, _ in frames]
    assert all(b > a for a, b in zip(times, times[1:], strict=False))  # one clock, forward
    assert all(len(hands) == 1 and hands[0]["id"] == 1 for _, hands in frames)
    steps = [np.linalg.norm(np.subtract(b[1][0]["palm_position"], a[1][0]["palm_position"]))
             for a, b in zip(frames, frames[1:], strict=False)]
    assert max(steps) < 20.0  # no jump between recordings: the hand moves there
    for (_, _, a1), (_, b0, _) in zip(spans, spans[1:], strict=False):
        assert b0 - a1 >= streams.MOVE_S + streams.HOLD_S
    for _, hands in frames[::40]:
        msg = keys.HANDS_FRAME.message(ts=1.0, seq=0, source="replay", device="leapjs",
                                       hands=hands)
        wire.validate(msg, wire.schema_for(keys.HANDS_FRAME.suffix))


def test_with_returns_each_swipe_is_followed_by_a_move_back_outside_every_span(dataset):
    trials = [leapjs_trial(r) for r in leapjs.read_set(dataset)]
    swipe = next(t for t in trials if t.truth == "swipe_right")
    plain, spans = streams.trials_stream([swipe])
    frames, with_return = streams.trials_stream([swipe], returns=True)
    assert with_return == spans and frames[:len(plain)] == plain
    back = frames[len(plain):]
    assert back and back[0][0] > spans[0][2]  # after the swipe's span
    start, end = (np.asarray(h[0]["palm_position"]) for h in (plain[0][1], plain[-1][1]))
    moved = np.asarray(back[-1][1][0]["palm_position"]) - end
    assert moved == pytest.approx(-streams.RETURN_LENGTH * (end - start), abs=1e-6)
    steps = np.linalg.norm(np.diff([h[0]["palm_position"] for _, h in back], axis=0), axis=1)
    assert steps.max() < 20.0  # a move, not a jump
    none_trial = next(t for t in trials if t.truth == "none")
    assert streams.trials_stream([none_trial], returns=True)[0] == \
        streams.trials_stream([none_trial])[0]  # no return after what is no swipe


def test_a_blended_hand_turns_with_unit_vectors_half_way():
    a, pa = leapjs_hand([0.0, 200.0, 0.0])
    b, pb = leapjs_hand([100.0, 200.0, 0.0])
    b["palmNormal"] = [1.0, 0.0, 0.0]
    ha, hb = hands_leapjs.to_hand(a, pa), hands_leapjs.to_hand(b, pb)
    mid = streams.blend_hands(ha, hb, 0.5)
    assert np.allclose(mid["palm_position"], [50.0, 200.0, 0.0])
    assert np.isclose(np.linalg.norm(mid["palm_normal"]), 1.0)
    assert np.allclose(mid["palm_normal"], np.array([1.0, -1.0, 0.0]) / np.sqrt(2))


def test_a_hand_turned_over_between_recordings_turns_rigidly_at_an_even_rate():
    a, pa = leapjs_hand([0.0, 200.0, 0.0])
    ha = hands_leapjs.to_hand(a, pa)
    flip = np.diag([-1.0, -1.0, 1.0])  # half a turn about the forward axis: palm up

    def flipped(p) -> list[float]:
        return (flip @ np.subtract(p, [0, 200, 0]) + [0, 200, 0]).tolist()

    palm_up = {**ha, "palm_normal": (flip @ ha["palm_normal"]).tolist(),
               "direction": (flip @ ha["direction"]).tolist(),
               "wrist_position": flipped(ha["wrist_position"]),
               "fingers": [{"type": f["type"], "bones": [
                   {**b, "prev_joint": flipped(b["prev_joint"]),
                    "next_joint": flipped(b["next_joint"])} for b in f["bones"]]}
                   for f in ha["fingers"]]}
    tip = np.asarray(ha["fingers"][1]["bones"][3]["next_joint"]) - [0, 200, 0]
    for s, turned_deg in ((0.25, 45.0), (0.5, 90.0), (0.75, 135.0)):
        mid = streams.blend_hands(ha, palm_up, s)
        normal = np.asarray(mid["palm_normal"])
        angle = np.degrees(np.arccos(np.clip(normal @ ha["palm_normal"], -1.0, 1.0)))
        assert angle == pytest.approx(turned_deg, abs=1e-6)  # not a flip in the middle
        mid_tip = np.asarray(mid["fingers"][1]["bones"][3]["next_joint"]) - [0, 200, 0]
        assert np.linalg.norm(mid_tip) == pytest.approx(np.linalg.norm(tip))  # rigid


def two_hands(left_palms, right_palms, left_ids=None):
    """A LeapJS recording of a left and a right hand (ids 3 and 4 unless `left_ids` says)."""
    frames = []
    for i, (lp, rp) in enumerate(zip(left_palms, right_palms, strict=True)):
        left, left_fingers = leapjs_hand(lp, hand_id=left_ids[i] if left_ids else 3,
                                         side="left")
        right, right_fingers = leapjs_hand(rp, hand_id=4)
        frames.append({"id": i, "timestamp": round(i * 1e6 / 115), "hands": [left, right],
                       "pointables": left_fingers + right_fingers})
    return {"frames": len(frames), "data": frames}


def test_a_swipe_is_read_from_the_palm_that_moves_most_along_x():
    still = swipe_palms(0.0) + [0, 0, 100]
    assert leapjs.swipe_of(two_hands(swipe_palms(-220.0), still)) == ("left", "swipe_left")
    assert leapjs.swipe_of(two_hands(still, swipe_palms(220.0))) == ("right", "swipe_right")


def test_a_recording_that_breaks_the_swipe_rule_is_no_swipe():
    still = swipe_palms(0.0) + [0, 0, 100]
    across = swipe_palms(220.0) + np.linspace(0, 200, len(still))[:, None] * [0, 1, 0]
    there_and_back = np.concatenate([swipe_palms(220.0), swipe_palms(-220.0) + [220, 0, 0]])
    retracked = [3] * 100 + [5] * (len(still) - 100)
    brief = swipe_palms(220.0, n=20)[40:60]  # 220 mm in 0.17 s
    for left in (swipe_palms(80.0), across, brief):
        assert leapjs.swipe_of(two_hands(left, still[:len(left)])) is None
    assert leapjs.swipe_of(two_hands(there_and_back, np.concatenate([still, still]))) is None
    assert leapjs.swipe_of(two_hands(swipe_palms(220.0), still, left_ids=retracked)) is None


def test_the_swipes_of_leapmotion_all_become_a_set(tmp_path):
    src = tmp_path / "leapmotion-all"
    still = swipe_palms(0.0) + [0, 0, 100]
    takes = {"precedent/participant-2-6": two_hands(swipe_palms(220.0), still),
             "suivant/participant-2-3": two_hands(still, swipe_palms(-220.0)),
             "suivant/participant-5-8": two_hands(still, swipe_palms(80.0))}  # no swipe
    for name, take in takes.items():
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        (src / f"{name}.json").write_text(json.dumps(take))
    assert leapjs.run(Namespace(src=src, dst=tmp_path / "both", left_only=False)) == 0
    both = leapjs.read_set(tmp_path / "both")
    assert {(r.person, r.gesture, r.take) for r in both} == {
        ("participant-2", "swipe_right", 6), ("participant-2", "swipe_left", 3)}
    for frame in both[0].frames():  # whole: both hands, as the sensor reported them
        assert sorted(h["side"] for h in frame["hands"]) == ["left", "right"]
    assert leapjs.run(Namespace(src=src, dst=tmp_path / "left", left_only=True)) == 0
    left = leapjs.read_set(tmp_path / "left")
    assert [(r.person, r.gesture, r.take) for r in left] == [("participant-2", "swipe_right", 6)]
    for frame in left[0].frames():
        assert [(h["side"], h["id"], len(h["fingers"])) for h in frame["hands"]] == [
            ("left", 3, 5)]


def test_a_folder_without_leapmotion_all_recordings_is_named(tmp_path, capsys):
    assert leapjs.run(Namespace(src=tmp_path, dst=tmp_path / "both", left_only=False)) == 2
    assert "participant-" in capsys.readouterr().err


def test_a_bad_hand_or_frame_is_left_out_and_counted_not_the_recording():
    """A frame whose only hand cannot be read is dropped, not published as no hand."""
    from collections import Counter

    rec = recording(swipe_palms(n=20))
    del rec["data"][3]["pointables"][2]  # hand without its middle finger
    rec["data"][5]["hands"][0]["palmNormal"] = [0.0, float("nan"), 1.0]
    del rec["data"][7]["timestamp"]
    rejected = Counter()
    frames = hands_leapjs.to_frames(rec, rejected)
    assert len(frames) == len(rec["data"]) - 3  # its only hand unreadable: not "hand gone"
    assert all(len(f["hands"]) == 1 for f in frames)
    assert [f["seq"] for f in frames] == list(range(len(frames)))
    assert sum(rejected.values()) == 3 and rejected["frame without a timestamp"] == 1
    for msg in frames:  # what is left still fits the contract
        wire.validate(msg, wire.schema_for(keys.HANDS_FRAME.suffix))
