"""Dataset generation follows the decision tables, discards null entries, shuffles D5."""

import dataclasses

import numpy as np
import pytest

from cbgo.errors import ConfigError
from cbgo.services.intent import datasets
from cbgo.wire import ACTIONS, OBJECT_TYPES


def test_the_vendored_tables_have_the_papers_dimensions():
    tables = datasets.load_tables()
    assert len(tables.gestures) == 9 and tables.users == ("user1", "user2")
    assert tables.gesture("D1", "pour", "box", 1, "user2") == "rotate"
    assert tables.gesture("D2", "open", "drawer", 0, "user1") == "grab"
    assert tables.gesture("D3", "move_left", "cup", 0, "user2") == "swipe_right"
    assert tables.gesture("D4", "pick_up", "box", 1, "user1") is None
    assert tables.gesture("D4", "pick_up", "box", 0, "user1") == "grab"
    assert tables.gesture("D5", "put_into", "drawer", 1, "user2") == "point"


@pytest.mark.parametrize("name", datasets.DATASETS)
def test_every_observation_follows_its_table_in_the_targets_context(name):
    tables = datasets.load_tables()
    for s in datasets.samples(name, 150, seed=3):
        target = s.scene.get(s.target)
        expected = tables.gesture(name, s.action, target.type, s.scene.state_bit(s.target),
                                  s.user)
        assert expected is not None and s.gesture == expected
        assert np.isclose(s.g.sum(), 1.0) and (s.g >= 0).all()
        assert np.linalg.norm(s.focus - np.asarray(target.position)) < 0.1
        assert not s.scene.is_hidden(s.target)
        pairs = datasets.intent_pairs(s.scene)
        assert (s.action, s.target) in pairs


def test_draws_whose_table_entry_is_null_are_discarded():
    tables = datasets.load_tables()
    no_moves = {a: (None if a.startswith("move") else g)
                for a, g in tables.tables["D1"].items()}
    stub = dataclasses.replace(tables, tables={**tables.tables, "D1": no_moves})
    rng = np.random.default_rng(0)
    draws = [datasets.draw("D1", rng, stub) for _ in range(300)]
    kept = [d for d in draws if d is not None]
    assert len(kept) < 200 and kept
    assert not any(d.action.startswith("move") for d in kept)
    ds = datasets.make("D1", 400, seed=1)
    assert not {"put_on", "close"} & {ACTIONS[a] for a in ds.action}  # null in D1's table


def test_the_gesture_vector_is_a_noisy_normalised_one_hot():
    rng = np.random.default_rng(0)
    gestures = datasets.load_tables().gestures
    vectors = np.array([datasets.gesture_vector("grab", gestures, rng) for _ in range(2000)])
    assert np.allclose(vectors.sum(1), 1.0)
    assert np.mean(vectors.argmax(1) == gestures.index("grab")) > 0.99
    assert 0.3 < vectors[:, gestures.index("grab")].mean() < 0.6


def test_d5_is_d4_with_the_object_order_shuffled():
    d4 = list(datasets.samples("D4", 100, seed=9))
    d5 = list(datasets.samples("D5", 100, seed=9))
    for a, b in zip(d4, d5, strict=True):
        assert (a.action, a.target, a.user, a.gesture) == (b.action, b.target, b.user, b.gesture)
        assert np.allclose(a.g, b.g) and sorted(a.scene.names) == sorted(b.scene.names)
    assert sum(a.scene.names != b.scene.names for a, b in zip(d4, d5, strict=True)) > 50
    ds5 = datasets.to_dataset(d5)
    slot_types = [OBJECT_TYPES[t] for t in ds5.obj_type[:, 0]]
    assert len(set(slot_types)) == 3  # slot 0 no longer always holds cup1


def test_a_dataset_file_round_trips_without_pickles(tmp_path):
    ds = datasets.make("D3", 60, seed=2)
    path = ds.save(tmp_path / "d3.npz")
    loaded = datasets.Dataset.load(path)
    assert loaded.meta == ds.meta and len(loaded) == 60
    for key, value in ds.arrays.items():
        assert np.array_equal(loaded.arrays[key], value), key
    with np.load(path, allow_pickle=False) as raw:
        assert raw["obj_name"].dtype.kind == "U"
    target = loaded.obj_name[np.arange(60), loaded.target]
    assert all(t for t in target)
    assert loaded.feasible[np.arange(60), loaded.action, loaded.target].all()


def test_a_foreign_file_is_refused_with_the_reason(tmp_path):
    np.savez(tmp_path / "x.npz", a=np.zeros(3), meta=np.array('{"format": "other"}'))
    with pytest.raises(ConfigError, match="not a cbgo-intent-dataset/1"):
        datasets.Dataset.load(tmp_path / "x.npz")
    with pytest.raises(ConfigError, match="unknown dataset"):
        datasets.make("D9", 10)


