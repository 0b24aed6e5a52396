"""End-to-end latency of the gesture pipeline, through real processes, on one host.

Starts a router and the real services as separate processes on a free loopback port
(leap-bridge with the simulated user, static-gesture, dynamic-gesture, episode, intent, planner)
and a robot, then drives ``--episodes`` episodes one after the other: per episode the bench asks
the leap-bridge (``@ctl/leap-bridge/play``) to have a simulated user perform one gesture while
looking at ``cup1``. The gesture is chosen from the world so that every episode has a feasible
intent: when the robot's gripper is empty, ``grab`` (→ ``pick_up(cup1)``); when it holds
something, ``thumbsup`` (→ ``place``). The bench waits for the intent and, for an accepted one,
for the end of its plan before the next episode; after an unexpected intent or a failed plan it
resets the world (``cbgo/sim/reset``).

The robot: the ``dry-robot`` service when this installation has it (``--robot auto``, the
default, or ``--robot dry-robot``), run with ``--action-s`` (0: actions end at once, so episodes
stay short) and its scene period set to 1/``--scene-rate-hz``; else (or with ``--robot bench``)
the bench answers ``cbgo/robot/act`` itself from the world model (`cbgo.world.apply`) and
publishes ``cbgo/scene/state`` at ``--scene-rate-hz`` and after each action. The scene rate
matters: the planner plans on a scene at least as new as the intent, so it waits for the next
``cbgo/scene/state`` (up to one period) before the first action; 20 Hz is mujoco-sim's default
rate. The output says which robot was used.

Clock and time stamps: every process runs on this host, so the wall clock (``time.time()``) is
one clock for all of them. ``ts`` fields are taken by the producer just before publishing;
"received" times are taken in this process's Zenoh callbacks (and the bench robot's queryable).

Measures, per episode (``--warmup`` episodes first are played but not counted):

- **end condition → intent received**: the episode's end condition is *no hand seen for the
  debounce* (``services/episode/segmenter.py``); it becomes true at
  ``T_end = ts(last hand frame) + debounce_s``, where the last hand frame is the summary's
  ``ended`` (the episode service's own last hand frame; the bench checks it against the frames
  it saw itself). The service notices it on its 5 ms timer or on the next frame, then publishes
  ``episode/event`` kind ``end`` (``ts``: that decision) and ``episode/summary`` (same ``ts``).
  Measured: arrival of the ``cbgo/intent`` naming that episode − ``T_end``.
- **last hand frame → intent received**: arrival of the intent − ``ts(last hand frame)``; it
  contains the debounce by construction (= the previous measure + ``debounce_s``).
- **frame → static probabilities received**: for every frame with a hand, arrival of the
  ``cbgo/gestures/static`` with the frame's ``seq`` − the frame's ``ts``.
- **intent → first robot action**: arrival of the first ``cbgo/robot/act`` query of that intent's
  plan at the robot − arrival of the intent at the bench (the planner receives it at the same
  moment). With the dry-robot, whose query arrivals the bench cannot see, the ``ts`` of its
  ``cbgo/robot/state`` announcing the action (``action`` set) stands in: the dry-robot stamps
  and publishes it as its handler starts the action.

A stage breakdown of end condition → intent (summary stamped, summary received, intent stamped)
shows where the time goes. Goals (loopback): end condition → intent p50 ≤ 20 ms and p99 ≤ 50 ms;
last hand frame → intent p50 ≤ debounce + 20 ms.

Examples::

    cbgo bench latency                          # 200 episodes, a few minutes
    cbgo bench latency --quick                  # smoke run: 4 episodes
    cbgo bench latency --episodes 500 --out out/latency.json
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import sys
import tempfile
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from cbgo import keys, registry, wire

PIPELINE = ("leap-bridge", "static-gesture", "dynamic-gesture", "episode", "intent", "planner")
QUICK_EPISODES = 4
SCENE = {  # a full cup, a closed drawer, a box, inside the workspace (the demo's cells)
    "objects": [
        {"name": "cup1", "type": "cup", "position": [0.44, 0.06, 0.03], "size": 0.06,
         "full": True, "on": None, "inside": None},
        {"name": "drawer1", "type": "drawer", "position": [0.68, -0.18, 0.055], "size": 0.11,
         "open": False, "opening": 0.0, "contains": []},
        {"name": "box1", "type": "box", "position": [0.56, 0.18, 0.025], "size": 0.05,
         "on": None, "inside": None},
    ],
    "robot": {"tcp": [0.3, 0.0, 0.4], "gripper_open": True, "holding": None},
}
TARGET = "cup1"
GESTURE_FOR = {False: ("grab", "pick_up"), True: ("thumbsup", "place")}  # by "holding?"
MEASURES = ("end_condition_to_intent", "last_hand_frame_to_intent", "frame_to_static",
            "intent_to_first_robot_action")
STAGES = ("summary_stamped", "summary_received", "intent_stamped", "intent_received")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--episodes", type=int, default=200, help="episodes measured [200]")
    parser.add_argument("--quick", action="store_true",
                        help=f"smoke run: {QUICK_EPISODES} episodes (overrides --episodes)")
    parser.add_argument("--warmup", type=int, default=1,
                        help="episodes played first and not counted (first-call costs) [1]")
    parser.add_argument("--out", default="out/bench-latency/results.json",
                        help="results JSON [out/bench-latency/results.json]")
    parser.add_argument("--robot", choices=("auto", "dry-robot", "bench"), default="auto",
                        help="who answers robot/act: the dry-robot service, or the bench "
                             "itself from the world model; auto: dry-robot if built [auto]")
    parser.add_argument("--debounce-s", type=float, default=0.15,
                        help="the episode service's debounce, s [0.15]")
    parser.add_argument("--rate-hz", type=float, default=60.0,
                        help="leap-bridge frame rate, Hz [60]")
    parser.add_argument("--user-speed", type=float, default=2.5,
                        help="simulated user's movement speed factor [2.5]")
    parser.add_argument("--hold-s", type=float, default=0.4,
                        help="how long the static gesture is held, s [0.4]")
    parser.add_argument("--pause-s", type=float, default=0.1,
                        help="no hand in view before each episode, s [0.1]")
    parser.add_argument("--scene-rate-hz", type=float, default=20.0,
                        help="the robot's cbgo/scene/state rate, Hz (the default of both "
                             "mujoco-sim and dry-robot) [20]")
    parser.add_argument("--action-s", type=float, default=0.0,
                        help="dry-robot: seconds each action takes [0]")
    parser.add_argument("--intent-samples", type=int, default=None,
                        help="intent: --posterior-samples (default: the service's own)")
    parser.add_argument("--no-dynamic", action="store_true",
                        help="leave the dynamic-gesture service out of the pipeline")
    parser.add_argument("--episode-timeout-s", type=float, default=5.0,
                        help="how long after its scenario an episode may take to end in a "
                             "finished plan before it counts as lost, s [5]")
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulated users [0]")


# ============================================================================ observations


@dataclass
class Frame:
    """What the bench keeps of one hand frame."""

    ts: float
    has_hand: bool
    received: float


@dataclass
class Observed:
    """Everything the bench's own subscriptions saw, with arrival times (one lock for all)."""

    frames: dict[int, Frame] = field(default_factory=dict)
    static: dict[int, float] = field(default_factory=dict)  # frame seq -> first arrival
    summaries: dict[str, tuple[float, dict]] = field(default_factory=dict)
    intents: dict[str, tuple[float, dict]] = field(default_factory=dict)
    plans: dict[str, tuple[float, dict]] = field(default_factory=dict)  # episode -> terminal
    robot_actions: list[float] = field(default_factory=list)  # robot/state ts, action set


