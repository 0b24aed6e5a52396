"""Run the paper's story end to end: every service, a simulated user, a robot, and a report.

`cbgo demo` starts the router and the seven services locally (`cbgo up`), resets the robot's
world to the session's scene, and lets simulated users perform a scripted session (bundled:
``paper``): user1 picks up a full cup, pours it into an empty one, puts it into the closed
drawer (the behaviour tree opens the drawer first), grabs without looking at anything (too
ambiguous: the intent service asks back which object, user1 answers with a swipe to box1 and
a thumbs-up, and the robot picks it up); user2, whose left and right are swapped, picks up the
other cup and swipes right to move it left; user1 swipes right to move it back. Wherever the
intent service asks back, the simulated user answers with the scripted intent.

It prints a timeline (episode -> gestures -> intent with probabilities -> plan -> result) and
writes an output folder: ``session.mcap`` (every data message of the session, for
`cbgo replay`, `cbgo plot` or any MCAP tool), ``before.png``/``after.png`` (renders of the
world; dry-robot has none), ``episode.png`` (the paper's episode figure of one step),
``timeline.txt``, ``result.json`` and ``services.log``. It exits with 1 if any step did not end
as scripted, 2 on a usage or start-up error.

``--robot dry`` swaps mujoco-sim for dry-robot (no physics, no MuJoCo needed); ``--robot franka
--robot-ip IP`` for franka, a Franka Research 3 (or franky-sim, with the scene's objects in its
world) at IP, on which the scene is declared, not built. ``--faults all``
kills each service and the router once mid-session (SIGKILL) and reports how each came back;
``--no-start`` runs the session against services already running elsewhere (``--connect``);
personal intent models of user1/user2 stored there (`cbgo feedback`) can change the outcomes,
which is why the demo's own services get a fresh ``CBGO_DATA_DIR`` in the output folder.

Examples::

    cbgo demo                                  # MuJoCo robot, output in out/demo-<time>/
    cbgo demo --robot dry                      # the symbolic robot: fast, no physics
    cbgo demo --robot franka --robot-ip 127.0.0.1   # franky-sim, or a real FR3's address
    cbgo demo --robot dry --faults all         # kill -9 every process once; recovery times
    cbgo demo --faults planner@1:plan,router@4:before
    cbgo demo --no-start --connect tcp/10.0.0.5:7447 --robot dry   # a deployed system
    cbgo demo --session my-session.yaml -o out/mine
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from cbgo.cli.common import add_network_arguments, fail, session
from cbgo.config import DEFAULT_ROUTER_LISTEN
from cbgo.endpoints import check_can_listen, local_endpoint
from cbgo.errors import ConfigError

ROBOTS = {"mujoco": "mujoco-sim", "dry": "dry-robot", "franka": "franka"}
PIPELINE = ("leap-bridge", "static-gesture", "dynamic-gesture", "episode", "intent", "planner")
PLAN_TIMEOUT_S = {"mujoco-sim": 240.0, "dry-robot": 30.0, "franka": 300.0}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds demo's flags."""
    parser.add_argument("--robot", choices=sorted(ROBOTS), default=None,
                        help="which robot executes the plans: mujoco (mujoco-sim, physics), "
                             "dry (dry-robot, the symbolic world model) or franka (a Franka "
                             "Research 3 at --robot-ip) [mujoco; with --no-start, the one that "
                             "is alive]")
    parser.add_argument("--robot-ip", default="", metavar="IP",
                        help="with --robot franka: the arm's FCI address (franky-sim prints "
                             "its 127.0.0.x); without it, franka plans and checks every action "
                             "without moving (its dry run)")
    parser.add_argument("--session", default="paper", metavar="NAME|FILE",
                        help="the scripted session: a bundled name or a YAML file [paper]")
    parser.add_argument("-o", "--out", metavar="DIR",
                        help="output folder [out/demo-<date>-<time>]")
    parser.add_argument("--faults", default="", metavar="SCHEDULE",
                        help="kill processes mid-session: 'all' (each service and the router "
                             "once) or TARGET@STEP[:before|gesture|plan],... ('robot' = the "
                             "robot service)")
    parser.add_argument("--steps", default="", metavar="N,M-K",
                        help="run only these steps of the session (1-based), e.g. 1-3")
    parser.add_argument("--no-start", action="store_true",
                        help="do not start anything; run against the services at --connect")
    parser.add_argument("--router-listen", default=DEFAULT_ROUTER_LISTEN, metavar="ENDPOINT",
                        help=f"where the demo's own router listens [{DEFAULT_ROUTER_LISTEN}]")
    parser.add_argument("--ready-timeout", type=float, default=180.0, metavar="S",
                        help="how long the services may take to come up [180]")
    parser.add_argument("--plan-timeout", type=float, default=0.0, metavar="S",
                        help="how long one plan may take [240 with mujoco, 30 with dry, 300 "
                             "with franka]")
    parser.add_argument("--plot-step", type=int, default=1, metavar="N",
                        help="the step whose episode is drawn in episode.png [1]")
    add_network_arguments(parser)


