"""Scripted demo sessions: a scene, simulated users, and steps that say how each must end.

A session file (YAML or JSON; the bundled one is ``sessions/paper.yaml``)::

    name: paper
    seed: 11                     # the simulated users' randomness derives from it
    users:                       # cbgo.simuser styles, by user name
      user1: {side: right}
    scene: {objects: [...], robot: {...}}   # a cbgo/sim/reset scene
    steps:
      - say: user1 looks at the full cup and grabs      # printed in the timeline
        user: user1
        gaze: cup1               # object name, [x, y, z] in the robot base frame, or null
        gestures: [grab]         # as in scenario files (cbgo.simuser.scenario)
        expect: {status: accepted, action: pick_up, object: cup1}
        goal: {holding: cup1}    # what must be true of the world afterwards
        ask: false               # true: the intent must be asked back first (see below)

``expect`` is checked against the episode's ``cbgo/intent`` (``status`` is required; ``action``
and ``object`` when given). An accepted intent must also end in a successful plan. When the
intent service asks back (``cbgo/intent/clarify``) where an accepted intent is expected, the
simulated user answers truthfully with gestures: a swipe right steps the highlight to the
expected candidate, a thumbs-up confirms it; the confirmed intent is then the step's.
``ask: true`` requires that question (the step shows the asking back). ``goal``
is checked on the world after the step:

- ``holding: NAME | null``: what the gripper holds;
- ``full: {CUP: bool}``, ``open: {DRAWER: bool}``, ``inside: {NAME: DRAWER | null}``,
  ``on: {NAME: SUPPORT | null}``: object states and relations;
- ``moved: left | right | up | down``: the TCP moved that way (as the person sees it) since the
  step began;
- ``unchanged: true``: the world is as it was before the step (nothing executed).

Unknown keys are errors, with the step and the field, so a typo cannot change a session.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from cbgo.errors import ConfigError
from cbgo.simuser.scenario import parse_scenario
from cbgo.world import Scene

BUNDLED = Path(__file__).parent / "sessions"
STATUSES = ("accepted", "low_confidence", "infeasible")
RELATIONS = ("full", "open", "inside", "on")
# The direction each move takes the TCP, as (axis, sign) in the robot base frame; the person
# faces the robot along -x, so their left is -y (cbgo.world.actions.MOVES).
MOVED = {"left": (1, -1), "right": (1, 1), "up": (2, 1), "down": (2, -1)}
MOVE_TOLERANCE_M = 0.03


@dataclass
class Expect:
    """How the intent of a step must come out."""

    status: str
    action: str | None = None
    object: str | None = None

    def mismatch(self, intent: dict) -> str | None:
        """Returns how an intent differs from the expectation, or None when it matches."""
        for name in ("status", "action", "object"):
            want = getattr(self, name)
            if want is not None and intent.get(name) != want:
                return f"{name} is {intent.get(name)!r}, expected {want!r}"
        return None

    def label(self) -> str:
        """Returns e.g. ``pick_up(cup1)`` or ``low_confidence``."""
        if self.status != "accepted":
            return self.status
        return f"{self.action or '?'}({self.object or ''})"


@dataclass
class Step:
    """One scripted episode and how it must end."""

    say: str
    user: str
    gestures: list[Any]
    expect: Expect
    goal: dict[str, Any]
    gaze: str | list[float] | None = None
    pause_s: float = 0.8
    ask: bool = False  # the intent must be asked back (and answered) before it is accepted

    def scenario(self, users: dict[str, Any], seed: int, name: str) -> dict[str, Any]:
        """Returns the inline scenario for ``@ctl/leap-bridge/play``: this step's episode."""
        episode = {"user": self.user, "gaze": self.gaze, "gestures": self.gestures,
                   "pause_s": self.pause_s}
        return {"name": name, "seed": seed, "users": {self.user: users[self.user]},
                "episodes": [episode]}


@dataclass
class Session:
    """A whole scripted demo session."""

    name: str
    seed: int
    users: dict[str, Any]
    scene: dict[str, Any]
    steps: list[Step] = field(default_factory=list)


def goal_failures(goal: dict[str, Any], before: dict[str, Any], after: dict[str, Any]
                  ) -> list[str]:
    """Returns what of a goal does not hold on the world `after` (empty: it holds).

    Args:
        goal: the step's goal.
        before: the scene/state message when the step began.
        after: the scene/state message now.
    """
    objects = {o["name"]: o for o in after["objects"]}
    out = []
    if "holding" in goal and after["robot"]["holding"] != goal["holding"]:
        out.append(f"the robot holds {after['robot']['holding']!r}, expected "
                   f"{goal['holding']!r}")
    for relation in RELATIONS:
        for name, want in goal.get(relation, {}).items():
            got = objects.get(name, {}).get(relation)
            if got != want:
                out.append(f"{name}.{relation} is {got!r}, expected {want!r}")
    if "moved" in goal:
        axis, sign = MOVED[goal["moved"]]
        delta = after["robot"]["tcp"][axis] - before["robot"]["tcp"][axis]
        if delta * sign < MOVE_TOLERANCE_M:
            out.append(f"the TCP moved {delta:+.3f} m along {'xyz'[axis]}, expected "
                       f"{goal['moved']}")
    if goal.get("unchanged") and world_of(before) != world_of(after):
        out.append("the world changed, expected nothing to be executed")
    return out