class Tap:
    """The bench's subscriptions to the pipeline's keys.

    Callbacks run on Zenoh's threads: they take the arrival time first, decode, and keep only
    what the measures need.
    """

    def __init__(self, session, k: keys.Keys):
        self.seen = Observed()
        self.cond = threading.Condition()
        self._subs = [session.declare_subscriber(k.of(topic), handler) for topic, handler in (
            (keys.HANDS_FRAME, self._on_frame), (keys.GESTURES_STATIC, self._on_static),
            (keys.EPISODE_SUMMARY, self._on_summary), (keys.INTENT, self._on_intent),
            (keys.PLAN_STATUS, self._on_plan), (keys.ROBOT_STATE, self._on_robot_state))]

    def _on_frame(self, sample) -> None:
        now = time.time()
        msg = wire.decode(sample.payload.to_bytes())
        with self.cond:
            self.seen.frames[msg["seq"]] = Frame(msg["ts"], bool(msg["hands"]), now)

    def _on_static(self, sample) -> None:
        now = time.time()
        seq = wire.decode(sample.payload.to_bytes())["seq"]
        with self.cond:
            self.seen.static.setdefault(seq, now)

    def _on_summary(self, sample) -> None:
        self._keep(self.seen.summaries, sample, lambda m: m["episode"])

    def _on_intent(self, sample) -> None:
        self._keep(self.seen.intents, sample, lambda m: m["episode"] or "")

    def _on_plan(self, sample) -> None:
        now = time.time()
        msg = wire.decode(sample.payload.to_bytes())
        if msg["state"] != "running":
            with self.cond:
                self.seen.plans[msg["intent"]["episode"] or ""] = (now, msg)
                self.cond.notify_all()

    def _on_robot_state(self, sample) -> None:
        msg = wire.decode(sample.payload.to_bytes())
        if msg.get("action") is not None:
            with self.cond:
                self.seen.robot_actions.append(msg["ts"])

    def first_action_after(self, since: float, until: float) -> float | None:
        """Returns the ts of the first robot/state announcing an action within [since, until)."""
        with self.cond:
            return next((t for t in self.seen.robot_actions if since <= t < until), None)

    def _keep(self, table: dict, sample, key_of) -> None:
        now = time.time()
        msg = wire.decode(sample.payload.to_bytes())
        with self.cond:
            table.setdefault(key_of(msg), (now, msg))
            self.cond.notify_all()


