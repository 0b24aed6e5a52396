"""The SHREC'17 converter and the real-data helpers, on skeleton files laid out like its own."""

import numpy as np
import pytest

from cbgo import keys, wire
from cbgo.services.dynamic_gesture.stroke import Segmenter, SegmenterConfig
from cbgo.wire import DYNAMIC_GESTURES
from cbgo_tools.data import shrec
from cbgo_tools.dynamic_gesture import realism, report, scoring, simdata, streams, train
from cbgo_tools.dynamic_gesture.trials import (
    Trial,
    mirrored_stream,
    mirrored_trial,
    pick_trials,
    shrec_trial,
    simulated_trials,
)


def upright_hand(palm_m=(0.427, -0.307, 0.488)) -> np.ndarray:
    """22 joints (m) of a right hand held up before the camera, palm towards it (−z)."""
    palm = np.asarray(palm_m)
    joints = np.zeros((22, 3))
    joints[0] = palm + [0.0, -0.05, 0.0]  # wrist below the palm
    joints[1] = palm
    # thumb on the person's left of a right hand whose palm faces the camera: −x
    bases = {0: -0.045, 1: -0.025, 2: 0.0, 3: 0.02, 4: 0.04}
    for f, x in bases.items():
        base = palm + [x, 0.03 if f else -0.01, 0.0]
        for j in range(4):  # slightly curled towards the palm side (−z)
            joints[2 + 4 * f + j] = base + [0.0, 0.025 * j, -0.004 * j * j]
    return joints


def write_sequence(root, gesture, person, take, joints):
    path = root / f"gesture_{gesture}/finger_1/subject_{person}/essai_{take}/skeletons_world.txt"
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, joints.reshape(len(joints), -1))
    return path


@pytest.fixture
def dataset(tmp_path):
    """A tiny copy: a swipe right of person 2 (train) and one of person 1 (test)."""
    t = np.linspace(0, 1, 30)[:, None, None]
    s = t**3 * (10 - 15 * t + 6 * t**2)
    swipe = upright_hand()[None] + s * np.array([0.2, 0.0, 0.0])  # 200 mm to the right
    still = np.repeat(upright_hand()[None], 10, axis=0)
    joints = np.concatenate([still, swipe, np.repeat(swipe[-1:], 10, axis=0)])
    write_sequence(tmp_path, 7, 2, 1, joints)
    write_sequence(tmp_path, 7, 1, 1, joints)
    (tmp_path / "train_gestures.txt").write_text(f"7 1 2 1 7 13 {len(joints)}\n")
    (tmp_path / "test_gestures.txt").write_text(f"7 1 1 1 7 13 {len(joints)}\n")
    return tmp_path


def test_every_converted_frame_fits_the_contract(dataset):
    (seq,) = shrec.read_split(dataset, "train")
    for msg in shrec.frames(seq, t0=100.0):
        wire.validate(msg, wire.schema_for(keys.HANDS_FRAME.suffix))


def test_the_axes_are_the_leap_frames_and_the_hand_is_upright_palm_to_the_sensor(dataset):
    (seq,) = shrec.read_split(dataset, "train")
    hands = shrec.to_hands(seq.joints())
    first, last = np.array(hands[0]["palm_position"]), np.array(hands[-1]["palm_position"])
    assert np.allclose(last - first, [200.0, 0.0, 0.0], atol=1e-6)  # swipe right is +x, mm
    assert np.allclose(hands[0]["direction"], [0, 1, 0], atol=0.05)  # fingers up
    assert np.allclose(hands[0]["palm_normal"], [0, 0, -1], atol=0.05)  # towards the camera
    # the median palm of the train split's swipes is put at the field centre
    assert np.allclose(first, shrec.FIELD_CENTRE_MM, atol=1.0)


def test_splits_are_read_from_their_lists_and_never_share_people(dataset):
    assert [s.person for s in shrec.read_split(dataset, "train")] == [2]
    assert [s.person for s in shrec.read_split(dataset, "test")] == [1]
    (dataset / "test_gestures.txt").write_text("7 1 2 1 7 13 50\n")
    with pytest.raises(ValueError, match="share people"):
        shrec.read_split(dataset, "train")


