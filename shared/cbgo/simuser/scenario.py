"""Scenario files: what a simulated user does, as data (YAML or JSON).

A scenario is a list of episodes performed by named users::

    name: pick-and-pour
    seed: 7                      # everything random (styles, noise) derives from it
    users:
      user1: {hand_scale: 1.0, side: right, speed: 1.0}
      user2: {hand_scale: 0.9, side: left, speed: 1.3, tremor_mm: 1.5}
    episodes:
      - user: user1
        gaze: cup1               # an object name (resolved in cbgo/scene/state) ...
        gestures: [point, grab]
      - gaze: [0.5, -0.2, 0.1]   # ... or a point in the robot base frame (m), or null
        gestures:
          - swipe_down
          - {gesture: rotate, angle_deg: 90}
          - {gesture: grab, hold_s: 1.5}
        pause_s: 2.0             # no hand in view before the episode
        dropout_frames: 1        # drop the hand for N frames mid-episode (tracking loss)

Besides gestures, a step may be an **idle motion** (`IDLE_MOTIONS`): what a hand does between
gestures that is no gesture — ``drift`` (a slow wander), ``wobble`` (a small 2–4 Hz shake),
``reposition`` (a slow move elsewhere in the field), ``turn`` (a slow palm roll and back).

A static step may also give the pose as **finger curls** (``curls``: thumb, index, middle,
ring, pinky, each 0 straight .. 1 curled; ``spread`` how far apart, 1 relaxed): any hand pose,
so a gesture outside the vocabulary can be shown and taught without a sensor
(`cbgo.hands.poses.curl_pose`)::

      - gestures:
          - {gesture: horns, curls: [1, 0, 1, 1, 0], hold_s: 3}

Rules: gesture names are the wire vocabulary (8 static, 5 dynamic), or any name
(`CURL_NAME`) for a step with ``curls``; unknown keys are errors (a typo must not silently
change a scenario); every error names the episode and the field.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import yaml

from cbgo.errors import ConfigError
from cbgo.hands.poses import check_curls
from cbgo.wire import DYNAMIC_GESTURES, STATIC_GESTURES

BUNDLED = Path(__file__).parent / "scenarios"


IDLE_MOTIONS = ("drift", "wobble", "reposition", "turn")
CURL_NAME = re.compile(r"^[a-z][a-z0-9_]{0,31}$")  # a pose given by curls: any such name

@dataclass
class UserStyle:
    """How one simulated person moves; every field has a typical default."""

    hand_scale: float = 1.0     # hand size relative to an average adult hand
    side: str = "right"         # which hand gestures
    # Speed and amplitude default to the middle of the simulated population whose swipes match
    # real people's (the dynamic-gesture service's training range, 0.85-1.6 and 0.75-1.5:
    # `cbgo bench dynamic --realism DIR` compares them with the SHREC'17 train split), so a
    # default user swipes like a typical person: median peak speed 455 mm/s, real people's
    # 474 (`cbgo bench dynamic --realism DIR --ranges default`).
    speed: float = 1.2          # >1 moves faster (a swipe takes about user.SWIPE_S / speed)
    amplitude: float = 1.1      # size of strokes relative to user.STROKE_MM (160 mm)
    curvature: float = 0.08     # sideways bow of strokes, fraction of their length
    tremor_mm: float = 0.8      # physiological tremor amplitude (RMS, mm)
    pose_variation: float = 1.0  # spread of static poses relative to the calibrated spread
    hold_s: float = 0.9         # how long a static gesture is held
    gaze_noise_m: float = 0.01  # eye-tracking noise (m, per axis)
    # How real people stroke (fitted to the SHREC'17 train split's swipes; `cbgo bench dynamic
    # --realism DIR` compares): a swipe starts about half its length before the middle of the
    # field and crosses it, often without a rest, the palm rolling as it goes, and the hand
    # comes back a little more slowly, often without stopping at the end.
    stroke_lead: float = 0.55   # where a swipe starts: this fraction of it before the middle
    stroke_spread_mm: float = 30.0  # where that middle is: SD around the field centre, mm
    rest_s: float = 0.12        # longest rest before a stroke (drawn from 0..rest_s)
    swipe_roll_deg: float = 45.0  # spread (SD) of the palm roll during a horizontal swipe
    medial_roll_deg: float = 50.0  # mean palm roll (thumb side down) swiping across the body
    return_slowdown: float = 1.0  # the return's duration over the stroke's, per share of its
    # length it comes back (real returns are about as fast as their swipe: 0.91 of its speed)
    length_spread: float = 0.37  # SD of the log of a swipe's length around its way's length
    # (`user.SWIPE_WAY_LENGTH`; one real person's, ways pooled: 0.38 over the SHREC'17 train
    # split; 0: every swipe of a way as long)
    rotate_drift_mm: float = 20.0  # how far, at most, the palm drifts (any way) while it
    # turns: a rolling palm is seldom held in place

    def __post_init__(self):
        if self.side not in ("left", "right"):
            raise ConfigError(f"side {self.side!r} must be 'left' or 'right'")
        for name in ("hand_scale", "speed", "amplitude", "hold_s"):
            if not 0.05 < float(getattr(self, name)) < 20:
                raise ConfigError(f"{name}={getattr(self, name)} is out of range")
        for name in ("curvature", "tremor_mm", "pose_variation", "gaze_noise_m", "stroke_lead",
                     "stroke_spread_mm", "rest_s", "swipe_roll_deg", "medial_roll_deg",
                     "return_slowdown", "length_spread", "rotate_drift_mm"):
            if float(getattr(self, name)) < 0:
                raise ConfigError(f"{name}={getattr(self, name)} must not be negative")


@dataclass
class GestureStep:
    """One gesture inside an episode, with its optional parameters."""

    gesture: str
    hold_s: float | None = None     # static: override the style's hold time
    angle_deg: float = 90.0         # rotate: palm roll angle
    aperture_mm: float | None = None  # pinch: thumb-index distance to show
    curls: list[float] | None = None  # static: the pose as finger curls, thumb..pinky, 0..1
    spread: float = 1.0             # with curls: how far apart the fingers are (1: relaxed)

    @property
    def dynamic(self) -> bool:
        """True for a stroke (swipe or rotate), False for a held pose."""
        return self.gesture in DYNAMIC_GESTURES

    @property
    def idle(self) -> bool:
        """True for an idle motion (`IDLE_MOTIONS`): no gesture at all."""
        return self.gesture in IDLE_MOTIONS


@dataclass
class Episode:
    """One episode: the hand enters, performs its gestures, leaves."""

    gestures: list[GestureStep]
    user: str | None = None
    gaze: str | list[float] | None = None
    pause_s: float = 1.5
    preparation: bool = True
    dropout_frames: int = 0


@dataclass
class Scenario:
    """A whole scripted session."""

    episodes: list[Episode]
    users: dict[str, UserStyle] = field(default_factory=lambda: {"user1": UserStyle()})
    name: str = "scenario"
    seed: int = 0

    def user_of(self, episode: Episode) -> str:
        """Returns the user name performing an episode (the first user by default)."""
        return episode.user or next(iter(self.users))


def _build(cls, data: Any, where: str):
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping, got {type(data).__name__}")
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ConfigError(f"{where}: unknown field(s) {unknown}; known: {sorted(known)}")
    try:
        return cls(**data)
    except TypeError as e:
        raise ConfigError(f"{where}: {e}") from None
    except ConfigError as e:
        raise ConfigError(f"{where}: {e}") from None


def _step(item: Any, where: str) -> GestureStep:
    step = _build(GestureStep, {"gesture": item} if isinstance(item, str) else item, where)
    if step.curls is not None:
        return _curl_step(step, where)
    if step.spread != 1.0:
        raise ConfigError(f"{where}: spread shapes a pose given by curls; give curls too")
    if step.gesture not in STATIC_GESTURES + DYNAMIC_GESTURES + IDLE_MOTIONS:
        raise ConfigError(f"{where}: unknown gesture {step.gesture!r}; known: "
                          f"{', '.join(STATIC_GESTURES + DYNAMIC_GESTURES)} and the idle "
                          f"motions {', '.join(IDLE_MOTIONS)}; or any name with its "
                          "finger curls, e.g. {gesture: horns, curls: [1, 0, 1, 1, 0]}")
    return step


def _curl_step(step: GestureStep, where: str) -> GestureStep:
    """Checks a step that gives its pose as finger curls (a held pose of any name)."""
    if not isinstance(step.gesture, str) or not CURL_NAME.match(step.gesture) or (
            step.gesture in DYNAMIC_GESTURES + IDLE_MOTIONS):
        raise ConfigError(f"{where}: gesture {step.gesture!r} with curls: name the held pose "
                          "with 1-32 lower-case letters, digits and '_' (not a stroke or idle "
                          "motion)")
    try:
        step.curls = list(check_curls(step.curls, step.spread))
    except ValueError as e:
        raise ConfigError(f"{where}: {e}") from None
    return step


def _episode(data: Any, index: int, users: dict[str, UserStyle]) -> Episode:
    where = f"episodes[{index}]"
    if not isinstance(data, dict) or not data.get("gestures"):
        raise ConfigError(f"{where}: needs a non-empty 'gestures' list")
    steps = [_step(g, f"{where}.gestures[{i}]") for i, g in enumerate(data["gestures"])]
    episode = _build(Episode, {**data, "gestures": steps}, where)
    if episode.user is not None and episode.user not in users:
        raise ConfigError(f"{where}: user {episode.user!r} is not in users {sorted(users)}")
    gaze = episode.gaze
    if gaze is not None and not isinstance(gaze, str) and not (
            isinstance(gaze, list) and len(gaze) == 3
            and all(isinstance(v, (int, float)) for v in gaze)):
        raise ConfigError(f"{where}.gaze: expected an object name, [x, y, z] (m) or null")
    return episode


def hold_scenario(gesture: str, curls: list[float] | None = None, takes: int = 1,
                  hold_s: float = 3.0, spread: float = 1.0, pause_s: float = 1.0,
                  seed: int = 0) -> dict:
    """Returns scenario data in which the user holds one pose `takes` times.

    The hand enters, forms the pose, holds it `hold_s` seconds and leaves; `pause_s` seconds
    without a hand come before each take. What `cbgo gestures record NAME --simulate POSE`
    sends to leap-bridge's ``play``: a demonstration without a sensor.

    Args:
        gesture: a static gesture of the vocabulary, or any name with `curls`.
        curls: the pose as finger curls (thumb..pinky, 0 straight .. 1 curled), or None for
            the vocabulary gesture's own pose.
        takes: how many times the pose is shown.
        hold_s: how long each is held.
        spread: with curls: how far apart the fingers are (1: relaxed).
        pause_s: seconds without a hand before each take.
        seed: the scenario's seed (the person's hand and their renditions).

    Raises:
        ConfigError: the same errors as a scenario file with that step.
    """
    step: dict[str, Any] = {"gesture": gesture, "hold_s": float(hold_s)}
    if curls is not None:
        step.update(curls=[float(c) for c in curls], spread=float(spread))
    data = {"name": f"hold-{gesture}", "seed": int(seed),
            "episodes": [{"gestures": [step], "gaze": None, "pause_s": float(pause_s)}
                         for _ in range(max(1, int(takes)))]}
    parse_scenario(data, f"hold {gesture}")  # the caller's mistakes are found here
    return data


def parse_scenario(data: Any, source: str = "scenario") -> Scenario:
    """Returns the Scenario described by decoded YAML/JSON data.

    Raises:
        ConfigError: naming the episode and field at fault.
    """
    if not isinstance(data, dict) or not isinstance(data.get("episodes"), list):
        raise ConfigError(f"{source}: expected a mapping with an 'episodes' list")
    users_data = data.get("users") or {"user1": {}}
    if not isinstance(users_data, dict):
        raise ConfigError(f"{source}: 'users' must map user names to styles")
    users = {str(name): _build(UserStyle, style or {}, f"users.{name}")
             for name, style in users_data.items()}
    episodes = [_episode(e, i, users) for i, e in enumerate(data["episodes"])]
    if not episodes:
        raise ConfigError(f"{source}: no episodes")
    extra = sorted(set(data) - {"episodes", "users", "name", "seed"})
    if extra:
        raise ConfigError(f"{source}: unknown field(s) {extra}")
    return Scenario(episodes=episodes, users=users, name=str(data.get("name", source)),
                    seed=int(data.get("seed", 0)))


def load_scenario(path: str) -> Scenario:
    """Reads a scenario file; a bare name (``demo``) means a bundled scenario.

    Raises:
        ConfigError: missing or invalid file.
    """
    file = Path(path)
    if not file.exists() and (BUNDLED / f"{path}.yaml").exists():
        file = BUNDLED / f"{path}.yaml"
    try:
        text = file.read_text()
    except OSError as e:
        bundled = ", ".join(sorted(p.stem for p in BUNDLED.glob("*.yaml")))
        raise ConfigError(f"cannot read scenario {path!r} ({e}); bundled: {bundled}") from None
    try:
        data = json.loads(text) if file.suffix == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as e:
        raise ConfigError(f"scenario {path!r} is not valid YAML/JSON: {e}") from None
    return parse_scenario(data, str(path))
