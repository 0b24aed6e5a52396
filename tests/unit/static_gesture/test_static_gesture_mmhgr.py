"""The multi-modal Leap HGR converter and the person-grouped cross-validation, on hands written
in the data set's layout (the data set itself is never needed by the tests)."""

import argparse

import numpy as np
import pytest

from cbgo.hands import features as F
from cbgo.hands.model import HandShape, build_hand
from cbgo.hands.poses import gesture_pose
from cbgo.services.static_gesture import invariant, mmhgr, motion, train
from cbgo_tools.data import mmhgr as mmhgr_data
from cbgo_tools.static_gesture import bench, crossval

_POINTS = ("mcpPosition", "pipPosition", "dipPosition", "TipPosition")


def _matrix(tag, v):
    return (f'<{tag} type_id="opencv-matrix">\n<rows>1</rows>\n<cols>3</cols>\n<dt>f</dt>\n'
            f'<data>\n  {v[0]:.6e} {v[1]:.6e} {v[2]:.6e}</data></{tag}>\n')


def frame_xml(hand, confidence=0.9, extended=(1, 1, 1, 1, 1)):
    """One frame file as the data set writes it (OpenCV storage, first image's hand)."""
    side = hand["side"].capitalize()
    fingers = ""
    for name, finger, flag in zip(("Thumb", "Index", "Middle", "Ring", "Pinky"),
                                  hand["fingers"], extended, strict=True):
        b = finger["bones"]
        points = (b[1]["prev_joint"], b[2]["prev_joint"], b[3]["prev_joint"],
                  b[3]["next_joint"])
        fingers += (f"<{name}>\n<Type>0</Type>\n<isExtended>{flag}</isExtended>\n"
                    + "".join(_matrix(t, p) for t, p in zip(_POINTS, points, strict=True))
                    + f"</{name}>\n")
    hand_xml = (f"<{side}>\n" + _matrix("Center", hand["palm_position"])
                + _matrix("Normal", hand["palm_normal"])
                + _matrix("Direction", hand["direction"])
                + f"<Confidence>{confidence}</Confidence>\n<PinchStrength>0.</PinchStrength>\n"
                f"<GrabStrength>0.5</GrabStrength>\n<Fingers>\n<nFingers>5</nFingers>\n"
                + fingers + f"</Fingers>\n</{side}>\n")
    return ('<?xml version="1.0"?>\n<opencv_storage>\n<Frame>\n<ID>1</ID>\n<Images>\n'
            f"<RigthImage>\n<Hands>\n<nHands>1</nHands>\n{hand_xml}</Hands>\n</RigthImage>\n"
            "</Images>\n</Frame>\n</opencv_storage>\n")


def _hand(name, side, seed):
    rng = np.random.default_rng(seed)
    return build_hand(HandShape.sample(rng, side=side), gesture_pose(name, rng),
                      np.array([0.0, 200.0, 10.0]))


def write_dataset(root, people=(1, 2), poses=("fist_moved", "five", "up", "ok"), per_pose=3):
    """Writes user_NN/train_pose/<pose>/frame_K.xml files; returns the hands in file order."""
    gesture_of = {"fist_moved": "grab", "ok": "pinch", "C": "two", "L": "point", "palm_m": "five",
                  **{p: g for p, g in mmhgr.POSE_MAP.items() if p not in ("fist_moved",)}}
    hands = {}
    for user in people:
        for pose in poses:
            folder = root / f"user_{user:02d}" / "train_pose" / pose
            folder.mkdir(parents=True)
            for k in range(per_pose):
                hand = _hand(gesture_of[pose], "right", 100 * user + k)
                (folder / f"frame_{k}.xml").write_text(frame_xml(hand, 0.5 + 0.1 * k))
                hands[(user, pose, k)] = hand
    return hands