# ============================================================================ helpers


def _select_steps(script, text: str) -> None:
    """Keeps only the chosen steps (``1,3-5``) of a session, in place."""
    if not text:
        return
    chosen: set[int] = set()
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        if not lo.isdigit() or (hi and not hi.isdigit()):
            fail(f"--steps: {part!r} is not N or N-M", 2)
        chosen.update(range(int(lo), int(hi or lo) + 1))
    if not chosen or min(chosen) < 1 or max(chosen) > len(script.steps):
        fail(f"--steps: choose steps in 1..{len(script.steps)}", 2)
    script.steps = [s for i, s in enumerate(script.steps, 1) if i in chosen]


def _start_system(args: argparse.Namespace, robot: str, out: Path) -> subprocess.Popen:
    """Starts `cbgo up` with the router and the services; its log goes to services.log."""
    try:
        check_can_listen([args.router_listen], "--router-listen",
                         hint="To play the session on the system there, add --no-start "
                              f"--connect {local_endpoint(args.router_listen)}.")
    except ConfigError as e:
        fail(str(e), 2)
    # Users' personal intent models (from earlier corrections) would change the outcomes.
    env = {**os.environ, "CBGO_DATA_DIR": str(out / "data")}
    if args.robot_ip:
        env["CBGO_ROBOT_IP"] = args.robot_ip
    argv = [sys.executable, "-m", "cbgo.cli.main", "up", "--no-color", "--router-listen",
            args.router_listen, "--connect", args.router_listen, *PIPELINE, robot]
    log = open(out / "services.log", "wb")  # noqa: SIM115 - the child owns it from here
    return subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env,
                            start_new_session=True)


def _stop_system(proc: subprocess.Popen | None) -> None:
    if proc is None or proc.poll() is not None:
        return
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def _render(runner, path: Path, say) -> str | None:
    """Saves a render of the world; returns why not when the robot cannot render."""
    from cbgo import keys as K
    from cbgo.demo.runner import DemoError

    try:
        reply = runner.query(runner.keys.of(K.SIM_RENDER), {"v": 1, "width": 800, "height": 600},
                             timeout=30.0)
    except DemoError as e:
        say(f"no render {path.name}: {e}")
        return str(e)
    if not reply.get("ok"):
        say(f"no render {path.name}: {reply.get('error')}")
        return reply.get("error")
    path.write_bytes(reply["png"])
    return None


def _plot(recording: Path, episode: str | None, output: Path, say) -> bool:
    if episode is None:
        say("no episode figure: the chosen step had no episode")
        return False
    done = subprocess.run([sys.executable, "-m", "cbgo.cli.main", "plot", "episode",
                           str(recording), "--episode", episode, "-o", str(output)],
                          capture_output=True, text=True, timeout=120)
    if done.returncode != 0:
        say(f"no episode figure: {done.stderr.strip()[-300:]}")
    return done.returncode == 0


# ============================================================================ run


