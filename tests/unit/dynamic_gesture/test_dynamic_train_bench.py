"""Training and benchmark plumbing on a tiny simulated data set (the real runs are CLI verbs)."""

import argparse
import json
from dataclasses import replace

import numpy as np
import pytest

from cbgo.services.dynamic_gesture.classifier import MIRROR
from cbgo.services.dynamic_gesture.library import DEFAULT_PATH, Library, read_default, save_default
from cbgo.services.dynamic_gesture.stroke import SegmenterConfig
from cbgo.simuser.scenario import UserStyle
from cbgo.wire import DYNAMIC_GESTURES
from cbgo_tools.dynamic_gesture import bench, realism, simdata, train


@pytest.fixture(scope="module")
def one_user():
    return simdata.run_user(7, simdata.TRAIN, reps=1)


def test_a_simulated_user_gives_labelled_windows_for_every_stroke(one_user):
    assert sorted(g for g, _, _ in one_user.strokes) == sorted(DYNAMIC_GESTURES)
    assert one_user.missed == []
    finals = [lw.truth for lw in one_user.windows if lw.window.final]
    assert sorted(t for t in finals if t != "none") == sorted(DYNAMIC_GESTURES)


def test_templates_and_calibration_learned_from_a_tiny_set_load_and_classify(one_user,
                                                                            tmp_path):
    templates = train.learn_templates([one_user])
    assert [t.name for t in templates] == list(DYNAMIC_GESTURES)
    classifier = Library(DEFAULT_PATH, None).load().classifier()
    feats, labels = train.labelled_features(classifier, [one_user])
    calibration = train.fit_neural_calibration(feats, labels, epochs=50)
    path = tmp_path / "tiny.json"
    save_default(path, templates, calibration, {"roll_scale_mm_per_rad": 100.0}, {"users": 1})
    loaded, again, data = read_default(path)
    assert [t.name for t in loaded] == list(DYNAMIC_GESTURES)
    probs = [again.probabilities(f) for f in feats]
    assert np.allclose(probs, [calibration.probabilities(f) for f in feats], atol=1e-4)
    assert np.allclose(np.sum(probs, 1), 1.0)
    assert json.loads(path.read_text())["training"] == {"users": 1} == data["training"]



def test_the_calibration_seed_draws_the_networks_start_and_nothing_else(one_user):
    same = [train.fit([one_user], [one_user], [], calibration_seed=k) for k in (3, 3)]
    other = train.fit([one_user], [one_user], [], calibration_seed=4)
    assert np.array_equal(same[0].calibration.w1, same[1].calibration.w1)
    assert not np.allclose(other.calibration.w1, same[0].calibration.w1)
    # the templates come from the demonstrations alone
    assert [t.shape.tolist() for t in other.templates] == [t.shape.tolist()
                                                           for t in same[0].templates]


def test_a_left_hands_demonstrations_are_learned_in_the_right_hands_space(one_user):
    lefts = [replace(lw, window=replace(lw.window, side="left")) for lw in one_user.windows]
    right = train.demonstrations([one_user])
    left = train.demonstrations([simdata.UserData("lefty", {}, lefts)])
    assert [w.side for ws in left.values() for w in ws] == ["right"] * 5
    for name, mirror in MIRROR.items():
        assert len(left[mirror]) == len(right[name]) == 1
        assert np.allclose(left[mirror][0].obs, right[name][0].obs * [-1, 1, 1, 1])
    assert {t.name: t.mirror for t in train.learn_templates([one_user])} == MIRROR


@pytest.mark.parametrize("side, medial, lateral", [("right", "swipe_left", "swipe_right"),
                                                   ("left", "swipe_right", "swipe_left")])
def test_a_simulated_palm_turns_to_face_where_it_swipes_across_the_body(side, medial, lateral):
    ranges = replace(simdata.TRAIN, left_share=float(side == "left"),
                     swipe_roll_deg=((0.0, 0.0),), medial_roll_deg=((50.0, 50.0),))
    user = simdata.run_user(11, ranges, reps=2, statics=False)
    roll = {}
    for lw in user.windows:
        if lw.window.final and lw.truth in (medial, lateral):
            roll.setdefault(lw.truth, []).append(np.degrees(lw.window.obs[-1, 3] / 50.0))
    assert user.style["side"] == side
    assert np.median(roll[medial]) == pytest.approx(50.0, abs=15.0)
    assert np.median(roll[lateral]) == pytest.approx(0.0, abs=15.0)