def test_a_missing_copy_says_where_to_get_it(tmp_path):
    with pytest.raises(FileNotFoundError, match="giach68/gesturesCodes"):
        shrec.read_split(tmp_path, "train")


def test_the_swipe_is_the_stroke_that_goes_farthest_its_way(dataset):
    (seq,) = shrec.read_split(dataset, "train")
    windows = shrec.segment(seq, Segmenter())
    truths = shrec.label_windows(seq.name, windows)
    assert "swipe_right" in truths
    assert shrec.label_windows("grab", windows) == ["none"] * len(windows)
    (habit,) = realism.habits(windows, truths, np.array(shrec.FIELD_CENTRE_MM), 100.0)
    assert 180 < habit["length_mm"] < 205 and abs(habit["roll_deg"]) < 2
    # A minimum-jerk move peaks at 1.875 times its mean speed; the stroke the segmenter cuts
    # leaves its slowest ends out, so less.
    assert 1.2 < habit["peak_over_mean"] < 1.875


def test_a_continuous_stream_keeps_the_hand_in_view_between_recordings(dataset):
    seqs = shrec.read_split(dataset, "train") + shrec.read_split(dataset, "test")
    joints, spans = streams.stream_joints(seqs)
    assert [name for name, _, _ in spans] == ["swipe_right", "swipe_right"]
    steps = np.linalg.norm(np.diff(joints[:, 1], axis=0), axis=1)
    assert steps.max() < 0.03  # no jump: the hand moves back between the two, slowly
    assert spans[1][1] > spans[0][2]



def test_between_recordings_a_skeleton_turned_over_turns_rigidly_about_its_palm():
    # Palm towards the camera, then turned about its direction (palm away) and moved 50 mm.
    a = upright_hand()
    palm = a[shrec.PALM_JOINT]
    axis = (a[10] - a[0]) / np.linalg.norm(a[10] - a[0])  # the hand's direction
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    flip = np.eye(3) + 2 * k @ k  # 180° about the direction
    b = (a - palm) @ flip.T + palm + [0.05, 0.0, 0.0]
    hand_a, hand_b = shrec.to_hands(np.stack([a, b]))
    shares = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    turned = streams.turned_joints(a, b, hand_a, hand_b, shares)
    assert np.allclose(turned[0], a) and np.allclose(turned[-1], b)
    hands = shrec.to_hands(turned)
    for hand, turned_deg in zip(hands, 180 * shares, strict=True):
        cos = np.dot(hand["palm_normal"], hand_a["palm_normal"])
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))) == pytest.approx(turned_deg, abs=1e-3)
    size = [np.linalg.norm(j - j[shrec.PALM_JOINT], axis=1) for j in turned]
    assert np.allclose(size, size[0])  # not squeezed through its palm on the way


def test_between_recordings_the_hand_moves_and_turns_slowly():
    def hand(x, normal):
        return {"palm_position": [x, 200.0, 0.0], "palm_normal": normal}

    down, side = [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]
    assert streams.junction_s(hand(0, down), hand(10, down)) == streams.MOVE_S
    assert streams.junction_s(hand(0, down), hand(300, down)) == pytest.approx(
        300 / streams.MOVE_MM_S)
    # a palm turned 90°: two seconds at 45°/s, not a rotate in 0.6 s
    assert streams.junction_s(hand(0, down), hand(10, side)) == pytest.approx(
        90 / streams.TURN_DEG_S)


