"""Recording by demonstration: the capture state machine, names, the duplicate check, the data
directory and the `cbgo gestures` verb."""

import argparse
import socket

import numpy as np
import pytest

from cbgo.cli import gestures as cli
from cbgo.examples import example, open_hand
from cbgo.services.static_gesture import demonstrate, train
from cbgo.simuser.scenario import hold_scenario, parse_scenario
from cbgo.simuser.user import SimulatedUser


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


# --------------------------------------------------------------------------- teaching without a
# sensor, and a new gesture that duplicates an old one


def simulated_takes(name, curls, takes=1, frames=40):
    """The rows `cbgo gestures record NAME --simulate CURLS` captures (no network)."""
    scenario = parse_scenario(hold_scenario(name, curls, takes, hold_s=2.5))
    capture = demonstrate.Capture(frames, takes, demonstrate.SIMULATED_SETTLE_S)
    for frame in SimulatedUser(scenario, 60.0).frames():
        capture.feed({"ts": 100.0 + frame.t, "hands": frame.hands})
    assert capture.done
    return capture.features()


@pytest.mark.parametrize("text, expected", [
    ("two", ("two", None)), ("1,0,1,1,0", ("horns", [1.0, 0.0, 1.0, 1.0, 0.0])),
    (" 1, 0.5, 1, 1, 0 ", ("horns", [1.0, 0.5, 1.0, 1.0, 0.0]))])
def test_simulate_takes_a_vocabulary_gesture_or_five_finger_curls(text, expected):
    assert demonstrate.simulate_pose(text, "horns") == expected


@pytest.mark.parametrize("text", ["horns", "1,0,1,1", "1,0,1,1,3", ""])
def test_a_bad_simulated_pose_says_what_it_may_be(text):
    with pytest.raises(ValueError, match="thumb,index,middle,ring,pinky"):
        demonstrate.simulate_pose(text, "horns")


def test_the_reading_of_takes_is_the_share_of_frames_each_name_wins():
    class Fixed:
        names = ["two", "peace", "none"]

        def predict_features(self, rows):
            return np.array([[0.9, 0.1, 0.0]] * 3 + [[0.1, 0.2, 0.7]])

    shares = demonstrate.reading(Fixed(), np.zeros((4, 57)))
    assert shares == {"two": 0.75, "none": 0.25}
    assert demonstrate.rival(shares, "peace") == ("two", 0.75)
    assert demonstrate.rival(shares, "two") is None  # its own name is no rival
    assert demonstrate.rival({"none": 0.9, "two": 0.1}, "horns") is None  # nor is none
    assert demonstrate.describe_shares(shares) == "two 75 %, none 25 %"


@pytest.fixture
def shipped_only(tmp_path, monkeypatch):
    """A data directory without a model of the user's: the shipped model is served."""
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path))
    return argparse.Namespace(served_model=None, force=False)


def test_a_new_name_shown_as_an_old_pose_is_refused_with_its_share(shipped_only, capsys):
    peace = simulated_takes("peace", [1, 0, 0, 1, 1])  # the two pose
    assert not demonstrate.check_takes(shipped_only, "peace", peace)
    out, err = capsys.readouterr()
    assert "reads the 40 frames as: two" in out
    assert "of the frames of 'peace' are already read as 'two'" in err
    assert "Not stored, not retrained, the model not swapped" in err and "--force" in err
    shipped_only.force = True
    assert demonstrate.check_takes(shipped_only, "peace", peace)
    assert "taught anyway (--force)" in capsys.readouterr().out


def test_a_pose_outside_the_vocabulary_passes_the_check(shipped_only, capsys):
    horns = simulated_takes("horns", [1, 0, 1, 1, 0])
    assert demonstrate.check_takes(shipped_only, "horns", horns)
    assert "already read as" not in capsys.readouterr().err
    # more examples of a known gesture are read as that gesture: no duplicate either
    assert demonstrate.check_takes(shipped_only, "two", simulated_takes("two", None))


# --------------------------------------------------------------------------- the data directory


def record_args(*extra):
    return parse(["record", "horns", "--static", *extra])


