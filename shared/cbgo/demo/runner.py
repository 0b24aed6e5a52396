"""Runs a scripted session against a running cbgo system and checks how every step ends.

For each step the runner asks leap-bridge to play the step's episode (``@ctl/leap-bridge/play``,
an inline scenario), then follows the system's own messages: the episode's events and summary,
its intent, the plan it started and the world afterwards. A step passes when the intent is the
scripted one, an accepted intent's plan succeeded, and the step's goal holds on the world.
When the intent service asks back where the script expects an accepted intent, the simulated
user answers truthfully, each answer an episode of its own: swipes right until the expected
candidate is highlighted, then a thumbs-up (`Runner.answer`).

With faults, the runner kills services (SIGKILL, by the pid in their status) at scheduled
points, measures how long each takes to come back (liveliness token gone and back, the new
pid), checks that nobody else was restarted, and repeats a step whose episode was lost, as a
user would repeat a gesture the robot did not react to. Before a repeat, the world is put back
as it was when the step began (``cbgo/sim/reset``) unless the step's goal already holds: a
killed simulator forgets its world, and a plan cut short leaves it half done.
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from cbgo import client
from cbgo import keys as K
from cbgo.demo.inbox import Heard, Inbox
from cbgo.demo.session import Session, Step, goal_failures, world_of
from cbgo.errors import CbgoError, QueryError

EPISODE_MARGIN_S = 8.0     # after the scenario's duration, how long the episode may still take
INTENT_TIMEOUT_S = 5.0     # episode summary -> intent
NO_PLAN_WAIT_S = 1.0       # how long a refused intent is watched for a plan that must not start
SCENE_SETTLE_S = 0.3       # after a plan ends, the scene/state that follows it
RECOVERY_TIMEOUT_S = 120.0
PLAN_KILL_DELAY_S = 0.05   # a plan-phase kill hits this long into the plan's first action
KILL_AT = 0.55             # when in an episode's playing time a gesture-phase kill hits
NEXT, CONFIRM = "swipe_right", "thumbsup"  # the gestures that answer a question (intent's)
ANSWER_SEED = 7919         # offsets the answers' simulated-user seeds from the steps'


class DemoError(CbgoError):
    """The demo cannot go on (a query failed, a service never came up)."""


@dataclass
class Fault:
    """A scheduled kill: during step `step` (0-based), in `phase` (before, gesture or plan)."""

    step: int
    phase: str
    target: str


@dataclass
class Recovery:
    """How a killed process came back."""

    target: str
    step: int
    phase: str
    pid_before: int | None = None
    pid_after: int | None = None
    gone_s: float | None = None      # kill -> its liveliness token disappeared
    back_s: float | None = None      # kill -> its liveliness token is back
    all_back_s: float | None = None  # kill -> every service's token is back
    others_restarted: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """Whether it came back as a new process and nobody else was restarted."""
        return (self.back_s is not None and self.all_back_s is not None
                and not self.others_restarted
                and (self.pid_after is not None and self.pid_after != self.pid_before))


@dataclass
class StepResult:
    """How one scripted step ended."""

    index: int
    step: Step
    ok: bool = False
    problems: list[str] = field(default_factory=list)
    attempts: int = 0
    episode: str | None = None
    summary: dict | None = None
    intent: dict | None = None
    plan: dict | None = None
    question: dict | None = None  # the cbgo/intent/clarify that asked back, as opened
    answers: list[str] = field(default_factory=list)  # the answering episodes
    scene_before: dict | None = None
    scene_after: dict | None = None
    lost: list[str] = field(default_factory=list)   # why earlier attempts were repeated
    started_at: float = 0.0
    ended_at: float = 0.0


class Runner:
    """Runs a session's steps one after another.

    Args:
        session: the Zenoh session.
        inbox: what the session hears.
        keys: the key prefix.
        script: the scripted session.
        say: where timeline lines go.
        robot: the name of the robot service (for faults: "robot" stands for it).
        plan_timeout_s: how long a plan may take.
        faults: kills to make, in order.
        max_attempts: how often a step lost to a fault is repeated.
    """

    def __init__(self, session, inbox: Inbox, keys: K.Keys, script: Session,
                 say: Callable[[str], None], robot: str, plan_timeout_s: float = 180.0,
                 faults: list[Fault] | None = None, max_attempts: int = 3):
        self.session, self.inbox, self.keys, self.script = session, inbox, keys, script
        self.say, self.robot = say, robot
        self.plan_timeout_s = plan_timeout_s
        self.faults = list(faults or [])
        self.max_attempts = max_attempts if self.faults else 1
        self.recoveries: list[Recovery] = []
        self._pids_before_plan: dict[str, int | None] | None = None
        self.t0 = time.time()

    # ---------------------------------------------------------------- queries

    def query(self, key: str, message: dict, timeout: float = 10.0) -> dict:
        """Returns the first reply to a query, checked against the contract.

        Raises:
            DemoError: an error reply, a malformed reply, or no reply within `timeout`.
        """
        try:
            return client.query(self.session, key, message, timeout_s=timeout,
                                hint="is the service running?")
        except QueryError as e:
            raise DemoError(f"{key}: {e}") from None

    def reset(self, scene: dict, timeout: float = 120.0) -> dict:
        """Resets the robot's world to `scene`; returns the settled scene/state."""
        body = {"objects": scene["objects"], "robot": scene["robot"]}
        reply = self.query(self.keys.of(K.SIM_RESET), {"v": 1, "scene": body}, timeout)
        if not reply.get("ok") or reply.get("scene") is None:
            raise DemoError(f"the robot refused the scene: {reply.get('error')}")
        return reply["scene"]

    def status(self, service: str, timeout: float = 3.0) -> dict | None:
        """Returns a service's status reply, or None if it does not answer."""
        return client.status(self.session, self.keys, service, timeout).get(service)

    # ---------------------------------------------------------------- session

    def run(self) -> list[StepResult]:
        """Runs every step; returns their results (a failed step does not stop the session)."""
        results = []
        for index, step in enumerate(self.script.steps):
            result = self.run_step(index, step)
            results.append(result)
            self.faults, missed = [f for f in self.faults if f.step > index], [
                f for f in self.faults if f.step <= index]
            result.problems += [f"the fault {f.target}@{f.step + 1}:{f.phase} could not be "
                                "made (the step never reached that phase)" for f in missed]
            result.ok = result.ok and not missed
            mark = "as scripted" if result.ok else "NOT as scripted: " + "; ".join(
                result.problems)
            self.say(f"{'ok' if result.ok else 'FAILED'}  step {index + 1}: {mark}")
        return results

    def run_step(self, index: int, step: Step) -> StepResult:
        """Plays one step (repeating it after a fault); returns how it ended."""
        result = StepResult(index, step, started_at=time.time())
        checkpoint = self.current_scene()
        result.scene_before = checkpoint
        self.say(f"step {index + 1}/{len(self.script.steps)}  {step.say}  "
                 f"(expect {step.expect.label()})")
        while True:
            result.attempts += 1
            problems = self.attempt(index, step, result, checkpoint)
            if not problems:
                result.ok = True
                break
            if result.attempts >= self.max_attempts or not self.faulted(index):
                result.problems = problems
                break
            result.lost.append("; ".join(problems))
            self.say(f"  episode lost ({'; '.join(problems)}); waiting for every service")
            if not self.inbox.wait_alive(self.expected(), RECOVERY_TIMEOUT_S):
                result.problems = problems + ["services did not come back"]
                break
            now = self.current_scene()
            # A restarted robot starts from a world of its own, which proves nothing.
            if now is not None and checkpoint is not None and not self.robot_restarted(index) \
                    and not goal_failures(step.goal, checkpoint, now) \
                    and not step.goal.get("unchanged"):
                result.ok, result.scene_after = True, now
                self.say("  the lost plan had already reached the step's goal")
                break
            if now is None or world_of(now) != world_of(checkpoint):
                self.say("  putting the world back as it was when the step began")
                self.reset(checkpoint)
            self.say(f"  repeating step {index + 1} (attempt {result.attempts + 1})")
        result.ended_at = time.time()
        return result

    def attempt(self, index: int, step: Step, result: StepResult,
                checkpoint: dict | None) -> list[str]:
        """Plays the step's episode once; returns what did not go as scripted."""
        self.kill_scheduled(index, "before", time.time())
        self._pids_before_plan = self.pids() if self.scheduled(index, "plan") else None
        mark = self.inbox.mark()
        played_at = time.time()
        scenario = step.scenario(self.script.users, self.script.seed + 101 * index
                                 + result.attempts, f"{self.script.name}-{index + 1}")
        reply = self.query(self.keys.ctl("leap-bridge", "play"), scenario)
        duration = float(reply.get("duration_s", 5.0))
        self.kill_scheduled(index, "gesture", played_at + KILL_AT * duration)
        summary = self.inbox.wait(mark, "episode/summary",
                                  lambda m: m["started"] >= played_at - 0.5,
                                  duration + EPISODE_MARGIN_S)
        if summary is None:
            return ["no episode was recognised"]
        result.summary, result.episode = summary.message, summary.message["episode"]
        self.show_episode(mark, summary)
        intent = self.inbox.wait(mark, "intent", lambda m: m["episode"] == result.episode,
                                 INTENT_TIMEOUT_S)
        if intent is None:
            return [f"no intent for episode {result.episode}"]
        result.intent = intent.message
        self.show_intent(intent)
        problems = []
        asked_episode = result.episode
        ident = intent.message.get("clarification")
        if ident is not None and step.expect.status == "accepted":
            answered, trouble = self.answer(step, result, ident)
            problems += trouble
            if answered is not None:
                intent, result.intent = answered, answered.message
                result.episode = answered.message["episode"]
        elif step.ask:
            problems.append("the intent was not asked back (no clarification)")
        mismatch = step.expect.mismatch(intent.message)
        if mismatch:
            problems.append(f"intent {mismatch}")
        if intent.message["status"] == "accepted":
            problems += self.follow_plan(mark, index, result)
        else:
            problems += self.no_plan(mark, result.episode)
        self.wait_until(played_at + duration)  # the user's hand has left before the next step
        own = {asked_episode, *result.answers}
        extra = [h.message["episode"] for h in self.inbox.since(mark, "episode/summary")
                 if h.message["episode"] not in own]
        if extra:
            problems.append(f"the step made more episodes than one: {', '.join(extra)}")
        result.scene_after = self.current_scene()
        if checkpoint is not None and result.scene_after is not None:
            problems += goal_failures(step.goal, checkpoint, result.scene_after)
        return problems

    def answer(self, step: Step, result: StepResult, ident: str) -> tuple[Heard | None,
                                                                         list[str]]:
        """Answers the question `ident` with the step's expected intent; returns its intent.

        The simulated user swipes right until the expected candidate is highlighted and
        confirms it with a thumbs-up; returns the intent of the last answer and the problems.
        """
        question = self.inbox.wait(0, "intent/clarify",
                                   lambda m: m["id"] == ident and m["state"] == "open",
                                   INTENT_TIMEOUT_S)
        if question is None:
            return None, [f"the intent names clarification {ident}, which was never heard"]
        result.question = q = question.message
        offered = [(c["action"], c["object"]) for c in q["candidates"]]
        self.say(f"{self._at(question.at)}  asked back: " + ", ".join(
            f"{a}({o or ''}) p={c['p']:.2f}" for (a, o), c in zip(offered, q["candidates"],
                                                                 strict=True))
            + f"; highlighted {q['highlighted'] + 1}")
        want = step.expect
        index = next((i for i, (a, o) in enumerate(offered) if a == want.action and (
            want.object is None or o == want.object)), None)
        if index is None:
            return None, [f"the intended {want.label()} is not among the candidates asked"]
        gestures = [NEXT] * ((index - q["highlighted"]) % len(offered)) + [CONFIRM]
        last = None
        for n, gesture in enumerate(gestures):
            last = self.play_answer(step, result, gesture, n)
            if last is None:
                return None, [f"the answer {gesture} got no episode or no intent"]
        if last.message.get("clarification") != ident or last.message["status"] != "accepted":
            return last, [f"the {CONFIRM} did not confirm clarification {ident}"]
        return last, []

    def play_answer(self, step: Step, result: StepResult, gesture: str,
                    n: int) -> Heard | None:
        """Plays one answering gesture as its own episode; returns its intent (None: lost)."""
        mark = self.inbox.mark()
        played_at = time.time()
        scenario = replace(step, gestures=[gesture], gaze=None).scenario(
            self.script.users, self.script.seed + ANSWER_SEED + 101 * result.index
            + 11 * result.attempts + n, f"{self.script.name}-{result.index + 1}-answer{n + 1}")
        self.say(f"{self.clock()}  {step.user} answers: {gesture}")
        reply = self.query(self.keys.ctl("leap-bridge", "play"), scenario)
        duration = float(reply.get("duration_s", 5.0))
        summary = self.inbox.wait(mark, "episode/summary",
                                  lambda m: m["started"] >= played_at - 0.5,
                                  duration + EPISODE_MARGIN_S)
        if summary is None:
            return None
        episode = summary.message["episode"]
        result.answers.append(episode)
        self.show_episode(mark, summary)
        intent = self.inbox.wait(mark, "intent", lambda m: m["episode"] == episode,
                                 INTENT_TIMEOUT_S)
        if intent is not None:
            self.show_intent(intent)
        self.wait_until(played_at + duration)  # the hand has left before the next gesture
        return intent

    def follow_plan(self, mark: int, index: int, result: StepResult) -> list[str]:
        """Waits for the plan of an accepted intent to end; returns problems."""
        episode = result.episode

        def running(m: dict) -> bool:
            return m["intent"]["episode"] == episode and any(
                s["state"] == "running" for s in m["sequence"])

        if self.scheduled(index, "plan"):
            first = self.inbox.wait(mark, "plan/status", running, 10.0)
            if first is not None:
                self.kill_scheduled(index, "plan", first.at + PLAN_KILL_DELAY_S,
                                    self._pids_before_plan)
        # A restarted planner remembers nothing: a plan cut short by its kill never ends.
        lost = any(r.step == index and r.target == "planner" for r in self.recoveries)
        end = self.inbox.wait(mark, "plan/status", lambda m: m["intent"]["episode"] == episode
                              and m["state"] != "running", 2.0 if lost else self.plan_timeout_s)
        if end is None:
            return [f"the plan of {episode} was lost with the planner" if lost else
                    f"the plan of {episode} did not end within {self.plan_timeout_s:g} s"]
        result.plan = end.message
        self.show_plan(mark, end)
        settled = self.inbox.wait(mark, "scene/state", lambda m: m["ts"] >= end.message["ts"],
                                  SCENE_SETTLE_S + 2.0)
        if settled is None:
            time.sleep(SCENE_SETTLE_S)
        if end.message["state"] != "success":
            return [f"plan {end.message['state']}: {end.message['error']}"]
        return []

    def no_plan(self, mark: int, episode: str) -> list[str]:
        """Checks that a refused intent starts nothing; returns problems."""
        plan = self.inbox.wait(mark, "plan/status", lambda m: m["intent"]["episode"] == episode,
                               NO_PLAN_WAIT_S)
        if plan is not None:
            return [f"a plan started for a refused intent: {plan.message['sequence']}"]
        self.say(f"{self.clock()}  plan: none (nothing is executed)")
        return []

    # ---------------------------------------------------------------- world

    def current_scene(self, timeout: float = 5.0) -> dict | None:
        """Returns the latest scene/state (waiting for one if none was heard yet)."""
        heard = self.inbox.latest("scene/state")
        if heard is None:
            heard = self.inbox.wait(0, "scene/state", lambda m: True, timeout)
        return heard.message if heard else None

    @staticmethod
    def wait_until(t: float) -> None:
        """Sleeps until wall-clock time `t` (returns at once if it has passed)."""
        time.sleep(max(0.0, t - time.time()))

    # ---------------------------------------------------------------- faults

    def expected(self) -> set[str]:
        """Every process the session needs alive (the router included)."""
        return {"router", "leap-bridge", "static-gesture", "dynamic-gesture", "episode",
                "intent", "planner", self.robot}

    def faulted(self, index: int) -> bool:
        """Whether a kill was made during step `index`."""
        return any(r.step == index for r in self.recoveries)

    def robot_restarted(self, index: int) -> bool:
        """Whether the robot service was killed during step `index`."""
        return any(r.step == index and r.target == self.robot for r in self.recoveries)

    def scheduled(self, index: int, phase: str) -> bool:
        """Whether a kill is still due in this step and phase."""
        return any(f.step == index and f.phase == phase for f in self.faults)

    def pids(self) -> dict[str, int | None]:
        """Returns every expected process's pid, from one status query to all of them."""
        statuses = client.status(self.session, self.keys, "*")
        return {name: statuses.get(name, {}).get("pid") for name in self.expected()}

    def kill_scheduled(self, index: int, phase: str, at: float,
                       pids: dict[str, int | None] | None = None) -> None:
        """Makes the kills scheduled for this step and phase, at time `at`.

        Args:
            index: the step (0-based).
            phase: before, gesture or plan.
            at: wall-clock time of the kill.
            pids: the processes' pids if already asked (asking takes tens of ms: a kill
                meant to land in the middle of a short robot action cannot wait for it).
        """
        due = [f for f in self.faults if f.step == index and f.phase == phase]
        for fault in due:
            self.faults.remove(fault)
            known = pids or self.pids()
            self.wait_until(at)
            self.recoveries.append(self.kill(fault, known))

    def kill(self, fault: Fault, pids: dict[str, int | None]) -> Recovery:
        """Kills one process with SIGKILL and measures its recovery.

        A killed simulator comes back with a world of its own; the world it had is put back
        (the last scene/state heard before the kill), as a real robot's world would still be.
        """
        target = self.robot if fault.target == "robot" else fault.target
        recovery = Recovery(target, fault.step, fault.phase)
        recovery.pid_before = pids.get(target)
        if recovery.pid_before is None:
            raise DemoError(f"cannot kill {target}: it does not answer its status query")
        world = self.current_scene()
        killed_at = time.time()
        os.kill(recovery.pid_before, signal.SIGKILL)
        self.say(f"{self.clock()}  FAULT: kill -9 {target} (pid {recovery.pid_before})")
        gone = self.inbox.token_change(target, False, killed_at, 15.0)
        back = self.inbox.token_change(target, True, killed_at, RECOVERY_TIMEOUT_S)
        all_back = self.inbox.wait_alive(self.expected(), RECOVERY_TIMEOUT_S)
        recovery.gone_s = None if gone is None else gone - killed_at
        recovery.back_s = None if back is None else back - killed_at
        recovery.all_back_s = time.time() - killed_at if all_back else None
        now = self.pids()
        recovery.pid_after = now[target]
        recovery.others_restarted = sorted(
            name for name, pid in pids.items() if name != target and pid is not None
            and now[name] != pid)
        back_text = "never" if recovery.back_s is None else f"after {recovery.back_s:.2f} s"
        self.say(f"{self.clock()}  {target} is back {back_text} as pid {recovery.pid_after}"
                 + (f"; also restarted: {recovery.others_restarted}"
                    if recovery.others_restarted else ""))
        if target == self.robot and all_back and world is not None:
            self.say(f"{self.clock()}  putting back the world {target} had before the kill")
            self.reset(world)
        return recovery

    # ---------------------------------------------------------------- timeline

    def clock(self) -> str:
        """Returns the session clock for a timeline line."""
        return f"[{time.time() - self.t0:7.2f} s]"

    def show_episode(self, mark: int, summary: Heard) -> None:
        """Prints an episode's events and its summary: g's leaders, focus, params."""
        s = summary.message
        events = [h for h in self.inbox.since(mark, "episode/event")
                  if h.message["episode"] == s["episode"]]
        for h in events:
            e = h.message
            if e["kind"] == "trigger":
                self.say(f"{self._at(h.at)}  trigger {e['gesture']} p={e.get('prob', 0):.2f}")
            else:
                self.say(f"{self._at(h.at)}  episode {e['kind']} {s['episode']}")
        g = sorted(zip(s["gestures"]["names"], s["gestures"]["probs"], strict=True),
                   key=lambda x: -x[1])[:3]
        focus = "none" if s["focus"] is None else (
            f"{s['focus_source']} ({', '.join(f'{v:.2f}' for v in s['focus'])})")
        self.say(f"{self._at(summary.at)}  episode of {s['user']}, "
                 f"{s['ended'] - s['started']:.2f} s: g = "
                 + ", ".join(f"{n} {p:.2f}" for n, p in g) + f"; focus {focus}"
                 + (f"; params {s['params']}" if s["params"] else ""))

    def show_intent(self, heard: Heard) -> None:
        """Prints an intent with its leading action and object probabilities."""
        m = heard.message
        what = f"{m['action']}({m['object'] or ''})" if m["action"] else "no action"
        top = sorted(m["p_action"].items(), key=lambda x: -x[1])[:3]
        objs = sorted(m["p_object"].items(), key=lambda x: -x[1])[:3]
        self.say(f"{self._at(heard.at)}  intent {m['status']}: {what} confidence "
                 f"{m['confidence']:.2f}; p(action) "
                 + ", ".join(f"{a} {p:.2f}" for a, p in top) + "; p(object) "
                 + ", ".join(f"{o} {p:.2f}" for o, p in objs)
                 + (f" -- {m['reason']}" if m["reason"] and m["status"] != "accepted" else ""))

    def show_plan(self, mark: int, end: Heard) -> None:
        """Prints a plan's primitives when it started and how it ended."""
        m = end.message
        steps = ", ".join(f"{s['action']}({s['object'] or ''}) {s['state']}"
                          for s in m["sequence"])
        first = next((h for h in self.inbox.since(mark, "plan/status")
                      if h.message["intent"]["episode"] == m["intent"]["episode"]), end)
        self.say(f"{self._at(first.at)}  plan: " + " -> ".join(
            f"{s['action']}({s['object'] or ''})" for s in m["sequence"]))
        self.say(f"{self._at(end.at)}  plan {m['state']} after {end.at - first.at:.1f} s: "
                 f"{steps}" + (f" -- {m['error']}" if m["error"] else ""))

    def _at(self, t: float) -> str:
        return f"[{t - self.t0:7.2f} s]"