def test_a_recording_mirrored_is_the_other_hands_swipe_the_other_way(dataset):
    (seq,) = shrec.read_split(dataset, "train")
    trial = mirrored_trial(shrec_trial(seq))
    assert trial.truth == "swipe_left" and trial.gesture == "swipe_right mirrored"
    frames = trial.frames()
    assert {h["side"] for _, hands in frames for h in hands} == {"left"}
    palm_x = [hands[0]["palm_position"][0] for _, hands in frames if hands]
    assert palm_x[-1] - palm_x[0] == pytest.approx(-200.0, abs=5.0)
    stream = mirrored_stream(*streams.shrec_stream([seq]))
    assert [name for name, _, _ in stream[1]] == ["swipe_left"]
    assert {h["side"] for _, hands in stream[0] for h in hands} == {"left"}


def test_stream_figures_count_recalled_strokes_and_each_false_stroke_once():
    strokes = [("swipe_up", 1.0, 2.0), ("swipe_left", 5.0, 6.0)]
    reports = [("swipe_up", 1.2, 1.6, "s1"), ("swipe_up", 1.2, 1.9, "s1"),  # recalled twice
               ("swipe_down", 2.5, 3.0, "s2"), ("swipe_down", 2.5, 3.2, "s2"),  # one false
               ("swipe_right", 5.1, 5.8, "s3")]  # the wrong gesture over a stroke: false
    figures = scoring.stream_figures(reports, strokes, 62.0)
    assert figures == {"strokes": 2, "recalled": 1, "false_triggers": 2,
                       "other_gesture_triggers": 0, "misread": 0,
                       "other_minutes": pytest.approx(1.0)}


def test_a_stroke_that_recalls_a_swipe_is_a_misread_not_a_false_trigger():
    strokes = [("swipe_up", 1.0, 2.0)]
    reports = [("swipe_left", 1.1, 1.4, "s1"), ("swipe_up", 1.1, 1.9, "s1")]
    figures = scoring.stream_figures(reports, strokes, 61.0)
    assert (figures["recalled"], figures["false_triggers"], figures["misread"]) == (1, 0, 1)


def test_stream_figures_count_triggers_during_other_gestures_apart():
    strokes = [("swipe_up", 1.0, 2.0)]
    others = [("grab", 10.0, 16.0)]
    reports = [("swipe_up", 1.2, 1.9, "s1"),
               ("swipe_down", 11.0, 11.5, "s2"),  # during the grab
               ("swipe_left", 20.0, 20.4, "s3")]  # on a hold or move
    figures = scoring.stream_figures(reports, strokes, 67.0, others)
    assert figures["false_triggers"] == 1 and figures["other_gesture_triggers"] == 1
    assert figures["other_minutes"] == pytest.approx(1.0)  # 67 s less the swipe and the grab


def test_leave_people_out_scores_each_person_with_a_library_learned_without_them(tmp_path):
    t = np.linspace(0, 1, 15)[:, None, None]
    s = t**3 * (10 - 15 * t + 6 * t**2)
    rows = []
    for person, (gesture, step) in {2: (7, [0.2, 0, 0]), 3: (7, [0.22, 0, 0]),
                                    4: (9, [0, 0.18, 0]), 5: (9, [0, 0.2, 0])}.items():
        swipe = upright_hand()[None] + s * np.array(step)
        joints = np.concatenate([np.repeat(swipe[:1], 10, 0), swipe, np.repeat(swipe[-1:], 10, 0)])
        write_sequence(tmp_path, gesture, person, 1, joints)
        rows.append(f"{gesture} 1 {person} 1 {gesture} {gesture * 2 - 1} {len(joints)}")
    (tmp_path / "train_gestures.txt").write_text("\n".join(rows) + "\n")
    (tmp_path / "test_gestures.txt").write_text("")
    recordings = shrec.sequence_windows(shrec.read_split(tmp_path, "train"))
    sim = [simdata.run_user(7, simdata.TRAIN, reps=1)]
    block = train.cross_validate(sim, sim, recordings, 2, 1.5, log=lambda *_: None,
                                 streams_per_person=3)
    assert block["people"] == [2, 3, 4, 5]
    confusion = np.asarray(block["confusion"])
    assert confusion.sum() == 4 and confusion[:4].sum() == 4  # every recording scored once
    held = {"swipe_right", "swipe_up"}  # balanced over the swipes the recordings hold
    assert set(block["recall"]) == held
    finals = np.asarray(block["confusion_finals"])  # answered by final windows only
    assert finals.sum() == 4 and set(block["recall_finals"]) == held
    first = np.asarray(block["confusion_first"])  # answered by the first reported gesture
    assert first.sum() == 4 and set(block["recall_first"]) == held
    # each held-out person's one swipe, played as a stream as many times as asked (`--streams`)
    assert block["streams"]["strokes"] == 4 * 3 and block["streams_per_person"] == 3
    # the same swipes mirrored into left hands score as the right hands they mirror
    assert block["left_hand_balanced_accuracy"] == pytest.approx(block["balanced_accuracy"])
    assert block["left_hand_balanced_accuracy_finals"] == pytest.approx(
        block["balanced_accuracy_finals"])
    for suffix in ("", "_finals", "_first"):  # how far other people could move the figure
        lo, hi = block[f"interval{suffix}"]
        assert 0.0 <= lo <= hi <= 1.0
    # `--misses`: every recording some rule answered wrong, and only those
    wrong = max(4 - int(np.trace(np.asarray(block[f"confusion{suffix}"])))
                for suffix in ("", "_finals", "_first"))
    assert len(block["misses"]) >= wrong
    assert all({m["all"], m["finals"], m["first"]} != {m["swipe"]} for m in block["misses"])


