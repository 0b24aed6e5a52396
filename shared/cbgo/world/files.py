"""Scene files: a contract scene body (``objects``, optional ``robot``) in JSON or YAML.

Read by every robot service (``--scene FILE``) and by ``cbgo sim reset --scene FILE``.
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from cbgo.errors import ConfigError


def read_scene_file(path: str) -> dict:
    """Returns the scene body in a JSON (``.json``) or YAML file: its ``objects`` and ``robot``.

    Raises:
        ConfigError: unreadable, or not a map with an ``objects`` list.
    """
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise ConfigError(f"cannot read scene file {path}: {e.strerror or e}") from e
    try:
        data = json.loads(text) if path.endswith(".json") else yaml.safe_load(text)
    except (ValueError, yaml.YAMLError) as e:
        raise ConfigError(f"cannot read scene file {path}: {_parse_error(e)}") from e
    if not isinstance(data, dict) or not isinstance(data.get("objects"), list):
        raise ConfigError(f"scene file {path}: expected a map with an 'objects' list")
    return {k: data[k] for k in ("objects", "robot") if k in data}


def _parse_error(error: Exception) -> str:
    """Returns a JSON or YAML parser's complaint as ``line L, column C: problem``."""
    if isinstance(error, json.JSONDecodeError):
        return f"line {error.lineno}, column {error.colno}: {error.msg}"
    mark = getattr(error, "problem_mark", None)
    if isinstance(error, yaml.MarkedYAMLError) and mark is not None:
        return f"line {mark.line + 1}, column {mark.column + 1}: {error.problem}"
    return str(error)