def test_a_converted_frame_reads_the_same_as_the_contract_hand_it_came_from(tmp_path):
    hands = write_dataset(tmp_path / "src")
    out = tmp_path / "cache.npz"
    assert mmhgr_data.convert(tmp_path / "src", out, progress=False) == len(hands)
    frames = mmhgr.load(out)
    assert sorted(set(frames.user)) == [1, 2] and set(frames.side) == {"right"}
    originals = [hands[(int(u), str(p), int(f))] for u, p, f in
                 zip(frames.user, frames.pose, frames.frame, strict=True)]
    # the vectorised features are the dict path's, and the device-independent ones are the
    # original hand's although the file has no wrist and no metacarpals
    x = mmhgr.features57(frames)
    assert x == pytest.approx(F.hands_features(mmhgr.hand_dicts(frames), True), abs=1e-9)
    want = invariant.derive(F.hands_features(originals, to_recorded_side=True))
    assert invariant.derive(x) == pytest.approx(want, abs=1e-3)
    assert list(frames.labels()[frames.pose == "up"]) == ["thumbsup"] * 6
    # the paper's pinch is an ok sign (thumb on index, the other three open)
    assert set(frames.labels()[frames.pose == "ok"]) == {"pinch"}


def test_a_frame_without_a_hand_is_skipped():
    frame = "<opencv_storage><Frame><ID>3</ID></Frame></opencv_storage>"
    assert mmhgr_data.parse_frame(frame) is None


def test_a_folder_without_frames_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="frame_"):
        mmhgr_data.convert(tmp_path, tmp_path / "c.npz")


def test_the_command_line_names_a_folder_without_frames(tmp_path, capsys):
    args = argparse.Namespace(src=tmp_path, out=tmp_path / "c.npz", info=False)
    assert mmhgr_data.run(args) == 2
    assert "frame_" in capsys.readouterr().err and not (tmp_path / "c.npz").exists()


def test_the_loader_says_none_without_a_cache(tmp_path):
    assert mmhgr.load(tmp_path / "absent.npz") is None


def test_derived_features_ignore_the_2pi_jumps_of_the_57():
    rng = np.random.default_rng(0)
    x = rng.normal(0.0, 0.5, (20, 57))
    jumped = x.copy()
    jumped[:, F.YAW_FEATURES] += 2 * np.pi * rng.integers(-1, 2, (20, len(F.YAW_FEATURES)))
    assert invariant.derive(jumped) == pytest.approx(invariant.derive(x), abs=1e-9)
    assert invariant.derive(x).shape == (20, invariant.N_DERIVED)


def test_continuous_features_read_a_yaw_near_plus_and_minus_pi_as_one_curl():
    rng = np.random.default_rng(1)
    derived = rng.normal(0.0, 0.5, (2, invariant.N_DERIVED))
    derived[0, invariant.YAWS] = np.pi - 0.01
    derived[1, invariant.YAWS] = -np.pi + 0.01
    derived[1, ~np.isin(np.arange(invariant.N_DERIVED), invariant.YAWS)] = derived[
        0, ~np.isin(np.arange(invariant.N_DERIVED), invariant.YAWS)]
    out = invariant.continuous(derived)
    assert out.shape == (2, len(invariant.NAMES_CONTINUOUS)) == (2, invariant.N_DERIVED + 15)
    assert np.abs(out[0] - out[1]).max() < 0.03  # 2π apart before, 0.02 rad apart in fact
    assert np.abs(derived[0] - derived[1]).max() > 6.0
    k = invariant.NAMES_CONTINUOUS.index("index_distal_dyaw_cos")
    assert out[0, k] == pytest.approx(np.cos(np.pi - 0.01))
    x57 = rng.normal(0.0, 0.5, (3, 57))
    assert invariant.transform(x57, invariant.TRANSFORM_CONTINUOUS) == pytest.approx(
        invariant.continuous(invariant.derive_palm(x57)))


def test_bends_are_the_angles_between_bones_however_the_hand_is_held():
    shape = HandShape.sample(np.random.default_rng(5), side="left")
    pose = gesture_pose("two", np.random.default_rng(6))
    turns = ((0, 0), (60, 0), (0, 50), (-90, 30))
    hands = [build_hand(shape, pose.rotated(roll=np.deg2rad(r), pitch=np.deg2rad(p)),
                        np.array([0.0, 200.0, 10.0])) for r, p in turns]
    bent = invariant.bends(F.hands_features(hands))
    assert bent.shape == (4, len(invariant.BEND_NAMES))
    # within a few degrees: every bone's direction leans on the hand's pitch, read from the
    # metacarpals, which fan out a little about the hand direction
    assert np.ptp(bent, axis=0).max() < np.deg2rad(6)
    straight = [k for k, name in enumerate(invariant.BEND_NAMES) if name.startswith("index")]
    assert np.ptp(bent[:, straight], axis=0).max() < np.deg2rad(2)

    def unit(bone):
        v = np.subtract(bone["prev_joint"], bone["next_joint"])
        return v / np.linalg.norm(v)

    index = hands[0]["fingers"][1]["bones"]
    k = invariant.BEND_NAMES.index("index_intermediate_bend")
    assert bent[0, k] == pytest.approx(np.arccos(unit(index[1]) @ unit(index[2])), abs=2e-3)
    names = invariant.names_of(invariant.TRANSFORM_BENDS)
    x = invariant.transform(F.hands_features(hands), invariant.TRANSFORM_BENDS)
    assert x.shape == (4, len(names)) and names[-len(invariant.BEND_NAMES):] == \
        invariant.BEND_NAMES


