"""Scenario files: parsing, defaults and errors that name the place at fault."""

import pytest

from cbgo.errors import ConfigError
from cbgo.simuser.scenario import BUNDLED, load_scenario, parse_scenario


def test_every_bundled_scenario_loads():
    names = sorted(p.stem for p in BUNDLED.glob("*.yaml"))
    assert {"demo", "static-all", "dynamic-all", "still"} <= set(names)
    for name in names:
        assert load_scenario(name).episodes


def test_gesture_steps_accept_names_and_mappings_with_parameters():
    scenario = parse_scenario({"episodes": [{"gestures": [
        "grab", {"gesture": "rotate", "angle_deg": 45}, {"gesture": "five", "hold_s": 2}]}]})
    steps = scenario.episodes[0].gestures
    assert [s.gesture for s in steps] == ["grab", "rotate", "five"]
    assert steps[1].dynamic and steps[1].angle_deg == 45
    assert not steps[2].dynamic and steps[2].hold_s == 2
    assert scenario.user_of(scenario.episodes[0]) == "user1"


@pytest.mark.parametrize("data, message", [
    ({"episodes": [{"gestures": ["wave"]}]}, "episodes[0].gestures[0]: unknown gesture 'wave'"),
    ({"episodes": [{"gestures": []}]}, "episodes[0]: needs a non-empty 'gestures' list"),
    ({"episodes": [{"gestures": ["grab"], "gaez": "cup1"}]}, "unknown field(s) ['gaez']"),
    ({"episodes": [{"gestures": ["grab"], "user": "bob"}]}, "user 'bob' is not in users"),
    ({"episodes": [{"gestures": ["grab"], "gaze": [1, 2]}]}, "episodes[0].gaze: expected"),
    ({"users": {"u": {"side": "middle"}}, "episodes": [{"gestures": ["grab"]}]},
     "users.u: side 'middle' must be 'left' or 'right'"),
    ({"users": {"u": {"speed": 0}}, "episodes": [{"gestures": ["grab"]}]}, "speed=0"),
    ({"episodes": []}, "no episodes"),
    ({"episodes": [{"gestures": ["grab"]}], "extra": 1}, "unknown field(s) ['extra']"),
    ([1, 2], "expected a mapping with an 'episodes' list"),
])
def test_a_bad_scenario_is_refused_naming_the_place_at_fault(data, message):
    with pytest.raises(ConfigError) as err:
        parse_scenario(data)
    assert message in str(err.value)


def test_a_missing_scenario_file_lists_the_bundled_ones(tmp_path):
    with pytest.raises(ConfigError, match="bundled: .*demo"):
        load_scenario(str(tmp_path / "nope.yaml"))
