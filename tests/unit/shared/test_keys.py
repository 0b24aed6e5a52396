"""Unit tests of cbgo.keys: key expressions under a configurable prefix, and delivery policy."""

from __future__ import annotations

import dataclasses

import pytest
import zenoh

from cbgo import keys
from cbgo.errors import ConfigError
from cbgo.keys import Keys

CELL = "cell-2/cbgo"
ALL_TOPICS = list(keys.TOPICS.values())


def intersects(a: str, b: str) -> bool:
    return zenoh.KeyExpr(a).intersects(zenoh.KeyExpr(b))


# --------------------------------------------------------------------------- building keys


def test_the_default_prefix_is_cbgo():
    assert keys.DEFAULT_PREFIX == "cbgo"
    assert Keys().prefix == "cbgo"
    assert repr(Keys()) == "Keys('cbgo')"


def test_the_hand_frame_key_under_the_default_prefix():
    assert Keys().of(keys.HANDS_FRAME) == "cbgo/hands/frame"


@pytest.mark.parametrize("topic", ALL_TOPICS, ids=[t.suffix for t in ALL_TOPICS])
def test_every_topic_key_is_the_prefix_and_its_suffix_and_a_canonical_zenoh_key(topic):
    for prefix in ("cbgo", CELL):
        key = Keys(prefix).of(topic)
        assert key == f"{prefix}/{topic.suffix}"
        assert str(zenoh.KeyExpr(key)) == key


def test_a_custom_prefix_is_put_in_front_of_every_key():
    cell = Keys(CELL)
    assert cell.of(keys.INTENT) == "cell-2/cbgo/intent"
    assert cell.of(keys.HANDS_FRAME) == "cell-2/cbgo/hands/frame"
    assert cell.alive("episode") == "cell-2/cbgo/@alive/episode"
    assert cell.ctl("episode", "status") == "cell-2/cbgo/@ctl/episode/status"
    assert cell.data == "cell-2/cbgo/**"


def test_liveliness_and_control_keys_carry_an_at_chunk():
    assert Keys().alive("episode") == "cbgo/@alive/episode"
    assert Keys().alive("*") == "cbgo/@alive/*"
    assert Keys().ctl("episode", "status") == "cbgo/@ctl/episode/status"
    assert Keys().ctl("mujoco-sim", "status") == "cbgo/@ctl/mujoco-sim/status"
    for key in (Keys().alive("episode"), Keys().alive("*"), Keys().ctl("episode", "status")):
        assert str(zenoh.KeyExpr(key)) == key


def test_the_data_wildcard_is_everything_below_the_prefix():
    assert Keys().data == "cbgo/**"


# --------------------------------------------------------------------------- zenoh semantics


def test_zenoh_does_not_match_an_alive_key_with_the_data_wildcard():
    # Checked against Zenoh itself: a `**` does not match a chunk that starts with '@'.
    assert zenoh.KeyExpr("cbgo/**").intersects(zenoh.KeyExpr("cbgo/@alive/episode")) is False


@pytest.mark.parametrize("prefix", ["cbgo", CELL])
def test_the_data_wildcard_matches_every_data_key_and_no_control_key(prefix):
    k = Keys(prefix)
    for topic in ALL_TOPICS:
        assert intersects(k.data, k.of(topic)), topic.suffix
    for control in (k.alive("episode"), k.alive("*"), k.ctl("episode", "status"),
                    k.ctl("router", "status")):
        assert not intersects(k.data, control), control


def test_the_alive_wildcard_matches_the_alive_keys_of_its_own_prefix_only():
    assert intersects(Keys().alive("*"), Keys().alive("episode"))
    assert not intersects(Keys().alive("*"), Keys(CELL).alive("episode"))
    assert not intersects(Keys().alive("*"), Keys().ctl("episode", "status"))
    assert not intersects(Keys().alive("*"), Keys().of(keys.HANDS_FRAME))


def test_two_cells_do_not_see_each_others_data():
    assert not intersects(Keys().data, Keys(CELL).of(keys.HANDS_FRAME))
    assert not intersects(Keys(CELL).data, Keys().of(keys.HANDS_FRAME))


# --------------------------------------------------------------------------- prefixes


@pytest.mark.parametrize("prefix", ["", "a//b", "cbgo/*", "cbgo/**", "@cbgo", "/cbgo", "cbgo/",
                                    "cbgo/@alive", "cb go", "cbgo/$*", "cbgo?", "cbgo#1",
                                    "cbgo/a*b"])
def test_an_invalid_prefix_is_rejected_with_a_config_error_that_shows_a_valid_one(prefix):
    with pytest.raises(ConfigError) as info:
        Keys(prefix)
    assert f"invalid key prefix {prefix!r}" in str(info.value)
    assert "'cell-2/cbgo'" in str(info.value)
    with pytest.raises(ConfigError):
        keys.check_prefix(prefix)


@pytest.mark.parametrize("prefix", ["cbgo", CELL, "lab.a/cell_3/cbgo", "X-1"])
def test_a_plain_prefix_is_accepted_and_is_a_valid_zenoh_key(prefix):
    assert keys.check_prefix(prefix) == prefix
    assert Keys(prefix).prefix == prefix
    assert str(zenoh.KeyExpr(prefix)) == prefix


@pytest.mark.parametrize("name", ["episode", "mujoco-sim", "leap-bridge", "router", "a1"])
def test_a_kebab_case_service_name_is_accepted(name):
    assert keys.check_service_name(name) == name


@pytest.mark.parametrize("name", ["", "Episode", "1st", "-a", "leap_bridge", "a/b", "a b", "*",
                                  "@alive"])