def world_of(scene: dict[str, Any]) -> tuple:
    """Returns the symbolic facts of a scene message (relations, states, held object)."""
    facts = tuple(sorted((o["name"], o.get("full"), o.get("open"), o.get("inside"), o.get("on"))
                         for o in scene["objects"]))
    return facts, scene["robot"]["holding"]


# ============================================================================ loading


def load_session(name_or_path: str) -> Session:
    """Loads a bundled session by name (``paper``) or a session file.

    Raises:
        ConfigError: the file is missing or malformed (the message names the step and field).
    """
    path = Path(name_or_path)
    if not path.exists():
        path = BUNDLED / f"{name_or_path}.yaml"
    if not path.exists():
        bundled = ", ".join(sorted(p.stem for p in BUNDLED.glob("*.yaml")))
        raise ConfigError(f"no session file {name_or_path!r} (bundled sessions: {bundled})")
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise ConfigError(f"{path}: {e}") from None
    return parse_session(data, str(path))


def parse_session(data: Any, source: str = "session") -> Session:
    """Returns a validated Session from parsed YAML/JSON data."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping")
    _only(data, {"name", "seed", "users", "scene", "steps"}, source)
    users = data.get("users") or {}
    steps = [_step(s, users, f"{source}: steps[{i}]") for i, s in enumerate(data.get("steps")
                                                                            or [])]
    if not steps:
        raise ConfigError(f"{source}: needs a non-empty 'steps' list")
    scene = data.get("scene")
    try:
        problems = Scene.from_dict(scene).problems() if isinstance(scene, dict) else [
            "missing"]
    except (KeyError, TypeError, ValueError) as e:
        problems = [str(e)]
    if problems:
        raise ConfigError(f"{source}: scene: {'; '.join(problems)}")
    session = Session(str(data.get("name", Path(source).stem)), int(data.get("seed", 0)),
                      users, scene, steps)
    # The simulated-user side of every step is checked by the scenario parser itself.
    for i, step in enumerate(steps):
        parse_scenario(step.scenario(users, session.seed, session.name), f"{source}: steps[{i}]")
    return session


def _step(data: Any, users: dict[str, Any], where: str) -> Step:
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping")
    _only(data, {"say", "user", "gaze", "gestures", "expect", "goal", "pause_s", "ask"}, where)
    for required in ("user", "gestures", "expect", "goal"):
        if required not in data:
            raise ConfigError(f"{where}: missing {required!r}")
    if data["user"] not in users:
        raise ConfigError(f"{where}: user {data['user']!r} is not in users {sorted(users)}")
    expect = data["expect"]
    if not isinstance(expect, dict):
        raise ConfigError(f"{where}.expect: expected a mapping")
    _only(expect, {"status", "action", "object"}, f"{where}.expect")
    if expect.get("status") not in STATUSES:
        raise ConfigError(f"{where}.expect.status: {expect.get('status')!r} is not one of "
                          f"{', '.join(STATUSES)}")
    _check_goal(data["goal"], f"{where}.goal")
    ask = data.get("ask", False)
    if not isinstance(ask, bool):
        raise ConfigError(f"{where}.ask: expected true or false, got {ask!r}")
    if ask and (expect.get("status") != "accepted" or not expect.get("action")):
        raise ConfigError(f"{where}.ask: a question is answered with the expected intent; "
                          "give expect: {status: accepted, action: ..., object: ...}")
    return Step(str(data.get("say", "")), data["user"], list(data["gestures"]), Expect(**expect),
                dict(data["goal"]), data.get("gaze"), float(data.get("pause_s", 0.8)), ask)


def _check_goal(goal: Any, where: str) -> None:
    if not isinstance(goal, dict) or not goal:
        raise ConfigError(f"{where}: expected a non-empty mapping")
    _only(goal, {"holding", "moved", "unchanged", *RELATIONS}, where)
    for relation in RELATIONS:
        if relation in goal and not isinstance(goal[relation], dict):
            raise ConfigError(f"{where}.{relation}: expected a mapping NAME: VALUE")
    if "moved" in goal and goal["moved"] not in MOVED:
        raise ConfigError(f"{where}.moved: {goal['moved']!r} is not one of {', '.join(MOVED)}")


def _only(data: dict, known: set[str], where: str) -> None:
    unknown = sorted(set(data) - known)
    if unknown:
        raise ConfigError(f"{where}: unknown field(s) {unknown}; known: {sorted(known)}")
