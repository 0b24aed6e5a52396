"""Unit tests of cbgo.config: layered settings, the Zenoh options and the Zenoh config."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field

import pytest

from cbgo import config
from cbgo.config import NoSettings, RuntimeOptions, ZenohOptions, resolve, zenoh_config
from cbgo.errors import ConfigError


@dataclass
class Demo:
    """Settings of a pretend service."""

    speed: float = field(default=1.0, metadata={"help": "how fast, in m/s"})
    label: str = field(default="demo", metadata={"help": "a name"})
    verbose: bool = field(default=False, metadata={"help": "talk more"})
    limit: int | None = field(default=None, metadata={"help": "optional cap"})
    tags: list[str] = field(default_factory=lambda: ["a"], metadata={"help": "some tags"})
    counts: list[int] = field(default_factory=list, metadata={"help": "some counts"})

    def __post_init__(self):
        if self.speed <= 0:
            raise ConfigError(f"speed {self.speed} must be positive")


@dataclass
class Percent:
    """A service whose help text has a percent sign."""

    share: float = field(default=0.5, metadata={"help": "share of frames kept, in %"})


def run(argv=(), env=None, cls=Demo, **kwargs) -> config.Resolved:
    return resolve(cls, list(argv), prog="x", env={} if env is None else env, **kwargs)


def settings_file(tmp_path, text: str, name: str = "settings.yaml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def config_error(argv=(), env=None, cls=Demo, **kwargs) -> str:
    with pytest.raises(ConfigError) as info:
        run(argv, env, cls, **kwargs)
    return str(info.value)


# --------------------------------------------------------------------------- precedence


@pytest.mark.parametrize(("layers", "expected"), [
    ((), 1.0),
    (("file",), 2.0),
    (("env",), 3.0),
    (("cli",), 4.0),
    (("file", "env"), 3.0),
    (("file", "cli"), 4.0),
    (("env", "cli"), 4.0),
    (("file", "env", "cli"), 4.0),
])
def test_defaults_lose_to_the_settings_file_which_loses_to_env_which_loses_to_flags(
        tmp_path, layers, expected):
    path = settings_file(tmp_path, "speed: 2.0\n")
    argv = ["--settings", path] if "file" in layers else []
    env = {"CBGO_SPEED": "3.0"} if "env" in layers else {}
    if "cli" in layers:
        argv += ["--speed", "4.0"]
    assert run(argv, env).settings.speed == expected


def test_all_four_layers_on_one_field_give_the_flag_and_leave_the_others_alone(tmp_path):
    path = settings_file(tmp_path, "speed: 2.0\nlabel: from-file\n")
    resolved = run(["--settings", path, "--speed", "4.5"],
                   {"CBGO_SPEED": "3.0", "CBGO_VERBOSE": "yes"})
    assert resolved.settings == Demo(speed=4.5, label="from-file", verbose=True)
    assert resolved.runtime.settings == path


def test_the_settings_file_can_be_named_by_the_environment(tmp_path):
    path = settings_file(tmp_path, "label: via-env\nlog_level: debug\n")
    resolved = run([], {"CBGO_SETTINGS": path})
    assert resolved.settings.label == "via-env"
    assert resolved.runtime.log_level == "debug"


def test_the_settings_flag_wins_over_the_settings_variable(tmp_path):
    flag = settings_file(tmp_path, "label: flag\n", "flag.yaml")
    var = settings_file(tmp_path, "label: var\n", "var.yaml")
    assert run(["--settings", flag], {"CBGO_SETTINGS": var}).settings.label == "flag"


def test_a_json_settings_file_with_dashed_names_is_read(tmp_path):
    path = settings_file(tmp_path, json.dumps({"log-level": "warning", "speed": 7,
                                               "tags": ["x", "y"], "mode": "peer"}), "s.json")
    resolved = run(["--settings", path])
    assert resolved.runtime.log_level == "warning"
    assert resolved.settings.speed == 7.0 and isinstance(resolved.settings.speed, float)
    assert resolved.settings.tags == ["x", "y"]
    assert resolved.zenoh.mode == "peer"


def test_an_empty_settings_file_changes_nothing(tmp_path):
    assert run(["--settings", settings_file(tmp_path, "")]).settings == Demo()


def test_zenoh_options_are_layered_like_the_others(tmp_path):
    path = settings_file(tmp_path, "mode: peer\nconnect: [tcp/file:7447]\nprefix: cell-1/cbgo\n")
    resolved = run(["--settings", path])
    assert (resolved.zenoh.mode, resolved.zenoh.connect, resolved.zenoh.prefix) == (
        "peer", ["tcp/file:7447"], "cell-1/cbgo")
    env = {"ZENOH_MODE": "client", "ZENOH_CONNECT": "tcp/a:1,tcp/b:2", "CBGO_PREFIX": "cell-2/cbgo"}
    resolved = run(["--settings", path], env)
    assert (resolved.zenoh.mode, resolved.zenoh.connect, resolved.zenoh.prefix) == (
        "client", ["tcp/a:1", "tcp/b:2"], "cell-2/cbgo")
    resolved = run(["--settings", path, "--connect", "tcp/x:1", "--connect", "tcp/y:2",
                    "--prefix", "cell-3/cbgo"], env)
    assert (resolved.zenoh.connect, resolved.zenoh.prefix) == (
        ["tcp/x:1", "tcp/y:2"], "cell-3/cbgo")


def test_zenoh_connect_is_a_comma_separated_list_trimmed_with_empty_items_ignored():
    resolved = run([], {"ZENOH_CONNECT": " tcp/a:1 ,,tcp/b:2,", "ZENOH_LISTEN": "tcp/0.0.0.0:9"})
    assert resolved.zenoh.connect == ["tcp/a:1", "tcp/b:2"]
    assert resolved.zenoh.listen == ["tcp/0.0.0.0:9"]


def test_whitespace_only_items_of_a_list_variable_are_ignored():
    resolved = run([], {"ZENOH_CONNECT": "tcp/a:1, ,tcp/b:2"})
    assert resolved.zenoh.connect == ["tcp/a:1", "tcp/b:2"]


def test_repeated_connect_flags_make_a_list():
    resolved = run(["--connect", "tcp/a:1", "--connect", "tcp/b:2"])
    assert resolved.zenoh.connect == ["tcp/a:1", "tcp/b:2"]


def test_the_zenoh_defaults_of_a_service_sit_below_every_layer():
    router = {"mode": "router", "connect": [], "listen": [config.DEFAULT_ROUTER_LISTEN]}
    resolved = run([], zenoh_defaults=router)
    assert resolved.zenoh.mode == "router"
    assert resolved.zenoh.connect == []
    assert resolved.zenoh.listen == ["tcp/127.0.0.1:7447"]  # loopback: this host only
    resolved = run(["--listen", "tcp/0.0.0.0:7448"], {"ZENOH_CONNECT": "tcp/other:7447"},
                   zenoh_defaults=router)
    assert resolved.zenoh.listen == ["tcp/0.0.0.0:7448"]
    assert resolved.zenoh.connect == ["tcp/other:7447"]


def test_the_defaults_are_a_client_of_the_local_router():
    resolved = run([], cls=NoSettings)
    assert resolved.zenoh == ZenohOptions(connect=["tcp/127.0.0.1:7447"], listen=[],
                                          mode="client", config=None, cfg=[], prefix="cbgo",
                                          scouting=False)
    assert resolved.runtime == RuntimeOptions(log_level="info", log_format="text",
                                              max_payload_bytes=1 << 20, settings=None)
    assert resolved.settings == NoSettings()


def test_resolved_options_are_plain_data_that_serialise_to_json():
    data = run(["--speed", "2"]).as_dict()
    assert data["settings"]["speed"] == 2.0
    assert data["zenoh"]["connect"] == ["tcp/127.0.0.1:7447"]
    assert data["runtime"]["log_level"] == "info"
    assert json.loads(json.dumps(data)) == data


# --------------------------------------------------------------------------- parsing values


@pytest.mark.parametrize(("text", "value"), [
    ("true", True), ("1", True), ("yes", True), ("on", True), ("TRUE", True),
    ("false", False), ("0", False), ("no", False), ("off", False), ("False", False),
])
def test_boolean_variables_are_parsed(text, value):
    assert run([], {"CBGO_SCOUTING": text}).zenoh.scouting is value
    assert run([], {"CBGO_VERBOSE": text}).settings.verbose is value


def test_a_boolean_flag_wins_over_the_variable_both_ways():
    assert run(["--scouting"], {"CBGO_SCOUTING": "0"}).zenoh.scouting is True
    assert run(["--no-scouting"], {"CBGO_SCOUTING": "true"}).zenoh.scouting is False
    assert run(["--verbose"]).settings.verbose is True


def test_typed_variables_are_converted_to_their_field_types():
    resolved = run([], {"CBGO_LIMIT": "5", "CBGO_COUNTS": "1, 2,3", "CBGO_TAGS": "p,q",
                        "CBGO_MAX_PAYLOAD_BYTES": "4096", "CBGO_LOG_FORMAT": "json"})
    assert resolved.settings.limit == 5
    assert resolved.settings.counts == [1, 2, 3]
    assert resolved.settings.tags == ["p", "q"]
    assert resolved.runtime.max_payload_bytes == 4096
    assert resolved.runtime.log_format == "json"


@pytest.mark.parametrize("text", ["", "none", "null"])
def test_an_optional_field_is_cleared_by_an_empty_or_none_value(text):
    assert run(["--limit", "3"]).settings.limit == 3
    assert run([], {"CBGO_LIMIT": text}).settings.limit is None
    assert run([], {"ZENOH_CONFIG": text}).zenoh.config is None


@pytest.mark.parametrize(("env", "variable", "expected"), [
    ({"CBGO_SCOUTING": "maybe"}, "CBGO_SCOUTING", "expected bool"),
    ({"CBGO_VERBOSE": "2"}, "CBGO_VERBOSE", "expected bool"),
    ({"CBGO_MAX_PAYLOAD_BYTES": "lots"}, "CBGO_MAX_PAYLOAD_BYTES", "expected int"),
    ({"CBGO_MAX_PAYLOAD_BYTES": "1e6"}, "CBGO_MAX_PAYLOAD_BYTES", "expected int"),
    ({"CBGO_SPEED": "fast"}, "CBGO_SPEED", "expected float"),
    ({"CBGO_LIMIT": "ten"}, "CBGO_LIMIT", "expected int or none"),
    ({"CBGO_COUNTS": "1,two"}, "CBGO_COUNTS", "expected int"),
])
def test_a_bad_variable_gives_a_config_error_naming_the_variable(env, variable, expected):
    text = config_error([], env)
    assert f"setting {variable}={env[variable]!r}" in text or variable in text
    assert expected in text


def test_a_bad_flag_value_gives_a_config_error_naming_the_setting():
    text = config_error(["--speed", "fast"])
    assert "speed='fast'" in text and "expected float" in text


def test_a_bad_flag_value_names_the_flag_as_it_is_typed():
    assert "--max-payload-bytes" in config_error(["--max-payload-bytes", "lots"])


def test_a_bad_value_in_the_settings_file_names_the_setting(tmp_path):
    text = config_error(["--settings", settings_file(tmp_path, "speed: fast\n")])
    assert "setting speed='fast'" in text and "expected float" in text


def test_a_fractional_number_for_an_integer_setting_in_the_file_is_rejected(tmp_path):
    config_error(["--settings", settings_file(tmp_path, "max_payload_bytes: 2048.9\n")])


def test_a_service_validation_error_surfaces_as_a_config_error():
    assert "speed -1.0 must be positive" in config_error(["--speed", "-1"])


# --------------------------------------------------------------------------- bad settings files


def test_an_unknown_setting_in_the_file_is_named_in_the_error(tmp_path):
    path = settings_file(tmp_path, "speed: 2\nspeeed: 3\nlog_levle: debug\n")
    text = config_error(["--settings", path])
    assert "unknown settings ['log_levle', 'speeed']" in text
    assert path in text
    assert "x --help" in text


def test_a_missing_settings_file_is_a_config_error(tmp_path):
    missing = str(tmp_path / "nope.yaml")
    assert f"cannot read settings file {missing!r}" in config_error(["--settings", missing])


def test_an_unparsable_settings_file_is_a_config_error(tmp_path):
    path = settings_file(tmp_path, "speed: [1, 2\n")
    assert "cannot read settings file" in config_error(["--settings", path])


def test_a_settings_file_that_is_not_a_mapping_is_a_config_error(tmp_path):
    path = settings_file(tmp_path, "- speed\n- 2\n")
    assert "must hold a mapping of setting: value" in config_error(["--settings", path])


# --------------------------------------------------------------------------- option checks


@pytest.mark.parametrize(("argv", "env", "expected"), [
    ([], {"ZENOH_MODE": "mesh"}, "mode 'mesh' is not one of client, peer, router"),
    (["--mode", "mesh"], {}, "mode 'mesh' is not one of client, peer, router"),
    ([], {"CBGO_PREFIX": "cbgo/*"}, "invalid key prefix 'cbgo/*'"),
    (["--prefix", "/cbgo"], {}, "invalid key prefix '/cbgo'"),
    (["--prefix", ""], {}, "invalid key prefix ''"),
    ([], {"CBGO_LOG_LEVEL": "verbose"},
     "log level 'verbose' is not one of debug, info, warning, error"),
    (["--log-level", "trace"], {}, "log level 'trace' is not one of"),
    (["--log-format", "xml"], {}, "log format 'xml' is not one of text, json"),
    (["--max-payload-bytes", "100"], {}, "max payload 100 bytes is too small; use at least 1024"),
    (["--cfg", "transport/unicast/max_links"], {}, "expected KEY:VALUE"),
    (["--cfg", "a:1", "--cfg", "nocolon"], {}, "--cfg 'nocolon': expected KEY:VALUE"),
    (["--config", "/no/such/zenoh.json5"], {},
     "Zenoh config file '/no/such/zenoh.json5' does not exist"),
    ([], {"ZENOH_CONFIG": "/no/such/zenoh.json5"}, "does not exist"),
    ([], {"ZENOH_CONNECT": ""}, "client mode needs at least one --connect endpoint"),
])
def test_an_invalid_option_is_a_config_error_that_says_what_is_wrong(argv, env, expected):
    assert expected in config_error(argv, env, cls=NoSettings)


def test_the_empty_connect_error_shows_an_example_endpoint():
    assert "--connect tcp/127.0.0.1:7447" in config_error([], {"ZENOH_CONNECT": ""})


def test_peer_and_router_modes_need_no_connect_endpoint():
    assert run([], {"ZENOH_CONNECT": "", "ZENOH_MODE": "peer"}).zenoh.connect == []
    assert run(["--mode", "router"], {"ZENOH_CONNECT": ""}).zenoh.mode == "router"


def test_an_unknown_flag_exits_like_argparse(capsys):
    with pytest.raises(SystemExit) as info:
        run(["--no-such-flag"])
    assert info.value.code == 2
    assert "--no-such-flag" in capsys.readouterr().err


def test_environment_variable_names():
    assert config.env_name("log_level") == "CBGO_LOG_LEVEL"
    assert config.env_name("prefix") == "CBGO_PREFIX"
    assert [config.env_name(n) for n in ("connect", "listen", "mode", "config")] == [
        "ZENOH_CONNECT", "ZENOH_LISTEN", "ZENOH_MODE", "ZENOH_CONFIG"]


# --------------------------------------------------------------------------- zenoh_config


def get(conf, key: str):
    return json.loads(conf.get_json(key))


def test_a_client_config_connects_to_the_router_and_waits_for_it():
    conf = zenoh_config(ZenohOptions(), "episode")
    assert get(conf, "mode") == "client"
    assert get(conf, "connect/endpoints") == ["tcp/127.0.0.1:7447"]
    assert get(conf, "connect/timeout_ms") == -1
    assert get(conf, "scouting/multicast/enabled") is False
    assert get(conf, "metadata") == {"name": "episode"}
    assert get(conf, "adminspace/enabled") is False


def test_scouting_can_be_turned_on():
    assert get(zenoh_config(ZenohOptions(scouting=True), "x"), "scouting/multicast/enabled") is True


def test_a_router_config_listens_and_turns_the_admin_space_on():
    options = ZenohOptions(mode="router", connect=[], listen=["tcp/0.0.0.0:7447"])
    conf = zenoh_config(options, "router")
    assert get(conf, "mode") == "router"
    assert get(conf, "adminspace/enabled") is True
    assert get(conf, "listen/endpoints") == ["tcp/0.0.0.0:7447"]
    assert get(conf, "metadata") == {"name": "router"}


def test_a_config_built_from_resolved_flags():
    resolved = run(["--mode", "peer", "--connect", "tcp/a:1", "--connect", "tcp/b:2",
                    "--listen", "tcp/0.0.0.0:9000", "--cfg", "transport/unicast/max_links:3"],
                   cls=NoSettings)
    conf = zenoh_config(resolved.zenoh, "intent")
    assert get(conf, "mode") == "peer"
    assert get(conf, "connect/endpoints") == ["tcp/a:1", "tcp/b:2"]
    assert get(conf, "listen/endpoints") == ["tcp/0.0.0.0:9000"]
    assert get(conf, "transport/unicast/max_links") == 3


def test_a_cfg_override_lands_in_the_config():
    conf = zenoh_config(ZenohOptions(cfg=["transport/unicast/max_links:3",
                                          "scouting/multicast/enabled:true"]), "x")
    assert get(conf, "transport/unicast/max_links") == 3
    # --cfg is applied last, so it can override what the options set
    assert get(conf, "scouting/multicast/enabled") is True


@pytest.mark.parametrize("item", ["transport/unicast/max_links:notanumber",
                                  "transport/unicast/max_links:{", "no/such/key:1"])
def test_a_cfg_override_that_zenoh_rejects_is_a_config_error_naming_it(item):
    with pytest.raises(ConfigError) as info:
        zenoh_config(ZenohOptions(cfg=[item]), "x")
    assert f"--cfg {item!r} rejected by Zenoh" in str(info.value)


def test_a_zenoh_config_file_is_applied_before_the_options(tmp_path):
    path = tmp_path / "zenoh.json5"
    path.write_text("{mode: 'peer', transport: {unicast: {max_links: 4}}}")
    conf = zenoh_config(ZenohOptions(config=str(path)), "x")
    assert get(conf, "transport/unicast/max_links") == 4
    assert get(conf, "mode") == "client"
    conf = zenoh_config(ZenohOptions(config=str(path), cfg=["transport/unicast/max_links:2"]), "x")
    assert get(conf, "transport/unicast/max_links") == 2


# --------------------------------------------------------------------------- --help


def test_help_lists_every_field_with_its_default(capsys):
    parser = config.build_parser("demo-service", "A demo service.", Demo)
    with pytest.raises(SystemExit) as info:
        parser.parse_args(["--help"])
    assert info.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "usage: demo-service" in out and "A demo service." in out
    for cls in (Demo, ZenohOptions, RuntimeOptions):
        for f in dataclasses.fields(cls):
            flag = "--" + f.name.replace("_", "-")
            assert flag in out, flag
            default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
            assert f"[default: {default}]" in out, (f.name, default)
    assert "--no-scouting" in out and "--no-verbose" in out
    assert "how fast, in m/s [default: 1.0]" in out
    assert "[default: ['tcp/127.0.0.1:7447']]" in out
    assert "service settings" in out and "Zenoh" in out and "runtime" in out
    assert "ZENOH_CONNECT" in out


def test_help_of_a_service_without_settings_has_no_settings_section(capsys):
    with pytest.raises(SystemExit):
        run(["--help"], cls=NoSettings)
    out = capsys.readouterr().out
    assert "service settings" not in out
    assert "--connect" in out and "--log-level" in out


def test_help_text_with_a_percent_sign_is_shown(capsys):
    with pytest.raises(SystemExit):
        run(["--help"], cls=Percent)
    assert "in %" in capsys.readouterr().out


def test_a_config_files_endpoints_stand_over_the_built_in_defaults(tmp_path):
    import json as _json

    from cbgo.config import ZenohOptions, zenoh_config

    path = tmp_path / "tls.json5"
    path.write_text('{connect: {endpoints: ["tls/router:7447"]}, '
                    'listen: {endpoints: ["tls/0.0.0.0:7447"]}}')
    client = zenoh_config(ZenohOptions(config=str(path)), "t")
    assert _json.loads(client.get_json("connect/endpoints")) == ["tls/router:7447"]
    assert _json.loads(client.get_json("connect/timeout_ms")) == -1
    router = zenoh_config(ZenohOptions(config=str(path), mode="router", connect=[],
                                       listen=[config.DEFAULT_ROUTER_LISTEN]), "r")
    assert _json.loads(router.get_json("listen/endpoints")) == ["tls/0.0.0.0:7447"]
    # an endpoint given by flag or environment still wins over the file
    chosen = zenoh_config(ZenohOptions(config=str(path), connect=["tls/10.0.0.5:7447"]), "t")
    assert _json.loads(chosen.get_json("connect/endpoints")) == ["tls/10.0.0.5:7447"]
    # without a file the default applies as before
    plain = zenoh_config(ZenohOptions(), "t")
    assert _json.loads(plain.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7447"]


# --- groups of settings (a dataclass-typed field: --group.name) --------------------------------


@dataclass
class _Gains:
    kp: float = field(default=1.0, metadata=config.described("proportional gain"))
    names: tuple[str, ...] = ("a", "b")
    on: bool = False

    def __post_init__(self):
        if self.kp < 0:
            raise ConfigError(f"kp={self.kp} must not be negative")


@dataclass
class _Grouped:
    rate_hz: float = 10.0
    gains: _Gains = field(default_factory=_Gains)


def test_a_group_is_layered_file_then_env_then_flags_under_its_dotted_name(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("gains: {kp: 2.0, names: [x]}\nrate-hz: 5\n")
    env = {"CBGO_GAINS_ON": "true", "CBGO_GAINS_KP": "3"}
    got = resolve(_Grouped, ["--settings", str(path), "--gains.kp", "4"], prog="t",
                  env=env).settings
    assert got.rate_hz == 5.0 and got.gains == _Gains(kp=4.0, names=("x",), on=True)
    got = resolve(_Grouped, ["--gains.names", "p,q", "--no-gains.on"], prog="t",
                  env={}).settings
    assert got.gains.names == ("p", "q") and got.gains.on is False


def test_a_groups_own_checks_and_unknown_names_are_errors_naming_the_group(tmp_path):
    with pytest.raises(ConfigError, match="kp=-1.0 must not be negative"):
        resolve(_Grouped, ["--gains.kp", "-1"], prog="t", env={})
    path = tmp_path / "s.yaml"
    path.write_text("gains: {kd: 1}\n")
    with pytest.raises(ConfigError, match=r"gains has unknown settings \['kd'\]"):
        resolve(_Grouped, ["--settings", str(path)], prog="t", env={})
    path.write_text("gains: 3\n")
    with pytest.raises(ConfigError, match="gains must be a mapping"):
        resolve(_Grouped, ["--settings", str(path)], prog="t", env={})


def test_the_documented_rows_of_a_group_are_its_dotted_flags_and_variables():
    rows = {r.flag: r for r in config.settings_rows(_Grouped)}
    assert set(rows) == {"--rate-hz", "--gains.kp", "--gains.names", "--gains.on"}
    assert rows["--gains.kp"].env == "CBGO_GAINS_KP"
    assert rows["--gains.kp"].meaning == "proportional gain"
