"""Scene files (cbgo.world.read_scene_file): JSON or YAML, checked, clear errors."""

import json

import pytest

from cbgo.errors import ConfigError
from cbgo.world import Scene, read_scene_file

BODY = {"objects": [{"name": "cup1", "type": "cup", "position": [0.44, 0.06, 0.0],
                     "size": 0.06, "full": True}],
        "robot": {"tcp": [0.44, 0.0, 0.26], "gripper_open": True, "holding": None}}


def test_json_and_yaml_files_give_the_same_scene_body(tmp_path):
    as_json = tmp_path / "s.json"
    as_json.write_text(json.dumps({**BODY, "comment": "ignored"}))
    as_yaml = tmp_path / "s.yaml"
    as_yaml.write_text("objects:\n  - {name: cup1, type: cup, position: [0.44, 0.06, 0.0], "
                       "size: 0.06, full: true}\nrobot: {tcp: [0.44, 0.0, 0.26], "
                       "gripper_open: true, holding: null}\n")
    assert read_scene_file(str(as_json)) == read_scene_file(str(as_yaml)) == BODY
    assert Scene.from_dict(read_scene_file(str(as_yaml))).problems() == []


@pytest.mark.parametrize("text, message", [
    ("objects: [", "cannot read scene file"),
    ("- just a list", "expected a map with an 'objects' list"),
    ("objects: 3", "expected a map with an 'objects' list"),
])
def test_a_bad_scene_file_is_a_config_error_naming_the_file(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        read_scene_file(str(path))
    assert message in str(info.value) and "bad.yaml" in str(info.value)


def test_a_missing_scene_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read scene file"):
        read_scene_file(str(tmp_path / "none.json"))