def test_the_curl_augmentation_bends_the_later_bones_of_the_four_fingers_alike():
    rng = np.random.default_rng(2)
    x = rng.normal(0.0, 0.5, (50, 57))
    x[:, 42:] = rng.uniform(20.0, 120.0, (50, 15))  # distances, mm
    out = invariant.augment(x, np.random.default_rng(3), size=(1.0, 1.0), angle_sd=0.0,
                            palm_sd_mm=0.0, curl_deg=15.0)
    moved = (out - x)[:, 2:42].reshape(50, 5, 4, 2)
    curl = moved[:, 1:, 2:, 0].reshape(50, -1)
    assert np.allclose(curl, curl[:, :1]) and (curl >= 0).all()
    assert curl.max() <= np.deg2rad(15.0) and curl.max() > np.deg2rad(10.0)
    moved[:, 1:, 2:, 0] = 0.0
    assert np.allclose(moved, 0.0) and np.allclose(out[:, 42:], x[:, 42:])


def test_the_palm_axis_features_keep_a_fingers_bend_whatever_the_hands_pitch():
    # The same pose held 25° higher or lower: the proximal features of `derive` move by about
    # twice that (they carry the hand's pitch), those against the palm axis stay put.
    shape = HandShape.sample(np.random.default_rng(3), side="left")
    pose = gesture_pose("two", np.random.default_rng(4))
    x = F.hands_features([build_hand(shape, pose.rotated(pitch=np.deg2rad(a)),
                                     np.array([0.0, 200.0, 10.0])) for a in (-25, 0, 25)])
    proximal_pitch = np.arange(0, 30, 6)
    moved = np.ptp(invariant.derive(x)[:, proximal_pitch], axis=0)
    kept = np.ptp(invariant.derive_palm(x)[:, proximal_pitch], axis=0)
    assert moved.min() > np.deg2rad(60) and kept.max() < np.deg2rad(8)


def test_a_converted_frame_reads_its_palm_axis_from_the_hand_direction(tmp_path):
    # The HGR set has no metacarpals: the stand-ins along the hand direction give the palm
    # axis of the original hand to within the fan of its real metacarpals.
    hands = write_dataset(tmp_path / "src", people=(1,), poses=("five", "up"), per_pose=2)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    originals = [hands[(int(u), str(p), int(f))] for u, p, f in
                 zip(frames.user, frames.pose, frames.frame, strict=True)]
    axis = invariant.palm_axis(mmhgr.features57(frames))
    want = invariant.palm_axis(F.hands_features(originals, to_recorded_side=True))
    assert axis[:, 0] == pytest.approx(want[:, 0], abs=0.1)
    assert np.abs(invariant.wrap(axis[:, 1] - want[:, 1])).max() < 0.1