# `--faults all`: each of the seven services and the router killed once, at points where the
# bundled session is doing something that needs them: the robot in the middle of its first
# action (step 1), the planner in the middle of a four-action plan (step 3), the others while
# a gesture is being made, the router between steps.
ALL_FAULTS = ((0, "plan", "robot"), (1, "gesture", "dynamic-gesture"), (2, "plan", "planner"),
              (3, "gesture", "static-gesture"), (4, "gesture", "episode"),
              (5, "gesture", "intent"), (6, "before", "router"), (6, "gesture", "leap-bridge"))
PHASES = ("before", "gesture", "plan")


def parse_faults(text: str, steps: int) -> list[Fault]:
    """Parses a fault schedule: ``all`` or ``TARGET@STEP[:PHASE],...`` (STEP 1-based).

    PHASE is ``before`` (the step begins), ``gesture`` (default: halfway through the gesture)
    or ``plan`` (while the step's plan executes). ``robot`` stands for whichever robot service
    runs. ``all`` is `ALL_FAULTS`, its steps clamped to the session's length.

    Raises:
        ValueError: a malformed item (the message names it).
    """
    if text == "all":
        return [Fault(min(step, steps - 1), phase, target) for step, phase, target in ALL_FAULTS]
    out = []
    for item in filter(None, (s.strip() for s in text.split(","))):
        target, _, rest = item.partition("@")
        step_text, _, phase = rest.partition(":")
        if not step_text.isdigit() or not 1 <= int(step_text) <= steps:
            raise ValueError(f"fault {item!r}: give TARGET@STEP with STEP in 1..{steps}")
        if phase not in ("", *PHASES):
            raise ValueError(f"fault {item!r}: phase must be one of {', '.join(PHASES)}")
        out.append(Fault(int(step_text) - 1, phase or "gesture", target))
    return out