def run(args: argparse.Namespace) -> int:
    """Starts the system (unless --no-start), runs the session, writes the report."""
    from cbgo.demo.session import load_session

    try:
        script = load_session(args.session)
    except ConfigError as e:
        fail(str(e), 2)
    _select_steps(script, args.steps)
    robot = ROBOTS[args.robot or "mujoco"]
    out = Path(args.out or time.strftime("out/demo-%Y%m%d-%H%M%S"))
    out.mkdir(parents=True, exist_ok=True)
    lines: list[str] = []

    def say(text: str) -> None:
        print(text, flush=True)
        lines.append(text)

    if args.robot_ip and (args.robot != "franka" or args.no_start):
        fail("--robot-ip is franka's address: it goes with --robot franka, and only when the "
             "demo starts the services (with --no-start, give it to the running franka)", 2)
    if args.faults and args.no_start:
        fail("--faults needs the demo to start the services itself (the kills go to local "
             "pids and `cbgo up` restarts them); drop --no-start", 2)
    proc = None
    if not args.no_start:
        proc = _start_system(args, robot, out)
        args.connect = [args.router_listen]
        args.connect_timeout = max(args.connect_timeout, 30.0)
        say(f"starting the router ({args.router_listen}) and {len(PIPELINE) + 1} services; "
            f"logs in {out / 'services.log'}")
    try:
        return _run_session(args, script, robot, out, say, lines)
    finally:
        _stop_system(proc)


def _run_session(args, script, robot: str, out: Path, say, lines: list[str]) -> int:
    from cbgo.demo.inbox import Inbox
    from cbgo.demo.runner import DemoError, Runner, parse_faults
    from cbgo.recording import Recorder

    try:
        faults = parse_faults(args.faults, len(script.steps)) if args.faults else []
    except ValueError as e:
        fail(str(e), 2)
    started = time.monotonic()
    with session(args, "cbgo-demo") as (sess, keys):
        recorder = Recorder(out / "session.mcap", prefix=keys.prefix, keys=[keys.data])
        inbox = Inbox(sess, keys, recorder)
        try:
            if args.no_start:
                robot = _robot_of_running_system(inbox, args.robot, say, args.ready_timeout)
            runner = Runner(sess, inbox, keys, script, say, robot,
                            args.plan_timeout or PLAN_TIMEOUT_S[robot], faults)
            report = _session_body(args, runner, inbox, script, robot, out, say, started)
        except DemoError as e:
            say(f"cbgo demo: {e}")
            report = None
        finally:
            inbox.close()
            recorder.close()
    if report is None:
        (out / "timeline.txt").write_text("\n".join(lines) + "\n")
        return 1
    results, timing = report
    # Messages on the followed keys that broke the contract were skipped by the timeline.
    timing["rejected_messages"] = inbox.rejected
    plotted = results and _plot(out / "session.mcap",
                                _plot_episode(results, args.plot_step), out / "episode.png", say)
    return _report(args, script, robot, out, results, runner.recoveries, timing, bool(plotted),
                   say, lines)


def _robot_of_running_system(inbox, chosen: str | None, say, timeout: float) -> str:
    """Returns the robot service of a running system: the one asked for, or the one alive.

    Waits for the first robot's liveliness token. A robot asked for (``--robot``) that is not
    the one alive ends the demo at once, naming the option that fits.
    """
    from cbgo.demo.runner import DemoError

    alive = inbox.wait_any(set(ROBOTS.values()), timeout)
    wanted = ROBOTS[chosen] if chosen else None
    if wanted and wanted not in alive and alive:
        other = sorted(alive)[0]
        flag = next(k for k, v in ROBOTS.items() if v == other)
        raise DemoError(f"--robot {chosen} asks for {wanted}, but the running system's robot "
                        f"is {other}: run with --robot {flag}")
    if wanted:
        return wanted
    if len(alive) == 1:
        (robot,) = alive
        say(f"the running system's robot: {robot}")
        return robot
    if len(alive) > 1:
        raise DemoError(f"two robots are alive ({', '.join(sorted(alive))}): choose one with "
                        f"--robot {'|'.join(sorted(ROBOTS))}")
    raise DemoError(f"no robot alive after {timeout:g} s: neither "
                    f"{' nor '.join(sorted(ROBOTS.values()))} (is the system up at --connect?)")


def _session_body(args, runner, inbox, script, robot, out, say, started):
    expected = runner.expected()
    if not inbox.wait_alive(expected, args.ready_timeout):
        from cbgo.demo.runner import DemoError
        missing = ", ".join(sorted(expected - inbox.alive))
        raise DemoError(f"not alive after {args.ready_timeout:g} s: {missing} (see "
                        f"{out / 'services.log'})")
    ready_s = time.monotonic() - started
    say(f"ready: {', '.join(sorted(expected))} alive after {ready_s:.1f} s")
    if args.no_start:
        _check_intent_settings(runner, say)
    runner.reset(script.scene)
    say(f"the world is reset to the '{script.name}' scene: "
        + ", ".join(f"{o['name']} ({o['type']})" for o in script.scene["objects"]))
    _render(runner, out / "before.png", say)
    runner.t0 = time.time()
    results = runner.run()
    session_s = time.time() - runner.t0
    _render(runner, out / "after.png", say)
    return results, {"ready_s": ready_s, "session_s": session_s}