# ============================================================================ the bench robot


class BenchRobot:
    """A robot answered by this process from the world model; records each action's arrival.

    Answers ``cbgo/robot/act`` (at once, `cbgo.world.apply`) and ``cbgo/sim/reset`` (a scene),
    publishes ``cbgo/scene/state`` every 1/``rate_hz`` s and after each change.
    """

    def __init__(self, session, k: keys.Keys, rate_hz: float):
        import zenoh

        from cbgo.world import Scene

        self.lock = threading.Lock()
        self.scene = Scene.from_dict(SCENE)
        self.seq = 0
        self.acts: list[tuple[float, dict]] = []
        self.stopping = threading.Event()
        self._pub = session.declare_publisher(
            k.of(keys.SCENE_STATE), congestion_control=zenoh.CongestionControl.BLOCK)
        self._act_key, self._reset_key = k.of(keys.ROBOT_ACT), k.of(keys.SIM_RESET)
        self._queryables = [session.declare_queryable(self._act_key, self._on_act),
                            session.declare_queryable(self._reset_key, self._on_reset)]
        self._thread = threading.Thread(target=self._publish_periodically, args=(rate_hz,),
                                        name="bench-robot-scene", daemon=True)
        self._thread.start()

    def _message(self) -> dict:
        """Returns the world as a scene/state message (call with the lock held)."""
        self.seq += 1
        return self.scene.to_message(self.seq, time.time())

    def _publish_periodically(self, rate_hz: float) -> None:
        while not self.stopping.wait(1.0 / rate_hz):
            with self.lock:
                message = self._message()
            self._pub.put(wire.encode(message))

    def _on_act(self, query) -> None:
        arrival = time.time()
        from cbgo.world import InfeasibleAction, apply

        request = wire.decode(query.payload.to_bytes())
        with self.lock:
            self.acts.append((arrival, request))
            try:
                self.scene = apply(request["action"], request.get("object"),
                                   request.get("params") or {}, self.scene)
                ok, error = True, None
            except InfeasibleAction as e:
                ok, error = False, f"refused: {e}"
            scene = self._message()
        reply = {"v": wire.SCHEMA_VERSION, "ok": ok, "error": error, "duration_s": 0.0,
                 "scene": scene}
        self._pub.put(wire.encode(scene))
        self._reply(query, self._act_key, reply, "robot/act")

    def _on_reset(self, query) -> None:
        from cbgo.world import Scene

        request = wire.decode(query.payload.to_bytes())
        with self.lock:
            self.scene = Scene.from_dict(request.get("scene") or SCENE)
            self.scene.settle()
            scene = self._message()
        self._pub.put(wire.encode(scene))
        reply = {"v": wire.SCHEMA_VERSION, "ok": True, "error": None, "scene": scene}
        self._reply(query, self._reset_key, reply, "sim/reset")

    @staticmethod
    def _reply(query, key: str, reply: dict, suffix: str) -> None:
        # Checked against the contract like any service's reply: the bench must not cheat.
        wire.validate(reply, wire.REPLY_SCHEMAS[suffix], key)
        try:
            query.reply(key, wire.encode(reply))
        finally:
            query.drop()

    def first_act_after(self, since: float, until: float) -> float | None:
        """Returns the arrival of the first robot/act query within [since, until), if any."""
        with self.lock:
            return next((t for t, _ in self.acts if since <= t < until), None)

    def close(self) -> None:
        """Stops the scene publisher."""
        self.stopping.set()
        self._thread.join(timeout=1.0)