def test_a_missed_recording_says_how_far_its_palm_went_and_which_way(tmp_path):
    t = np.linspace(0, 1, 15)[:, None, None]
    swipe = upright_hand()[None] + t * np.array([0.2, 0.0, 0.0])  # 200 mm to the right
    write_sequence(tmp_path, 8, 2, 1, swipe)  # labelled swipe_left
    (tmp_path / "train_gestures.txt").write_text(f"8 1 2 1 8 15 {len(swipe)}\n")
    (tmp_path / "test_gestures.txt").write_text("")
    (seq,) = shrec.read_split(tmp_path, "train")
    miss = train._miss(seq, {"all": "swipe_right", "finals": "swipe_right", "first": "nothing"})
    assert (miss["person"], miss["swipe"], miss["all"], miss["first"]) == (
        2, "swipe_left", "swipe_right", "nothing")
    assert (miss["reach_mm"], miss["along_mm"], miss["against_mm"]) == (200, 0, 200)


def test_simulated_trials_give_each_user_every_dynamic_gesture_in_its_own_appearance():
    trials = simulated_trials(1, 50_000, simdata.HELD_OUT)
    assert sorted(t.truth for t in trials) == sorted(DYNAMIC_GESTURES)
    for trial in trials:
        frames = trial.frames()
        assert frames[0][0] == 0.0 and all(hands for _, hands in frames)  # hand in view
        gaps = np.diff([t for t, _ in frames])
        assert gaps.max() < 0.1  # one appearance: the hand never leaves in between


def test_the_live_score_counts_rotate_when_the_trials_hold_it():
    rows = [{"truth": "swipe_up", "dynamic": "swipe_up"},
            {"truth": "rotate", "dynamic": scoring.NOTHING},
            {"truth": "none", "dynamic": "swipe_left"}]
    block = scoring.score(rows, "dynamic")
    assert block["recall"] == {"swipe_up": 1.0, "rotate": 0.0}
    assert block["balanced_accuracy"] == 0.5 and block["other_false"] == 1


def test_the_live_score_says_how_far_other_people_could_move_it():
    rows = [{"truth": t, "dynamic": t, "person": p}
            for p in "abc" for t in ("swipe_up", "swipe_down")]
    rows[0]["dynamic"] = scoring.NOTHING  # person a misses a swipe_up
    block = scoring.score(rows, "dynamic")
    lo, hi = block["interval"]
    assert block["people"] == 3 and lo < block["balanced_accuracy"] < hi == 1.0
    one = scoring.score([{**r, "person": "a"} for r in rows], "dynamic")
    assert one["interval"] is None  # one person: nothing to draw from


