"""Foxglove scene entities built from wire messages: hands, objects, the arm, the focus ray.

Pure functions from decoded wire messages (plain dicts) to ``foxglove.SceneEntity`` dicts of
Foxglove's JSON schema (``schemas/SceneUpdate.json``). Everything is drawn in the robot base
frame (`BASE_FRAME`, metres, +z up); hand geometry arrives in the Leap frame (mm) and is
converted with the frame's ``to_base`` transform (`cbgo.transform`), the default sensor pose
when a frame has none. Every primitive list of an entity is present, as the schema requires.
"""

from __future__ import annotations

import numpy as np

from cbgo import transform
from cbgo.foxglove import arm
from cbgo.world import drawer_direction

BASE_FRAME = "base"
LEAP_FRAME = "leap"
IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
LINE_LIST = 2  # foxglove.LineType: each pair of points is one segment
JOINT_M, TIP_M, PALM_M = 0.010, 0.013, 0.020  # sphere diameters of hand joints, tips, palm
BONE_LINE_PX = 3.0  # bone thickness, screen pixels (scale invariant)
TCP_M = 0.03
LINK_M, JOINT_BALL_M = 0.05, 0.07  # the arm's link thickness and joint spheres, m
ARM, ARM_NOMINAL = (0.85, 0.87, 0.9, 1.0), (0.85, 0.87, 0.9, 0.3)
FOCUS_M = 0.025
# Where a ray of gaze starts when nobody reports the eyes: the contract carries no head pose,
# so a nominal eye point 0.45 m above the sensor and 0.30 m towards the user (Leap mm) is used;
# it only makes the ray visible and is labelled as nominal in the entity's metadata.
NOMINAL_EYE_LEAP_MM = (0.0, 450.0, 300.0)

SIDE_COLOURS = {"left": (0.25, 0.55, 1.0, 1.0), "right": (1.0, 0.55, 0.15, 1.0)}
OBJECT_COLOURS = {"cup": (0.85, 0.85, 0.9, 0.9), "box": (0.65, 0.45, 0.25, 0.9),
                  "drawer": (0.55, 0.55, 0.6, 0.9)}
FULL_CUP = (0.3, 0.6, 1.0, 0.9)
TARGET = (1.0, 0.85, 0.0, 1.0)
TCP_OPEN, TCP_CLOSED, TCP_UNKNOWN = (0.2, 0.9, 0.3, 1.0), (0.9, 0.2, 0.2, 1.0), (0.6,) * 4
FOCUS = (1.0, 0.2, 0.8, 1.0)
TEXT = (1.0, 1.0, 1.0, 1.0)
CUP_DIAMETER = 0.8  # a cup's diameter, as a fraction of its bounding cube's edge
DRAWER_TRAVEL = 0.818  # the tray slides out 0.818 x the cabinet size (docs/protocol.md)


def stamp(ts: float) -> dict:
    """Returns a Foxglove time of a wire ``ts`` (s since the Unix epoch)."""
    ns = max(0, int(round(ts * 1e9)))
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def colour(rgba) -> dict:
    """Returns a foxglove.Color."""
    r, g, b, a = rgba
    return {"r": r, "g": g, "b": b, "a": a}


def vec(p) -> dict:
    """Returns a foxglove.Vector3 / Point3 of three numbers."""
    return {"x": float(p[0]), "y": float(p[1]), "z": float(p[2])}


def pose(position) -> dict:
    """Returns a foxglove.Pose at position with no rotation."""
    return {"position": vec(position), "orientation": dict(IDENTITY)}


def entity(entity_id: str, ts: float, **primitives) -> dict:
    """Returns a foxglove.SceneEntity in the base frame with every primitive list present."""
    metadata = primitives.pop("metadata", {})
    out = {"timestamp": stamp(ts), "frame_id": BASE_FRAME, "id": entity_id,
           "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False,
           "metadata": [{"key": k, "value": str(v)} for k, v in metadata.items()]}
    for name in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts",
                 "models"):
        out[name] = primitives.pop(name, [])
    if primitives:
        raise TypeError(f"unknown primitive lists {sorted(primitives)}")
    return out


def sphere(position, diameter: float, rgba) -> dict:
    """Returns a foxglove.SpherePrimitive."""
    return {"pose": pose(position), "size": vec((diameter,) * 3), "color": colour(rgba)}