def test_a_service_name_that_is_not_kebab_case_is_rejected(name):
    with pytest.raises(ConfigError, match="invalid service name"):
        keys.check_service_name(name)


# --------------------------------------------------------------------------- parsing keys


@pytest.mark.parametrize("topic", ALL_TOPICS, ids=[t.suffix for t in ALL_TOPICS])
def test_topic_of_finds_the_topic_of_every_contract_key(topic):
    assert Keys().topic_of(Keys().of(topic)) is topic
    assert Keys(CELL).topic_of(Keys(CELL).of(topic)) is topic


@pytest.mark.parametrize("key", [
    "cbgo/@alive/episode", "cbgo/@ctl/episode/status", "other/hands/frame",
    "cbgo/hands/frame/extra", "cbgo/hands", "cbgohands/frame", "cbgo", "cbgo/", "hands/frame",
    "cbgo/**", "cell-2/cbgo/hands/frame",
])
def test_topic_of_returns_none_for_a_key_that_is_not_a_contract_key(key):
    assert Keys().topic_of(key) is None


def test_topic_of_with_a_custom_prefix_ignores_default_prefix_keys():
    assert Keys(CELL).topic_of("cbgo/hands/frame") is None
    assert Keys(CELL).topic_of("cell-2/cbgo/hands/frame") is keys.HANDS_FRAME


def test_service_of_alive_reads_the_service_name_of_a_liveliness_key():
    assert Keys().service_of_alive("cbgo/@alive/episode") == "episode"
    assert Keys().service_of_alive(Keys().alive("mujoco-sim")) == "mujoco-sim"
    assert Keys(CELL).service_of_alive("cell-2/cbgo/@alive/intent") == "intent"


@pytest.mark.parametrize("key", ["cbgo/@ctl/episode/status", "cbgo/hands/frame",
                                 "cell-2/cbgo/@alive/episode", "other/@alive/episode",
                                 "@alive/episode"])
def test_service_of_alive_returns_none_for_other_keys(key):
    assert Keys().service_of_alive(key) is None


def test_service_of_alive_returns_none_for_an_alive_key_without_a_name():
    assert Keys().service_of_alive("cbgo/@alive/") is None


@pytest.mark.parametrize(("prefix", "typed", "full"), [
    ("cbgo", "hands/frame", "cbgo/hands/frame"),
    ("cbgo", "/hands/frame", "cbgo/hands/frame"),
    ("cbgo", "cbgo/hands/frame", "cbgo/hands/frame"),
    ("cbgo", "cbgo", "cbgo"),
    ("cbgo", "cbgo/**", "cbgo/**"),
    ("cbgo", "**", "cbgo/**"),
    ("cbgo", "gestures/*", "cbgo/gestures/*"),
    ("cbgo", "@/router/**", "@/router/**"),
    ("cbgo", "@alive", "@alive"),
    ("cbgo", "cbgo2/x", "cbgo/cbgo2/x"),
    (CELL, "hands/frame", "cell-2/cbgo/hands/frame"),
    (CELL, "cell-2/cbgo/intent", "cell-2/cbgo/intent"),
    (CELL, "cbgo/intent", "cell-2/cbgo/cbgo/intent"),
])
def test_resolve_takes_prefixed_and_admin_keys_as_they_are_and_others_as_relative(
        prefix, typed, full):
    assert Keys(prefix).resolve(typed) == full


# --------------------------------------------------------------------------- delivery policy


def test_hand_frames_are_dropped_under_congestion_and_sent_express():
    assert keys.HANDS_FRAME.reliable is False
    assert keys.HANDS_FRAME.express is True
    assert keys.HANDS_FRAME.query is False


@pytest.mark.parametrize("suffix", ["episode/event", "episode/summary", "intent", "plan/status",
                                    "robot/act", "intent/feedback", "intent/clarify",
                                    "intent/answer", "scene/state", "user",
                                    "robot/stop", "intent/infer", "sim/reset", "sim/render",
                                    "sim/info"])
def test_events_summaries_intents_plans_and_actions_are_reliable(suffix):
    assert keys.TOPICS[suffix].reliable is True


@pytest.mark.parametrize("suffix", ["hands/frame", "gaze", "gestures/static", "robot/state"])
def test_high_rate_streams_are_droppable(suffix):
    assert keys.TOPICS[suffix].reliable is False


def test_exactly_the_five_query_keys_are_answered_by_queryables():
    assert {s for s, t in keys.TOPICS.items() if t.query} == {
        "intent/infer", "robot/act", "sim/reset", "sim/render", "sim/info"}


def test_a_stop_is_sent_express_and_reliably():
    assert keys.ROBOT_STOP.express and keys.ROBOT_STOP.reliable


def test_the_topic_table_holds_the_twenty_one_contract_keys_by_suffix():
    assert len(keys.TOPICS) == 21
    assert all(suffix == topic.suffix for suffix, topic in keys.TOPICS.items())


def test_a_topic_is_immutable():
    with pytest.raises(dataclasses.FrozenInstanceError):
        keys.HANDS_FRAME.reliable = True  # type: ignore[misc]


@pytest.mark.parametrize("typed, full", [
    ("@ctl/*/status", "cbgo/@ctl/*/status"),
    ("@ctl/episode/status", "cbgo/@ctl/episode/status"),
    ("@alive/*", "cbgo/@alive/*"),
    ("@/*/router", "@/*/router"),
])
def test_resolve_puts_cbgos_own_control_keys_under_the_prefix(typed, full):
    assert Keys("cbgo").resolve(typed) == full
    assert Keys(CELL).resolve(typed) == (full.replace("cbgo/", f"{CELL}/", 1)
                                         if full.startswith("cbgo/") else full)