def test_the_live_report_names_gesture_messages_no_summary_holds(capsys):
    rows = [{"truth": "swipe_up", "dynamic": "swipe_up", "finals": "swipe_up",
             "first": "swipe_up", "summary": scoring.NOTHING, "person": "a"}]
    lines = []
    result = {"trials": rows, "streams": [], "latency_ms": {},
              "episode_stray": {"late": 1, "outside": 0}}
    assert report.report_live(result, None, lines.append) == 0
    assert any("1 gesture messages arrived after their episode had ended" in x for x in lines)
    lines.clear()
    report.report_live({**result, "episode_stray": {"late": 0, "outside": 0}}, None,
                          lines.append)
    assert not any("episode service" in x for x in lines)


def test_the_live_report_judges_issue_14s_goals_and_a_short_stream_sample_not_at_all():
    rows = [{"truth": t, "dynamic": t, "finals": t, "first": t, "summary": t, "person": p}
            for p in "abc" for t in ("swipe_up", "swipe_down")]
    rows[0]["summary"] = scoring.NOTHING  # person a's swipe_up missing from its summary
    stream = {"strokes": 10, "recalled": 9, "false_triggers": 3, "other_gesture_triggers": 0,
              "misread": 0, "other_minutes": 2.0}
    result = {"trials": rows, "streams": [stream], "latency_ms": {}, "episode_stray": {}}
    lines = []
    assert report.report_live(result, None, lines.append) == 0
    goals = {name: (met, text) for name, met, text in result["goals"]}
    assert goals["real swipes: gestures/dynamic ≥ 95% balanced"][0] is True
    met, text = goals["real swipes: episode summary's g ≥ 95% balanced"]
    assert met is False and text.startswith("83.3%") and "interval over the 3 people" in text
    met, text = goals["continuous streams: recall ≥ 90%"]
    assert met is None and text.startswith("9/10 = 90.0% (under 50 swipes")  # too few
    met, text = goals["continuous streams: false triggers ≤ 1/min"]
    assert met is None and "1.50/min" in text and "too few to judge" in text  # 2 min only
    printed = "\n".join(lines)
    assert "  MISS  real swipes: episode summary's g ≥ 95% balanced: 83.3%" in printed
    assert "  ----  continuous streams: false triggers ≤ 1/min: 3 in 2.0 min" in printed
    long = scoring.stream_goals({**stream, "strokes": 60, "recalled": 55,
                                   "other_minutes": 12.0})
    assert [met for _, met, _ in long] == [True, True]  # 55 of 60; 3 in 12 min: 0.25/min
    worse = scoring.stream_goals({**stream, "strokes": 60, "recalled": 50,
                                    "false_triggers": 13, "other_minutes": 12.0})
    assert [met for _, met, _ in worse] == [False, False]
    blocks = {field: {"balanced_accuracy": 0.96, "interval": None, "people": 0}
              for field in ("dynamic", "summary")}
    many = [{"truth": "swipe_up"}] * scoring.GOALS["synthetic_trials"]
    synthetic = scoring.live_goals({**blocks, "trials": many}, {"strokes": 0}, synthetic=True)
    assert synthetic[0][:2] == ("synthetic strokes, rotate included: gestures/dynamic ≥ 97% "
                                "balanced", False)
    assert synthetic[2] == ("continuous streams", None, "none played")


def test_synthetic_strokes_are_judged_over_enough_trials_only():
    blocks = {field: {"balanced_accuracy": 0.99, "interval": None, "people": 0}
              for field in ("dynamic", "summary")}
    least = scoring.GOALS["synthetic_trials"]
    few = [{"truth": "swipe_up"}] * 80 + [{"truth": "none"}] * least  # others do not count
    goals = scoring.live_goals({**blocks, "trials": few}, {"strokes": 0}, synthetic=True)
    assert [met for _, met, _ in goals[:2]] == [None, None]  # 80 trials: a draw of 16 users
    assert goals[0][2].startswith("99.0%, 80 trials (under 250 trials: too few to judge")
    enough = [{"truth": "swipe_up"}] * least
    goals = scoring.live_goals({**blocks, "trials": enough}, {"strokes": 0}, synthetic=True)
    assert [met for _, met, _ in goals[:2]] == [True, True]