def test_crossvalidation_scores_each_person_with_a_model_that_never_saw_them(tmp_path):
    write_dataset(tmp_path / "src", people=(1, 2, 3, 4),
                  poses=("fist_moved", "five", "up", "C", "L", "palm_m"), per_pose=2)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    options = train.TrainOptions(per_gesture=2, none=4, off_vocabulary=4, hidden=[4],
                                 epochs=1, mmhgr_stride=1)
    lines = []
    fig = crossval.crossvalidate(frames, options, folds=2, samples=4, log=lines.append)
    assert fig["folds"] == 2 and len(lines) == 2 and fig["people"] == 4
    assert fig["classes"] == ["grab", "five", "thumbsup"] and fig["n"] == 4 * 3 * 2
    assert set(fig["per_person"]) == {1, 2, 3, 4}
    assert set(fig["rejection"]) <= {"C", "L"} and fig["rejection_n"] > 0
    for key in ("interval", "rejection_interval"):  # how far other people move the figures
        lo, hi = fig[key]
        assert 0.0 <= lo <= hi <= 1.0
    assert sum(b["n"] for b in fig["by_confidence"]) == fig["n"]
    assert set(fig["turned"]) == set(crossval.TURNS)
    assert fig["rejection_overall"] >= fig["network"]["rejection_overall"]
    assert fig["accuracy"] <= fig["network"]["accuracy"]
    assert all("network_accuracy" in s for s in fig["per_style"].values())
    # The test frames flag every finger extended: only five's show their pose.
    assert fig["tracker_agrees"]["share"] == pytest.approx(1 / 3)
    assert fig["tracker_agrees"]["balanced"] is None  # grab and thumbsup have no such frame
    assert fig["tracker_agrees"]["thumb_too_share"] == pytest.approx(1 / 3)  # five's thumb out
    # Every held-out person's midway hands are scored; the flat hands' answers are shares.
    assert fig["transitions"]["n"] == 4 * crossval.TRANSITIONS_PER_PERSON
    assert set(fig["transitions"]["per_pair"]) == {"five/grab", "five/thumbsup", "grab/thumbsup"}
    flat = fig["flat_hands"]["palm_m"]
    assert flat["n"] == 4 * 2
    assert flat["five"] + flat["rejected"] + flat["other"] == pytest.approx(1)
    if flat["other"] > 0:  # which gesture the others mostly are, and no more than all of them
        assert flat["most_other"][0] not in ("five", "none")
        assert 0 < flat["most_other"][1] <= flat["other"] + 1e-9
    else:
        assert flat["most_other"] is None
    # Frames 0 and 1 of each take follow each other: the second of each known take is measured.
    motion = fig["finger_motion"]
    assert motion["n"] == 4 * 3 and sum(b["share"] for b in motion["by_motion"]) == \
        pytest.approx(1)
    assert [(g["lo"], g["hi"], g["tv"]) for g in motion["gates"]] == \
        list(crossval.FINGER_GATES)
    assert all(0.0 <= g["lost"] <= g["touched"] <= 1.0 for g in motion["gates"])
    # the gesture that loses most loses at least the mean share
    assert all(g["worst"][0] in mmhgr.POSE_MAP.values() and
               g["lost"] - 1e-9 <= g["worst"][1] <= 1.0 for g in motion["gates"])
    assert motion["transitions"][10] <= motion["transitions"][50]
    # hands changing pose over time: the rule can only add to what the model rejects
    assert motion["timed"]["n"] > 4 * crossval.TIMED_PER_PERSON
    assert all(motion["timed"]["rejected_alone"] <= g["timed_rejected"] <= 1.0
               for g in motion["gates"])
    # each changing hand is answered one of four ways (its two ends are different gestures)
    for split in [motion["timed"]["alone"]] + [g["timed"] for g in motion["gates"]]:
        assert sum(split.values()) == pytest.approx(1)
    assert 0.0 <= motion["timed"]["held_other"] <= 1.0
    for key in ("by_time_alone", "by_time"):  # every hand in one tenth of its change's time
        tenths = motion["timed"][key]
        assert sum(b["n"] for b in tenths) == motion["timed"]["n"]
        assert all(sum(b[k] for k in ("rejected", "left", "reached", "other")) ==
                   pytest.approx(1) for b in tenths)
        ways = [b["way"] for b in tenths]
        assert ways == sorted(ways) and 0 < ways[0] < 0.01 and 0.99 < ways[-1] < 1
    crossval.print_figures(fig)
    png = bench.plot_transitions(motion["timed"], tmp_path / "plots")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_finger_motion_is_the_bends_change_since_the_takes_previous_kept_frame(tmp_path):
    write_dataset(tmp_path / "src", people=(1,), poses=("five", "up"), per_pose=3)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    moved, previous = crossval.finger_motion(frames)
    first = frames.frame == 0
    assert np.isnan(moved[first]).all() and not np.isnan(moved[~first]).any()
    assert (previous[first] == -1).all()
    assert (frames.pose[previous[~first]] == frames.pose[~first]).all()
    assert (frames.frame[previous[~first]] == frames.frame[~first] - 1).all()
    bends = np.degrees(invariant.bends(mmhgr.features57(frames)))
    for i in np.flatnonzero(~first):  # against the same take's frame before
        j = np.flatnonzero((frames.pose == frames.pose[i]) & (frames.frame == frames.frame[i] - 1))
        assert moved[i] == pytest.approx(np.sqrt(np.mean((bends[i] - bends[j[0]]) ** 2)))
    # a frame too far after the one before is not its follower: a new stretch of the take
    far = frames.subset(np.argsort(frames.frame))
    far.frame[far.frame == 2] = 2 + crossval.MAX_FRAME_GAP + 1
    assert np.isnan(crossval.finger_motion(far)[0][far.frame > 2]).all()


