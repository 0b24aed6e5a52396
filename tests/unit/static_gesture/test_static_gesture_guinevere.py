"""Guinevere's static poses as takes (`guinevere.py`): LeapJS files laid out as the set's, made
from simulated hands, converted, then scored by the shipped model as `cbgo bench static
--takes` scores them."""

import argparse
import json

import numpy as np
import pytest

from cbgo.hands.model import HandShape, build_hand
from cbgo.hands.poses import gesture_pose
from cbgo.recording import read_recording
from cbgo.services.static_gesture.classifier import StaticClassifier, default_model_path
from cbgo.wire import decode
from cbgo_tools.data import guinevere
from cbgo_tools.data.leapjs_frames import JOINTS
from cbgo_tools.static_gesture import takes


def leapjs_frame(hand, timestamp_us, hand_id=131):
    """A contract hand as LeapJS writes it: the hand's fields, and one pointable per finger
    with its joints (carp → mcp → pip → dip → btip) and tracker flags."""
    leap = {"id": hand_id, "type": hand["side"], "confidence": hand["confidence"],
            "palmPosition": hand["palm_position"], "palmVelocity": hand["palm_velocity"],
            "palmNormal": hand["palm_normal"], "direction": hand["direction"],
            "wrist": hand["wrist_position"], "palmWidth": hand["palm_width"],
            "grabStrength": hand["grab_strength"], "pinchStrength": hand["pinch_strength"]}
    pointables = []
    for index, finger in enumerate(hand["fingers"]):
        bones = finger["bones"]
        joints = [bones[0]["prev_joint"]] + [b["next_joint"] for b in bones]
        pointables.append({"handId": hand_id, "type": index, "width": bones[0]["width"],
                           "extended": index == 1, **dict(zip(JOINTS, joints, strict=True))})
    return {"timestamp": timestamp_us, "hands": [leap], "pointables": pointables}


def write_leapjs_take(path, gesture, frames=10, seed=0):
    rng = np.random.default_rng(seed)
    shape = HandShape.sample(rng, side="right")
    data = [leapjs_frame(build_hand(shape, gesture_pose(gesture, rng), np.array([0, 200, 0.0])),
                         5_000_000 + i * 18_000) for i in range(frames)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"frames": frames, "data": data}))


@pytest.fixture
def guinevere_set(tmp_path):
    """The set's layout: a folder per pose, takes under 01/, and an info.json."""
    src = tmp_path / "guinevre-static2"
    write_leapjs_take(src / "point-index" / "01" / "point-index-2.json", "point")
    write_leapjs_take(src / "thumb" / "01" / "thumb-2.json", "thumbsup", seed=1)
    write_leapjs_take(src / "grab" / "01" / "grab-2.json", "grab", seed=2)
    (src / "info.json").write_text('{"name": "guinevere-static2"}')
    return src


def test_scored_poses_become_takes_and_grab_is_left_out(guinevere_set, tmp_path, capsys):
    specs = guinevere.convert(guinevere_set, tmp_path / "takes")
    assert sorted(s.split("=")[0] for s in specs) == ["point", "thumbsup"]
    printed = capsys.readouterr().out
    assert "grab-2.json: left out, not the paper's grab" in printed
    assert not list((tmp_path / "takes").glob("*grab*"))


def test_a_take_holds_every_frame_in_time_order_on_the_frame_key(guinevere_set, tmp_path):
    guinevere.convert(guinevere_set, tmp_path / "takes")
    recorded = list(read_recording(tmp_path / "takes" / "point-point-index-2.mcap"))
    assert [m.key for m in recorded] == ["cbgo/hands/frame"] * 10
    stamps = [decode(m.payload)["ts"] for m in recorded]
    assert np.allclose(np.diff(stamps), 0.018)
    assert [m.log_time_ns for m in recorded] == sorted(m.log_time_ns for m in recorded)


def test_the_shipped_model_reads_leapjs_laid_out_hands_as_the_pose_they_hold(guinevere_set,
                                                                              tmp_path):
    specs = guinevere.convert(guinevere_set, tmp_path / "takes")
    scores = takes.score_takes(StaticClassifier.load(default_model_path(), samples=8), specs)
    assert {s.label: (s.hands, s.skipped) for s in scores} == {"point": (10, 0),
                                                               "thumbsup": (10, 0)}
    assert all(s.share == 1.0 for s in scores), [s.answers for s in scores]


def test_the_tracker_view_of_a_take_is_its_median_strengths_and_usual_finger_flags(
        guinevere_set):
    seen = guinevere.describe(json.loads(
        (guinevere_set / "point-index" / "01" / "point-index-2.json").read_text()))
    assert seen["hands"] == 10 and seen["extended"] == "01000" and seen["extended_share"] == 1
    assert 0.0 <= seen["grab_strength"] <= 1.0


def test_a_folder_without_takes_is_a_clear_error(tmp_path, capsys):
    assert guinevere.run(argparse.Namespace(src=tmp_path, dst=tmp_path / "takes")) == 2
    assert "no LeapJS takes" in capsys.readouterr().err


def test_the_cache_gives_back_the_takes_convert_wrote(guinevere_set, tmp_path):
    written = guinevere.convert(guinevere_set, tmp_path / "takes")
    assert sorted(guinevere.cached_takes(tmp_path / "takes")) == sorted(written)
    assert guinevere.cached_takes(tmp_path / "nothing-here") == []


def test_scored_takes_print_from_plain_figures(guinevere_set, tmp_path, capsys):
    specs = guinevere.convert(guinevere_set, tmp_path / "takes")
    fig = takes.figures(takes.score_takes(StaticClassifier.load(default_model_path(), samples=8),
                                          specs))
    json.dumps(fig)  # plain data: the bench's --json holds it
    capsys.readouterr()
    takes.print_figures(fig, "static-bnn-x", "Guinevere's static takes")
    printed = capsys.readouterr().out
    assert printed.startswith("Guinevere's static takes, model static-bnn-x")
    assert "thumbsup" in printed and "known gestures, frames right: 100.0%" in printed


def test_an_unreadable_hand_is_left_out_and_said(guinevere_set, tmp_path, capsys):
    path = guinevere_set / "thumb" / "01" / "thumb-2.json"
    take = json.loads(path.read_text())
    del take["data"][4]["pointables"][0]  # the thumb's pointable
    path.write_text(json.dumps(take))
    guinevere.convert(guinevere_set, tmp_path / "takes")
    line = next(x for x in capsys.readouterr().out.splitlines() if "thumb-2.json" in x)
    assert "thumbsup-thumb-2.mcap: 9 frames" in line
    assert "left out as unreadable: 1 hand: KeyError" in line