def test_the_live_score_reads_the_field_asked_for():
    rows = [{"truth": "swipe_up", "dynamic": "swipe_up", "first": "swipe_down"},
            {"truth": "swipe_down", "dynamic": "swipe_down", "first": "swipe_down"}]
    assert scoring.score(rows, "dynamic")["balanced_accuracy"] == 1.0
    assert scoring.score(rows, "first")["recall"] == {"swipe_up": 0.0, "swipe_down": 1.0}


class _Answers:
    """A classifier stub: each window's probabilities by its position in the stroke."""

    names = ["swipe_up", "swipe_down", "none"]

    def __init__(self, by_index):
        self.by_index, self.calls = by_index, 0

    def classify(self, window):
        probs = self.by_index(self.calls, window)
        self.calls += 1
        return np.asarray(probs, dtype=float)


def test_a_trial_is_answered_by_its_surest_window_its_surest_final_and_its_first_gesture(synth):
    windows = synth.feed(Segmenter(), synth.trajectory(
        [("hold", 0.5), ("move", 0.7, (0.0, 240.0, 0.0)), ("hold", 0.5)]))
    assert len(windows) >= 5 and windows[-1].final

    def probs(i, window):  # a sure early swipe_down (confirmed), then swipe_up surer, final unsure
        if window.final:
            return [0.55, 0.0, 0.45]
        return [0.0, 0.7, 0.3] if i < 2 else [0.95, 0.0, 0.05]

    answers = train.trial_answers(_Answers(probs), windows, 1.5)
    assert answers == {"all": "swipe_up", "finals": "swipe_up", "first": "swipe_down"}

    def unsure(i, window):  # nothing reaches GESTURE_P: no rule reports a gesture
        return [0.45, 0.0, 0.55]

    assert set(train.trial_answers(_Answers(unsure), windows, 1.5).values()) == {"nothing"}


@pytest.mark.parametrize("argv", [["bench", "dynamic", "--real"],
                                  ["train", "dynamic", "--folds", "2", "--real"]])
def test_the_cli_names_a_missing_data_folder_without_a_traceback(tmp_path, capsys, argv):
    from cbgo.cli.main import main

    with pytest.raises(SystemExit) as ended:
        main([*argv, str(tmp_path)])
    err = capsys.readouterr().err
    assert ended.value.code == 2 and err.startswith("cbgo: no ") and "Traceback" not in err
    assert str(tmp_path) in err


def test_live_groups_of_held_out_people_need_the_shrec_train_split(dataset, capsys):
    # `cbgo bench dynamic --real DIR --folds N` learns each group's library from the train
    # split's other people: the test split's are never learned from.
    from cbgo.cli.main import main

    with pytest.raises(SystemExit) as ended:
        main(["bench", "dynamic", "--real", str(dataset), "--split", "test", "--folds", "2"])
    assert ended.value.code == 2 and "train split" in capsys.readouterr().err


def test_each_group_of_people_is_held_out_of_its_library_once(tmp_path):
    rows = []
    for person in (2, 3, 4, 5, 6):
        write_sequence(tmp_path, 7, person, 1, np.repeat(upright_hand()[None], 30, 0))
        rows.append(f"7 1 {person} 1 7 13 30")
    (tmp_path / "train_gestures.txt").write_text("\n".join(rows) + "\n")
    (tmp_path / "test_gestures.txt").write_text("")
    recordings = shrec.sequence_windows(shrec.read_split(tmp_path, "train"))
    sim = [simdata.run_user(7, simdata.TRAIN, reps=1)]
    groups = [held for held, _ in train.fold_classifiers(sim, sim, recordings, 2, 1.5)]
    assert groups == [{2, 4, 6}, {3, 5}]


