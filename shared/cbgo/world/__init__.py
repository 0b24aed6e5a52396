"""The symbolic world model shared by intent, planner and the dry robot.

- `cbgo.world.grid`: the 4×4×4 workspace grid in front of the robot (`Grid`, `DEFAULT_GRID`);
- `cbgo.world.scene`: `Scene`, `SceneObject`, `Robot`, to and from the contract's scene dict;
  which way a drawer opens (`drawer_direction`);
- `cbgo.world.actions`: preconditions (`failures`, `check`, `feasible`, `candidates`; room for
  the gripper at a move's goal, `gripper_room`) and symbolic effects (`apply`) of the eleven
  actions;
- `cbgo.world.generate`: random valid scenes as the paper samples them (`paper_scene`, its whole
  distribution; `random_scene`, drawers in the back row, the intent datasets');
- `cbgo.world.files`: scene files in JSON or YAML (`read_scene_file`);
- `cbgo.world.workspace`: the workspace of the contract (`workspace_info`, the ``cbgo/sim/info``
  answer) and whether a scene fits in it (`workspace_problems`; `reset_refusal`, the
  judgement of ``cbgo/sim/reset``);
- `cbgo.world.consistency`: whether a reported scene can be the truth (`check_consistent`,
  `failure_error`).

Pure Python, NumPy and YAML: no Zenoh, no torch.
"""

from cbgo.world.actions import (
    MOVES,
    OBJECT_AGNOSTIC,
    Failure,
    InfeasibleAction,
    apply,
    candidates,
    check,
    failures,
    feasible,
    gripper_room,
)
from cbgo.world.consistency import check_consistent, failure_error
from cbgo.world.files import read_scene_file
from cbgo.world.generate import paper_scene, random_scene
from cbgo.world.grid import DEFAULT_GRID, Grid
from cbgo.world.scene import Robot, Scene, SceneObject, drawer_direction
from cbgo.world.workspace import (
    reset_refusal,
    table_area,
    workspace_info,
    workspace_problems,
)

__all__ = [
    "DEFAULT_GRID", "MOVES", "OBJECT_AGNOSTIC", "Failure", "Grid", "InfeasibleAction", "Robot",
    "Scene", "SceneObject", "apply", "candidates", "check", "check_consistent", "drawer_direction",
    "failure_error", "failures", "feasible", "gripper_room", "paper_scene", "random_scene",
    "read_scene_file", "reset_refusal", "table_area", "workspace_info", "workspace_problems",
]
