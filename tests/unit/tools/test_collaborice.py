"""CollaborICE's JSON-lines LeapC frames → contract hands (`cbgo_tools.data.collaborice`), and
`cbgo data fetch` keeping what it can read from a source that lacks some files' contents.

The frames here are synthetic lines written as the set's recorder writes them (metres, LeapC
axes, quaternions x, y, z, w), not copied from the set.
"""

import json
import math
import shutil
import subprocess

import numpy as np
import pytest

from cbgo.hands import features as F
from cbgo_tools.data import DATASETS, collaborice, command

FINGERS = ("thumb", "index", "middle", "ring", "pinky")
BONES = ("metacarpal", "proximal", "intermediate", "distal")
# a quarter turn about +x: any rotation that is not the identity, as the set's thumbs carry
QUARTER_TURN = [math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4)]


def synthetic_line(palm_orientation=(0.0, 0.0, 0.0, 1.0), hand_type="right") -> str:
    """One frame: a flat right hand over the sensor, fingers away from the user (−z), metres."""
    fingers = {}
    for f, name in enumerate(FINGERS):
        x = -0.04 + 0.02 * f
        base = [x, 0.2, 0.0]
        bones, joint = {}, base
        for b, bone in enumerate(BONES):
            length = 0.0 if (name == "thumb" and b == 0) else 0.03
            nxt = [joint[0], joint[1], joint[2] - length]
            bones[bone] = {"prev_joint": joint, "next_joint": nxt,
                           "rotation": QUARTER_TURN if length == 0.0 else [0, 0, 0, 1]}
            joint = nxt
        fingers[name] = bones
    hand = {"hand_type": hand_type, "hand_id": 7, "confidence": 0.9,
            "hand_keypoints": {"palm_position": [0.0, 0.2, 0.03],
                               "palm_orientation": list(palm_orientation),
                               "arm": {"prev_joint": [0.0, 0.2, 0.3],
                                       "next_joint": [0.0, 0.2, 0.08],
                                       "rotation": [0, 0, 0, 1]},
                               "fingers": fingers, "grab_angle": math.pi / 2}}
    return json.dumps({"frame_id": 1, "tracking_frame_id": 10, "timestamp": 1.0,
                       "hands": [hand]})


def test_positions_become_millimetres_in_the_leap_frame():
    (hand,) = collaborice.hands_of_line(synthetic_line())
    assert hand["palm_position"] == pytest.approx([0.0, 200.0, 30.0])
    assert hand["wrist_position"] == pytest.approx([0.0, 200.0, 80.0])  # arm.next_joint
    index_tip = hand["fingers"][1]["bones"][3]["next_joint"]
    assert index_tip == pytest.approx([-20.0, 200.0, -120.0])
    assert hand["side"] == "right" and hand["id"] == 7 and hand["confidence"] == 0.9
    assert hand["grab_strength"] == pytest.approx(0.5)  # grab_angle / π
    assert hand["palm_velocity"] == [0.0, 0.0, 0.0]


def test_palm_axes_come_from_the_orientation_basis():
    # LeapC's palm basis is {normal × direction, −normal, −direction}: the identity is a hand
    # palm down, fingers away from the user
    (hand,) = collaborice.hands_of_line(synthetic_line())
    assert hand["palm_normal"] == pytest.approx([0.0, -1.0, 0.0])
    assert hand["direction"] == pytest.approx([0.0, 0.0, -1.0])
    # a quarter turn about +y: fingers to the left (−x), palm still down
    turned = [0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4)]
    (hand,) = collaborice.hands_of_line(synthetic_line(turned))
    assert hand["direction"] == pytest.approx([-1.0, 0.0, 0.0], abs=1e-9)
    assert hand["palm_normal"] == pytest.approx([0.0, -1.0, 0.0], abs=1e-9)
    normal, direction = collaborice.palm_axes([0.0, 0.0, 0.0, 2.0])  # not unit: normalised
    assert direction == pytest.approx([0.0, 0.0, -1.0])


