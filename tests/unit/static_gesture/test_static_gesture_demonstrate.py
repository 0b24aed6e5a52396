"""Recording by demonstration: the capture state machine, names, and the `cbgo gestures` verb."""

import argparse

import numpy as np
import pytest

from cbgo.cli import gestures as cli
from cbgo.examples import example, open_hand
from cbgo.services.static_gesture import demonstrate, train


def frames(hand_flags, start=0.0, dt=0.1):
    return [example("hands/frame", ts=start + i * dt,
                    hands=[open_hand(palm=(float(i), 200.0, 30.0))] if present else [])
            for i, present in enumerate(hand_flags)]


def test_frames_count_only_after_the_hand_has_settled():
    capture = demonstrate.Capture(frames=3, settle_s=0.25)
    lines = [capture.feed(m) for m in frames([0, 1, 1, 1, 1, 1, 1])]
    assert lines[1].startswith("take 1: hand seen")
    # hand seen at t=0.1; frames from t=0.35 on count: t=0.4, 0.5, 0.6
    assert capture.done and lines[-1] == "take 1: 3 frames captured"
    assert capture.features()[:, 42:].shape == (3, 15)


def test_a_second_take_waits_for_the_hand_to_leave_and_come_back():
    capture = demonstrate.Capture(frames=2, takes=2)
    stream = frames([1, 1, 1, 1, 0, 1, 1])
    first = [capture.feed(m) for m in stream[:4]]
    assert "take the hand away for take 2" in first[1]
    assert len(capture.rows) == 2  # the frames before the gap did not count for take 2
    rest = [capture.feed(m) for m in stream[4:]]
    assert rest[0] == "take 2: show the gesture"
    assert capture.done and len(capture.rows) == 4


def test_a_hand_lost_mid_take_settles_again_when_it_is_back():
    capture = demonstrate.Capture(frames=3, settle_s=0.15)
    for m in frames([1, 1, 1, 1, 0, 1, 1, 1, 1]):
        capture.feed(m)
    # rows: t=0.2, 0.3 (first stay); after the loss the hand is back at t=0.5, counts from 0.7
    assert len(capture.rows) == 3 and capture.done


@pytest.mark.parametrize("name", ["horns", "ok_sign", "v2"])
def test_good_gesture_names_pass(name):
    assert demonstrate.check_name(name) == name


@pytest.mark.parametrize("name", ["", "Horns", "2fingers", "a-b", "none", "x" * 33])
def test_bad_gesture_names_are_refused_with_what_a_name_may_be(name):
    with pytest.raises(ValueError):
        demonstrate.check_name(name)


def parse(argv):
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    return parser.parse_args(argv)


def test_record_needs_a_kind_and_takes_the_shared_options():
    args = parse(["record", "horns", "--static", "--frames", "30", "--takes", "2", "--user",
                  "alice", "--timeout", "5"])
    assert (args.kind, args.name, args.frames, args.takes, args.user, args.timeout) == (
        "static", "horns", 30, 2, "alice", 5.0)
    with pytest.raises(SystemExit):
        parse(["record", "horns"])
    with pytest.raises(SystemExit):
        parse(["record", "horns", "--static", "--dynamic"])


def test_a_missing_demonstration_module_is_a_clear_error(monkeypatch, capsys):
    monkeypatch.setitem(cli.MODULES, "dynamic", "cbgo.services.nothing_here.demonstrate")
    with pytest.raises(SystemExit):
        cli.run(parse(["record", "circle", "--dynamic"]))
    assert "dynamic gestures by demonstration are not available" in capsys.readouterr().err


def test_a_bad_name_exits_with_a_configuration_error(capsys):
    assert cli.run(parse(["record", "Bad Name", "--static"])) == 2
    assert "lower-case letters" in capsys.readouterr().err


def test_list_shows_the_recorded_static_gestures(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path))
    assert cli.run(parse(["list"])) == 0
    assert "no recorded gestures yet" in capsys.readouterr().out
    train.store_gesture("horns", np.zeros((4, 57)), {"user": "alice", "time": "T1", "count": 4})
    assert cli.run(parse(["list"])) == 0
    out = capsys.readouterr().out
    assert "horns" in out and "alice" in out
    assert cli.run(parse(["list", "--json"])) == 0
    assert '"name": "horns"' in capsys.readouterr().out
