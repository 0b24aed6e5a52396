"""cbgo.client: replies checked against the contract, size limits per key, QueryError, status.

A fake Zenoh session answers with scripted replies at once, the way a real one hands back what
came before the timeout, so no test waits for time to pass.
"""

from types import SimpleNamespace

import pytest
import zenoh

from cbgo import client, wire
from cbgo.errors import QueryError
from cbgo.examples import example
from cbgo.keys import Keys


def _ok(key: str, payload: bytes):
    return SimpleNamespace(ok=SimpleNamespace(key_expr=key, payload=SimpleNamespace(
        to_bytes=lambda: payload)), err=None)


def _err(text: str):
    return SimpleNamespace(ok=None, err=SimpleNamespace(payload=SimpleNamespace(
        to_bytes=lambda: text.encode())))


class FakeSession:
    """Answers each queried key with the replies scripted for it; records the queries."""

    def __init__(self, answers: dict[str, list] | None = None, alive: list[str] = ()):
        self.answers = answers or {}
        self.tokens = list(alive)
        self.queries: list[tuple[str, bytes | None, float]] = []

    def get(self, key, payload=None, timeout=None, consolidation=None):
        self.queries.append((key, payload, timeout))
        self.consolidation = consolidation
        return list(self.answers.get(key, []))

    def liveliness(self):
        return SimpleNamespace(get=lambda key, timeout: [_ok(t, b"") for t in self.tokens])


ACT = "cbgo/robot/act"


def test_query_returns_the_reply_checked_against_the_keys_reply_schema():
    reply = example("robot/act", "reply")
    sess = FakeSession({ACT: [_ok(ACT, wire.encode(reply))]})
    query = example("robot/act", "query")
    assert client.query(sess, ACT, query, timeout_s=2.0) == reply
    assert sess.queries == [(ACT, wire.encode(query), 2.0)]


def test_a_reply_that_breaks_the_schema_raises_query_error_naming_the_field():
    sess = FakeSession({ACT: [_ok(ACT, wire.encode({"v": 1, "ok": "yes"}))]})
    with pytest.raises(QueryError, match="malformed reply: cbgo/robot/act: ok: expected a bool"):
        client.query(sess, ACT, example("robot/act", "query"))


def test_an_error_reply_raises_query_error_with_its_text():
    sess = FakeSession({ACT: [_err("object cup9 does not exist")]})
    with pytest.raises(QueryError, match="^object cup9 does not exist$"):
        client.query(sess, ACT, example("robot/act", "query"))


def test_no_reply_raises_query_error_saying_how_long_it_waited():
    with pytest.raises(QueryError, match=r"no reply on cbgo/robot/act within 2 s \(is mujoco"):
        client.query(FakeSession(), ACT, example("robot/act", "query"), timeout_s=2.0,
                     hint="is mujoco-sim up?")


def test_an_error_reply_does_not_hide_a_good_one_from_another_service():
    reply = example("robot/act", "reply")
    sess = FakeSession({ACT: [_err("busy"), _ok(ACT, wire.encode(reply))]})
    assert client.query(sess, ACT, example("robot/act", "query"))["ok"] is True


def test_render_replies_may_be_larger_than_the_default_limit_and_others_may_not():
    big = b"\x89PNG" + bytes(wire.DEFAULT_MAX_BYTES + 10)
    render = "cell-2/cbgo/sim/render"
    sess = FakeSession({render: [_ok(render, wire.encode(
        example("sim/render", "reply", png=big)))]})
    assert client.query(sess, render, {"v": 1})["png"] == big

    sess = FakeSession({ACT: [_ok(ACT, wire.encode(example("robot/act", "reply", pad=big)))]})
    with pytest.raises(QueryError, match="exceeds the limit of 1048576 bytes"):
        client.query(sess, ACT, example("robot/act", "query"))


def test_a_control_key_without_a_reply_schema_accepts_any_map():
    key = "cbgo/@ctl/leap-bridge/play"
    sess = FakeSession({key: [_ok(key, wire.encode({"playing": True}))]})
    assert client.query(sess, key) == {"playing": True}
    assert sess.queries[0][1] is None  # no message: no payload


def test_query_all_returns_every_reply_and_marks_malformed_ones_as_errors():
    key = "cbgo/@ctl/*/status"
    good = _status("episode")
    sess = FakeSession({key: [_ok("cbgo/@ctl/episode/status", wire.encode(good)),
                              _ok("cbgo/@ctl/intent/status", wire.encode({"v": 1})),
                              _err("not now")]})
    got = client.query_all(sess, key)
    assert sess.consolidation == zenoh.ConsolidationMode.NONE  # two processes of a name: two
    assert got[0] == (True, good)
    assert got[1][0] is False and got[1][1].startswith(
        "malformed reply: cbgo/@ctl/intent/status: ")
    assert got[2] == (False, "not now")


def test_status_lists_every_service_that_answers_with_a_valid_status():
    keys = Keys("cell-2/cbgo")
    key = "cell-2/cbgo/@ctl/*/status"
    sess = FakeSession({key: [
        _ok("cell-2/cbgo/@ctl/episode/status", wire.encode(_status("episode"))),
        _ok("cell-2/cbgo/@ctl/intent/status", wire.encode(_status("intent"))),
        _ok("cell-2/cbgo/@ctl/broken/status", b"\xc1 not msgpack"),
    ]})
    assert sorted(client.status(sess, keys)) == ["episode", "intent"]


def test_alive_names_the_services_whose_tokens_are_present():
    sess = FakeSession(alive=["cbgo/@alive/router", "cbgo/@alive/episode", "cbgo/other"])
    assert client.alive(sess, Keys()) == {"router", "episode"}


class CountingPublisher:
    """Matches a subscriber from the `after`-th look at its matching status on."""

    def __init__(self, after: int | None):
        self.after, self.looks, self.sent = after, 0, []
        self.key_expr = "cbgo/intent/feedback"

    @property
    def matching_status(self):
        self.looks += 1
        return SimpleNamespace(matching=self.after is not None and self.looks >= self.after)

    def put(self, payload: bytes) -> None:
        self.sent.append(payload)


def test_put_when_matched_puts_only_once_a_subscriber_is_there():
    pub = CountingPublisher(after=3)
    client.put_when_matched(pub, b"x", timeout_s=30.0)
    assert pub.sent == [b"x"] and pub.looks >= 3


def test_put_when_matched_without_a_subscriber_raises_instead_of_losing_the_message():
    pub = CountingPublisher(after=None)
    with pytest.raises(TimeoutError, match="no subscriber on cbgo/intent/feedback"):
        client.put_when_matched(pub, b"x", timeout_s=0.0)
    assert pub.sent == []


def test_a_bad_network_flag_is_a_connect_error_with_the_configuration_exit_code():
    with pytest.raises(client.ConnectError, match="configuration error: mode 'bogus'") as e:
        client.connect({"mode": "bogus"})
    assert e.value.code == 2


def _status(name: str) -> dict:
    return {"v": 1, "ts": 1.0, "name": name, "version": "0.1", "pid": 7, "host": "h",
            "uptime_s": 1.0, "config": {}, "counters": {"received": 0, "published": 0,
                                                        "rejected": 0, "errors": 0},
            "last_error": None}
