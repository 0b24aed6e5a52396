"""The service registry's alternatives and how `cbgo up` chooses what to start."""

import pytest

from cbgo import registry
from cbgo.cli import up


def names(services):
    return [s.name for s in services]


def test_the_default_set_is_web_and_the_seven_pipeline_services_without_alternatives():
    assert names(registry.defaults()) == ["web", "leap-bridge", "static-gesture", "dynamic-gesture",
                                          "episode", "intent", "planner", "mujoco-sim"]
    assert "dry-robot" not in names(registry.available())
    assert names(registry.alternatives("mujoco-sim")) == ["dry-robot", "franka"]
    assert registry.by_name("dry-robot").role == registry.by_name("mujoco-sim").role


def test_foxglove_bridge_is_optional_never_in_the_default_set():
    bridge = registry.by_name("foxglove-bridge")
    assert bridge.optional and bridge.replaces is None and bridge.exists()
    assert bridge.script == "cbgo-foxglove-bridge"
    assert bridge.package == "cbgo.services.foxglove_bridge"
    assert "foxglove-bridge" not in names(registry.defaults())
    assert "foxglove-bridge" not in names(up.chosen_services([]))
    assert names(up.chosen_services(["foxglove-bridge", "planner"])) == ["foxglove-bridge",
                                                                         "planner"]


def test_every_robot_choice_names_a_service_that_answers_robot_act():
    for name in registry.ROBOTS.values():
        assert registry.by_name(name).role == "mujoco-sim"


def test_swap_puts_the_alternative_in_place_and_leaves_lists_without_a_robot_alone():
    dry = registry.by_name("dry-robot")
    swapped = registry.swap(registry.defaults(), dry)
    assert names(swapped) == [*names(registry.defaults())[:-1], "dry-robot"]
    planner_only = [registry.by_name("planner")]
    assert registry.swap(planner_only, dry) == planner_only


def test_clashes_finds_two_implementations_of_the_same_keys():
    both = [registry.by_name("mujoco-sim"), registry.by_name("planner"),
            registry.by_name("dry-robot")]
    assert [(a.name, b.name) for a, b in registry.clashes(both)] == [("mujoco-sim",
                                                                       "dry-robot")]
    assert registry.clashes(registry.defaults()) == []


def test_up_starts_the_defaults_or_dry_robot_in_mujoco_sims_place():
    assert names(up.chosen_services([])) == names(registry.available())
    chosen = names(up.chosen_services([], robot="dry"))
    assert "dry-robot" in chosen and "mujoco-sim" not in chosen
    assert names(up.chosen_services(["dry-robot", "planner"])) == ["dry-robot", "planner"]
    assert names(up.chosen_services(["mujoco-sim"], robot="dry")) == ["dry-robot"]
    assert names(up.chosen_services(["dry-robot"], robot="mujoco")) == ["mujoco-sim"]


def test_up_refuses_both_robots_and_unknown_names(capsys):
    with pytest.raises(SystemExit) as exit_info:
        up.chosen_services(["mujoco-sim", "dry-robot"])
    assert exit_info.value.code == 2
    assert "answer the same keys" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        up.chosen_services(["no-such-service"])
    assert "unknown service 'no-such-service'" in capsys.readouterr().err


def test_up_list_shows_the_alternative_and_how_to_start_it(capsys):
    assert up.list_services() == 0
    out = capsys.readouterr().out
    line = next(row for row in out.splitlines() if row.startswith("dry-robot "))
    assert "replaces mujoco-sim" in line
    assert "`cbgo up --robot dry`" in out
