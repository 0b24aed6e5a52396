"""Ultraleap's own recorded hand poses (Gemini tracking): reader and a bench on the live model.

Why: static gestures should hold on the Leap Motion Controller 2 (Ultraleap Gemini / LeapC
tracking). No public LMC2 recording set exists that we know of, but Ultraleap's
Unity plugin (``ultraleap/UnityPlugin``, Apache-2.0) ships the hand poses of its pose detector
as serialized Gemini hands: one frame per pose, one person, both sides (the left hand is the
right one mirrored). They are the only Gemini-generation skeletons we have: the thumb's
metacarpal of zero length, Gemini's joint placement and palm width. They are vendored in
``ultraleap_poses/`` with the plugin's licence (see its README).

Rules:

- A pose file is a Unity YAML asset (``HandPoseScriptableObject``); its ``serializedHand`` and
  ``mirroredHand`` are Leap ``Hand`` objects in Unity's world: metres, LEFT-handed (+x right,
  +y up, +z away from the user). `hand_of` converts them into contract hands in the Leap
  frame (mm, right-handed, +z towards the user) by flipping z, and moves the palm to
  `FIELD_CENTRE_MM` (Unity's world origin is not the sensor; no feature reads the palm's
  position). Bone rotations are left out: the features read bone directions from the joints,
  and the zero-length thumb metacarpal borrows its proximal's direction, as LeapC frames do
  (``services/leap_bridge/leap_device.py``). Field names are read case-insensitively: the
  plugin's versions spell them ``fingers`` / ``Fingers``.
- The poses were captured held up in front of a head-mounted sensor: fingers up (the hand
  direction's +y about 0.9, except the thumbs: sideways), palm towards the user. That is far
  outside how the paper's people and the HGR set's held their hands over a desktop sensor, so
  `score_poses` also scores each pose turned (rigidly, about its palm) into the orientation of
  the calibrated poses (``cbgo.hands.poses.gesture_mean``) of ``five``, ``grab``, ``point`` and
  ``thumbsup``: what the model makes of the same hand shape held as the training hands were.
- `POSES` maps the files to cbgo's vocabulary: ``fist`` → grab, ``open_palm`` → five,
  ``point``, ``thumbs_up`` and ``thumbs_extended`` → thumbsup, ``v`` → two, ``ok`` → pinch
  (the paper's pinch is an ok sign's shape: ``mmhgr.POSE_MAP``); ``horns`` is no gesture of
  ours (``none``: right when answered ``none`` or with top p < 0.5).
- Thumbs down: each thumbs-up pose, turned like the training thumbs-ups, is also rolled 180°
  about the hand's direction (`rolled_over`), which points its thumb down. A thumbs-down is no
  gesture of ours (``none``), and a consumer that reads thumbs-up as "yes" must not get it.

Example::

    cbgo bench static --no-crossval --no-latency   # the poses' answers among its figures
    cbgo bench static --model M --no-crossval --no-latency   # another model's
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from cbgo.hands import features as F
from cbgo.services.static_gesture.classifier import NONE, is_rejected
from cbgo.wire import BONE_TYPES, FINGER_TYPES

POSES_DIR = Path(__file__).with_name("ultraleap_poses")
POSES = {"fist": "grab", "open_palm": "five", "point": "point", "thumbs_up": "thumbsup",
         "thumbs_extended": "thumbsup", "v": "two", "ok": "pinch", "horns": "none"}
FIELD_CENTRE_MM = (0.0, 200.0, 0.0)
TRAINING_ORIENTATIONS = ("five", "grab", "point", "thumbsup")


def _lower_keys(value):
    """Returns YAML data with every mapping key's first letter lower-cased, recursively."""
    if isinstance(value, dict):
        return {k[:1].lower() + k[1:]: _lower_keys(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_lower_keys(v) for v in value]
    return value


def read_pose(path: Path) -> dict:
    """Returns a pose asset's fields (keys lower-camel-case), from Unity YAML."""
    # Unity's YAML has %TAG directives and "--- !u!114 &id" documents that PyYAML rejects;
    # the asset holds one document, so both are dropped.
    text = "\n".join(line for line in Path(path).read_text().splitlines()
                     if not line.startswith(("%", "---")))
    return _lower_keys(yaml.safe_load(text))["monoBehaviour"]


def _leap(v: dict) -> np.ndarray:
    """A Unity vector in the Leap frame's axes (z flipped), its units kept."""
    return np.array([v["x"], v["y"], -v["z"]], dtype=np.float64)


def _mm(v: dict) -> np.ndarray:
    return 1000.0 * _leap(v)


def _unit(v: dict) -> list[float]:
    return F.unit(np, _leap(v)).tolist()


def hand_of(serialized: dict, hand_id: int = 1) -> dict:
    """Returns the contract hand (Leap frame, mm) of one serialized Unity ``Hand``."""
    shift = np.asarray(FIELD_CENTRE_MM) - _mm(serialized["palmPosition"])

    def point(v: dict) -> list[float]:
        return (_mm(v) + shift).tolist()

    fingers = [{"type": ftype, "bones": [
        {"type": btype, "prev_joint": point(bone["prevJoint"]),
         "next_joint": point(bone["nextJoint"]), "width": 1000.0 * float(bone["width"])}
        for btype, bone in zip(BONE_TYPES, finger["bones"], strict=True)]}
        for ftype, finger in zip(FINGER_TYPES, serialized["fingers"], strict=True)]
    return {"id": hand_id, "side": "left" if serialized["isLeft"] else "right",
            "confidence": float(np.clip(serialized["confidence"], 0.0, 1.0)),
            "palm_position": list(FIELD_CENTRE_MM),
            "palm_velocity": _mm(serialized["palmVelocity"]).tolist(),
            "palm_normal": _unit(serialized["palmNormal"]),
            "direction": _unit(serialized["direction"]),
            "wrist_position": point(serialized["wristPosition"]),
            "palm_width": 1000.0 * float(serialized["palmWidth"]),
            "grab_strength": float(np.clip(serialized["grabStrength"], 0.0, 1.0)),
            "pinch_strength": float(np.clip(serialized["pinchStrength"], 0.0, 1.0)),
            "fingers": fingers}


def load_poses(folder: Path = POSES_DIR) -> dict[str, list[dict]]:
    """Returns {pose name: [right hand, left hand]} of every asset in `folder`."""
    out = {}
    for path in sorted(Path(folder).glob("*.asset")):
        pose = read_pose(path)
        hands = [hand_of(pose["serializedHand"]), hand_of(pose["mirroredHand"])]
        out[path.stem] = sorted(hands, key=lambda h: h["side"] != "right")
    return out


def turned_like(hand: dict, reference: dict) -> dict:
    """Returns `hand` turned about its palm centre so that its palm frame is `reference`'s."""
    rot = F.hand_basis(reference).T @ F.hand_basis(hand)
    centre = np.asarray(hand["palm_position"], dtype=np.float64)

    def point(p) -> list[float]:
        return (rot @ (np.asarray(p, dtype=np.float64) - centre) + centre).tolist()

    def vector(v) -> list[float]:
        return (rot @ np.asarray(v, dtype=np.float64)).tolist()

    return {**hand, "palm_normal": vector(hand["palm_normal"]),
            "direction": vector(hand["direction"]),
            "palm_velocity": vector(hand["palm_velocity"]),
            "wrist_position": point(hand["wrist_position"]),
            "fingers": [{**f, "bones": [{**b, "prev_joint": point(b["prev_joint"]),
                                         "next_joint": point(b["next_joint"])}
                                        for b in f["bones"]]} for f in hand["fingers"]]}


def rolled_over(hand: dict) -> dict:
    """Returns `hand` rolled 180° about its own direction (a thumbs-up becomes a thumbs-down)."""
    return turned_like(hand, {"direction": hand["direction"],
                              "palm_normal": [-v for v in hand["palm_normal"]]})


def thumb_elevation_deg(hand: dict) -> float:
    """Returns how far the thumb's distal bone points above level (+y, degrees; < 0: down)."""
    thumb = next(f for f in hand["fingers"] if f["type"] == "thumb")
    distal = thumb["bones"][-1]
    d = np.asarray(distal["next_joint"], dtype=np.float64) - np.asarray(distal["prev_joint"])
    return float(np.degrees(np.arcsin(d[1] / np.linalg.norm(d))))


def _right(truth: str, names: list[str], probs: np.ndarray) -> bool:
    top = int(np.argmax(probs))
    if truth == NONE:
        return bool(is_rejected(names[top], probs[top]))
    return names[top] == truth


def score_poses(classifier, poses: dict[str, list[dict]] | None = None) -> dict:
    """Scores a `StaticClassifier` on the poses as held, and turned like the training hands.

    Returns:
        ``{"poses": [{pose, truth, answer, p, right, turned: {orientation: (answer, p)}}],
        "right": k, "n": n, "right_turned": k, "n_turned": n, "thumbs_down": [{pose,
        answer, p, right, elevation_deg}]}``; both sides of a pose are mirror images, so each
        pose is scored on its right hand (the left gives the same answer: a unit test holds
        them together). ``thumbs_down``: the thumbs-up poses turned like the training
        thumbs-ups and `rolled_over`, right when rejected.
    """
    from cbgo.hands.model import HandShape, build_hand  # noqa: PLC0415
    from cbgo.hands.poses import gesture_mean  # noqa: PLC0415

    poses = load_poses() if poses is None else poses
    references = {g: build_hand(HandShape(side="right"), gesture_mean(g), FIELD_CENTRE_MM)
                  for g in TRAINING_ORIENTATIONS}
    rows, right_turned, n_turned, thumbs_down = [], 0, 0, []
    for name, (hand, _) in poses.items():
        truth = POSES.get(name, "none")
        turned = [turned_like(hand, ref) for ref in references.values()]
        probs = classifier.classify_hands([hand, *turned])
        names = classifier.names
        answers = [(names[int(np.argmax(p))], float(np.max(p))) for p in probs]
        oks = [_right(truth, names, p) for p in probs]
        right_turned += sum(oks[1:])
        n_turned += len(oks) - 1
        rows.append({"pose": name, "truth": truth, "answer": answers[0][0], "p": answers[0][1],
                     "right": oks[0], "turned": dict(zip(references, answers[1:], strict=True)),
                     "direction": hand["direction"], "palm_normal": hand["palm_normal"]})
        if truth == "thumbsup":
            down = rolled_over(turned[TRAINING_ORIENTATIONS.index("thumbsup")])
            p = classifier.classify_hands([down])[0]
            thumbs_down.append({"pose": name, "answer": names[int(np.argmax(p))],
                                "p": float(np.max(p)), "right": _right(NONE, names, p),
                                "elevation_deg": thumb_elevation_deg(down)})
    return {"poses": rows, "right": sum(r["right"] for r in rows), "n": len(rows),
            "right_turned": right_turned, "n_turned": n_turned, "thumbs_down": thumbs_down}


def print_scores(fig: dict) -> None:
    """Prints `score_poses`' figures: one line per pose."""
    print(f"Ultraleap's Gemini-tracked poses (UnityPlugin, 1 person, held fingers up, palm to "
          f"the user): {fig['right']}/{fig['n']} right as held; turned like the training "
          f"hands ({', '.join(TRAINING_ORIENTATIONS)}): {fig['right_turned']}/{fig['n_turned']}")
    for row in fig["poses"]:
        turned = "  ".join(f"{a}:{p:.2f}" for a, p in row["turned"].values())
        print(f"  {row['pose']:16s} ({row['truth']:8s}) as held {row['answer']}:{row['p']:.2f}"
              f"{'' if row['right'] else ' ✗'}; turned {turned}")
    down = fig.get("thumbs_down", [])
    if down:
        print(f"  thumbs-ups turned like the training ones, then rolled over into thumbs-downs "
              f"(no gesture; right when rejected): {sum(d['right'] for d in down)}/{len(down)}: "
              + ", ".join(f"{d['pose']} (thumb {d['elevation_deg']:.0f}° from level) "
                          f"{d['answer']}:{d['p']:.2f}{'' if d['right'] else ' ✗'}"
                          for d in down))
