"""Fixtures of the mujoco-sim tests: the fixed scene and one run of every action on it."""

import json
from pathlib import Path

import pytest

SCENES = Path(__file__).parents[2] / "artifacts" / "scenes"

# Every action once, on the fixed scene, in an order that makes each feasible.
SEQUENCE = [
    ("open", "drawer1", {}),
    ("pick_up", "cup1", {}),
    ("move_up", None, {}),
    ("move_right", None, {}),
    ("move_down", None, {}),
    ("move_left", None, {}),
    ("pour", "cup2", {}),
    ("put_into", "drawer1", {}),
    ("close", "drawer1", {}),
    ("pick_up", "box1", {}),
    ("put_on", "box2", {}),
    ("pick_up", "cup2", {}),
    ("place", None, {}),
]


def read_scene(name: str) -> dict:
    """Returns a scene file of tests/artifacts/scenes."""
    return json.loads((SCENES / f"{name}.json").read_text())


@pytest.fixture
def fixed_scene():
    """The fixed test scene: two cups (cup1 full), two boxes, a closed drawer."""
    return read_scene("fixed")


@pytest.fixture
def scene_file():
    """Returns a function that reads a scene of tests/artifacts/scenes by name."""
    return read_scene


@pytest.fixture
def sequence():
    """The actions of `sequence_run`, in order."""
    return list(SEQUENCE)


@pytest.fixture(scope="module")
def sequence_run():
    """Runs `SEQUENCE` once on the fixed scene; yields [(step, outcome, scene after, tcp
    before, tcp after)]."""
    from cbgo.services.mujoco_sim import observe, scenes
    from cbgo.services.mujoco_sim.skills import Robot

    loaded = scenes.load(read_scene("fixed"))
    robot = Robot(loaded.sim)
    out = []
    for step in SEQUENCE:
        before = list(loaded.sim.tcp()[0])
        outcome = robot.execute(*step)
        out.append((step, outcome, observe.scene_state(loaded.sim, 0), before,
                    list(loaded.sim.tcp()[0])))
    return out
