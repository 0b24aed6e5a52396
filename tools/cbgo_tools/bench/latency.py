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

The robot: the ``dry-robot`` service (the world model as a robot cell, `cbgo.robot_cell`), run
with ``--action-s`` (0: actions end at once, so episodes stay short) and its scene rate set to
``--scene-rate-hz`` (``--state-rate-hz``; it also publishes after each action). The scene rate
matters: the planner plans on a scene at least as new as the intent, so it waits for the next
``cbgo/scene/state`` (up to one period) before the first action; 20 Hz is mujoco-sim's default
rate.

Clock and time stamps: every process runs on this host, so the wall clock (``time.time()``) is
one clock for all of them. ``ts`` fields are taken by the producer just before publishing;
"received" times are taken in this process's Zenoh callbacks.

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
- **intent → first robot action**: the start of the first robot action of that intent's plan −
  arrival of the intent at the bench (the planner receives it at the same moment). The bench
  cannot see the robot/act query arrive, so the ``ts`` of the dry-robot's ``cbgo/robot/state``
  announcing the action (``action`` set) stands for it: the dry-robot stamps and publishes it
  as its handler starts the action.

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
from dataclasses import asdict
from pathlib import Path

from cbgo import keys, wire
from cbgo_tools.bench.latency_figures import (
    Frame,
    Observed,
    Run,
    episode_record,
    goals,
    measure,
    report,
    static_latencies,
    tally,
)

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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--episodes", type=int, default=200, help="episodes measured [200]")
    parser.add_argument("--quick", action="store_true",
                        help=f"smoke run: {QUICK_EPISODES} episodes (overrides --episodes)")
    parser.add_argument("--warmup", type=int, default=1,
                        help="episodes played first and not counted (first-call costs) [1]")
    parser.add_argument("--out", default="out/bench-latency/results.json",
                        help="results JSON [out/bench-latency/results.json]")
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


# ============================================================================ episodes


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
                                   keys.SIM_RESET.message(scene=SCENE), timeout=30.0)
        if not (replies and replies[0][0] and replies[0][1]["ok"]):
            raise RuntimeError(f"sim/reset failed: {replies}")
        self.holding = False
        time.sleep(0.2)  # let the new scene reach intent, planner and the leap-bridge


# ============================================================================ running


def start_pipeline(stack, args: argparse.Namespace, data_dir: Path) -> list[str]:
    """Starts router, services and dry-robot as processes; returns the names to wait for."""
    env = {"CBGO_DATA_DIR": str(data_dir)}  # no personal models or user gestures of this host
    stack.start_router()
    names = [n for n in PIPELINE if not (args.no_dynamic and n == "dynamic-gesture")]
    flags = {"leap-bridge": ["--source", "simulated", "--rate-hz", str(args.rate_hz)],
             "episode": ["--debounce-s", str(args.debounce_s)],
             "intent": ["--no-personalise"] + (
                 ["--posterior-samples", str(args.intent_samples)] if args.intent_samples
                 else []),
             "dry-robot": ["--action-s", str(args.action_s),
                           "--state-rate-hz", str(args.scene_rate_hz)]}
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
    results = {"settings": {k: v for k, v in vars(args).items() if k != "func"},
               "episodes": episodes, "robot": _robot_text(args),
               "loadavg_before": _loadavg()}
    with _sigterm_as_interrupt(), tempfile.TemporaryDirectory() as tmp, \
            Stack(Path(tmp)) as stack:
        names = start_pipeline(stack, args, Path(tmp) / "data")
        stack.wait_alive(names, timeout=180)
        tap = Tap(stack.session(), stack.keys)
        time.sleep(0.5)  # let the bench's subscriptions reach the router
        print(f"latency bench: {episodes} episodes (+{args.warmup} warm-up), "
              f"{' + '.join(names)} as processes, robot: {results['robot']}", flush=True)
        runs = drive(stack, tap, args, episodes + args.warmup)
        results.update(_analyse(runs, tap, args, tap.first_action_after))
        results["services"] = _service_status(stack, names[1:])
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


def _robot_text(args: argparse.Namespace) -> str:
    return (f"dry-robot service (--action-s {args.action_s:g}, scene/state at "
            f"{args.scene_rate_hz:g} Hz; first action: ts of its robot/state announcing it)")


def _loadavg() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]