def _check_intent_settings(runner, say) -> None:
    """Warns about intent settings of a running system that change the scripted outcomes."""
    status = runner.status("intent") or {}
    config = status.get("config", {})
    if config.get("accept_repairable") is False:
        say("warning: intent runs with --no-accept-repairable: intents whose preconditions "
            "the planner repairs (a cup into a closed drawer) will be refused")


def _plot_episode(results, step: int) -> str | None:
    index = min(max(step, 1), len(results)) - 1
    return results[index].episode


def _report(args, script, robot, out, results, recoveries, timing, plotted, say,
            lines) -> int:
    passed = sum(r.ok for r in results)
    say(f"\nsession '{script.name}': {passed}/{len(results)} steps as scripted in "
        f"{timing['session_s']:.1f} s (robot: {robot}; ready after {timing['ready_s']:.1f} s)")
    if timing["rejected_messages"]:
        say(f"warning: {timing['rejected_messages']} messages broke the contract and were "
            "ignored (see `cbgo echo` for which)")
    for r in results:
        mark = "ok " if r.ok else "FAIL"
        intent = r.intent or {}
        got = "no intent" if not intent else intent["status"] if intent["status"] != (
            "accepted") else f"{intent['action']}({intent.get('object') or ''})"
        plan = (r.plan or {}).get("state", "-")
        say(f"  {mark} {r.index + 1}. {r.step.user:6} expect {r.step.expect.label():24} got "
            f"{got:24} plan {plan:8} attempts {r.attempts}")
    if recoveries:
        say("\nfaults (kill -9 -> liveliness token back; every token back):")
        for rec in recoveries:
            back = "never" if rec.back_s is None else f"{rec.back_s:6.2f} s"
            every = "never" if rec.all_back_s is None else f"{rec.all_back_s:6.2f} s"
            say(f"  {'ok ' if rec.ok else 'FAIL'} {rec.target:16} step {rec.step + 1} "
                f"{rec.phase:8} back {back}  all back {every}  pid {rec.pid_before} -> "
                f"{rec.pid_after}" + (f"  others restarted: {rec.others_restarted}"
                                      if rec.others_restarted else ""))
    files = [p.name for p in sorted(out.iterdir()) if p.is_file()] + ["timeline.txt",
                                                                      "result.json"]
    say(f"\noutput in {out}/: {', '.join(sorted(set(files)))}")
    (out / "timeline.txt").write_text("\n".join(lines) + "\n")
    (out / "result.json").write_text(json.dumps(_result_json(script, robot, results,
                                                             recoveries, timing, plotted),
                                                indent=2) + "\n")
    ok = passed == len(results) and all(rec.ok for rec in recoveries)
    return 0 if ok else 1


def _result_json(script, robot, results, recoveries, timing, plotted) -> dict:
    def step(r) -> dict:
        intent, plan = r.intent or {}, r.plan or {}
        return {"step": r.index + 1, "user": r.step.user, "say": r.step.say, "ok": r.ok,
                "problems": r.problems, "attempts": r.attempts, "lost": r.lost,
                "expect": vars(r.step.expect), "episode": r.episode,
                "intent": {k: intent.get(k) for k in ("status", "action", "object",
                                                      "confidence", "reason", "p_action",
                                                      "p_object", "clarification")}
                if intent else None,
                "plan": {"state": plan.get("state"), "error": plan.get("error"),
                         "sequence": [[s["action"], s["object"], s["state"]]
                                      for s in plan.get("sequence", [])]} if plan else None,
                "question": r.question, "answers": r.answers,
                "seconds": round(r.ended_at - r.started_at, 3)}
    return {"session": script.name, "robot": robot, **timing, "episode_figure": plotted,
            "steps": [step(r) for r in results],
            "faults": [{**vars(rec), "ok": rec.ok} for rec in recoveries]}