def test_cbgo_dataset_make_writes_a_file_that_info_describes(tmp_path, capsys):
    from cbgo.cli.main import main

    path = tmp_path / "d2.npz"
    with pytest.raises(SystemExit) as made:
        main(["data", "intent", "make", "D2", "-n", "25", "--seed", "4", "-o", str(path)])
    assert made.value.code == 0 and len(datasets.Dataset.load(path)) == 25
    with pytest.raises(SystemExit) as shown:
        main(["data", "intent", "info", str(path)])
    out = capsys.readouterr().out
    assert shown.value.code == 0 and "D2 (25 observations, seed 4" in out and "g float32" in out


# ---------------------------------------------------------------- repairable intents


def test_the_repair_rule_opens_closed_drawers_and_sets_held_objects_aside():
    from cbgo.world.repairs import after_repairs
    from cbgo_tools.intent.evaluate import demo_scene

    holding = demo_scene()  # full cup1 in the gripper, drawer1 closed
    opened = after_repairs("put_into", "drawer1", holding)
    assert opened is not None and opened.get("drawer1").open and not holding.get("drawer1").open
    set_aside = after_repairs("pick_up", "cup2", holding)
    assert set_aside is not None and set_aside.robot.holding is None
    empty = demo_scene(holding=None)
    assert after_repairs("put_into", "drawer1", empty) is None  # nothing to put in: no repair
    assert after_repairs("pick_up", "cup2", empty) is None  # feasible: nothing to repair
    assert after_repairs("pour", "cup1", holding) is None  # the held cup: not repairable
    assert ("put_into", "drawer1") not in datasets.intent_pairs(holding)
    assert ("put_into", "drawer1") in datasets.intent_pairs(holding, repairable=True)
    assert datasets.gesture_context("put_into", "drawer1", holding) == (1, True)
    assert datasets.gesture_context("open", "drawer1", holding) == (0, False)


def test_a_full_closed_drawer_is_not_repairable():
    from cbgo.world import SceneObject
    from cbgo.world.repairs import after_repairs
    from cbgo_tools.intent.evaluate import demo_scene

    scene = demo_scene()
    scene.objects.append(SceneObject("box2", "box", (0, 0, 0), 0.05, inside="drawer1"))
    scene.settle()
    assert scene.problems() == []
    assert after_repairs("put_into", "drawer1", scene) is None  # drawer_full has no repair
    assert ("put_into", "drawer1") not in datasets.intent_pairs(scene, repairable=True)


def test_repairable_draws_read_the_table_in_the_state_the_planner_makes():
    from cbgo.world import failures
    from cbgo.world.repairs import REPAIRABLE

    tables = datasets.load_tables()
    items = list(datasets.samples("D4", 1500, seed=40, repairable=True))
    repaired = [s for s in items if s.repaired]
    assert {"put_into", "pick_up"} <= {s.action for s in repaired}
    assert 0.01 < len(repaired) / len(items) < 0.2
    for s in items:
        found = failures(s.action, s.target, s.scene)
        assert s.repaired == bool(found) and {f.code for f in found} <= REPAIRABLE
        assert (s.action, s.target) in datasets.intent_pairs(s.scene, repairable=True)
    for s in repaired:
        target = s.scene.get(s.target)
        if s.action == "put_into":  # a closed drawer gets the open drawer's gesture
            assert not target.open and s.scene.robot.holding is not None
            assert s.gesture == tables.gesture("D4", "put_into", "drawer", 1, s.user)
        else:  # pick up while holding: the target's own entry
            assert s.scene.robot.holding not in (None, s.target)
            assert s.gesture == tables.gesture("D4", "pick_up", target.type,
                                               s.scene.state_bit(s.target), s.user)


def test_without_the_option_nothing_needs_repairs_and_the_arrays_say_which_would():
    plain = datasets.make("D4", 400, seed=41)
    assert plain.meta["repairable"] is False and not plain.repaired.any()
    rows = np.arange(len(plain))
    assert plain.feasible[rows, plain.action, plain.target].all()
    assert plain.repairable.any() and not (plain.repairable & plain.feasible).any()
    mixed = datasets.make("D4", 1500, seed=40, repairable=True)
    assert mixed.meta["repairable"] is True and mixed.repaired.sum() > 10
    rows = np.arange(len(mixed))
    hit_feasible = mixed.feasible[rows, mixed.action, mixed.target]
    hit_repairable = mixed.repairable[rows, mixed.action, mixed.target]
    assert np.array_equal(hit_repairable, mixed.repaired)
    assert np.array_equal(hit_feasible, ~mixed.repaired)


def test_cbgo_dataset_make_repairable_records_it(tmp_path, capsys):
    from cbgo.cli.main import main

    path = tmp_path / "d4r.npz"
    with pytest.raises(SystemExit) as made:
        main(["data", "intent", "make", "D4", "-n", "300", "--seed", "3", "--repairable", "-o",
              str(path)])
    ds = datasets.Dataset.load(path)
    assert made.value.code == 0 and ds.meta["repairable"] is True
    with pytest.raises(SystemExit):
        main(["data", "intent", "info", str(path)])
    out = capsys.readouterr().out
    assert "repairable intents: True" in out
    assert f"intents needing the planner's repairs: {int(ds.repaired.sum())}" in out