# ============================================================================ episodes


@dataclass
class Run:
    """One played episode: what was asked and when."""

    index: int
    gesture: str
    expected: str
    played: float
    duration_s: float
    finished: float = 0.0
    reset_after: bool = False


def _scenario(index: int, gesture: str, args: argparse.Namespace) -> dict:
    """Returns the inline scenario of one episode: one gesture, looking at the target."""
    return {"name": f"latency-{index}", "seed": args.seed + index,
            "users": {"user1": {"speed": args.user_speed, "hold_s": args.hold_s}},
            "episodes": [{"user": "user1", "gaze": TARGET, "gestures": [gesture],
                          "pause_s": args.pause_s, "preparation": False}]}


class Driver:
    """Plays episodes one at a time and waits for each to end in an intent (and its plan)."""

    def __init__(self, stack, tap: Tap, args: argparse.Namespace):
        self.stack, self.tap, self.args = stack, tap, args
        self.holding = False  # the world as the latest plan left it

    def play(self, index: int) -> Run:
        """Plays one episode and waits for its outcome (or the timeout)."""
        gesture, expected = GESTURE_FOR[self.holding]
        played = time.time()
        (ok, reply), = self.stack.query(self.stack.keys.ctl("leap-bridge", "play"),
                                        _scenario(index, gesture, self.args))
        if not ok:
            raise RuntimeError(f"leap-bridge refused the scenario: {reply}")
        run = Run(index, gesture, expected, played, reply["duration_s"])
        self._wait_outcome(run)
        run.finished = time.time()
        return run

    def _wait_outcome(self, run: Run) -> None:
        """Waits until the scenario is over and every episode it made ended in a plan/intent."""
        end = run.played + run.duration_s
        deadline = end + self.args.episode_timeout_s
        with self.tap.cond:
            while time.time() < deadline:
                if time.time() >= end and self._settled(run):
                    return
                self.tap.cond.wait(0.02)
        self._after(run, settled=False)

    def _settled(self, run: Run) -> bool:
        """Whether the run's episodes all have intents and accepted ones finished plans."""
        seen = self.tap.seen
        mine = [e for e, (_, s) in seen.summaries.items() if s["started"] >= run.played]
        if not mine or any(e not in seen.intents for e in mine):
            return False
        accepted = [e for e in mine if seen.intents[e][1]["status"] == "accepted"]
        if any(e not in seen.plans for e in accepted):
            return False
        self._after(run, settled=True, episodes=mine)
        return True

    def _after(self, run: Run, settled: bool, episodes: list[str] = ()) -> None:
        """Updates the world the next gesture is chosen for; resets it when it went astray."""
        seen = self.tap.seen
        last = episodes[-1] if episodes else None
        intent = seen.intents[last][1] if last else None
        plan = seen.plans.get(last, (0, {}))[1] if last else {}
        went_as_asked = (settled and len(episodes) == 1 and intent["status"] == "accepted"
                         and intent["action"] == run.expected and plan.get("state") == "success")
        if went_as_asked:
            self.holding = run.expected == "pick_up"
            return
        run.reset_after = True
        self.holding = False

    def reset_world_if_needed(self, run: Run) -> None:
        """Resets the world to the start scene after an episode that went astray."""
        if run.reset_after:
            self.reset_world()

    def reset_world(self) -> None:
        """Asks the robot to load the start scene (cbgo/sim/reset)."""
        replies = self.stack.query(self.stack.keys.of(keys.SIM_RESET),
                                   {"v": wire.SCHEMA_VERSION, "scene": SCENE}, timeout=30.0)
        if not (replies and replies[0][0] and replies[0][1]["ok"]):
            raise RuntimeError(f"sim/reset failed: {replies}")
        self.holding = False
        time.sleep(0.2)  # let the new scene reach intent, planner and the leap-bridge


