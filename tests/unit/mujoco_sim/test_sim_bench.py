"""`cbgo bench sim`: its own scene generator stays inside the workspace and covers it, and the
printed report accounts for every feasible action of its scenes."""

import argparse

import numpy as np
import pytest

from cbgo import world
from cbgo.services.mujoco_sim import scenes
from cbgo.services.mujoco_sim.skills import Robot, missing_preconditions
from cbgo.wire import ACTIONS
from cbgo_tools.mujoco_sim import bench


def test_the_independent_generator_stays_inside_the_workspace_and_covers_it():
    rng = np.random.default_rng(11)
    drawn = [bench.workspace_scene(rng) for _ in range(300)]
    refused = [r for r in map(world.reset_refusal, drawn) if r is not None]
    assert len(refused) <= 3, refused  # footprints never overlap by construction
    covers = [bench.coverage(s) for s in drawn]
    assert len({c for cov in covers for c in cov["columns"]}) == 16
    # drawers anywhere (the near ones open away from the robot)
    assert {c for cov in covers for c in cov["drawer_columns"]} == set(world.DEFAULT_GRID.columns())
    assert {cov["level"] for cov in covers} == {0, 1, 2, 3}
    assert max(cov["tower"] for cov in covers) == world.workspace_info()["max_stack"]
    assert sum(cov["in_open"] for cov in covers) > 10
    assert sum(cov["in_closed"] for cov in covers) > 10
    assert 0.3 < np.mean([cov["held"] for cov in covers]) < 0.7


def _table(lines):
    rows = {}
    for line in lines[1:len(ACTIONS) + 2]:
        name, *cells = line.split()
        rows[name] = [int(c) for c in cells[:4]] + [int(cells[5])]
    return rows


@pytest.fixture(scope="module")
def two_scenes():
    return bench.run_scenes(2, seed=4)


def test_every_feasible_action_of_each_scene_is_tried_once_and_checked(two_scenes):
    for run in two_scenes:
        symbolic, _, _ = bench.draw_scene(4, run.index, "independent")
        observed = Robot(scenes.load(symbolic).sim).symbolic()
        expected = sorted(
            (a, o) for a in ACTIONS
            for o in ([None] if a in world.OBJECT_AGNOSTIC else observed.names)
            if world.feasible(a, o, observed) and missing_preconditions(a, observed) is None)
        assert expected, "a scene with nothing to do tests nothing"
        assert sorted((t.action, t.obj) for t in run.trials) == expected
        for t in run.trials:
            assert t.ok == (t.error is None) and not (t.ok and t.refused)
            assert isinstance(t.inconsistent, list)


def test_the_report_counts_add_up_to_the_trials(two_scenes):
    lines = bench.report(two_scenes)
    assert lines[0].split()[:6] == ["action", "tried", "done", "refused", "failed", "success%"]
    rows = _table(lines)
    assert list(rows) == [*ACTIONS, "all"]
    trials = [t for r in two_scenes for t in r.trials]
    for name, (tried, done, refused, failed, inconsistent) in rows.items():
        mine = [t for t in trials if name in ("all", t.action)]
        assert tried == len(mine) == done + refused + failed
        assert done == sum(t.ok for t in mine) and refused == sum(t.refused for t in mine)
        assert inconsistent == sum(bool(t.inconsistent) for t in mine)
    assert [sum(r[k] for n, r in rows.items() if n != "all") for k in range(5)] == rows["all"]
    assert lines[len(ACTIONS) + 2].startswith("scenes: 2 drawn, 2 run")
    listed = [line for line in lines if line.startswith(("  refused:", "  failed:"))]
    assert len(listed) == rows["all"][2] + rows["all"][3]


def test_the_cli_entry_prints_the_report(capsys):
    parser = argparse.ArgumentParser()
    bench.add_arguments(parser)
    assert bench.run(parser.parse_args(["--scenes", "1", "--seed", "4",
                                        "--actions", "move_up", "move_down"])) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[0] == "action" and [line.split()[0] for line in out[1:4]] == [
        "move_up", "move_down", "all"]
    assert out[-1].startswith("generator independent, seed 4")
