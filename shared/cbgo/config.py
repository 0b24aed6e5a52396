"""Configuration: Zenoh options, runtime options and each service's own settings.

Precedence is fixed, resolved once at start-up by `resolve()`:

    dataclass defaults  <  settings file (--settings / CBGO_SETTINGS, YAML or JSON)
                        <  environment (CBGO_<FIELD>, and ZENOH_CONNECT / ZENOH_LISTEN /
                           ZENOH_MODE / ZENOH_CONFIG)  <  command-line flags

A service declares its settings as a `@dataclass` whose fields have defaults and a
``metadata={"help": ...}``; every field becomes a ``--field-name`` flag and a
``CBGO_FIELD_NAME`` variable. Validation belongs in the dataclass's ``__post_init__`` and raises
`ConfigError` naming the fix. This module is the only place that reads the environment.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml

from cbgo.errors import ConfigError
from cbgo.keys import DEFAULT_PREFIX, check_prefix
from cbgo.wire import DEFAULT_MAX_BYTES

DEFAULT_PORT = 7447
DEFAULT_CONNECT = f"tcp/127.0.0.1:{DEFAULT_PORT}"
# Loopback: a router reachable from other hosts is a decision (`--listen tcp/0.0.0.0:7447`),
# since anyone who reaches it may publish robot/act; the process warns when it listens so.
DEFAULT_ROUTER_LISTEN = f"tcp/127.0.0.1:{DEFAULT_PORT}"
MODES = ("client", "peer", "router")
LOG_LEVELS = ("debug", "info", "warning", "error")
LOG_FORMATS = ("text", "json")


def described(text: str) -> dict:
    """Returns the field metadata that gives a setting its --help text."""
    return {"help": text}


_help = described


@dataclass
class ZenohOptions:
    """How a process joins the Zenoh network (shared by every service and CLI verb)."""

    connect: list[str] = field(default_factory=lambda: [DEFAULT_CONNECT], metadata=_help(
        "endpoint(s) to connect to, e.g. tcp/router:7447 (env ZENOH_CONNECT, comma-separated)"))
    listen: list[str] = field(default_factory=list, metadata=_help(
        "endpoint(s) to listen on (env ZENOH_LISTEN, comma-separated)"))
    mode: str = field(default="client", metadata=_help(
        "Zenoh mode: client (default, through the router), peer or router (env ZENOH_MODE)"))
    config: str | None = field(default=None, metadata=_help(
        "a Zenoh JSON5 config file, applied before the other options (env ZENOH_CONFIG)"))
    cfg: list[str] = field(default_factory=list, metadata=_help(
        "raw Zenoh config override KEY:VALUE (JSON5 value), repeatable, e.g. "
        "--cfg 'transport/unicast/max_links:2'"))
    prefix: str = field(default=DEFAULT_PREFIX, metadata=_help(
        "key prefix shared by all services of one robot cell (env CBGO_PREFIX)"))
    scouting: bool = field(default=False, metadata=_help(
        "enable multicast scouting (off by default: services connect to the router by endpoint)"))

    def __post_init__(self):
        if self.mode not in MODES:
            raise ConfigError(f"mode {self.mode!r} is not one of {', '.join(MODES)}")
        check_prefix(self.prefix)
        for item in self.cfg:
            if ":" not in item:
                raise ConfigError(f"--cfg {item!r}: expected KEY:VALUE, e.g. "
                                  "'scouting/multicast/enabled:true'")
        if self.config is not None and not Path(self.config).is_file():
            raise ConfigError(f"Zenoh config file {self.config!r} does not exist")
        if self.mode == "client" and not self.connect:
            raise ConfigError("client mode needs at least one --connect endpoint, "
                              f"e.g. --connect {DEFAULT_CONNECT}")


@dataclass
class RuntimeOptions:
    """Options of the service runtime itself."""

    log_level: str = field(default="info", metadata=_help(
        "log level: debug, info, warning, error (env CBGO_LOG_LEVEL)"))
    log_format: str = field(default="text", metadata=_help(
        "log format: text, or json (one object a line, for log collectors)"))
    max_payload_bytes: int = field(default=DEFAULT_MAX_BYTES, metadata=_help(
        "largest accepted input payload in bytes; larger ones are rejected"))
    settings: str | None = field(default=None, metadata=_help(
        "a YAML/JSON file with settings (any flag name, with underscores) (env CBGO_SETTINGS)"))

    def __post_init__(self):
        if self.log_level not in LOG_LEVELS:
            raise ConfigError(f"log level {self.log_level!r} is not one of {', '.join(LOG_LEVELS)}")
        if self.log_format not in LOG_FORMATS:
            raise ConfigError(f"log format {self.log_format!r} is not one of "
                              f"{', '.join(LOG_FORMATS)}")
        if self.max_payload_bytes < 1024:
            raise ConfigError(f"max payload {self.max_payload_bytes} bytes is too small; use at "
                              "least 1024")


@dataclass
class NoSettings:
    """Settings of a service that has none of its own."""


# Environment variables that do not follow the CBGO_<FIELD> pattern.
_ENV_ALIASES = {"connect": "ZENOH_CONNECT", "listen": "ZENOH_LISTEN", "mode": "ZENOH_MODE",
                "config": "ZENOH_CONFIG"}


def env_name(field_name: str) -> str:
    """Returns the environment variable of a field, e.g. ``CBGO_LOG_LEVEL``."""
    return _ENV_ALIASES.get(field_name, "CBGO_" + field_name.upper())


def _base_type(tp: Any) -> tuple[Any, bool]:
    """Returns (the type without Optional, whether None is allowed)."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return args[0], len(args) < len(typing.get_args(tp))
    return tp, False