def test_a_transition_lies_between_two_gestures_of_one_person(tmp_path):
    write_dataset(tmp_path / "src", people=(1, 2), poses=("fist_moved", "five", "up", "C"),
                  per_pose=2)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    x = mmhgr.features57(frames)
    labels = frames.labels()
    drawn = crossval.transition_ends(frames, 30, np.random.default_rng(5))
    ends = [crossval.transitions(frames, *drawn, alpha) for alpha in (0.0, 0.5, 1.0)]
    (first, pairs), (mid, _), (second, _) = ends
    yaws = np.array([n.endswith("_dyaw") for n in F.FEATURE_NAMES])

    def gap(a, b):  # per feature, the yaws read modulo a turn
        d = a - b
        d[..., yaws] = invariant.wrap(d[..., yaws])
        return np.abs(d)

    for k in range(30):
        i, j = (int(np.argmin(gap(x, end[k]).max(1))) for end in (first, second))
        assert gap(x[i], first[k]).max() < 1e-9 and gap(x[j], second[k]).max() < 1e-6
        assert frames.user[i] == frames.user[j] and labels[i] != labels[j] != ""
        assert pairs[k] == "/".join(sorted((labels[i], labels[j])))
        # halfway: every pitch and distance, every yaw by the shorter way round
        step = second[k] - first[k]
        step[yaws] = invariant.wrap(step[yaws])
        assert np.abs(mid[k] - (first[k] + step / 2)).max() < 1e-6
    fives = frames.subset(labels == "five")
    assert len(crossval.transitions(fives, *crossval.transition_ends(
        fives, 5, np.random.default_rng(0)))[0]) == 0  # one gesture: no pair


@pytest.mark.parametrize(("pose", "flags", "agrees"), [
    ("three", (0, 1, 1, 1, 0), True),
    ("three", (1, 1, 1, 1, 0), True),    # the thumb's flag is left aside
    ("three", (0, 1, 1, 1, 1), False),   # the skeleton holds the pinky out: a four
    ("fist_moved", (1, 0, 0, 0, 0), True),
    ("index", (0, 1, 1, 0, 0), False),
    ("ok", (0, 0, 1, 1, 1), True),       # pinch: the index on the thumb, the others open
    ("ok", (0, 1, 1, 1, 1), False),
    ("C", (0, 1, 1, 1, 1), False),       # not a gesture pose
])
def test_a_frame_agrees_with_its_pose_when_the_trackers_finger_flags_show_it(
        tmp_path, pose, flags, agrees):
    folder = tmp_path / "src" / "user_01" / "train_pose" / pose
    folder.mkdir(parents=True)
    (folder / "frame_1.xml").write_text(frame_xml(_hand("five", "right", 1), extended=flags))
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    assert mmhgr.load(tmp_path / "c.npz").tracker_agrees().tolist() == [agrees]


@pytest.mark.parametrize(("pose", "thumb", "agrees"), [
    ("five", 1, True), ("five", 0, False),        # a five with the thumb in shows a four
    ("four", 0, True), ("four", 1, False),
    ("fist_moved", 0, True), ("fist_moved", 1, False),  # a grab with the thumb out: thumbs-up
    ("up", 1, True), ("up", 0, False),
    ("three", 0, True), ("three", 1, True),       # either way
])
def test_a_frame_agrees_with_its_poses_thumb_when_the_pose_fixes_it(tmp_path, pose, thumb,
                                                                      agrees):
    folder = tmp_path / "src" / "user_01" / "train_pose" / pose
    folder.mkdir(parents=True)
    flags = (thumb, 1, 1, 1, 1)
    (folder / "frame_1.xml").write_text(frame_xml(_hand("five", "right", 1), extended=flags))
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    assert mmhgr.load(tmp_path / "c.npz").thumb_agrees().tolist() == [agrees]