def line_list(points, rgba, thickness: float = BONE_LINE_PX) -> dict:
    """Returns a foxglove.LinePrimitive of segments (pairs of points), in pixels."""
    return {"type": LINE_LIST, "pose": pose((0, 0, 0)), "thickness": thickness,
            "scale_invariant": True, "points": [vec(p) for p in points],
            "color": colour(rgba), "colors": [], "indices": []}


def text(position, words: str, rgba=TEXT, size_px: float = 14.0) -> dict:
    """Returns a billboard foxglove.TextPrimitive."""
    return {"pose": pose(position), "billboard": True, "font_size": size_px,
            "scale_invariant": True, "color": colour(rgba), "text": words}


def to_base_of(frame: dict) -> np.ndarray:
    """Returns the frame's Leap(mm)->base(m) matrix, else the default sensor pose's."""
    values = frame.get("to_base")
    return np.asarray(values, dtype=float).reshape(4, 4) if values else \
        transform.default_to_base()


def hands_entity(frame: dict) -> dict:
    """Returns the ``hands`` entity of a hands/frame: bones as lines, joints as spheres."""
    matrix = to_base_of(frame)
    lines, spheres = [], []
    for hand in frame["hands"]:
        rgba = SIDE_COLOURS.get(hand["side"], TEXT)
        segments = []
        for finger in hand["fingers"]:
            for bone in finger["bones"]:
                start = transform.leap_to_base(matrix, bone["prev_joint"])
                end = transform.leap_to_base(matrix, bone["next_joint"])
                segments += [start, end]
                spheres.append(sphere(start, JOINT_M, rgba))
            spheres.append(sphere(segments[-1], TIP_M, rgba))
        lines.append(line_list(segments, rgba))
        spheres.append(sphere(transform.leap_to_base(matrix, hand["palm_position"]), PALM_M,
                              rgba))
    return entity("hands", frame["ts"], lines=lines, spheres=spheres,
                  metadata={"hands": len(frame["hands"]), "seq": frame["seq"]})


def _object_shape(obj: dict, rgba) -> dict:
    size = obj["size"]
    if obj["type"] == "cup":
        return {"cylinders": [{"pose": pose(obj["position"]),
                               "size": vec((size * CUP_DIAMETER, size * CUP_DIAMETER, size)),
                               "bottom_scale": 1.0, "top_scale": 1.0, "color": colour(rgba)}]}
    cubes = [{"pose": pose(obj["position"]), "size": vec((size,) * 3), "color": colour(rgba)}]
    opening = obj.get("opening", 1.0 if obj.get("open") else 0.0)
    if obj["type"] == "drawer" and opening > 0:  # the tray, slid out the way it opens
        x, y, z = obj["position"]
        way = drawer_direction(x)
        tray = (x + way * (size / 2 + opening * DRAWER_TRAVEL * size / 2), y, z - size / 4)
        cubes.append({"pose": pose(tray), "size": vec((opening * DRAWER_TRAVEL * size,
                                                       size * 0.9, size / 2)),
                      "color": colour(rgba)})
    return {"cubes": cubes}


def objects_entity(scene: dict, target: str | None) -> dict:
    """Returns the ``objects`` entity of a scene/state.

    Cups are cylinders, boxes and drawers cubes (an open drawer's tray too), names are labels;
    the target object (of the last accepted intent) is drawn in yellow.
    """
    parts: dict[str, list] = {"cubes": [], "cylinders": [], "texts": []}
    for obj in scene["objects"]:
        rgba = FULL_CUP if obj["type"] == "cup" and obj.get("full") else \
            OBJECT_COLOURS.get(obj["type"], TEXT)
        if obj["name"] == target:
            rgba = TARGET
        for name, shapes in _object_shape(obj, rgba).items():
            parts[name] += shapes
        x, y, z = obj["position"]
        label = obj["name"] + (" (target)" if obj["name"] == target else "")
        parts["texts"].append(text((x, y, z + obj["size"] / 2 + 0.03), label,
                                   TARGET if obj["name"] == target else TEXT))
    return entity("objects", scene["ts"], **parts,
                  metadata={"target": target or "", "objects": len(scene["objects"])})