# ============================================================================ measuring


def figures(values_s: list[float]) -> dict:
    """Returns n, p50, p90, p99, max, min in ms of a list of seconds."""
    ms = np.asarray(values_s, dtype=float) * 1e3
    if ms.size == 0:
        return {"n": 0}
    return {"n": int(ms.size), "p50": float(np.percentile(ms, 50)),
            "p90": float(np.percentile(ms, 90)), "p99": float(np.percentile(ms, 99)),
            "max": float(ms.max()), "min": float(ms.min())}


def episode_record(run: Run, next_played: float, seen: Observed, debounce_s: float,
                   first_act) -> dict:
    """Returns the time stamps and latencies (s) of one played episode, or why it was lost."""
    mine = sorted((s for _, s in seen.summaries.values()
                   if run.played <= s["started"] < next_played), key=lambda s: s["started"])
    record = {"index": run.index, "gesture": run.gesture, "expected": run.expected,
              "summaries": len(mine), "reset_after": run.reset_after}
    if not mine:
        return {**record, "lost": "no episode summary (no hand seen, or the episode service "
                                  "missed it)"}
    summary = mine[-1]
    if summary["episode"] not in seen.intents:
        return {**record, "episode": summary["episode"], "lost": "no intent for the summary"}
    summary_rx = seen.summaries[summary["episode"]][0]
    intent_rx, intent = seen.intents[summary["episode"]]
    last_hand = summary["ended"]
    end = last_hand + debounce_s
    record.update(
        episode=summary["episode"], lost=None, status=intent["status"],
        action=intent["action"], object=intent["object"], reason=intent["reason"],
        confidence=intent["confidence"],
        last_hand_ts=last_hand, end_condition=end, summary_ts=summary["ts"],
        summary_received=summary_rx, intent_ts=intent["ts"], intent_received=intent_rx,
        bench_last_hand_ts=_bench_last_hand(seen, summary))
    plan = seen.plans.get(summary["episode"])
    record["plan"] = plan[1]["state"] if plan else None
    record["plan_error"] = plan[1]["error"] if plan else None
    # Searched from the intent's own stamp: the bench's receipt could come after the planner's
    # first action if this process was held up; the latency is still taken from the receipt.
    act = first_act(intent["ts"], next_played) if intent["status"] == "accepted" else None
    record["first_robot_action"] = act
    return record


def _bench_last_hand(seen: Observed, summary: dict) -> float | None:
    """The last frame with a hand the bench itself saw within the summary's episode."""
    stamps = [f.ts for f in seen.frames.values()
              if f.has_hand and summary["started"] <= f.ts <= summary["ended"] + 1e-9]
    return max(stamps) if stamps else None