def test_the_benchmark_scores_final_windows_and_counts_missed_strokes(one_user):
    classifier = Library(DEFAULT_PATH, None).load().classifier()
    figures = bench.score(classifier, [one_user], [])
    final = figures["final"]
    assert final["true_strokes"] == 5 and final["missed_strokes"] == 0
    confusion = np.asarray(final["confusion"])
    assert confusion.sum() == final["samples"]
    recalls = [confusion[i, i] / row.sum() for i, row in enumerate(confusion) if row.sum()]
    assert final["balanced_accuracy"] == pytest.approx(np.mean(recalls))
    # One user, one stroke per gesture: one unsure stroke costs a sixth; chance is a sixth.
    assert final["balanced_accuracy"] > 0.6
    cost = bench.cost(classifier, [lw.window for lw in one_user.windows if lw.window.final],
                      limit=3)
    assert cost["classify_ms_median"] > 0 and cost["templates"] == 5


def test_the_held_out_peoples_streams_are_judged_against_issue_14s_goals(capsys):
    streams = {"strokes": 100, "recalled": 95, "false_triggers": 12, "other_gesture_triggers": 3,
               "misread": 1, "other_minutes": 10.0}
    train.print_leave_people_out({"folds": 4, "people": [1, 2], "streams": streams})
    out = capsys.readouterr().out
    assert "  PASS  continuous streams: recall ≥ 90%: 95/100 = 95.0%" in out
    assert "  MISS  continuous streams: false triggers ≤ 1/min: 12 in 10.0 min = 1.20/min" in out


def test_replayed_simulated_trials_are_answered_as_the_service_answers(capsys, tmp_path):
    parser = argparse.ArgumentParser()
    bench.add_arguments(parser)
    out = tmp_path / "replay.json"
    args = parser.parse_args(["--replay-sim", "1", "--ranges", "train", "--json", str(out)])
    assert bench.run(args) == 0
    printed = capsys.readouterr().out
    assert "5 trials of 1 simulated train users, replayed offline" in printed
    assert "gestures/dynamic, final windows only" in printed
    assert "----  synthetic strokes, rotate included: gestures/dynamic ≥ 97% balanced" in printed
    assert "5 trials of train users (under 250 trials" in printed  # judged on whom it says
    result = json.loads(out.read_text())
    trials = result["trials"]
    assert sorted(t["truth"] for t in trials) == sorted(DYNAMIC_GESTURES)
    # this user's five gestures, each from anywhere in the field with its preparation and
    # return, are all answered right by the shipped library, by any rule
    assert all(t["dynamic"] == t["finals"] == t["first"] == t["truth"] for t in trials)
    assert result["dynamic"]["balanced_accuracy"] == 1.0
    # scored by the user's style too: one user, one style, its five trials
    (style,) = {t["style"] for t in trials}
    assert result["by_style"] == {style: {"right": 5, "trials": 5}}
    assert f"{style} 5/5 = 100.0%" in printed


def test_a_users_style_is_named_by_the_halves_of_its_ranges():
    ranges = simdata.HELD_OUT  # amplitude 0.55-0.75 or 1.5-1.8, speed 0.7-0.85 or 1.6-1.9
    assert ranges.quarter(UserStyle(amplitude=0.7, speed=0.75)) == "small/slow"
    assert ranges.quarter(UserStyle(amplitude=1.8, speed=0.75)) == "large/slow"
    assert ranges.quarter(UserStyle(amplitude=0.7, speed=1.7)) == "small/fast"
    # one interval: split at its middle (training amplitude 0.75-1.5, speed 0.85-1.6)
    assert simdata.TRAIN.quarter(UserStyle(amplitude=1.0, speed=1.3)) == "small/fast"
    assert simdata.TRAIN.quarter(UserStyle(amplitude=1.4, speed=1.2)) == "large/slow"
    # one value: the default style, neither half
    assert simdata.RANGES["default"].quarter(UserStyle()) == "typical/typical"


def test_the_default_user_strokes_like_the_middle_of_the_population_fitted_to_real_people():
    # the training range's swipes are the ones `--realism` matches with real people's
    typical = UserStyle()
    for value, (interval,) in ((typical.speed, simdata.TRAIN.speed),
                               (typical.amplitude, simdata.TRAIN.amplitude)):
        assert abs(value - sum(interval) / 2) <= 0.05 * sum(interval) / 2


def test_the_default_ranges_draw_the_default_style_but_its_swipes_still_vary():
    rng = np.random.default_rng(4)
    style, angles = simdata.RANGES["default"].draw(rng, "u")
    assert style == UserStyle(side="right")
    low, high = simdata.TRAIN.angle_deg[0]
    assert low * 0.93 <= angles[0] < angles[1] <= high * 1.07 and style.length_spread > 0


def test_the_realism_bench_draws_its_simulated_users_from_the_ranges_asked():
    def median_peak(speed: float) -> float:
        ranges = replace(simdata.RANGES["default"], speed=((speed, speed),))
        rows = realism.simulated_habits(1, 3, SegmenterConfig(), ranges)
        return float(np.median(realism.known_values(rows, "peak_mm_s")))

    # the same person's swipes, one and a half times as quick
    assert median_peak(1.5) > 1.3 * median_peak(1.0)
