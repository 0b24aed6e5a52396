"""Scenes: consistency rules, the paper's state bit, and the contract's scene dict."""

import pytest
from world_scenes import obj, world

from cbgo import wire
from cbgo.world import Robot, Scene, random_scene


def test_a_scene_round_trips_through_the_contract_dict_and_validates():
    scene = world(obj("drawer1", "drawer", (3, 1), open=True), obj("cup1", "cup", inside="drawer1",
                                                                   full=True),
                  obj("box1", "box", (0, 0)), obj("cup2", "cup", on="box1"),
                  obj("box2", "box", (2, 2)), holding="box2", tcp_cell=(2, 2, 2))
    message = scene.to_message(seq=3)
    wire.validate(message, wire.SCENE_STATE, "cbgo/scene/state")
    drawer = next(o for o in message["objects"] if o["name"] == "drawer1")
    assert drawer["contains"] == ["cup1"] and drawer["open"] and drawer["opening"] == 1.0
    assert Scene.from_dict(message) == scene


def test_from_dict_fills_in_defaults_containment_and_the_opening():
    scene = Scene.from_dict({"objects": [
        {"name": "d", "type": "drawer", "position": [0.68, 0.0, 0.055], "size": 0.11,
         "opening": 0.7, "contains": ["c"]},
        {"name": "c", "type": "cup", "position": [0.6, 0.0, 0.04], "size": 0.06}],
        "robot": {"tcp": [0.4, 0.0, 0.3], "gripper_open": True, "holding": None}})
    assert scene.get("d").open and scene.get("c").inside == "d" and not scene.get("c").full
    assert scene.problems() == []


def test_the_state_bit_is_full_cup_open_drawer_and_blocked_box():
    scene = world(obj("cup1", "cup", (0, 0), full=True), obj("cup2", "cup", (0, 1)),
                  obj("drawer1", "drawer", (3, 0), open=True), obj("drawer2", "drawer", (3, 2)),
                  obj("box1", "box", (1, 1)), obj("cup3", "cup", on="box1"),
                  obj("box2", "box", (1, 2)), obj("box3", "box", inside="drawer1"))
    bits = {n: scene.state_bit(n) for n in scene.names}
    assert bits == {"cup1": 1, "cup2": 0, "drawer1": 1, "drawer2": 0, "box1": 1, "cup3": 0,
                    "box2": 0, "box3": 1}


def test_stacked_contained_and_held_objects_rest_where_their_support_puts_them():
    scene = world(obj("drawer1", "drawer", (3, 1)), obj("box1", "box", on="drawer1"),
                  obj("cup1", "cup", on="box1"), obj("box2", "box", inside="drawer1"),
                  obj("cup2", "cup", (0, 0)), holding="cup2", tcp_cell=(0, 0, 2))
    d, b1, c1, b2 = (scene.get(n) for n in ("drawer1", "box1", "cup1", "box2"))
    assert b1.position[2] == pytest.approx(d.position[2] + d.size / 2 + b1.size / 2)
    assert c1.position[2] == pytest.approx(b1.position[2] + b1.size / 2 + c1.size / 2)
    assert b2.position[:2] == d.position[:2] and b2.position[2] < d.position[2]
    assert scene.get("cup2").position == scene.robot.tcp
    assert scene.is_hidden("box2") and not scene.is_free("box2")
    assert scene.tower_below("cup1") == ["box1", "drawer1"] and scene.stack_level("cup1") == 2


@pytest.mark.parametrize("change, problem", [
    (lambda s: s.objects.append(obj("cup1", "cup", (2, 2))), "used more than once"),
    (lambda s: setattr(s.get("box1"), "on", "cup1"), "only boxes and drawers carry"),
    (lambda s: setattr(s.get("cup1"), "on", "box1"), "all stand on box1"),
    (lambda s: setattr(s.get("box1"), "on", "box2"), "cycle"),
    (lambda s: setattr(s.get("drawer1"), "on", "box1"), "must stand on the table"),
    (lambda s: setattr(s.get("cup2"), "inside", "box1"), "not a drawer here"),
    (lambda s: setattr(s.robot, "holding", "cup9"), "not in the scene"),
    (lambda s: setattr(s.robot, "holding", "drawer1"), "not graspable"),
    (lambda s: setattr(s.robot, "holding", "cup1"), "open gripper"),
    (lambda s: setattr(s.get("box1"), "type", "plate"), "unknown type"),
])
def test_inconsistent_scenes_are_reported_in_a_sentence(change, problem):
    scene = world(obj("box1", "box", (0, 0)), obj("box2", "box", on="box1"),
                  obj("cup1", "cup", (1, 1)), obj("cup2", "cup", (1, 2)),
                  obj("drawer1", "drawer", (3, 0)))
    change(scene)
    assert any(problem in p for p in scene.problems()), scene.problems()


def test_a_drawer_over_capacity_is_reported():
    scene = world(obj("drawer1", "drawer", (3, 0), open=True), obj("cup1", "cup",
                                                                   inside="drawer1"))
    scene.objects.append(obj("cup2", "cup", inside="drawer1"))
    assert any("capacity" in p for p in scene.problems())


def test_get_names_the_known_objects_when_one_is_missing():
    with pytest.raises(KeyError, match="cup1"):
        Scene([obj("cup1", "cup")], Robot()).get("cup7")


def test_a_generated_scene_survives_the_wire_and_back():
    scene = random_scene(11)
    decoded = wire.decode(wire.encode(scene.to_message()))
    assert Scene.from_dict(decoded) == scene
