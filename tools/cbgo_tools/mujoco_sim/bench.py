"""Benchmark the simulated robot: every feasible action on random scenes it was not tuned on.

Three scene generators (``--generator``):

- ``independent`` (the default): `workspace_scene`, a generator of its own (not the world
  model's), drawn inside the workspace of the contract (`cbgo.world.workspace_info`, what
  ``cbgo/sim/info`` answers): 0-2 drawers in any column (the column their tray opens into
  kept free), 0-2 boxes and 1-3 cups of every documented size, anywhere in their cell; towers
  up to the documented height, objects in open and closed drawers, a held cup or box, full
  and empty cups, the TCP on every level. A scene the workspace refuses is drawn again.
- ``paper``: the paper's scene distribution (`cbgo.world.paper_scene`: drawers on any column,
  cups of 0.03 … 0.07 m). A scene refused at reset is *not* drawn again but counted: the goal
  is none; the last line sums up scenes refused at reset, feasible actions done (goal ≥ 99 %),
  physical refusals and inconsistent outcomes.
- ``world``: the world model's `cbgo.world.random_scene` (drawers in the back row).

Each scene is loaded as ``cbgo/sim/reset`` would (one that does not settle as described is
counted and skipped). Every feasible (action, object) of the settled scene is then tried, each
on a fresh copy of the scene: feasible means the world model's preconditions hold
(`cbgo.world.candidates`) and the one the simulator adds as a precondition
(`skills.missing_preconditions`: an empty gripper to grasp a handle). After every action, done
or not, the scene read from the physics is checked with `cbgo.world.check_consistent`.
Printed:

- per action kind: tried, done, refused (the simulator turned a feasible action down without
  moving: a physical refusal), failed (it moved and its check failed), success %, scenes left
  inconsistent, act wall time p50/p99 and simulated time p50 over the executed actions;
- every physical refusal and failure with its reason, every inconsistent scene with its
  contradictions, and every scene that reset refused or did not settle as described.

Runs in-process (no Zenoh): the figures are the simulator's own. ``--jobs N`` spreads scenes
over N processes; results do not depend on it (each scene has its own seed).

Examples::

    cbgo bench sim
    cbgo bench sim --generator paper --scenes 100
    cbgo bench sim --scenes 5 --seed 3
    cbgo bench sim --actions put_into open close --jobs 2
    cbgo bench sim --generator world
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from cbgo import world
from cbgo.wire import ACTIONS
from cbgo.world import Robot as RobotState
from cbgo.world import Scene, SceneObject

GENERATORS = ("independent", "paper", "world")
MAX_DRAWS = 50  # scenes drawn at most for one scene index before giving up


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--scenes", type=int, default=100, help="random scenes [100]")
    parser.add_argument("--seed", type=int, default=0, help="seed of the scene generator [0]")
    parser.add_argument("--actions", nargs="+", choices=ACTIONS, default=list(ACTIONS),
                        metavar="ACTION", help="action kinds to try [all eleven]")
    parser.add_argument("--generator", choices=GENERATORS, default="independent",
                        help="independent (this bench's), paper (the paper's distribution, "
                             "cbgo.world.paper_scene: a scene refused at reset is counted, not "
                             "redrawn) or world (cbgo.world.random_scene) [independent]")
    parser.add_argument("--jobs", type=int, default=1, help="processes [1]")


# --------------------------------------------------------------------------- scenes


def workspace_scene(rng: np.random.Generator, info: dict | None = None) -> Scene:
    """Returns a random scene inside the documented workspace (see the module docstring).

    Built only from `info` (a ``cbgo/sim/info`` workspace), not from the world model's grid.
    The scene may still be one the workspace refuses (two footprints touching): callers judge
    it with `cbgo.world.reset_refusal`.
    """
    info = world.workspace_info() if info is None else info
    xs, ys = info["columns_x"], info["columns_y"]
    cell = min(np.diff(xs).min(), np.diff(ys).min())
    free = [(i, j) for i in range(len(xs)) for j in range(len(ys))]
    objects: list[SceneObject] = []
    counts = {"drawer": int(rng.integers(0, 3)), "box": int(rng.integers(0, 3)),
              "cup": int(rng.integers(1, 4))}
    for kind in ("drawer", "box", "cup"):
        for n in range(counts[kind]):
            lo, hi = info["sizes"][kind]["min"], info["sizes"][kind]["max"]
            obj = SceneObject(f"{kind}{n + 1}", kind, (0.0, 0.0, 0.0),
                              round(float(rng.uniform(lo, hi)), 3))
            obj.full = kind == "cup" and bool(rng.random() < 0.5)
            obj.open = kind == "drawer" and bool(rng.random() < 0.5)
            if kind == "drawer" or not _rest_somewhere(obj, objects, rng, info):
                if not _stand_on_table(obj, free, rng, info, cell):
                    continue  # no column left for it
            objects.append(obj)
    scene = Scene(objects, _robot(objects, rng, info))
    for obj in objects:
        if obj.on is None and obj.inside is None and not scene.is_held(obj.name):
            obj.position = (*obj.position[:2], obj.size / 2)
    scene.settle()
    return scene


def _stand_on_table(obj: SceneObject, free: list, rng: np.random.Generator, info: dict,
                    cell: float) -> bool:
    """Puts an object on a free column, anywhere in its cell and the table area.

    A drawer also takes the column its tray opens into, and stays on its column's side of
    ``drawer_opens_away_below_x`` (which way it opens is the column's).
    """
    xs, ys, area = info["columns_x"], info["columns_y"], info["table_area"]
    room = max(0.0, (cell - obj.size) / 2 - 0.002)
    options = [c for c in free if obj.type != "drawer" or _tray_column(c, info) in free]
    if not options:
        return False
    i, j = options[int(rng.integers(len(options)))]
    free.remove((i, j))
    x = float(np.clip(xs[i] + rng.uniform(-room, room), *area["x"]))
    y = float(np.clip(ys[j] + rng.uniform(-room, room), *area["y"]))
    if obj.type == "drawer":
        free.remove(_tray_column((i, j), info))
        split = info.get("drawer_opens_away_below_x", np.inf)
        x = min(x, split - 0.001) if xs[i] < split else max(x, split)
    obj.position = (round(x, 4), round(y, 4), 0.0)
    return True


def _tray_column(column: tuple[int, int], info: dict) -> tuple[int, int] | None:
    """Returns the column a drawer standing on `column` opens its tray into (None: off the grid).

    Towards the robot (−x) from ``drawer_opens_away_below_x`` on, away from it nearer.
    """
    xs = info["columns_x"]
    way = 1 if xs[column[0]] < info.get("drawer_opens_away_below_x", -np.inf) else -1
    i = column[0] + way
    return (i, column[1]) if 0 <= i < len(xs) else None


def _rest_somewhere(obj: SceneObject, objects: list[SceneObject], rng: np.random.Generator,
                    info: dict) -> bool:
    """Puts a cup or box on a free support or into a drawer with room (or leaves it)."""
    scene = Scene(objects)
    supports = [o.name for o in objects if o.type in ("box", "drawer") and o.inside is None
                and scene.above(o.name) is None
                and scene.stack_level(o.name) + 2 <= info["max_stack"]]
    drawers = [o.name for o in objects if o.type == "drawer"
               and len(scene.contents(o.name)) < info["drawer_capacity"]]
    roll = rng.random()
    if supports and roll < 0.35:
        obj.on = supports[int(rng.integers(len(supports)))]
        return True
    if drawers and roll < 0.6:
        obj.inside = drawers[int(rng.integers(len(drawers)))]
        return True
    return False


def _robot(objects: list[SceneObject], rng: np.random.Generator, info: dict) -> RobotState:
    """Holds a free cup or box half of the time; the TCP on any cell (held: above level 0)."""
    scene = Scene(objects)
    free = [o.name for o in objects if o.type != "drawer" and scene.is_free(o.name)
            and o.on is None]
    xs, ys, zs = info["columns_x"], info["columns_y"], info["levels_z"]
    held = free[int(rng.integers(len(free)))] if free and rng.random() < 0.5 else None
    k = int(rng.integers(1 if held else 0, len(zs)))
    tcp = (xs[int(rng.integers(len(xs)))], ys[int(rng.integers(len(ys)))], zs[k])
    return RobotState(tcp, gripper_open=held is None, holding=held)


def draw_scene(seed: int, index: int, generator: str) -> tuple[Scene | None, int, list[str]]:
    """Returns scene `index` of a run, how many draws it took and the refusals on the way.

    A scene that `cbgo.world.reset_refusal` refuses is drawn again (at most `MAX_DRAWS`),
    except for the ``paper`` generator, whose refusals count: None and the refusal.
    """
    rng = np.random.default_rng([seed, index])
    refusals = []
    for draw in range(1, MAX_DRAWS + 1):
        scene = _generate(generator, rng)
        reason = world.reset_refusal(scene)
        if reason is None:
            return scene, draw, refusals
        refusals.append(reason)
        if generator == "paper":
            break
    return None, len(refusals), refusals


def _generate(generator: str, rng: np.random.Generator) -> Scene:
    if generator == "independent":
        return workspace_scene(rng)
    if generator == "paper":
        return world.paper_scene(rng)
    return world.random_scene(rng)


# --------------------------------------------------------------------------- runs


@dataclass
class Trial:
    """One action tried on a fresh copy of a scene."""

    scene: int
    action: str
    obj: str | None
    ok: bool
    refused: bool
    error: str | None
    wall_s: float
    sim_s: float
    inconsistent: list[str]


@dataclass
class SceneRun:
    """What happened to one scene: its trials, or why it was not run."""

    index: int
    draws: int
    refused_at_reset: list[str] = field(default_factory=list)
    gave_up: bool = False  # refused at reset, not drawn again (paper) or too often
    not_settled: list[str] = field(default_factory=list)
    start_inconsistent: list[str] = field(default_factory=list)
    trials: list[Trial] = field(default_factory=list)
    covers: dict = field(default_factory=dict)


def coverage(scene: Scene) -> dict:
    """Returns what a scene covers: table columns, the TCP's level, towers, drawers, held."""
    grid = world.DEFAULT_GRID
    table = [o for o in scene.objects
             if o.on is None and o.inside is None and not scene.is_held(o.name)]
    return {"columns": sorted({grid.column_of(o.position) for o in table}),
            "drawer_columns": sorted({grid.column_of(o.position) for o in table
                                      if o.type == "drawer"}),
            "level": grid.cell_of(scene.robot.tcp)[2],
            "tower": max([scene.stack_level(o.name) + 1 for o in scene.objects] or [0]),
            "in_open": sum(o.inside is not None and scene.get(o.inside).open
                           for o in scene.objects),
            "in_closed": sum(o.inside is not None and not scene.get(o.inside).open
                             for o in scene.objects),
            "held": scene.robot.holding is not None}


def feasible_actions(scene: Scene, actions=ACTIONS) -> list[tuple[str, str | None]]:
    """Returns every (action, object) the preconditions allow on a scene (see the docstring)."""
    from cbgo.services.mujoco_sim.skills import missing_preconditions

    return [(a, o) for a, o in world.candidates(scene)
            if a in actions and missing_preconditions(a, scene) is None]


def run_scene(seed: int, index: int, generator: str = "independent",
              actions=ACTIONS) -> SceneRun:
    """Draws scene `index` and tries every feasible action on it, each on a fresh copy."""
    from cbgo.services.mujoco_sim import observe, scenes
    from cbgo.services.mujoco_sim.skills import Robot

    symbolic, draws, refusals = draw_scene(seed, index, generator)
    run = SceneRun(index, draws, refusals, gave_up=symbolic is None)
    if symbolic is None:
        return run
    run.covers = coverage(symbolic)
    loaded = scenes.load(symbolic)
    run.not_settled = scenes.mismatches(loaded.sim, loaded.scene)
    run.start_inconsistent = world.check_consistent(observe.scene_state(loaded.sim, 0))
    if run.not_settled:
        return run  # sim/reset answers ok: false; nobody acts on such a world
    todo = feasible_actions(Robot(loaded.sim).symbolic(), actions)
    for n, (action, obj) in enumerate(todo):
        sim = loaded.sim if n == 0 else scenes.load(symbolic).sim
        t0 = time.perf_counter()
        outcome = Robot(sim).execute(action, obj, {})
        wall = time.perf_counter() - t0
        run.trials.append(Trial(index, action, obj, outcome.ok, outcome.refused, outcome.error,
                                wall, outcome.sim_s,
                                world.check_consistent(observe.scene_state(sim, 0))))
    return run


def run_scenes(count: int, seed: int, generator: str = "independent", actions=ACTIONS,
               jobs: int = 1) -> list[SceneRun]:
    """Runs `count` scenes (in `jobs` processes) with a progress bar on stderr."""
    from tqdm import tqdm

    bar = tqdm(total=count, desc="scenes", unit="scene", file=sys.stderr, disable=None)
    args = ([seed] * count, range(count), [generator] * count, [tuple(actions)] * count)
    try:
        if jobs > 1:
            with ProcessPoolExecutor(jobs) as pool:
                return [_advance(bar, r) for r in pool.map(run_scene, *args)]
        return [_advance(bar, run_scene(*a)) for a in zip(*args, strict=True)]
    finally:
        bar.close()


def _advance(bar, run: SceneRun) -> SceneRun:
    bar.update(1)
    return run


# --------------------------------------------------------------------------- report

HEADER = (f"{'action':<11} {'tried':>5} {'done':>5} {'refused':>7} {'failed':>6} "
          f"{'success%':>8} {'inconsistent':>12} {'wall p50':>8} {'wall p99':>8} {'sim p50':>7}")


def row(name: str, trials: list[Trial]) -> str:
    """Returns one line of the table over some trials (times over the executed ones, s)."""
    done = sum(t.ok for t in trials)
    refused = sum(t.refused for t in trials)
    executed = [t for t in trials if not t.refused]
    wall = [t.wall_s for t in executed] or [float("nan")]
    sim = [t.sim_s for t in executed] or [float("nan")]
    success = 100.0 * done / len(trials) if trials else float("nan")
    return (f"{name:<11} {len(trials):>5} {done:>5} {refused:>7} {len(trials) - done - refused:>6}"
            f" {success:>8.1f} {sum(bool(t.inconsistent) for t in trials):>12}"
            f" {np.percentile(wall, 50):>8.3f} {np.percentile(wall, 99):>8.3f}"
            f" {np.percentile(sim, 50):>7.2f}")


def report(runs: list[SceneRun], actions=ACTIONS) -> list[str]:
    """Returns the printed report of a run.

    The table, what the scenes covered, then every refusal, failure and inconsistency with
    its reason.
    """
    trials = [t for r in runs for t in r.trials]
    lines = [HEADER] + [row(a, [t for t in trials if t.action == a]) for a in actions]
    lines.append(row("all", trials))
    ran = [r for r in runs if not (r.gave_up or r.not_settled)]
    lines.append(f"scenes: {len(runs)} drawn, {len(ran)} run, "
                 f"{sum(len(r.refused_at_reset) - r.gave_up for r in runs)} redrawn "
                 f"(refused at reset), {sum(r.gave_up for r in runs)} refused at reset, "
                 f"{sum(bool(r.not_settled) for r in runs)} not settled as described, "
                 f"{sum(bool(r.start_inconsistent) for r in runs)} inconsistent at start, "
                 f"{sum(bool(t.inconsistent) for t in trials)} inconsistent after an action")
    lines.append(_coverage_line([r.covers for r in ran if r.covers]))
    lines.append(summary(runs))
    for t in trials:
        if not t.ok:
            kind = "refused" if t.refused else "failed"
            lines.append(f"  {kind}: scene {t.scene} {t.action}({t.obj or ''}): {t.error}")
        if t.inconsistent:
            lines.append(f"  inconsistent: scene {t.scene} after {t.action}({t.obj or ''}): "
                         + "; ".join(t.inconsistent))
    for r in runs:
        for what, problems in (("reset refused", r.refused_at_reset[-1:]),
                               ("not settled", r.not_settled),
                               ("inconsistent at start", r.start_inconsistent)):
            if problems:
                lines.append(f"  {what}: scene {r.index}: " + "; ".join(problems))
    return lines


def summary(runs: list[SceneRun]) -> str:
    """Returns the run in one line: the figures the paper-scene goals are stated in."""
    trials = [t for r in runs for t in r.trials]
    done = sum(t.ok for t in trials)
    share = 100.0 * done / len(trials) if trials else float("nan")
    return (f"summary: {len(runs)} scenes, {sum(r.gave_up for r in runs)} refused at reset, "
            f"{sum(bool(r.not_settled) for r in runs)} not settled; feasible actions done "
            f"{done} of {len(trials)} ({share:.1f} %), {sum(t.refused for t in trials)} "
            f"refused, {sum(not t.ok and not t.refused for t in trials)} failed; "
            f"{sum(bool(t.inconsistent) for t in trials)} inconsistent outcomes")


def _coverage_line(covers: list[dict]) -> str:
    if not covers:
        return "covered: nothing"
    towers = np.bincount([c["tower"] for c in covers])
    return (f"covered: {len({col for c in covers for col in c['columns']})} table columns, "
            f"drawers in {len({col for c in covers for col in c['drawer_columns']})}, "
            f"TCP levels {sorted({c['level'] for c in covers})}, scenes with a tower of "
            + ", ".join(f"{h}: {n}" for h, n in enumerate(towers) if n and h > 1)
            + f", objects in open drawers {sum(c['in_open'] for c in covers)}, in closed "
            f"{sum(c['in_closed'] for c in covers)}, held {sum(c['held'] for c in covers)}")


def run(args: argparse.Namespace) -> int:
    """Runs the benchmark and prints the report; returns 0."""
    t0 = time.perf_counter()
    runs = run_scenes(args.scenes, args.seed, args.generator, args.actions, args.jobs)
    for line in report(runs, args.actions):
        print(line)
    print(f"generator {args.generator}, seed {args.seed}; times in s per executed action "
          f"(wall: this process, sim: simulated); bench took {time.perf_counter() - t0:.0f} s")
    return 0