def _coerce(value: Any, tp: Any, name: str) -> Any:
    """Converts a string (env, flag) or file value to a field's type."""
    base, nullable = _base_type(tp)
    if value is None or (nullable and value in ("", "none", "null")):
        return None
    origin = typing.get_origin(base)
    try:
        if origin is tuple:  # tuple[X, ...]: read as a list, kept as a tuple
            return tuple(_coerce(value, list[typing.get_args(base)[0]], name))
        if origin is list:
            (item,) = typing.get_args(base) or (str,)
            # "a,b" or repeated flags, or both: --sensor-position 1,0,0
            items = [part for x in ([value] if isinstance(value, str) else value)
                     for part in (x.split(",") if isinstance(x, str) else [x])]
            items = [x.strip() if isinstance(x, str) else x for x in items]
            return [_coerce(x, item, name) for x in items if x != ""]
        if origin is Literal:
            if value not in typing.get_args(base):
                raise ValueError(f"not one of {typing.get_args(base)}")
            return value
        if base is bool:
            if isinstance(value, bool):
                return value
            lowered = str(value).lower()
            if lowered not in ("1", "true", "yes", "on", "0", "false", "no", "off"):
                raise ValueError("not a boolean")
            return lowered in ("1", "true", "yes", "on")
        if base is int:
            return _as_int(value)
        if base in (float, str):
            if base is float and isinstance(value, bool):
                raise ValueError("a boolean is not a number")
            return base(value)
        if base is dict or typing.get_origin(base) is dict:
            return json.loads(value) if isinstance(value, str) else dict(value)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"setting {name}={value!r}: expected {_type_name(tp)} ({e})") from None
    return value


def _as_int(value: Any) -> int:
    """Returns an integer without silently truncating 2048.9 or turning true into 1."""
    if isinstance(value, bool):
        raise ValueError("a boolean is not an integer")
    if isinstance(value, float):
        if not value.is_integer():
            raise ValueError("not a whole number")
        return int(value)
    return int(value)


def _type_name(tp: Any) -> str:
    base, nullable = _base_type(tp)
    name = getattr(base, "__name__", str(base))
    return f"{name} or none" if nullable else name


def _resolve_hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


@dataclass(frozen=True)
class SettingRow:
    """One setting as the documentation shows it (`settings_rows`)."""

    flag: str
    env: str
    type: str
    default: Any
    meaning: str