def robot_entity(ts: float, tcp, gripper_open: bool | None, holding: str | None,
                 joints=None, nominal: bool = False) -> dict:
    """Returns the ``robot`` entity: the arm's links posed by its joints, and the TCP.

    The links run between the joint frames of the Panda/FR3 kinematics (`arm.link_points`),
    drawn as lines `LINK_M` thick with a sphere at each joint. Without joints (no
    ``robot/state`` yet) a thin line from the base to the TCP stands for the arm; ``nominal``
    joints (``kinematics: false``: dry-robot or franka's dry run, which publish the ready
    posture) are drawn faded and labelled so. The TCP sphere is green with the gripper open,
    red closed, grey while unknown (no scene yet).
    """
    rgba = {True: TCP_OPEN, False: TCP_CLOSED}.get(gripper_open, TCP_UNKNOWN)
    label = "TCP" + (f" holding {holding}" if holding else "")
    spheres, texts = [sphere(tcp, TCP_M, rgba)], [text((tcp[0], tcp[1], tcp[2] + 0.05), label)]
    if joints is None:
        lines = [line_list([(0.0, 0.0, 0.0), tcp], (0.7, 0.7, 0.7, 0.6), 2.0)]
    else:
        points = arm.link_points(joints)
        shade = ARM_NOMINAL if nominal else ARM
        links = [p for pair in zip(points[:-1], points[1:], strict=True) for p in pair]
        lines = [{**line_list(links, shade, LINK_M), "scale_invariant": False}]
        spheres += [sphere(p, JOINT_BALL_M, shade) for p in points[1:-1]]
        if nominal:
            texts.append(text(points[-3], "arm: nominal pose (no kinematics)", ARM_NOMINAL))
    return entity("robot", ts, spheres=spheres, lines=lines, texts=texts,
                  metadata={"holding": holding or "", "joints": "nominal" if nominal else (
                      "none" if joints is None else "measured")})


def focus_entity(gaze: dict, origin, nominal: bool) -> dict:
    """Returns the ``focus`` entity: the gaze or pointing ray from origin to the point.

    Args:
        gaze: the gaze message (point in the base frame).
        origin: where the ray starts, base frame (the index fingertip for pointing, else the
            nominal eye point).
        nominal: whether origin is the nominal eye point (recorded in the metadata).
    """
    point = gaze["point"]
    return entity("focus", gaze["ts"], spheres=[sphere(point, FOCUS_M, FOCUS)],
                  lines=[line_list([origin, point], FOCUS, 2.0)],
                  metadata={"source": gaze["source"],
                            "origin": "nominal eye point" if nominal else "index fingertip"})


def ray_origin(gaze: dict, frame: dict | None) -> tuple[np.ndarray, bool]:
    """Returns where the focus ray starts (base frame) and whether that point is nominal."""
    matrix = to_base_of(frame) if frame else transform.default_to_base()
    if gaze["source"] == "pointing" and frame and frame["hands"]:
        tip = frame["hands"][0]["fingers"][1]["bones"][3]["next_joint"]
        return transform.leap_to_base(matrix, tip), False
    return transform.leap_to_base(matrix, NOMINAL_EYE_LEAP_MM), True


def leap_transform(frame: dict) -> dict:
    """Returns the foxglove.FrameTransform of the Leap frame in the base frame.

    The Leap frame is in mm and the base in m; Foxglove's transforms are rigid, so the child
    frame ``leap`` is the sensor's pose (its axes, in metres): its scale is not carried.
    """
    matrix = to_base_of(frame)
    rotation = matrix[:3, :3] * 1000.0
    return {"timestamp": stamp(frame["ts"]), "parent_frame_id": BASE_FRAME,
            "child_frame_id": LEAP_FRAME, "translation": vec(matrix[:3, 3]),
            "rotation": quaternion(rotation)}


def quaternion(m: np.ndarray) -> dict:
    """Returns the foxglove.Quaternion of a 3x3 rotation matrix."""
    trace = float(np.trace(m))
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
        q[i], q[j], q[k] = s / 4, (m[j, i] + m[i, j]) / s, (m[k, i] + m[i, k]) / s
    q = np.asarray(q) / np.linalg.norm(q)
    return {"x": float(q[0]), "y": float(q[1]), "z": float(q[2]), "w": float(q[3])}