def test_whether_a_swipe_was_returned_is_unknown_where_its_recording_ends_too_soon(dataset):
    (seq,) = shrec.read_split(dataset, "train")
    windows = shrec.segment(seq, Segmenter())
    truths = shrec.label_windows(seq.name, windows)
    middle = np.array(shrec.FIELD_CENTRE_MM)
    end_t = (len(seq.joints()) - 1) / shrec.RATE_HZ
    (cut,) = realism.habits(windows, truths, middle, 100.0, end_t)
    assert np.isnan(cut["returned"])  # the recording stops 0.3 s after the swipe
    (held,) = realism.habits(windows, truths, middle, 100.0, end_t + realism.NEIGHBOUR_S)
    assert held["returned"] == 0.0  # long enough to have seen a return: there was none


def test_a_habits_spread_is_split_between_people_and_within_a_person(capsys):
    # person a swipes 100 and 400 mm, person b 200 and 200: in logs, a's mean is log 200, b's
    # too (nothing between them), a's swipes lie log 2 from their mean, b's not at all
    rows = [{"person": p, "length_mm": v, "duration_s": 0.5, "peak_mm_s": np.nan}
            for p, v in (("a", 100.0), ("a", 400.0), ("b", 200.0), ("b", 200.0))]
    between, within = realism.person_spread(rows, "length_mm")
    assert between == pytest.approx(0.0, abs=1e-12)
    assert within == pytest.approx(np.sqrt((np.log(2) ** 2 + 0.0) / 2))
    assert all(np.isnan(realism.person_spread(rows, "peak_mm_s")))  # nothing known
    one = [dict(r, person="a") for r in rows]  # one person: no spread between people
    assert np.isnan(realism.person_spread(one, "length_mm")[0])
    table = realism.print_spread(rows, one)
    assert table["duration_s"]["real"] == (0.0, 0.0)
    assert "between people, within" in capsys.readouterr().out


def test_peak_speed_by_length_shows_whether_short_swipes_are_too_slow_for_the_gate(capsys):
    # peak speed grows as the square root of length: slope 0.5; the 50 mm swipes are slow
    lengths = [50.0, 50.0, 80.0, 120.0, 160.0, 250.0]
    rows = [{"length_mm": v, "peak_mm_s": 25.0 * np.sqrt(v)} for v in lengths]
    table = realism.print_speed_by_length(rows, rows[2:])
    assert table["real"]["slope"] == pytest.approx(0.5)
    short = table["real"]["20-70"]
    assert short["share"] == pytest.approx(2 / 6) and short["under_200"] == 1.0
    assert short["peak_p50"] == pytest.approx(25.0 * np.sqrt(50.0))
    assert "20-70" not in table["simulated"] and table["simulated"]["200-400"]["under_200"] == 0
    assert "peak speed by length" in capsys.readouterr().out


def test_the_by_way_table_gives_each_ways_medians_real_beside_simulated(capsys):
    def row(way: str, length: float) -> dict:
        return {"way": way, "length_mm": length, "peak_mm_s": 2.5 * length, "duration_s": 0.6}

    real = [row("across", 230.0), row("across", 240.0), row("down", 130.0)]
    table = realism.by_way(real, [row("up", 150.0)])
    assert table["across"]["real"] == {"swipes": 2, "length_mm": 235.0, "peak_mm_s": 587.5,
                                       "duration_s": 0.6}
    assert table["down"]["real"]["swipes"] == 1 and table["up"]["real"]["swipes"] == 0
    assert np.isnan(table["outward"]["simulated"]["length_mm"])
    assert "by way (medians)" in capsys.readouterr().out


