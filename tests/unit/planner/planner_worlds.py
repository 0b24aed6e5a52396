"""Scenes, intents and the symbolic robot (tests/fakes/symbolic_robot.py) for planner tests.

Imported by the tests as `planner_worlds` (this folder is on sys.path under pytest).
"""

import importlib.util
import sys
import time
from pathlib import Path

from cbgo.world import Scene


def _load_fake():
    path = Path(__file__).parents[2] / "fakes" / "symbolic_robot.py"
    spec = importlib.util.spec_from_file_location("symbolic_robot", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["symbolic_robot"] = module
    spec.loader.exec_module(module)
    return module


symbolic_robot = _load_fake()
FakeRobot = symbolic_robot.FakeRobot

# grid columns: x = 0.32 + 0.12 i (i = 0 nearest the robot), y = -0.18 + 0.12 j
X = [0.32, 0.44, 0.56, 0.68]
Y = [-0.18, -0.06, 0.06, 0.18]


def cup(name, i, j, full=False, on=None, inside=None):
    return {"name": name, "type": "cup", "position": [X[i], Y[j], 0.03], "size": 0.06,
            "full": full, "on": on, "inside": inside}


def box(name, i, j, on=None, inside=None):
    return {"name": name, "type": "box", "position": [X[i], Y[j], 0.025], "size": 0.05,
            "on": on, "inside": inside}


def drawer(name, j, open=False):
    """A drawer in the back row (its tray comes out over column (2, j))."""
    return {"name": name, "type": "drawer", "position": [X[3], Y[j], 0.055], "size": 0.11,
            "open": open}


def scene(*objects, holding=None, tcp=(0.44, 0.06, 0.26)):
    """A settled, consistent contract scene dict."""
    body = {"objects": list(objects),
            "robot": {"tcp": list(tcp), "gripper_open": holding is None, "holding": holding}}
    s = Scene.from_dict(body)
    assert s.problems() == [], s.problems()
    s.settle()
    return s.to_dict()


def intent(action, obj=None, status="accepted", params=None, p_object=None):
    """A valid cbgo/intent message."""
    p_object = p_object or ({obj: 0.9} if obj else {})
    return {"v": 1, "ts": time.time(), "episode": "ep-1", "action": action, "object": obj,
            "params": params or {}, "p_action": {action: 0.9} if action else {},
            "p_object": p_object, "confidence": 0.9, "status": status, "reason": "",
            "model": "test"}