def settings_rows(cls: type, prefix: str = "") -> list[SettingRow]:
    """Returns a settings dataclass's settings as documented.

    The same flags, environment variables and help texts as ``--help``
    (`add_dataclass_arguments`); a group's settings follow under ``--group.name``.
    """
    hints = _resolve_hints(cls)
    rows = []
    for f in dataclasses.fields(cls):
        tp, name = hints[f.name], prefix + f.name
        if _is_group(tp):
            rows += settings_rows(_base_type(tp)[0], name + ".")
            continue
        rows.append(SettingRow("--" + name.replace("_", "-"), env_name(name.replace(".", "_")),
                               _type_name(tp), _default(f), f.metadata.get("help", "")))
    return rows


def add_dataclass_arguments(parser: argparse.ArgumentParser, cls: type, title: str,
                            shown_defaults: dict | None = None, prefix: str = "",
                            skip: tuple[str, ...] = ()) -> None:
    """Adds one ``--field-name`` flag per dataclass field (``--group.field-name`` in a group).

    Flags default to SUPPRESS, so unset flags do not override lower layers.

    Args:
        parser: the parser to extend.
        cls: the dataclass.
        title: the heading of the flags in --help.
        shown_defaults: defaults to show instead of the dataclass's (a router's listen).
        prefix: the group's name and a dot, for a group of settings (see `_layer`).
        skip: fields that get no flag here (the command defines that flag its own way).
    """
    group = parser.add_argument_group(title)
    hints = _resolve_hints(cls)
    for f in dataclasses.fields(cls):
        tp, name = hints[f.name], prefix + f.name
        if f.name in skip:
            continue
        if _is_group(tp):
            add_dataclass_arguments(parser, _base_type(tp)[0], f"{title}: {f.name}.*",
                                    prefix=name + ".")
            continue
        base, _ = _base_type(tp)
        flag = "--" + name.replace("_", "-")
        text = f.metadata.get("help", "").replace("%", "%%")  # argparse %-formats help
        default = _default(f)
        default = (shown_defaults or {}).get(f.name, default)
        text = f"{text} [default: {default}]" if text else f"[default: {default}]"
        kwargs: dict[str, Any] = {"dest": name, "default": argparse.SUPPRESS, "help": text}
        if base is bool:
            group.add_argument(flag, action=argparse.BooleanOptionalAction, **kwargs)
        elif typing.get_origin(base) in (list, tuple):
            group.add_argument(flag, action="append", metavar="VALUE", **kwargs)
        else:
            choices = typing.get_args(base) if typing.get_origin(base) is Literal else None
            group.add_argument(flag, metavar=name.split(".")[-1].upper(), choices=choices,
                               **kwargs)


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    return f.default_factory() if f.default_factory is not dataclasses.MISSING else None


def add_zenoh_arguments(parser: argparse.ArgumentParser, shown_defaults: dict | None = None,
                        skip: tuple[str, ...] = ()) -> None:
    """Adds the Zenoh flags: --connect, --listen, --mode, --config, --cfg, --prefix, --scouting.

    `skip` names the ones a command defines its own way (`cbgo up`'s --listen is its router's).
    """
    add_dataclass_arguments(parser, ZenohOptions, "Zenoh", shown_defaults, skip=skip)