def test_wider_turns_spare_the_thumb_poses_told_apart_by_orientation(tmp_path):
    write_dataset(tmp_path / "src", people=(1,), poses=("fist_moved", "five", "up"), per_pose=2)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    names = ["grab", "five", "thumbsup", "none"]
    still, _, _ = train.mmhgr_rows(frames, names, train.TrainOptions(
        mmhgr_stride=1, rotate_deg=0.0), np.random.default_rng(0))
    wide, y, _ = train.mmhgr_rows(frames, names, train.TrainOptions(
        mmhgr_stride=1, rotate_deg=0.0, rotate_shape_deg=45.0), np.random.default_rng(0))
    assert np.allclose(still, mmhgr.features57(frames))
    moved = ~np.isclose(wide, still).all(axis=1)
    thumbs = y == names.index("thumbsup")
    assert not moved[thumbs].any() and moved[~thumbs].all()


def test_a_spliced_hand_is_one_persons_fist_with_fingers_of_their_open_hand(tmp_path):
    write_dataset(tmp_path / "src", people=(1, 2), poses=("fist_moved", "five"), per_pose=3)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    horns = np.array([[0, 1, 0, 0, 1]], dtype=bool)
    spliced = mmhgr.splice_fingers(frames, horns, 40, np.random.default_rng(0))
    assert len(spliced) == 40 and set(spliced.pose) == {"spliced"}
    assert spliced.extended.tolist() == [[False, True, False, False, True]] * 40

    def local(f):
        return np.einsum("nij,nfkj->nfki", mmhgr.palm_basis(f), f.joints - f.palm[:, None, None])

    fists, fives = (frames.subset(frames.pose == p) for p in ("fist_moved", "five"))
    got, fist_local, five_local = local(spliced), local(fists), local(fives)
    for n in range(len(spliced)):
        own = fists.user == spliced.user[n]
        # the curled fingers and the palm are one of the same person's fists ...
        assert [k for k in np.flatnonzero(own)
                if np.allclose(got[n, [0, 2, 3]], fist_local[k, [0, 2, 3]], atol=1e-3)]
        # ... and the index and pinky those of one of their open hands, in the palm's frame
        donors = [k for k in np.flatnonzero(fives.user == spliced.user[n])
                  if np.allclose(got[n, [1, 4]], five_local[k, [1, 4]], atol=1e-3)]
        assert donors
    x = invariant.bends(mmhgr.features57(spliced))
    assert x[:, 3:6].sum(1).max() < x[:, 6:9].sum(1).min()  # the index straight, the middle bent


def test_spliced_hands_train_none_when_asked(tmp_path):
    write_dataset(tmp_path / "src", people=(1,), poses=("fist_moved", "five"), per_pose=3)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    names = ["grab", "five", "none"]
    rng = np.random.default_rng(0)
    plain = train.mmhgr_rows(frames, names, train.TrainOptions(mmhgr_stride=1), rng)
    more = train.mmhgr_rows(frames, names, train.TrainOptions(mmhgr_stride=1, spliced_none=7),
                            rng)
    assert len(more[1]) == len(plain[1]) + 7
    assert more[1][-7:].tolist() == [2] * 7 and set(more[2][-7:]) == {"mmhgr_none"}


@pytest.mark.parametrize(("ok_sign", "label"), [("pinch", "pinch"), ("none", "none")])
def test_the_ok_signs_train_as_pinch_or_as_none_as_asked(tmp_path, ok_sign, label):
    write_dataset(tmp_path / "src", people=(1,), poses=("five", "ok"), per_pose=3)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    names = ["pinch", "five", "none"]
    options = train.TrainOptions(mmhgr_stride=1, ok_sign=ok_sign)
    _, y, source = train.mmhgr_rows(frames, names, options, np.random.default_rng(0))
    ok = frames.pose == "ok"
    assert set(np.array(names)[y[ok]]) == {label}
    assert set(np.array(names)[y[~ok]]) == {"five"}
    assert set(source[ok]) == {"mmhgr" if ok_sign == "pinch" else "mmhgr_none"}
    assert set(frames.labels(ok_sign)[ok]) == {"pinch" if ok_sign == "pinch" else ""}
    assert ("ok" in mmhgr.unknown_poses(ok_sign)) == (ok_sign == "none")


