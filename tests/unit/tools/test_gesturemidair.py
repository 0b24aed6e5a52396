"""GestureMidAir's fingertip paths, carried by an open hand (synthetic files, no data)."""

import numpy as np
import pytest

from cbgo import wire
from cbgo_tools.data import gesturemidair
from cbgo_tools.dynamic_gesture import trials


def test_only_the_asked_splits_people_are_read_and_only_their_swipes(tmp_path, midair_set):
    root = midair_set(tmp_path / "set")
    train = gesturemidair.read_split(root)
    assert {(d.person, d.gesture) for d in train} == {("ann", "left-swipe"),
                                                      ("ann", "right-swipe")}
    assert {d.person for d in gesturemidair.read_split(root, "test")} == {"bob"}


def test_a_folder_that_is_not_the_set_names_the_fetch(tmp_path):
    with pytest.raises(FileNotFoundError, match="cbgo data fetch gesturemidair"):
        gesturemidair.read_split(tmp_path)


def test_repeated_times_are_dropped_and_time_starts_at_zero(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("1 2 3 1000\n1 2 3 1000\n2 2 3 1017\n")
    samples = gesturemidair.read_samples(path)
    assert samples[:, 3].tolist() == [0.0, pytest.approx(0.017)]


def test_an_open_hand_carries_the_path_on_its_index_tip_with_rest_around(tmp_path, midair_set):
    root = midair_set(tmp_path / "set")
    drawing = next(d for d in gesturemidair.read_split(root) if d.gesture == "right-swipe")
    samples = drawing.samples()
    frames = gesturemidair.hand_frames(samples)
    rest = round(gesturemidair.REST_S / np.median(np.diff(samples[:, 3])))
    assert len(frames) == len(samples) + 2 * rest
    times = [t for t, _ in frames]
    assert times[0] == 0.0 and all(b > a for a, b in zip(times, times[1:], strict=False))
    for (_, hands), tip in zip(frames[rest:-rest], samples[:, :3], strict=True):
        wire.validate(hands[0], wire.HAND)
        assert np.allclose(gesturemidair._index_tip(hands[0]), tip, atol=1e-6)
    first, last = frames[0][1][0], frames[-1][1][0]
    assert np.allclose(first["palm_position"], frames[rest][1][0]["palm_position"])
    assert np.allclose(last["palm_position"], frames[-rest - 1][1][0]["palm_position"])


def test_the_set_is_read_as_trials_of_its_train_people(tmp_path, midair_set):
    root = midair_set(tmp_path / "set")
    device, chosen, _ = trials.real_trials(root, "train")
    assert device == "gesturemidair"
    assert sorted(t.truth for t in chosen) == ["swipe_left", "swipe_right"]
    assert {t.person for t in chosen} == {"ann"}
