"""Benchmark the simulated robot: each action on random scenes where it is feasible.

For every action, scenes come from the world model's seeded generator
(`cbgo.world.random_scene`), one seed after the other, until ``--scenes`` of them allow the
action on some object (checked by the world model on the settled physics); the object is
drawn at random among the feasible ones. Each scene is compiled, settled, the action executed
and verified from the physics. Printed per action:

- success: the physics check passed, over all feasible scenes; feasible means the world
  model's preconditions hold, and those the simulator adds (`Robot.precheck`: an empty
  gripper to grasp a handle, a move's goal cell free of objects); ``refused`` counts plans
  the simulator then turned down without moving (a move whose way is blocked by an object,
  a pour with no collision-free tilt);
- sim s and wall s per action, and their ratio, the real-time factor (goal: >= 10), also
  against the process's CPU time (what the figure is on a core of its own);
- compile s (MjSpec -> MjModel) and settle s per scene.

Runs in-process (no Zenoh): the figures are the simulator's own. ``--jobs N`` spreads actions
over N processes.

Examples::

    cbgo bench sim
    cbgo bench sim --scenes 10 --actions pick_up pour
    cbgo bench sim --jobs 2 --failures
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from cbgo import world
from cbgo.wire import ACTIONS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--scenes", type=int, default=50, help="feasible scenes per action [50]")
    parser.add_argument("--actions", nargs="+", choices=ACTIONS, default=list(ACTIONS),
                        metavar="ACTION", help="actions to run [all eleven]")
    parser.add_argument("--seed", type=int, default=0, help="first scene seed [0]")
    parser.add_argument("--jobs", type=int, default=1, help="processes [1]")
    parser.add_argument("--failures", action="store_true", help="list every failure")


@dataclass
class ActionStats:
    """The runs of one action."""

    action: str
    ok: int = 0
    refused: int = 0
    runs: int = 0
    sim_s: list[float] = field(default_factory=list)
    wall_s: list[float] = field(default_factory=list)
    cpu_s: list[float] = field(default_factory=list)
    compile_s: list[float] = field(default_factory=list)
    settle_wall_s: list[float] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    seeds_tried: int = 0


def _feasible(action: str, scene: world.Scene) -> list[str | None]:
    from cbgo.services.mujoco_sim.skills import missing_preconditions

    if missing_preconditions(action, scene):
        return []
    if action in world.OBJECT_AGNOSTIC:
        return [None] if world.feasible(action, None, scene) else []
    return [name for name in scene.names if world.feasible(action, name, scene)]


def run_action(action: str, scenes: int, seed: int) -> ActionStats:
    """Runs one action on `scenes` feasible random scenes, seeds from `seed` on."""
    from cbgo.services.mujoco_sim import scenes as scene_mod
    from cbgo.services.mujoco_sim.skills import Robot

    stats = ActionStats(action)
    rng = np.random.default_rng(seed + ACTIONS.index(action))
    s = seed
    while stats.runs < scenes:
        symbolic = world.random_scene(s)
        s += 1
        stats.seeds_tried += 1
        if not _feasible(action, symbolic):
            continue
        t0 = time.perf_counter()
        loaded = scene_mod.load(symbolic)
        stats.settle_wall_s.append(time.perf_counter() - t0)
        robot = Robot(loaded.sim)
        names = [None] if action in world.OBJECT_AGNOSTIC else list(loaded.sim.items)
        options = [n for n in names if robot.precheck(action, n) is None]
        if not options:
            continue  # the settled physics disagrees with the generator: not this action's run
        target = options[int(rng.integers(len(options)))]
        t0, c0 = time.perf_counter(), time.process_time()
        outcome = robot.execute(action, target, {})
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        stats.runs += 1
        stats.compile_s.append(loaded.compile_s)
        if outcome.ok:
            stats.ok += 1
        else:
            stats.refused += outcome.refused
            stats.failures.append(f"seed {s - 1} {action}({target or ''}): {outcome.error}")
        if not outcome.refused:
            stats.sim_s.append(outcome.sim_s)
            stats.wall_s.append(wall)
            stats.cpu_s.append(cpu)
    return stats


def _figures(runs: int, ok: int, refused: int, sim: float, wall: float, cpu: float,
             executed: int) -> str:
    n = max(executed, 1)
    return (f"{runs:>4} {100.0 * ok / max(runs, 1):>8.1f} {refused:>7} {sim / n:>7.2f} "
            f"{wall / n:>7.3f} {sim / max(wall, 1e-9):>8.1f} {sim / max(cpu, 1e-9):>7.1f}")


def _row(st: ActionStats) -> str:
    return (f"{st.action:<11} " + _figures(st.runs, st.ok, st.refused, sum(st.sim_s),
                                           sum(st.wall_s), sum(st.cpu_s), len(st.sim_s))
            + f" {np.mean(st.compile_s or [0]) * 1e3:>10.0f}"
            f" {np.mean(st.settle_wall_s or [0]) * 1e3:>8.0f}")


def run(args: argparse.Namespace) -> int:
    """Runs the benchmark and prints one row per action; returns 0."""
    t0 = time.perf_counter()
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(run_action, args.actions, [args.scenes] * len(args.actions),
                                    [args.seed] * len(args.actions)))
    else:
        results = [run_action(a, args.scenes, args.seed) for a in args.actions]
    print(f"{'action':<11} {'runs':>4} {'success%':>8} {'refused':>7} {'sim s':>7} "
          f"{'wall s':>7} {'RTF wall':>8} {'RTF cpu':>7} {'compile ms':>10} {'load ms':>8}")
    for st in results:
        print(_row(st), flush=True)
    total = _figures(sum(st.runs for st in results), sum(st.ok for st in results),
                     sum(st.refused for st in results), sum(sum(st.sim_s) for st in results),
                     sum(sum(st.wall_s) for st in results), sum(sum(st.cpu_s) for st in results),
                     sum(len(st.sim_s) for st in results))
    compiles = [c for st in results for c in st.compile_s]
    print(f"{'all':<11} {total} {np.mean(compiles or [0]) * 1e3:>10.0f}")
    print(f"compile: first {max(compiles or [0]) * 1e3:.0f} ms (meshes decoded), median "
          f"{np.median(compiles or [0]) * 1e3:.0f} ms; sim/wall/cpu per executed action; "
          f"RTF = sim s / wall s (or / CPU s of this process); bench took "
          f"{time.perf_counter() - t0:.0f} s")
    if args.failures:
        for st in results:
            for line in st.failures:
                print("  " + line)
    return 0