def test_the_running_services_data_directory_is_used(tmp_path):
    theirs = tmp_path / "theirs"  # not created yet: the service writes nothing until taught
    statuses = [{"name": "static-gesture", "data_dir": str(theirs), "host": socket.gethostname()}]
    assert cli.resolve_data_dir(record_args(), statuses, "static-gesture", env={
        "HOME": str(tmp_path)}) == theirs
    theirs.mkdir()  # another machine's, shared here
    elsewhere = [{**statuses[0], "host": "robot-pc"}]
    assert cli.resolve_data_dir(record_args(), elsewhere, "static-gesture", env={
        "HOME": str(tmp_path)}) == theirs
    assert cli.resolve_data_dir(record_args(), [], "static-gesture", env={
        "CBGO_DATA_DIR": str(tmp_path / "mine")}) == tmp_path / "mine"
    assert cli.resolve_data_dir(record_args(), statuses, "static-gesture", env={
        "CBGO_DATA_DIR": str(theirs)}) == theirs


def test_a_data_directory_other_than_the_services_is_an_error_naming_both(tmp_path):
    statuses = [{"name": "static-gesture", "data_dir": str(tmp_path / "theirs")}]
    with pytest.raises(ValueError, match=r"reads its gestures and model from .*theirs, not "
                                         r".*mine \(--data-dir\).*--data-dir .*theirs"):
        cli.resolve_data_dir(record_args("--data-dir", str(tmp_path / "mine")), statuses,
                             "static-gesture", env={})
    with pytest.raises(ValueError, match=r"\(CBGO_DATA_DIR\).*CBGO_DATA_DIR="):
        cli.resolve_data_dir(record_args(), statuses, "static-gesture",
                             env={"CBGO_DATA_DIR": str(tmp_path / "mine")})
    with pytest.raises(ValueError, match="on another machine, which is not here"):
        cli.resolve_data_dir(record_args(), [{**statuses[0], "host": "robot-pc"}],
                             "static-gesture", env={"HOME": str(tmp_path)})
    two = statuses + [{"name": "static-gesture", "data_dir": str(tmp_path)}]
    with pytest.raises(ValueError, match="2 static-gesture services answer"):
        cli.resolve_data_dir(record_args(), two, "static-gesture", env={})


def test_record_help_describes_the_verb_with_examples(capsys):
    with pytest.raises(SystemExit):
        parse(["record", "--help"])
    out = capsys.readouterr().out
    assert "Record a gesture by showing it" in out and "--simulate 1,0,1,1,0" in out
    assert "data directory must be the running service's" in out
    assert cli.service_of("static") == "static-gesture"
    assert cli.service_of("dynamic") == "dynamic-gesture"


def test_simulate_goes_with_static_and_a_bad_pose_is_refused_before_connecting(capsys):
    with pytest.raises(SystemExit):
        cli.run(parse(["record", "circle", "--dynamic", "--simulate", "two"]))
    assert "--simulate shows a held pose" in capsys.readouterr().err
    assert cli.run(record_args("--simulate", "1,2,3")) == 2
    assert "five finger curls" in capsys.readouterr().err


def test_a_new_gesture_takes_the_no_gesture_rows_of_its_finger_pattern_out_of_none():
    horns, two = simulated_takes("horns", [1, 0, 1, 1, 0]), simulated_takes("two", None)
    assert (train.finger_patterns(horns) == [1, 0, 0, 1]).all()
    assert (train.finger_patterns(two) == [1, 1, 0, 0]).all()
    options = train.TrainOptions(per_gesture=2, none=4, off_vocabulary=300, mmhgr=False)
    users = [train.UserGesture("horns", horns, [{}])]
    data = train.build_dataset(options, user=users)
    none = data.y == data.names.index("none")
    assert none.sum() > 200
    assert not (train.finger_patterns(data.x[none]) == [1, 0, 0, 1]).all(1).any()
    # without the new gesture, the simulated off-vocabulary hands include that pattern
    plain = train.build_dataset(options, user=[])
    none = plain.y == plain.names.index("none")
    assert (train.finger_patterns(plain.x[none]) == [1, 0, 0, 1]).all(1).sum() > 5
    # more examples of a gesture of the vocabulary claim nothing
    extra = train.build_dataset(options, user=[train.UserGesture("two", two, [{}])])
    assert (extra.y == extra.names.index("none")).sum() == none.sum()


@pytest.mark.parametrize("user", [None, "../alice"])
def test_personal_needs_a_user_a_file_may_be_named_after_before_connecting(user, capsys):
    argv = ["record", "thumbsup", "--static", "--personal", *(["--user", user] if user else [])]
    assert cli.run(parse(argv)) == 2
    assert "--personal needs --user NAME" in capsys.readouterr().err
