"""The eleven actions as motions of a real arm and gripper: pure planning, nothing moves here.

`plan_action(action, object, params, scene)` checks the world model's preconditions
(`cbgo.world.failures`, room for the gripper at a move's goal included) and returns a `Plan`: the
steps in the table frame and the scene the world model expects after them (`cbgo.world.apply`).
Targets come from the world model (a move's goal cell, the column of ``place``, where a load
rests on its support or in a drawer); how the hand gets there is decided here:

- every approach is from above: up to `travel_z` (clear of every object's top), across, then
  straight down, slowly, to the grasp or release pose;
- a grasp closes on the object's size (`Grasp`): the gripper reports whether it holds something
  of that width, and a grasp that closes on nothing is a failure, not a success; after the
  lift of a grasped object and the pull or push of a handle the gap is measured again
  (`Holding`): a load or handle that slipped out of the fingers fails the action;
- a release lowers the load until its bottom is `RELEASE_GAP` above its support, opens, leaves
  straight up;
- ``open``/``close`` grasp the drawer's handle (`HANDLE_WIDTH`) and pull it out (towards the
  robot, or away from it for a cabinet nearer than 0.50 m: `cbgo.world.drawer_direction`) or
  push it back, by the tray's travel (`cbgo.world.workspace.DRAWER_TRAVEL_PER_SIZE`);
- ``pour`` carries the held cup over the target, tilts it about the fingers' closing axis by
  ``params.angle_deg`` (default 90), holds, and tilts it back.

Every point of a plan is then checked against the safety box (`frames.SafetyBox`) by the caller
before anything is sent.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from cbgo import world
from cbgo.world import DEFAULT_GRID, Grid, Scene, drawer_direction
from cbgo.world.actions import GRASP_DEPTH
from cbgo.world.workspace import DRAWER_HANDLE_OUT, DRAWER_TRAVEL_PER_SIZE

GRIPPER_MAX = 0.08  # m between the Franka Hand's fingers fully open (its datasheet)
OPEN_MARGIN = 0.012  # m between each open finger and the object it is about to close on
HANDLE_WIDTH = 0.02  # m, the drawer handle's thickness between the fingers
HANDLE_Z_FRACTION = 0.5  # the handle's height as a fraction of the cabinet's size
TRAVEL_CLEARANCE = 0.08  # m between the hand's fingertips and the tallest object when crossing
RELEASE_GAP = 0.003  # m between a load's bottom and its support when the fingers open
POUR_ANGLES = (30.0, 135.0)  # degrees a pour may tilt the cup (params.angle_deg)
POUR_OVER = 0.03  # m the held cup's bottom passes above the target cup's rim while pouring
POUR_HOLD_S = 0.5  # s the tilted cup is held over the target


@dataclass(frozen=True)
class Move:
    """Move the TCP to a table-frame point, hand top-down or tilted about its closing axis."""

    position: tuple[float, float, float]
    tilt_deg: float = 0.0
    slow: bool = False  # near objects: at a fraction of the speed


@dataclass(frozen=True)
class Gripper:
    """Open (or close without force) the fingers to a width, m."""

    width: float


@dataclass(frozen=True)
class Grasp:
    """Close on `what`, expected `width` m wide; failing to hold it fails the action."""

    width: float
    what: str


@dataclass(frozen=True)
class Holding:
    """Check that the fingers still hold `what`, `width` m wide: it may have slipped out."""

    width: float
    what: str


@dataclass(frozen=True)
class Pause:
    """Hold still for `seconds`."""

    seconds: float


Step = Move | Gripper | Grasp | Holding | Pause


@dataclass
class Plan:
    """The steps of one action and the scene the world model expects after them."""

    steps: list[Step]
    after: Scene
    touched: list[str] = field(default_factory=list)  # objects the action handles

    def points(self) -> list[tuple[float, float, float]]:
        """Returns every TCP point the plan commands, in order."""
        return [s.position for s in self.steps if isinstance(s, Move)]

    def describe(self) -> list[dict[str, Any]]:
        """Returns the steps as plain data (for a dry run's reply and the log)."""
        out: list[dict[str, Any]] = []
        for step in self.steps:
            if isinstance(step, Move):
                out.append({"move": [round(v, 4) for v in step.position],
                            "tilt_deg": step.tilt_deg, "slow": step.slow})
            elif isinstance(step, Grasp):
                out.append({"grasp": step.what, "width": round(step.width, 4)})
            elif isinstance(step, Holding):
                out.append({"holding": step.what, "width": round(step.width, 4)})
            elif isinstance(step, Gripper):
                out.append({"gripper": round(step.width, 4)})
            else:
                out.append({"pause": step.seconds})
        return out


class PlanRefused(ValueError):
    """The action cannot be planned: a precondition fails or a parameter is out of range."""


def plan_action(action: str, obj: str | None, params: Mapping[str, Any] | None, scene: Scene,
                grid: Grid = DEFAULT_GRID) -> Plan:
    """Returns the plan of one action from the arm's current TCP (``scene.robot.tcp``).

    Raises:
        PlanRefused: the world model forbids it, or a parameter is out of range.
    """
    params = {**world.actions.DEFAULT_PARAMS.get(action, {}), **(params or {})}
    found = world.failures(action, obj, scene, params, grid)
    if found:
        raise PlanRefused("; ".join(f.message for f in found))
    if action in ("open", "close") and scene.robot.holding is not None:
        raise PlanRefused(f"the gripper holds {scene.robot.holding}; it must be empty to grasp "
                          "a handle")
    after = world.apply(action, obj, params, scene, grid)
    if action in world.MOVES:
        return Plan([Move(tuple(after.robot.tcp))], after)
    builders = {"pick_up": _pick_up, "place": _release, "put_on": _release,
                "put_into": _release, "pour": _pour, "open": _drawer, "close": _drawer}
    steps, touched = builders[action](action, obj, params, scene, after)
    return Plan(steps, after, touched)


def travel_z(scene: Scene, held: str | None, grid: Grid = DEFAULT_GRID) -> float:
    """Returns the TCP height at which the hand, and what it holds, cross over every object."""
    tops = [float(o.position[2]) + o.size / 2 for o in scene.objects if o.name != held]
    hang = 0.0
    if held is not None:
        load = scene.get(held)
        hang = load.size - _grip_depth(load.size)
    top_level = grid.position((0, 0, grid.shape[2] - 1))[2]
    return round(max([top_level] + [t + hang + TRAVEL_CLEARANCE for t in tops]), 4)


def _grip_depth(size: float) -> float:
    """Returns how far under an object's top the TCP holds it (the world model's rule)."""
    return min(GRASP_DEPTH, size / 2)


def _pre_width(size: float) -> float:
    return min(GRIPPER_MAX, size + 2 * OPEN_MARGIN)


def _from_above(start, goal, height: float) -> list[Step]:
    """Returns up to `height` over `start`, across at that height, and slowly down to `goal`."""
    x, y, z = (float(v) for v in start)
    gx, gy, gz = (float(v) for v in goal)
    steps: list[Step] = []
    if z < height - 1e-4:
        steps.append(Move((x, y, height)))
    steps.append(Move((gx, gy, height)))
    steps.append(Move((gx, gy, gz), slow=True))
    return steps


def _pick_up(_action, obj: str, _params, scene: Scene, _after) -> tuple[list[Step], list[str]]:
    target = scene.get(obj)
    x, y, z = (float(v) for v in target.position)
    grasp = (x, y, z + target.size / 2 - _grip_depth(target.size))
    height = travel_z(scene, None)
    lift = travel_z(scene, obj)
    steps = [Gripper(_pre_width(target.size)),
             *_from_above(scene.robot.tcp, grasp, height),
             Grasp(target.size, obj),
             Move((x, y, lift), slow=True),
             Holding(target.size, obj)]
    return steps, [obj, *scene.tower_above(obj)]


def _release(_action, _obj, _params, scene: Scene, after: Scene) -> tuple[list[Step], list[str]]:
    held = scene.robot.holding
    load = after.get(held)
    x, y, z = (float(v) for v in load.position)
    release = (x, y, z + load.size / 2 - _grip_depth(load.size) + RELEASE_GAP)
    height = travel_z(scene, held)
    steps = [*_from_above(scene.robot.tcp, release, height),
             Gripper(_pre_width(load.size)),
             Move((x, y, travel_z(after, None)), slow=True)]
    return steps, [held]


def _pour(_action, obj: str, params, scene: Scene, _after) -> tuple[list[Step], list[str]]:
    angle = params.get("angle_deg")
    if type(angle) not in (int, float) or not POUR_ANGLES[0] <= angle <= POUR_ANGLES[1]:
        raise PlanRefused(f"angle_deg must be a number of degrees in {POUR_ANGLES[0]:g}.."
                          f"{POUR_ANGLES[1]:g}, got {angle!r}")
    held = scene.get(scene.robot.holding)
    target = scene.get(obj)
    tx, ty, tz = (float(v) for v in target.position)
    rim = tz + target.size / 2
    # the held cup's centre beside the target's, its lip over the target's opening
    over = (tx + (held.size + target.size) / 4,
            ty, rim + POUR_OVER + held.size - _grip_depth(held.size))
    height = max(travel_z(scene, held.name), over[2])
    steps = [*_from_above(scene.robot.tcp, over, height),
             Move(over, tilt_deg=float(angle), slow=True),
             Pause(POUR_HOLD_S),
             Move(over, tilt_deg=0.0, slow=True),
             Move((over[0], over[1], height))]
    return steps, [held.name, obj]


def handle_point(scene: Scene, drawer: str, opened: bool) -> tuple[float, float, float]:
    """Returns where the TCP grasps a drawer's handle, the drawer open or closed."""
    item = scene.get(drawer)
    x, y, _ = (float(v) for v in item.position)
    way = drawer_direction(x)  # the way it opens along x: towards the robot or away
    front = x + way * (item.size / 2 + DRAWER_HANDLE_OUT)
    if opened:
        front += way * DRAWER_TRAVEL_PER_SIZE * item.size
    return front, y, HANDLE_Z_FRACTION * item.size


def _drawer(action: str, obj: str, _params, scene: Scene, _after) -> tuple[list[Step], list[str]]:
    opening = action == "open"
    start = handle_point(scene, obj, opened=not opening)
    end = handle_point(scene, obj, opened=opening)
    height = travel_z(scene, None)
    handle = f"the handle of {obj}"
    steps = [Gripper(_pre_width(HANDLE_WIDTH)),
             *_from_above(scene.robot.tcp, start, height),
             Grasp(HANDLE_WIDTH, handle),
             Move(end, slow=True),
             Holding(HANDLE_WIDTH, handle),
             Gripper(_pre_width(HANDLE_WIDTH)),
             Move((end[0], end[1], height), slow=True)]
    return steps, [obj, *scene.contents(obj)]