def static_latencies(seen: Observed, runs: list[Run]) -> tuple[list[float], int]:
    """Returns frame ts → static arrival (s) for the measured frames with a hand; and misses.

    Misses: frames with a hand that got no static message (dropped under load).
    """
    start, stop = runs[0].played, runs[-1].finished
    values, missing = [], 0
    for seq, frame in seen.frames.items():
        if frame.has_hand and start <= frame.ts <= stop:
            if seq in seen.static:
                values.append(seen.static[seq] - frame.ts)
            else:
                missing += 1
    return values, missing


def measure(records: list[dict], static: list[float], debounce_s: float) -> dict:
    """Returns the four measures and the stage breakdown (figures in ms)."""
    ok = [r for r in records if not r["lost"]]
    acted = [r for r in ok if r["first_robot_action"] is not None]
    out = {
        "end_condition_to_intent": figures([r["intent_received"] - r["end_condition"]
                                            for r in ok]),
        "last_hand_frame_to_intent": figures([r["intent_received"] - r["last_hand_ts"]
                                              for r in ok]),
        "frame_to_static": figures(static),
        "intent_to_first_robot_action": figures([r["first_robot_action"] - r["intent_received"]
                                                 for r in acted]),
    }
    stamps = {"summary_stamped": "summary_ts", "summary_received": "summary_received",
              "intent_stamped": "intent_ts", "intent_received": "intent_received"}
    breakdown = {stage: figures([r[field_] - r["end_condition"] for r in ok])
                 for stage, field_ in stamps.items()}
    return {"measures": out, "breakdown_from_end_condition": breakdown,
            "stages": stage_durations(ok)}


# (what happens, from which time stamp, to which) between the end condition and the intent
STAGE_SPANS = (
    ("episode: notices the end, builds the summary", "end_condition", "summary_ts"),
    ("summary: episode -> bench", "summary_ts", "summary_received"),
    ("intent: summary -> inference -> stamped", "summary_received", "intent_ts"),
    ("intent: intent -> bench", "intent_ts", "intent_received"),
)


def stage_durations(records: list[dict]) -> dict:
    """Returns the figures of each stage between the end condition and the intent's arrival.

    The summary's arrival at the bench stands in for its arrival at the intent service (both
    subscribe to the same publication through the same router).
    """
    return {name: figures([r[stop] - r[start] for r in records])
            for name, start, stop in STAGE_SPANS}


def goals(measures: dict, debounce_s: float) -> dict:
    """Returns, per measure, its goal as text and whether it was met (None: no goal)."""
    end, last = measures["end_condition_to_intent"], measures["last_hand_frame_to_intent"]
    limit = debounce_s * 1e3 + 20.0
    return {
        "end_condition_to_intent": {
            "goal": "p50 <= 20 ms, p99 <= 50 ms",
            "met": bool(end["n"]) and end["p50"] <= 20.0 and end["p99"] <= 50.0},
        "last_hand_frame_to_intent": {
            "goal": f"p50 <= debounce + 20 ms = {limit:g} ms",
            "met": bool(last["n"]) and last["p50"] <= limit},
        "frame_to_static": {"goal": None, "met": None},
        "intent_to_first_robot_action": {"goal": None, "met": None},
    }


def tally(records: list[dict]) -> dict:
    """Counts lost episodes by reason, intent statuses, unexpected actions, plan outcomes."""
    out = {"episodes": len(records), "lost": 0, "lost_reasons": {}, "status": {},
           "as_expected": 0, "unexpected": {}, "plans": {}, "split": 0, "resets": 0,
           "bench_saw_other_last_hand": 0}
    for r in records:
        out["resets"] += r["reset_after"]
        out["split"] += r["summaries"] > 1
        if r["lost"]:
            out["lost"] += 1
            out["lost_reasons"][r["lost"]] = out["lost_reasons"].get(r["lost"], 0) + 1
            continue
        _count(out["status"], f"{r['status']} {r['action']}({r['object'] or ''})"
                              + ("" if r["status"] == "accepted" else f": {r['reason']}"))
        if r["status"] == "accepted" and r["action"] == r["expected"]:
            out["as_expected"] += 1
        else:
            _count(out["unexpected"], f"{r['gesture']} -> {r['status']} {r['action']}"
                                      f"({r['object'] or ''})")
        _count(out["plans"], str(r["plan"]) + (f": {r['plan_error']}" if r["plan_error"] else ""))
        bench_view = r["bench_last_hand_ts"]
        if bench_view is None or abs(bench_view - r["last_hand_ts"]) > 1e-6:
            out["bench_saw_other_last_hand"] += 1
    return out