@pytest.mark.parametrize("ok_sign", ["pinch", "none"])
def test_crossvalidation_scores_the_ok_signs_as_what_they_were_trained_as(tmp_path, ok_sign):
    write_dataset(tmp_path / "src", people=(1, 2), poses=("five", "ok", "C", "L"),
                  per_pose=2)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    options = train.TrainOptions(per_gesture=2, none=4, off_vocabulary=4, hidden=[4],
                                 epochs=1, mmhgr_stride=1, ok_sign=ok_sign)
    fig = crossval.crossvalidate(frames, options, folds=2, samples=4)
    if ok_sign == "pinch":  # a gesture of the held-out people, scored as one
        assert fig["classes"] == ["pinch", "five"] and fig["n"] == 2 * 2 * 2
        assert "ok" not in fig["rejection_seen"]
    else:  # an unknown pose every fold trains as none: the other people's were seen
        assert fig["classes"] == ["five"] and fig["n"] == 2 * 2
        assert "ok" in fig["rejection_seen"] and "ok" not in fig["rejection"]
    assert set(fig["rejection"]) | set(fig["rejection_seen"]) >= {"C", "L"}


def test_an_ok_sign_that_is_neither_choice_is_refused():
    with pytest.raises(ValueError, match="ok_sign"):
        train.TrainOptions(ok_sign="ok")


def test_a_timed_transition_moves_from_one_held_gesture_to_another_over_time(tmp_path):
    write_dataset(tmp_path / "src", people=(1,), poses=("fist_moved", "five"), per_pose=1)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    rng = np.random.default_rng(0)
    now, before, which, through = crossval.timed_transitions(
        frames, *crossval.transition_ends(frames, 1, rng), rng)
    assert (which == 0).all()
    assert (np.diff(through) > 0).all() and 0 < through[0] and through[-1] < 1
    x = mmhgr.features57(frames)
    first, second = (x[frames.pose == p][0] for p in ("fist_moved", "five"))
    if np.abs(now[0] - first).max() > np.abs(now[0] - second).max():  # drawn the other way
        first, second = second, first
    count = len(now)  # strictly between the ends, at the rate
    assert crossval.TRANSITION_S[0] * crossval.TIMED_RATE_HZ - 1 <= count <= \
        crossval.TRANSITION_S[1] * crossval.TIMED_RATE_HZ
    ahead = int(motion.WINDOW_S * crossval.TIMED_RATE_HZ)
    assert np.allclose(before[:ahead - 1], first)  # a window back the hand was still held
    assert np.allclose(before[ahead:], now[:-ahead], atol=1e-6)  # the same path, a window later
    distance = np.abs(now - first).max(1)
    assert (np.diff(distance) >= -1e-9).all() and 0 < distance[0] < distance[-1]
    assert np.abs(now[-1] - second).max() > 0  # the held second pose is not a transition


def test_a_hand_found_mid_change_is_followed_while_younger_than_the_window(tmp_path):
    write_dataset(tmp_path / "src", people=(1,), poses=("fist_moved", "five"), per_pose=1)
    mmhgr_data.convert(tmp_path / "src", tmp_path / "c.npz", progress=False)
    frames = mmhgr.load(tmp_path / "c.npz")
    rng = np.random.default_rng(3)
    ends = crossval.transition_ends(frames, 20, rng)
    now, first, which = crossval.appearing_transitions(frames, *ends, rng)
    young = int(np.ceil(motion.WINDOW_S * crossval.TIMED_RATE_HZ))
    counts = np.bincount(which, minlength=20)
    assert 1 <= counts.min() and counts.max() <= young  # found before the change's end
    assert (counts < young).any()  # some found so late the change ends before the window
    for k in range(20):
        mine = which == k
        assert np.allclose(first[mine], now[mine][0])  # compared with the frame it was found at
    x = mmhgr.features57(frames)
    ends_x = [x[frames.pose == p][0] for p in ("fist_moved", "five")]
    # strictly inside a change: never the held pose it leaves, nor the one it reaches
    assert all(np.abs(now - end).max(1).min() > 0 for end in ends_x)
    empty = crossval.appearing_transitions(frames, np.zeros(0, int), np.zeros(0, int), rng)
    assert [a.shape[0] for a in empty] == [0, 0, 0]