def test_geometry_measures_a_forward_bow_and_a_drift_off_the_swipes_direction():
    # a 200 mm swipe left (across the body for a right hand) that bows 30 mm forward (away
    # from the person, -z) in its middle and ends 20 mm higher and 40 mm farther forward
    s = np.linspace(0.0, 1.0, 21)[:, None]
    xyz = s * np.array([-200.0, 20.0, -40.0]) + np.sin(np.pi * s) * np.array([0.0, 0.0, -30.0])
    sideways = realism.swipe_sideways("swipe_left", "right")
    assert np.allclose(sideways, [0, 1, 0])  # across: up
    g = realism.geometry(xyz, 200.0, sideways)
    assert g["drift_sideways"] == pytest.approx(0.1) and g["drift_forward"] == pytest.approx(0.2)
    # the bow is taken off the straight line between the ends, which is tilted by the drift
    assert g["arc_forward"] == pytest.approx(0.15, abs=0.01) and abs(g["arc_sideways"]) < 0.01
    # up and down are measured medial: a left hand's as the right hand's mirror image
    assert np.allclose(realism.swipe_sideways("swipe_down", "right"), [-1, 0, 0])
    assert np.allclose(realism.swipe_sideways("swipe_down", "left"), [1, 0, 0])


def test_the_geometry_table_gives_each_ways_percentiles_real_beside_simulated(capsys):
    def row(way: str, arc: float) -> dict:
        return {"way": way, **dict.fromkeys(realism.GEOMETRY, 0.0), "arc_forward": arc}

    real = [row("across", a) for a in (0.1, 0.2, 0.3)]
    table = realism.print_geometry(real, [row("up", 0.0)])
    assert table["across"]["arc_forward"]["real"][0] == pytest.approx(0.2)
    assert table["across"]["arc_forward"]["simulated"] == []
    assert table["up"]["arc_forward"]["simulated"] == [0.0, 0.0, 0.0]
    assert "geometry by way" in capsys.readouterr().out


def test_ungated_counts_slow_swipes_and_keeps_the_rest_of_the_config():
    config = realism.ungated(SegmenterConfig(end_speed_mm_s=55.0))
    assert config.min_peak_speed_mm_s == 0.0 and config.mid_peak_speed_mm_s == 0.0
    assert config.end_speed_mm_s == 55.0


def test_the_realism_table_gives_a_yes_or_no_habit_as_a_share_and_draws_the_habits(tmp_path,
                                                                                   capsys):
    rows = [dict.fromkeys(realism.HABITS, float(k)) | {"returned": r}
            for k, r in enumerate((1.0, 0.0, np.nan, 1.0))]
    same = [dict.fromkeys(realism.HABITS, 2.0)] * 2  # one value: still drawn
    table = realism.print_realism(rows, same)
    assert table["returned"]["real"][:2] == [pytest.approx(2 / 3), 3.0]  # of the 3 known
    assert table["length_mm"]["real"][0] == 1.5 and table["length_mm"]["simulated"][0] == 2.0
    assert table["length_mm"]["real"][3] == 4 and table["length_mm"]["simulated"][3] == 2
    out = capsys.readouterr().out
    assert "returned (share)" in out and "n 4" in out
    path = realism.plot_realism(rows, same, tmp_path / "figures")
    assert path == tmp_path / "figures" / "realism.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_without_realism_says_what_it_draws(tmp_path, capsys):
    from cbgo.cli.main import main

    with pytest.raises(SystemExit) as ended:
        main(["bench", "dynamic", "--plot", str(tmp_path)])
    assert ended.value.code == 2 and "--realism" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())  # nothing was run or drawn


def test_the_live_bench_plays_as_many_other_gestures_as_asked():
    trials = [Trial(truth, truth, str(i % 3), None)
              for i in range(4) for truth in ("swipe_up", "swipe_down", "none", "none")]
    assert pick_trials(trials, 0, 1) == trials  # everything, in order
    swipes_only = pick_trials(trials, 0, 1, others=0)
    assert [t.truth for t in swipes_only].count("none") == 0 and len(swipes_only) == 8
    two = pick_trials(trials, 1, 1, others=2)
    assert sorted(t.truth for t in two) == ["none", "none", "swipe_down", "swipe_up"]
    assert len(pick_trials(trials, 1, 1)) == 3  # others as many as per_class
    assert len(pick_trials(trials, 1, 1, others=-1)) == 2 + 8