def _count(table: dict, key: str) -> None:
    table[key] = table.get(key, 0) + 1


# ============================================================================ printing


def _row(name: str, fig: dict, goal: dict | None = None) -> str:
    if not fig.get("n"):
        return f"  {name:<46} {'0':>5}  -"
    text = (f"  {name:<46} {fig['n']:>5} {fig['p50']:8.2f} {fig['p90']:8.2f} {fig['p99']:8.2f} "
            f"{fig['max']:8.2f}")
    if goal and goal["goal"]:
        text += f"   {goal['goal']}: {'met' if goal['met'] else 'MISSED'}"
    return text


def report(results: dict) -> str:
    """Returns the printed table of a results dict."""
    m, g = results["measures"], results["goals"]
    lines = [f"{'measure (ms)':<48} {'n':>5} {'p50':>8} {'p90':>8} {'p99':>8} {'max':>8}   goal"]
    lines += [_row(name.replace("_", " "), m[name], g[name]) for name in MEASURES]
    lines.append("where end condition -> intent goes, stage by stage (ms):")
    lines += [_row(f"  {stage}", fig) for stage, fig in results["stages"].items()]
    t = results["tally"]
    lines.append(f"episodes: {t['episodes']} measured, {t['lost']} lost"
                 + (f" {t['lost_reasons']}" if t["lost"] else "")
                 + f"; {t['as_expected']} as expected; intents {t['status']}")
    if t["unexpected"]:
        lines.append(f"unexpected intents: {t['unexpected']}")
    lines.append(f"plans: {t['plans']}; world resets: {t['resets']}; split episodes: "
                 f"{t['split']}; summaries whose last hand frame the bench saw differently: "
                 f"{t['bench_saw_other_last_hand']}")
    lines.append(f"frames with a hand without a static message: {results['static_missing']}")
    lines.append(f"robot: {results['robot']}; load average before {results['loadavg_before']}, "
                 f"after {results['loadavg_after']}")
    return "\n".join(lines)


# ============================================================================ running


def _choose_robot(choice: str) -> str:
    built = _dry_robot_built()
    if choice == "dry-robot" and not built:
        raise SystemExit("--robot dry-robot: the dry-robot service is not built in this "
                         "installation; use --robot bench")
    return "dry-robot" if choice == "dry-robot" or (choice == "auto" and built) else "bench"


def _dry_robot_built() -> bool:
    try:
        return registry.by_name("dry-robot").exists()
    except KeyError:
        return False


def start_pipeline(stack, args: argparse.Namespace, robot: str, data_dir: Path) -> list[str]:
    """Starts router, services and (dry-robot) as processes; returns the names to wait for."""
    env = {"CBGO_DATA_DIR": str(data_dir)}  # no personal models or user gestures of this host
    stack.start_router()
    names = [n for n in PIPELINE if not (args.no_dynamic and n == "dynamic-gesture")]
    flags = {"leap-bridge": ["--source", "simulated", "--rate-hz", str(args.rate_hz)],
             "episode": ["--debounce-s", str(args.debounce_s)],
             "intent": ["--no-personalise"] + (
                 ["--posterior-samples", str(args.intent_samples)] if args.intent_samples
                 else []),
             "dry-robot": ["--action-s", str(args.action_s),
                           "--period-s", str(1.0 / args.scene_rate_hz)]}
    if robot == "dry-robot":
        names.append("dry-robot")
    for name in names:
        stack.start_service(name, *flags.get(name, []), env=env)
    return ["router", *names]