def read_settings_file(path: str | None) -> dict[str, Any]:
    """Returns the mapping in a YAML/JSON settings file ({} for None).

    Raises:
        ConfigError: the file is missing, unreadable or not a mapping.
    """
    if not path:
        return {}
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as e:
        raise ConfigError(f"cannot read settings file {path!r}: {e}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"settings file {path!r} must hold a mapping of setting: value")
    return {str(k).replace("-", "_"): v for k, v in data.items()}


def _layer(cls: type, file_values: dict, env: typing.Mapping[str, str], cli: dict,
           consumed: set[str], overrides: dict | None = None, prefix: str = "") -> Any:
    """Builds `cls` from its defaults < the file < the environment < the flags.

    A field whose type is itself a dataclass is a *group* of settings (`nested_fields`): its
    fields are ``--group.name`` flags, ``CBGO_GROUP_NAME`` variables and ``group: {name: ...}``
    in the file, layered the same way.
    """
    hints = _resolve_hints(cls)
    values: dict[str, Any] = dict(overrides or {})
    for f in dataclasses.fields(cls):
        tp, name = hints[f.name], prefix + f.name
        if _is_group(tp):
            values[f.name] = _layer_group(tp, f.name, name, file_values, env, cli, consumed)
            continue
        if f.name in file_values:
            values[f.name] = _coerce(file_values[f.name], tp, name)
            consumed.add(f.name)
        variable = env_name(name.replace(".", "_"))
        if variable in env:
            values[f.name] = _coerce(env[variable], tp, variable)
        if name in cli:
            raw = cli[name]
            flag = "--" + name.replace("_", "-")
            values[f.name] = raw if isinstance(raw, bool) else _coerce(raw, tp, flag)
    try:
        return cls(**values)
    except TypeError as e:
        raise ConfigError(f"bad settings for {cls.__name__}: {e}") from None


def _is_group(tp: Any) -> bool:
    return dataclasses.is_dataclass(_base_type(tp)[0])


def _layer_group(group_cls: type, key: str, name: str, file_values: dict,
                 env: typing.Mapping[str, str], cli: dict, consumed: set[str]) -> Any:
    """Builds one group of settings (see `_layer`); its unknown file keys are errors."""
    raw = file_values.get(key, {})
    if not isinstance(raw, dict):
        raise ConfigError(f"setting {name} must be a mapping of its settings, got {raw!r}")
    sub_file = {str(k).replace("-", "_"): v for k, v in raw.items()}
    sub_consumed: set[str] = set()
    value = _layer(group_cls, sub_file, env, cli, sub_consumed, prefix=name + ".")
    unknown = sorted(set(sub_file) - sub_consumed)
    if unknown:
        raise ConfigError(f"settings file: {name} has unknown settings {unknown}")
    if key in file_values:
        consumed.add(key)
    return value


@dataclass
class Resolved:
    """The outcome of `resolve`: the three option sets of a process."""

    zenoh: ZenohOptions
    runtime: RuntimeOptions
    settings: Any

    def as_dict(self) -> dict[str, Any]:
        """Returns everything as plain data (served in status and logged at start)."""
        return {"zenoh": dataclasses.asdict(self.zenoh),
                "runtime": dataclasses.asdict(self.runtime),
                "settings": dataclasses.asdict(self.settings)}


def build_parser(prog: str, description: str, settings_cls: type,
                 zenoh_defaults: dict | None = None) -> argparse.ArgumentParser:
    """Returns the argument parser of a service: its settings, then Zenoh and runtime flags."""
    parser = argparse.ArgumentParser(
        prog=prog, description=description,
        epilog="Every flag can also be set as CBGO_<FLAG> in the environment (ZENOH_CONNECT, "
               "ZENOH_LISTEN, ZENOH_MODE, ZENOH_CONFIG for the Zenoh ones) or in the --settings "
               "file; flags win over the environment, which wins over the file.")
    if dataclasses.fields(settings_cls):
        add_dataclass_arguments(parser, settings_cls, "service settings")
    add_zenoh_arguments(parser, zenoh_defaults)
    add_dataclass_arguments(parser, RuntimeOptions, "runtime")
    return parser


def resolve(settings_cls: type, argv: list[str] | None, *, prog: str, description: str = "",
            env: typing.Mapping[str, str] | None = None,
            zenoh_defaults: dict | None = None) -> Resolved:
    """Parses flags and layers file, environment and flags over the defaults.

    Args:
        settings_cls: the service's settings dataclass (`NoSettings` for none).
        argv: command-line arguments (None: sys.argv[1:]).
        prog: program name for --help.
        description: what the program does, for --help.
        env: the environment (os.environ by default).
        zenoh_defaults: service-specific Zenoh defaults (the router listens by default).

    Raises:
        ConfigError: any invalid value, with the fix.
        SystemExit: --help, or unknown flags (argparse).
    """
    env = os.environ if env is None else env
    cli = vars(build_parser(prog, description, settings_cls, zenoh_defaults).parse_args(argv))
    settings_path = cli.get("settings", env.get("CBGO_SETTINGS"))
    file_values = read_settings_file(settings_path)
    consumed: set[str] = set()
    resolved = Resolved(
        zenoh=_layer(ZenohOptions, file_values, env, cli, consumed, zenoh_defaults),
        runtime=_layer(RuntimeOptions, file_values, env, cli, consumed),
        settings=_layer(settings_cls, file_values, env, cli, consumed),
    )
    unknown = sorted(set(file_values) - consumed)
    if unknown:
        raise ConfigError(f"settings file {settings_path!r} has unknown settings {unknown}; "
                          f"see {prog} --help for the valid names")
    return resolved


def resolve_zenoh(cli: dict, env: typing.Mapping[str, str] | None = None) -> ZenohOptions:
    """Returns the Zenoh options of a CLI tool: environment < flags (no settings file).

    Args:
        cli: parsed flags (``vars(args)``; absent flags are simply missing).
        env: the environment (os.environ by default).

    Raises:
        ConfigError: an invalid value.
    """
    return _layer(ZenohOptions, {}, os.environ if env is None else env, cli, set())


def data_dir(env: typing.Mapping[str, str] | None = None) -> Path:
    """Returns where user data lives (recorded gestures, personal models); not created here.

    ``CBGO_DATA_DIR``, else ``$XDG_DATA_HOME/cbgo``, else ``~/.local/share/cbgo``.
    """
    env = os.environ if env is None else env
    if env.get("CBGO_DATA_DIR"):
        return Path(env["CBGO_DATA_DIR"]).expanduser()
    base = env.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "cbgo"


def cache_dir(env: typing.Mapping[str, str] | None = None) -> Path:
    """Returns where fetched and converted third-party data sets live; not created here.

    ``CBGO_CACHE_DIR``, else ``$XDG_CACHE_HOME/cbgo``, else ``~/.cache/cbgo``. The data sets
    have licences of their own (or none), so they stay outside the repository and the data
    directory: ``cbgo data list`` shows what is where.
    """
    env = os.environ if env is None else env
    if env.get("CBGO_CACHE_DIR"):
        return Path(env["CBGO_CACHE_DIR"]).expanduser()
    base = env.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "cbgo"


def _file_wins(options: ZenohOptions, conf, key: str, endpoints: list[str]) -> bool:
    """Whether a config file's own endpoints at `key` stand over cbgo's built-in default.

    Endpoints given by flag or environment always win; but the built-in defaults
    (``tcp/127.0.0.1:7447`` to connect and for the router to listen on) must not replace
    the ones a ``--config`` file names, e.g. ``tls/router:7447`` in a TLS deployment.
    """
    if not options.config or endpoints not in ([DEFAULT_CONNECT], [DEFAULT_ROUTER_LISTEN]):
        return False
    try:
        own = json.loads(conf.get_json(key))
    except Exception:  # zenoh raises ZError for a key it does not know
        return False
    return isinstance(own, list) and bool(own)  # unset: [] (connect) or a per-mode map


def zenoh_config(options: ZenohOptions, name: str):
    """Returns the zenoh.Config of a process named `name`.

    Client mode waits for the router forever (``connect/timeout_ms: -1``) instead of failing;
    multicast scouting is off unless asked for; routers enable the admin space; every session
    carries ``metadata: {name}`` so the router's admin space lists it by name.
    """
    import zenoh  # imported here so that config parsing works without a Zenoh runtime

    conf = zenoh.Config.from_file(options.config) if options.config else zenoh.Config()
    conf.insert_json5("mode", json.dumps(options.mode))
    if options.connect and not _file_wins(options, conf, "connect/endpoints", options.connect):
        conf.insert_json5("connect/endpoints", json.dumps(options.connect))
    if options.connect:
        conf.insert_json5("connect/timeout_ms", "-1")
    if options.listen and not _file_wins(options, conf, "listen/endpoints", options.listen):
        conf.insert_json5("listen/endpoints", json.dumps(options.listen))
    conf.insert_json5("scouting/multicast/enabled", json.dumps(options.scouting))
    conf.insert_json5("metadata", json.dumps({"name": name}))
    if options.mode == "router":
        conf.insert_json5("adminspace/enabled", "true")
    for item in options.cfg:
        key, value = item.split(":", 1)
        try:
            conf.insert_json5(key, value)
        except Exception as e:  # zenoh raises ZError; name the bad override
            raise ConfigError(f"--cfg {item!r} rejected by Zenoh: {e}") from None
    return conf
