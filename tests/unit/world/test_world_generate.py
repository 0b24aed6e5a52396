"""The random scene generator: valid, seeded, distributed as the paper describes."""

from collections import Counter

import numpy as np

from cbgo import wire
from cbgo.world import (
    DEFAULT_GRID,
    Scene,
    drawer_direction,
    paper_scene,
    random_scene,
    workspace_problems,
)
from cbgo.world.actions import reserved_columns
from cbgo.world.generate import PAPER_CUP_SIZES, TYPE_ORDER
from cbgo.world.scene import DRAWER_CAPACITY, MAX_STACK

SEEDS = range(400)


def test_every_generated_scene_is_consistent_and_fits_the_contract():
    for seed in SEEDS:
        scene = random_scene(seed)
        assert scene.problems() == [], (seed, scene.problems())
        message = scene.to_message(seq=seed)
        wire.validate(message, wire.SCENE_STATE, "cbgo/scene/state")
        assert Scene.from_dict(wire.decode(wire.encode(message))) == scene


def test_objects_are_the_leading_types_of_the_paper_with_unique_names():
    for seed in SEEDS:
        scene = random_scene(seed)
        types = tuple(o.type for o in scene.objects)
        assert 2 <= len(types) <= 7 and types == TYPE_ORDER[:len(types)]
        assert len(set(scene.names)) == len(scene.names)
        assert all(o.name.startswith(o.type) for o in scene.objects)


def test_stacking_containment_and_holding_are_consistent_with_positions():
    for seed in SEEDS:
        scene = random_scene(seed)
        for o in scene.objects:
            if o.on is not None:
                base = scene.get(o.on)
                assert base.type in ("box", "drawer") and scene.above(base.name) == o.name
                assert np.isclose(o.position[2], base.position[2] + (base.size + o.size) / 2)
                assert scene.stack_level(o.name) < MAX_STACK
            if o.inside is not None:
                assert o.type in ("cup", "box") and scene.get(o.inside).type == "drawer"
                assert o.on is None and scene.above(o.name) is None
            if o.on is None and o.inside is None and not scene.is_held(o.name):
                assert np.isclose(o.position[2], o.size / 2)
            if o.type == "drawer":
                assert DEFAULT_GRID.column_of(o.position)[0] == DEFAULT_GRID.shape[0] - 1
                assert len(scene.contents(o.name)) <= DRAWER_CAPACITY
        held = scene.robot.holding
        if held is not None:
            assert scene.get(held).position == scene.robot.tcp and not scene.robot.gripper_open
            assert scene.get(held).type in ("cup", "box")
        else:
            assert scene.robot.gripper_open
        assert DEFAULT_GRID.position(DEFAULT_GRID.cell_of(scene.robot.tcp)) == scene.robot.tcp


def test_the_same_seed_gives_the_same_scene_and_others_differ():
    assert random_scene(5) == random_scene(5)
    assert random_scene(5) != random_scene(6)
    rng_a, rng_b = np.random.default_rng(3), np.random.default_rng(3)
    assert [random_scene(rng_a) for _ in range(3)] == [random_scene(rng_b) for _ in range(3)]


def test_counts_states_and_holding_follow_the_papers_distribution():
    scenes = [random_scene(seed) for seed in range(2000)]
    counts = np.array([len(s.objects) for s in scenes])
    assert 3.3 < counts.mean() < 3.8 and counts.min() == 2 and counts.max() >= 6
    assert 0.4 < np.mean([s.robot.holding is not None for s in scenes]) < 0.5
    drawers = [o for s in scenes for o in s.objects if o.type == "drawer"]
    cups = [o for s in scenes for o in s.objects if o.type == "cup"]
    assert 0.45 < np.mean([d.open for d in drawers]) < 0.55
    assert 0.45 < np.mean([c.full for c in cups]) < 0.55
    assert np.mean([any(o.on for o in s.objects) for s in scenes]) > 0.2
    assert np.mean([any(o.inside for o in s.objects) for s in scenes]) > 0.1


# ------------------------------------------------------------------ the paper's distribution


def test_paper_scenes_put_drawers_on_every_column_and_cups_of_every_paper_size():
    scenes = [paper_scene(seed) for seed in range(1500)]
    drawers = [o for s in scenes for o in s.objects if o.type == "drawer"]
    columns = Counter(DEFAULT_GRID.column_of(d.position) for d in drawers)
    assert set(columns) == set(DEFAULT_GRID.columns())
    assert min(columns.values()) > 0.5 * len(drawers) / 16  # about uniform
    cups = Counter(o.size for s in scenes for o in s.objects if o.type == "cup")
    assert set(cups) == set(PAPER_CUP_SIZES) == {0.03, 0.04, 0.05, 0.06, 0.07}
    assert min(cups.values()) > 0.15 * sum(cups.values())
    assert {o.size for s in scenes for o in s.objects if o.type != "cup"} == {0.05, 0.11}


def test_paper_scenes_are_valid_fit_the_workspace_and_keep_every_tray_free():
    for seed in range(600):
        scene = paper_scene(seed)
        assert scene.problems() == [] and workspace_problems(scene) == [], seed
        types = tuple(o.type for o in scene.objects)
        assert 2 <= len(types) <= 7 and types == TYPE_ORDER[:len(types)]
        taken = reserved_columns(scene)
        table = [o for o in scene.objects
                 if o.on is None and o.inside is None and not scene.is_held(o.name)]
        assert len({DEFAULT_GRID.column_of(o.position) for o in table}) == len(table)
        for drawer in (o for o in table if o.type == "drawer"):
            i, j = DEFAULT_GRID.column_of(drawer.position)
            tray = (i + drawer_direction(drawer.position[0]), j)
            assert taken[tray] == drawer.name, seed  # nothing else stands in its way


def test_paper_scenes_are_seeded_and_leave_the_intent_datasets_scenes_alone():
    assert paper_scene(5) == paper_scene(5) and paper_scene(5) != paper_scene(6)
    assert random_scene(5) != paper_scene(5)
    assert all(DEFAULT_GRID.column_of(o.position)[0] == 3
               for s in (random_scene(seed) for seed in range(200))
               for o in s.objects if o.type == "drawer")