def drive(stack, tap: Tap, args: argparse.Namespace, total: int) -> list[Run]:
    """Plays warm-up and measured episodes with a progress bar; returns the measured runs."""
    from tqdm import tqdm

    driver = Driver(stack, tap, args)
    driver.reset_world()
    runs = []
    with tqdm(total=total, desc="episodes", unit="ep", file=sys.stderr, disable=None) as bar:
        for index in range(total):
            run = driver.play(index)
            driver.reset_world_if_needed(run)
            runs.append(run)
            bar.update(1)
    return runs[args.warmup:]


def run(args: argparse.Namespace) -> int:
    """Runs the pipeline as processes, drives the episodes, prints and writes the figures."""
    from cbgo.testing import Stack

    episodes = QUICK_EPISODES if args.quick else args.episodes
    if episodes < 1 or args.warmup < 0:
        raise SystemExit("--episodes must be >= 1 and --warmup >= 0")
    robot = _choose_robot(args.robot)
    results = {"settings": {k: v for k, v in vars(args).items() if k != "func"},
               "episodes": episodes, "robot": _robot_text(robot, args),
               "loadavg_before": _loadavg()}
    with _sigterm_as_interrupt(), tempfile.TemporaryDirectory() as tmp, \
            Stack(Path(tmp)) as stack:
        names = start_pipeline(stack, args, robot, Path(tmp) / "data")
        bench_robot = None
        try:
            if robot == "bench":
                bench_robot = BenchRobot(stack.session(), stack.keys, args.scene_rate_hz)
            stack.wait_alive(names, timeout=180)
            tap = Tap(stack.session(), stack.keys)
            time.sleep(0.5)  # let the bench's subscriptions reach the router
            print(f"latency bench: {episodes} episodes (+{args.warmup} warm-up), "
                  f"{' + '.join(names)} as processes, robot: {results['robot']}", flush=True)
            runs = drive(stack, tap, args, episodes + args.warmup)
            first_act = (bench_robot.first_act_after if bench_robot
                         else tap.first_action_after)
            results.update(_analyse(runs, tap, args, first_act))
            results["services"] = _service_status(stack, names[1:])
        finally:
            if bench_robot is not None:
                bench_robot.close()
    results["loadavg_after"] = _loadavg()
    print(report(results))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    print(f"wrote {out}")
    return 0


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """Makes SIGTERM end the bench like Ctrl-C, so that the Stack stops every process."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(_signum, _frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _analyse(runs: list[Run], tap: Tap, args: argparse.Namespace, first_act) -> dict:
    with tap.cond:
        seen = Observed(dict(tap.seen.frames), dict(tap.seen.static),
                        dict(tap.seen.summaries), dict(tap.seen.intents),
                        dict(tap.seen.plans), list(tap.seen.robot_actions))
    bounds = [r.played for r in runs[1:]] + [float("inf")]
    records = [episode_record(r, nxt, seen, args.debounce_s, first_act)
               for r, nxt in zip(runs, bounds, strict=True)]
    static, missing = static_latencies(seen, runs)
    measured = measure(records, static, args.debounce_s)
    return {**measured, "goals": goals(measured["measures"], args.debounce_s),
            "tally": tally(records), "static_missing": missing,
            "runs": [asdict(r) for r in runs], "records": records}


def _service_status(stack, names: list[str]) -> dict:
    """The counters (and the episode service's own end latency) of every service."""
    out = {}
    for name in names:
        try:
            status = stack.status(name)
        except AssertionError as e:
            out[name] = {"error": str(e)}
            continue
        out[name] = {"counters": status["counters"],
                     **{k: status[k] for k in ("end_latency_ms", "ended_by", "stray", "plans")
                        if k in status}}
    return out


def _robot_text(robot: str, args: argparse.Namespace) -> str:
    if robot == "dry-robot":
        return (f"dry-robot service (--action-s {args.action_s:g}, scene/state at "
                f"{args.scene_rate_hz:g} Hz; first action: ts of its robot/state announcing it)")
    return (f"bench (world model in the bench process; scene/state at {args.scene_rate_hz:g} Hz "
            "and after each action; first action: robot/act query arrival)")


def _loadavg() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]
