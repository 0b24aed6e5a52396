"""check_consistent: the contradictions a robot must never publish after a failure."""

from world_scenes import obj, world

from cbgo.world import check_consistent, failure_error, random_scene


def _body(scene):
    return scene.to_message(seq=1)


def _objects(body):
    return {o["name"]: o for o in body["objects"]}


def test_scenes_of_the_world_model_are_consistent():
    for seed in range(200):
        assert check_consistent(random_scene(seed)) == [], seed


def test_an_object_held_and_inside_a_drawer_at_once_is_a_contradiction():
    scene = world(obj("drawer1", "drawer", (3, 1), open=True), obj("cup1", "cup"),
                  holding="cup1", tcp_cell=(3, 1, 0))
    body = _body(scene)
    _objects(body)["cup1"]["inside"] = "drawer1"
    _objects(body)["drawer1"]["contains"] = ["cup1"]
    assert check_consistent(body) == [
        "the robot holds cup1, which also rests on or inside another object"]


def test_inside_and_contains_must_agree_both_ways():
    scene = world(obj("drawer1", "drawer", (3, 1), open=True),
                  obj("cup1", "cup", inside="drawer1"), obj("box1", "box", (0, 0)))
    body = _body(scene)
    assert check_consistent(body) == []
    _objects(body)["drawer1"]["contains"] = []
    assert check_consistent(body) == [
        "cup1 is inside drawer1, but drawer1 does not list it in contains"]
    _objects(body)["drawer1"]["contains"] = ["cup1", "box1"]
    assert check_consistent(body) == ["drawer1 holds 2 objects; its capacity is 1",
                                      "drawer1 contains box1, but box1 is inside nothing"]
    _objects(body)["drawer1"]["contains"] = ["cup1", "cup9"]
    assert check_consistent(body) == ["drawer1 contains cup9, which is not in the scene"]


def test_a_held_object_far_from_the_gripper_is_a_contradiction():
    scene = world(obj("cup1", "cup"), holding="cup1", tcp_cell=(1, 1, 2))
    body = _body(scene)
    assert check_consistent(body) == []
    _objects(body)["cup1"]["position"] = [0.44, -0.06, 0.03]  # on the table, still "held"
    assert check_consistent(body) == ["the robot holds cup1, but cup1 is 0.23 m from the TCP"]


def test_an_object_on_the_table_must_lie_on_it_lying_down_is_fine_floating_is_not():
    scene = world(obj("cup1", "cup"), obj("box1", "box", (2, 2)))
    body = _body(scene)
    _objects(body)["cup1"]["position"][2] = 0.024  # fallen over: lower than upright
    assert check_consistent(body) == []
    _objects(body)["box1"]["position"][2] = 0.2  # on something unnamed, or in mid-air
    assert check_consistent(body) == [
        "box1 is reported on the table, but its centre is 0.20 m high (it stands on something "
        "unnamed or is falling)"]



def test_a_failure_error_names_the_contradictions_and_leaves_a_consistent_scene_alone():
    scene = world(obj("drawer1", "drawer", (3, 1), open=True), obj("cup1", "cup"),
                  holding="cup1", tcp_cell=(3, 1, 0))
    body = _body(scene)
    assert failure_error("stuck", body) == ("stuck", [])
    _objects(body)["cup1"]["inside"] = "drawer1"
    _objects(body)["drawer1"]["contains"] = ["cup1"]
    error, problems = failure_error("stuck", body)
    assert problems == check_consistent(body) and problems
    assert error == "stuck; the scene after it is inconsistent: " + "; ".join(problems)
