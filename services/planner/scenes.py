"""The scene the behaviour tree checks preconditions against.

Rules:
- the newest scene wins, by its ``ts`` (the publisher's clock): a ``cbgo/scene/state`` that
  arrives after the robot's reply but was taken before it is ignored;
- while a robot action is in flight (`hold`), observations are set aside: the tree must not
  react to the half-open drawer of its own action. The action's reply carries the scene after
  it; on `release`, a set-aside observation newer than that reply is taken;
- messages are parsed into a `cbgo.world.Scene` only when the tree asks (`scene`);
- `last_held` remembers the object the robot held most recently (for the pour and fetch rules).
"""

from __future__ import annotations

from typing import Any

from cbgo.world import Scene


class SceneSource:
    """The latest trusted scene; see the module docstring.

    Args:
        scene: an initial scene (tests, predictions), or None to wait for observations.
    """

    def __init__(self, scene: Scene | None = None):
        self._message: dict[str, Any] | None = None
        self._ts = float("-inf")
        self._parsed: Scene | None = scene
        self._held_back: dict[str, Any] | None = None
        self.busy = False
        self.version = 0
        self.last_held: str | None = scene.robot.holding if scene is not None else None

    @property
    def ready(self) -> bool:
        """Whether any scene is known."""
        return self._parsed is not None or self._message is not None

    @property
    def ts(self) -> float:
        """Time stamp of the newest scene taken (-inf before the first)."""
        return self._ts

    def scene(self) -> Scene:
        """Returns the current scene (do not mutate it).

        Raises:
            LookupError: no scene is known yet.
        """
        if self._parsed is None:
            if self._message is None:
                raise LookupError("no cbgo/scene/state received yet")
            self._parsed = Scene.from_dict(self._message)
        return self._parsed

    def observe(self, message: dict[str, Any]) -> bool:
        """Takes a ``cbgo/scene/state`` message; returns whether it became the current scene."""
        if self.busy:
            if self._held_back is None or message["ts"] >= self._held_back["ts"]:
                self._held_back = message
            return False
        return self._take(message)

    def hold(self) -> None:
        """Called when a robot action is sent: observations wait until its reply."""
        self.busy = True

    def release(self, reply_scene: dict[str, Any] | None = None) -> None:
        """Called when the action ended: takes its reply's scene, then newer observations."""
        self.busy = False
        if reply_scene is not None:
            self._take(reply_scene, force=True)
        held, self._held_back = self._held_back, None
        if held is not None:
            self._take(held)

    def _take(self, message: dict[str, Any], force: bool = False) -> bool:
        ts = float(message.get("ts", 0.0))
        if not force and ts < self._ts:
            return False
        self._message, self._ts, self._parsed = message, max(ts, self._ts), None
        self.version += 1
        holding = (message.get("robot") or {}).get("holding")
        if holding is not None:
            self.last_held = holding
        return True