def test_the_zero_length_thumb_metacarpal_loses_its_rotation_as_on_a_live_sensor():
    (hand,) = collaborice.hands_of_line(synthetic_line())
    metacarpal, proximal = hand["fingers"][0]["bones"][:2]
    assert "rotation" not in metacarpal and metacarpal["width"] == 0.0
    assert proximal["rotation"] == [0, 0, 0, 1] and proximal["width"] > 0.0
    # so the features borrow the proximal's direction: no bend between the two
    assert F.hand_features(hand)[4:6] == pytest.approx([0.0, 0.0], abs=1e-9)


def test_malformed_lines_are_counted_and_skipped(tmp_path):
    broken = json.loads(synthetic_line())
    del broken["hands"][0]["hand_keypoints"]["fingers"]["ring"]
    zero_quaternion = synthetic_line(palm_orientation=(0.0, 0.0, 0.0, 0.0))
    path = tmp_path / "thumb.txt"
    path.write_text("\n".join([synthetic_line(), "{not json", json.dumps(broken),
                               synthetic_line(hand_type="middle"), zero_quaternion, "",
                               synthetic_line()]) + "\n")
    hands, skipped = collaborice.read_file(path)
    assert len(hands) == 2 and skipped == 4


def test_pose_files_map_the_sets_names(tmp_path):
    for person, pose in (("3", "thumb"), ("3", "ok"), ("2", "ng"), ("2", "other")):
        (tmp_path / person).mkdir(exist_ok=True)
        (tmp_path / person / f"{pose}.txt").write_text(synthetic_line() + "\n")
    files = collaborice.pose_files(tmp_path)
    assert [(p, pose, collaborice.GESTURES[pose]) for p, pose, _ in files] == [
        ("2", "ng", "none"), ("3", "ok", "pinch"), ("3", "thumb", "thumbsup")]
    assert collaborice.pose_files(tmp_path / "absent") == []


class AlwaysGrab:
    names = ["grab", "thumbsup", "none"]

    def classify_hands(self, hands):
        return np.tile([0.9, 0.1, 0.0], (len(hands), 1))


def test_score_counts_what_each_pose_is_read_as(tmp_path):
    (tmp_path / "3").mkdir()
    (tmp_path / "3" / "thumb.txt").write_text((synthetic_line() + "\n") * 3 + "oops\n")
    fig = collaborice.score(AlwaysGrab(), tmp_path)
    (row,) = fig["files"]
    assert (row["hands"], row["skipped"], row["right"]) == (3, 1, 0)
    assert fig["gestures"]["thumbsup"]["answers"] == {"grab": 3}
    assert collaborice.score(AlwaysGrab(), tmp_path / "absent") is None


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_fetch_keeps_the_readable_files_and_names_the_others(tmp_path, monkeypatch, capsys):
    data = DATASETS["collaborice"]
    repo = tmp_path / "upstream"
    folder = repo / data.folder
    for person in ("2", "3"):
        (folder / person).mkdir(parents=True)
        (folder / person / "thumb.txt").write_text(f"person {person}\n")
    for step in (["init", "-q"], ["add", "."],
                 ["-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "data"]):
        subprocess.run(["git", "-C", str(repo), *step], check=True)
    blob = subprocess.run(["git", "-C", str(repo), "rev-parse", f"HEAD:{data.folder}/2/thumb.txt"],
                          capture_output=True, text=True, check=True).stdout.strip()
    (repo / ".git" / "objects" / blob[:2] / blob[2:]).unlink()  # its contents are gone
    monkeypatch.setenv("CBGO_CACHE_DIR", str(tmp_path / "cache"))
    assert command.fetch(data, source=str(repo)) == 0
    fetched = tmp_path / "cache" / "collaborice"
    assert (fetched / "3" / "thumb.txt").read_text() == "person 3\n"
    assert not (fetched / "2").exists()
    assert f"1 could not be read from this source (their contents are missing there): " \
           f"{data.folder}/2/thumb.txt" in capsys.readouterr().err
