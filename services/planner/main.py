"""planner: executes each accepted intent as a behaviour tree that repairs missing preconditions.

Behaviour (the contract is services/planner/README.md):
- an intent or a scene marked ``replayed: true`` (sent by ``cbgo replay``) is refused, counted
  and logged, unless ``--accept-replayed``: a recording must not move the robot by accident;
- ``cbgo/intent`` with status ``accepted`` is queued (others are counted and ignored); intents run
  one after the other, never preempting: a new intent waits until the running one ends (at most
  ``queue_size`` wait; beyond, the oldest waiting one is dropped with a failure status);
- each runs as the tree of `tree.create_tree`, checked against the newest ``cbgo/scene/state``
  (or the scene in the last ``robot/act`` reply), primitives sent one by one on
  ``cbgo/robot/act``;
- ``cbgo/plan/status`` is published after every tick that changed something;
- any message on ``cbgo/robot/stop`` aborts the running plan at once and drops waiting intents.

Threads: the tree lives on the service's event loop and is ticked by a timer (``tick_hz``), so
intents, scenes and ticks never race and FakeBus tests are deterministic. The one blocking call,
the ``robot/act`` query, runs on `RobotClient`'s worker thread; the tree polls its future.
``robot/stop`` is handled at once on Zenoh's thread: it halts the client (no primitive is sent
after it, even one a tick was about to send) and the next tick aborts the tree.
"""

from __future__ import annotations

import queue
import threading
import time
from collections import deque
from concurrent.futures import Future
from dataclasses import dataclass, field

from cbgo import keys, wire
from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError
from cbgo.logs import RateLimited
from cbgo.runtime import Context, Service, main_for
from cbgo.services.planner.plan import Plan
from cbgo.services.planner.scenes import SceneSource

FRESH_SCENE_S = 1.0  # how long an intent waits for a scene newer than itself


@dataclass
class PlannerSettings:
    """Settings of the planner (flags ``--tick-hz`` ... or env ``CBGO_TICK_HZ`` ...)."""

    tick_hz: float = field(default=20.0, metadata=_help(
        "how often the behaviour tree is ticked, Hz (1-200)"))
    act_timeout_s: float = field(default=120.0, metadata=_help(
        "how long one robot/act may take before it counts as failed, s"))
    max_repairs: int = field(default=8, metadata=_help(
        "repair actions one intent may add before its plan fails (0-50)"))
    queue_size: int = field(default=4, metadata=_help(
        "intents that may wait while one runs; beyond, the oldest waiting one is dropped"))
    scene_timeout_s: float = field(default=10.0, metadata=_help(
        "how long an intent waits for a first cbgo/scene/state before it fails, s"))
    check_first: bool = field(default=True, metadata=_help(
        "simulate each plan on the world model first; fail at once, without moving, if the "
        "model says it cannot succeed"))
    accept_replayed: bool = field(default=False, metadata=_help(
        "execute intents (and plan on scenes) marked replayed: true by `cbgo replay`; off, "
        "they are refused, counted in status plans.refused_replayed and logged"))

    def __post_init__(self):
        if not 1.0 <= self.tick_hz <= 200.0:
            raise ConfigError(f"tick_hz={self.tick_hz} must be within 1-200 Hz")
        if self.act_timeout_s <= 0:
            raise ConfigError(f"act_timeout_s={self.act_timeout_s} must be positive")
        if not 0 <= self.max_repairs <= 50:
            raise ConfigError(f"max_repairs={self.max_repairs} must be within 0-50")
        if not 1 <= self.queue_size <= 100:
            raise ConfigError(f"queue_size={self.queue_size} must be within 1-100")
        if self.scene_timeout_s <= 0:
            raise ConfigError(f"scene_timeout_s={self.scene_timeout_s} must be positive")


class RobotClient:
    """Sends ``robot/act`` queries one at a time, off the event loop.

    Args:
        ctx: the service context (its `query` blocks until the reply).
        timeout_s: the query timeout.
        inline: run each query at once on the caller's thread (tests).
    """

    def __init__(self, ctx: Context, timeout_s: float, inline: bool = False):
        self.ctx, self.timeout_s, self.inline = ctx, timeout_s, inline
        self.sent = 0
        self._lock = threading.Lock()
        self._halted = False
        self._jobs: queue.Queue = queue.Queue()
        self._thread: threading.Thread | None = None

    def send(self, action: str, obj: str | None, params: dict) -> Future:
        """Queues one primitive; the future resolves to the reply (``ok: false`` on errors)."""
        future: Future = Future()
        query = keys.ROBOT_ACT.message(action=action, object=obj, params=params)
        with self._lock:
            if self._halted:
                future.set_result(_failed("stopped"))
                return future
            self.sent += 1
            if not self.inline:
                self._start()
                self._jobs.put((future, query))
                return future
        future.set_running_or_notify_cancel()
        future.set_result(self._query(query))
        return future

    def cancel(self, future: Future) -> None:
        """Abandons a primitive: dropped if not yet sent, else its reply is ignored.

        The motion itself is stopped by ``robot/stop``, which is what aborts a plan.
        """
        future.cancel()

    def halt(self) -> None:
        """Refuses every primitive from now on (called on robot/stop, from any thread)."""
        with self._lock:
            self._halted = True

    def resume(self) -> None:
        """Accepts primitives again (after the aborted plan has been cleaned up)."""
        with self._lock:
            self._halted = False

    def close(self) -> None:
        """Stops the worker thread after the query in flight, if any."""
        self.halt()
        self._jobs.put((None, None))

    def _start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._work, name="robot-act", daemon=True)
            self._thread.start()

    def _work(self) -> None:
        while True:
            future, query = self._jobs.get()
            if future is None:
                return
            if not future.set_running_or_notify_cancel():
                continue  # cancelled before it was sent
            try:
                future.set_result(self._query(query))
            except Exception as e:  # noqa: BLE001 - handed to the waiting behaviour as is
                future.set_exception(e)

    def _query(self, query: dict) -> dict:
        try:
            return self.ctx.query(keys.ROBOT_ACT, query, self.timeout_s)
        except QueryError as e:
            return _failed(str(e))


def _failed(error: str) -> dict:
    return keys.ROBOT_ACT.reply(False, error, duration_s=0.0,
            scene=None)


class Planner(Service):
    """Intent in, robot actions out, progress on plan/status.

    Args:
        settings: the planner's settings.
        inline_queries: send robot/act on the event loop's thread (tests with FakeBus).
    """

    name = "planner"
    description = ("Executes each accepted cbgo/intent as a behaviour tree that repairs missing "
                   "preconditions; primitives on cbgo/robot/act, progress on cbgo/plan/status.")
    settings_class = PlannerSettings

    def __init__(self, settings: PlannerSettings, inline_queries: bool = False):
        super().__init__(settings)
        self.inline_queries = inline_queries
        self.scenes = SceneSource()
        self.plan: Plan | None = None
        self.counts = {"ignored": 0, "accepted": 0, "dropped": 0, "succeeded": 0, "failed": 0,
                       "stopped": 0, "refused_replayed": 0}
        self._waiting: deque[dict] = deque()
        self._lock = threading.Lock()  # `_waiting` and `_stop`: robot/stop is on Zenoh's thread
        self._stop: str | None = None
        self._cancelled: list[dict] = []
        self._last_status: dict | None = None
        self._scene_wait_ticks = 0

    def setup(self, ctx: Context) -> None:
        """Called once before the service is announced alive: declares inputs, output, timer."""
        self.ctx = ctx
        self.replay_log = RateLimited(ctx.log)
        self.robot = RobotClient(ctx, self.settings.act_timeout_s, self.inline_queries)
        ctx.subscribe(keys.INTENT, self.on_intent)
        ctx.subscribe(keys.SCENE_STATE, self.on_scene)
        ctx.subscribe(keys.ROBOT_STOP, self.on_stop, immediate=True)
        ctx.publishes(keys.PLAN_STATUS)
        ctx.every(1.0 / self.settings.tick_hz, self.on_tick)

    # ------------------------------------------------------------ inputs

    def on_intent(self, msg: dict):
        """Queues an accepted intent; counts and ignores the others, refuses replayed ones."""
        if msg["status"] != "accepted":
            self.counts["ignored"] += 1
            self.ctx.log.debug("ignoring a %s intent (%s %s)", msg["status"], msg["action"],
                              msg["object"])
            return None
        if self._refused_as_replayed(msg, "intent", f"intent {msg['action']}({msg['object']})"):
            return None
        self.counts["accepted"] += 1
        with self._lock:
            self._waiting.append(msg)
            full = len(self._waiting) > self.settings.queue_size
            dropped = self._waiting.popleft() if full else None
        out = []
        if dropped is not None:
            self.counts["dropped"] += 1
            out.append((keys.PLAN_STATUS, _unstarted(dropped, (
                f"dropped: newer intents arrived while {self.settings.queue_size} waited"))))
        # Start at once when idle rather than on the next tick: up to a tick less latency.
        return out + (self._advance(count_wait=False) if self.plan is None else [])

    def on_scene(self, msg: dict):
        """Keeps the newest scene (set aside while a primitive runs); may start a waiting plan."""
        if self._refused_as_replayed(msg, "scene", "scene"):
            return None
        self.scenes.observe(msg)
        if self.plan is None and self._waiting:
            return self._advance(count_wait=False)
        return None

    def _refused_as_replayed(self, msg: dict, kind: str, what: str) -> bool:
        """Whether a message comes from a replay the planner must not act on (counted, logged).

        A replayed intent is a past decision, a replayed scene a past world: executing one, or
        planning on the other, moves the robot for what no one asked for now.
        """
        if msg.get(wire.REPLAYED) is not True or self.settings.accept_replayed:
            return False
        self.counts["refused_replayed"] += 1
        self.replay_log.warning(kind, f"refused a replayed {what} (replayed: true, from `cbgo "
                                "replay`); start the planner with --accept-replayed to act on "
                                "replayed messages")
        return True

    def on_stop(self, msg: dict) -> None:
        """Called at once on Zenoh's thread: no primitive goes out from now; aborts next tick."""
        reason = msg.get("reason") if isinstance(msg, dict) else None
        with self._lock:
            self.robot.halt()
            self._stop = "stopped" + (f": {reason}" if isinstance(reason, str) and reason else "")
            self._cancelled += list(self._waiting)
            self._waiting.clear()
        self.ctx.log.warning("robot/stop received: aborting the plan")

    # ------------------------------------------------------------ the tree's clock

    def on_tick(self):
        """Timer: handles a stop, starts the next intent, ticks the tree, reports changes."""
        return self._handle_stop() + self._advance(count_wait=True)

    def _advance(self, count_wait: bool) -> list:
        """Starts the next intent if idle, ticks the tree, reports changes.

        Args:
            count_wait: whether this call counts as a tick of an intent's wait for a fresh
                scene (only timer ticks do, so the wait is measured in timer time).
        """
        out = []
        if self.plan is None:
            out += self._start_next(count_wait)
        if self.plan is not None:
            self.plan.tick()
            out += self._report()
            if self.plan.done:
                self._ended(self.plan)
        return out

    def _handle_stop(self) -> list:
        with self._lock:
            stop, cancelled = self._stop, self._cancelled
            self._stop, self._cancelled = None, []
        if stop is None:
            return []
        out = [(keys.PLAN_STATUS, _unstarted(i, f"{stop} before it started")) for i in cancelled]
        if self.plan is not None:
            self.plan.abort(stop)
            out += self._report()
            self.counts["stopped"] += 1
            self._ended(self.plan, counted=True)
        with self._lock:
            if self._stop is None:  # else another stop came meanwhile: stay halted for it
                self.robot.resume()
        return out

    def _start_next(self, count_wait: bool) -> list:
        with self._lock:
            intent = self._waiting[0] if self._waiting else None
        if intent is None:
            return []
        waited = self._scene_wait_ticks / self.settings.tick_hz
        # Plan on a scene at least as new as the intent (the world may have changed since the
        # last scene: a reset, another client's action), unless none comes within FRESH_SCENE_S.
        stale = self.scenes.ts < intent["ts"] and waited < FRESH_SCENE_S
        if not self.scenes.ready or stale:
            self._scene_wait_ticks += count_wait
            if waited < self.settings.scene_timeout_s or not count_wait:
                return []
        with self._lock:
            if not self._waiting or self._waiting[0] is not intent:
                return []
            self._waiting.popleft()
        self._scene_wait_ticks = 0
        if not self.scenes.ready:
            self.counts["failed"] += 1
            return [(keys.PLAN_STATUS, _unstarted(intent, (
                f"no cbgo/scene/state within {self.settings.scene_timeout_s:g} s (is the robot "
                "or the simulator up?)")))]
        self.ctx.log.info("executing %s(%s)", intent["action"], intent["object"])
        self.plan = Plan(intent, self.scenes, self.robot, self.settings.max_repairs,
                         self.settings.check_first)
        return []

    def _report(self) -> list:
        status = self.plan.status()
        comparable = {k: v for k, v in status.items() if k != "ts"}
        if comparable == self._last_status:
            return []
        self._last_status = comparable
        return [(keys.PLAN_STATUS, status)]

    def _ended(self, plan: Plan, counted: bool = False) -> None:
        if not counted:
            self.counts["succeeded" if plan.state == "success" else "failed"] += 1
        level = self.ctx.log.info if plan.state == "success" else self.ctx.log.warning
        level("%s(%s) ended: %s%s", plan.intent["action"], plan.intent["object"], plan.state,
              f" ({plan.error})" if plan.error else "")
        self.plan, self._last_status = None, None

    # ------------------------------------------------------------ lifecycle

    def status_extra(self) -> dict:
        """Adds plan counters, the waiting intents and the running plan (on Zenoh's thread)."""
        plan = self.plan
        current = None
        if plan is not None:
            current = {"action": plan.intent["action"], "object": plan.intent["object"],
                       "state": plan.state, "error": plan.error}
        return {"plans": dict(self.counts), "waiting": len(self._waiting), "current": current,
                "robot_acts_sent": self.robot.sent}

    def shutdown(self) -> None:
        """Called once at exit: abandons the running plan and stops the robot/act worker."""
        if self.plan is not None:
            self.plan.abort("the planner stopped")
            self.ctx.publish(keys.PLAN_STATUS, self.plan.status())
        self.robot.close()


def _unstarted(intent: dict, error: str) -> dict:
    """Returns the failure status of an intent that never ran."""
    return keys.PLAN_STATUS.message(ts=time.time(), intent=intent, sequence=[],
            state="failure", tree="", error=error)


main = main_for(Planner)

if __name__ == "__main__":
    main()
