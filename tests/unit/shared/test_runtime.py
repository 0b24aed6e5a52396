"""The runtime's dispatch, driven in memory through FakeBus (the same code as over Zenoh)."""

import math
import time
from dataclasses import dataclass

import pytest

from cbgo import keys, wire
from cbgo.errors import QueryError
from cbgo.examples import example
from cbgo.runtime import Service
from cbgo.testing import FakeBus


@dataclass
class EchoSettings:
    fail_on: str = "boom"


class Echo(Service):
    """Turns each user into an episode start; answers intent/infer; stops on robot/stop."""

    name = "echo"
    settings_class = EchoSettings

    def setup(self, ctx):
        self.ctx = ctx
        self.stops = []
        self.ticks = 0
        ctx.subscribe(keys.USER, self.on_user)
        ctx.subscribe(keys.ROBOT_STOP, self.on_stop, immediate=True)
        ctx.queryable(keys.INTENT_INFER, self.on_infer)
        ctx.control("reload", lambda q: {"reloaded": True, "asked": q})
        ctx.every(0.5, self.on_tick)
        ctx.publishes(keys.EPISODE_EVENT)

    def on_user(self, msg):
        if msg["user"] == self.settings.fail_on:
            raise RuntimeError("handler exploded")
        if msg["user"] == "invalid-output":
            return [(keys.EPISODE_EVENT, {"v": 1, "ts": -5.0, "episode": "x", "kind": "start"})]
        return [(keys.EPISODE_EVENT, {"v": 1, "ts": time.time(), "episode": msg["user"],
                                      "kind": "start"})]

    def on_stop(self, msg):
        self.stops.append(msg)

    def on_infer(self, query):
        user = query["user"]
        if user == "nobody":
            raise QueryError("unknown user 'nobody'")
        if user == "crash":
            raise ZeroDivisionError("division by zero")
        reply = example("intent/infer", "reply")
        if user == "bad-reply":
            reply["confidence"] = 2.0
        return reply

    def on_tick(self):
        self.ticks += 1
        return [(keys.GAZE, example("gaze"))]


@pytest.fixture
def bus():
    return FakeBus(Echo(EchoSettings()))


def test_a_valid_input_reaches_the_handler_and_its_output_is_published(bus):
    out = bus.feed(keys.USER, example("user", user="alice"))
    assert [(suffix, msg["episode"]) for suffix, msg in out] == [("episode/event", "alice")]
    assert bus.counters.as_dict() == {"received": 1, "published": 1, "rejected": 0,
                                      "errors": 0, "dropped": 0}


@pytest.mark.parametrize("payload, problem", [
    (b"\xc1", "not a msgpack payload"),
    (wire.encode({"v": 1, "ts": math.inf, "user": "a"}), "ts: expected a finite number"),
    (wire.encode({"v": 1, "ts": 1.0}), "user: missing required field"),
    (wire.encode({"v": 3, "ts": 1.0, "user": "a"}), "schema version 3 is newer"),
])
def test_a_bad_input_is_counted_and_the_next_good_one_still_works(bus, payload, problem):
    assert bus.feed_raw(keys.USER, payload) == []
    assert bus.counters.rejected == 1
    assert problem in bus.counters.last_error["message"]
    assert len(bus.feed(keys.USER, example("user"))) == 1


def test_an_input_over_the_size_limit_is_rejected():
    bus = FakeBus(Echo(EchoSettings()), max_payload_bytes=2048)
    assert bus.feed(keys.USER, example("user", user="x" * 3000)) == []
    assert "exceeds the limit of 2048 bytes" in bus.counters.last_error["message"]


def test_a_failing_handler_is_counted_as_an_error_and_the_service_goes_on(bus):
    assert bus.feed(keys.USER, example("user", user="boom")) == []
    assert bus.counters.errors == 1
    assert "RuntimeError: handler exploded" in bus.counters.last_error["message"]
    assert len(bus.feed(keys.USER, example("user"))) == 1


def test_an_output_that_breaks_the_contract_is_never_published(bus):
    assert bus.feed(keys.USER, example("user", user="invalid-output")) == []
    assert bus.counters.errors == 1
    assert bus.counters.published == 0
    assert "ts: expected a finite number >= 0.0" in bus.counters.last_error["message"]


def test_robot_stop_accepts_any_payload_at_all(bus):
    bus.feed_raw(keys.ROBOT_STOP, b"")
    bus.feed_raw(keys.ROBOT_STOP, b"\xc1 garbage")
    bus.feed(keys.ROBOT_STOP, {"v": 1, "ts": 1.0})
    assert bus.service.stops == [{}, {}, {"v": 1, "ts": 1.0}]
    assert bus.counters.rejected == 0


def test_a_valid_query_gets_the_handlers_reply(bus):
    ok, reply = bus.query(keys.INTENT_INFER, example("intent/infer", "query"))
    assert ok and reply["action"] == "pick_up"


@pytest.mark.parametrize("user, reason", [
    ("nobody", "unknown user 'nobody'"),
    ("crash", "internal error in echo: ZeroDivisionError: division by zero"),
    ("bad-reply", "internal error in echo: RejectedMessage: cbgo/intent/infer: confidence"),
])
def test_a_query_that_cannot_be_answered_gets_an_error_reply(bus, user, reason):
    ok, text = bus.query(keys.INTENT_INFER, example("intent/infer", "query", user=user))
    assert not ok
    assert text.startswith(reason)


def test_a_malformed_query_gets_an_error_reply_naming_the_field(bus):
    ok, text = bus.query(keys.INTENT_INFER, {"v": 1, "gestures": {"names": [], "probs": []}})
    assert not ok
    assert text == "rejected: cbgo/intent/infer: scene: missing required field (expected a map)"
    ok, text = bus.query(keys.INTENT_INFER, None)
    assert not ok and "missing required field" in text
    assert bus.counters.rejected == 2


def test_the_status_control_query_reports_name_counters_and_config(bus):
    bus.feed_raw(keys.USER, b"junk")
    ok, status = bus.query("status", None)
    assert ok
    wire.validate(status, wire.SERVICE_STATUS)
    assert status["name"] == "echo"
    assert status["counters"]["rejected"] == 1
    assert status["inputs"] == ["cbgo/user", "cbgo/robot/stop"]
    assert "cbgo/episode/event" in status["outputs"]
    assert "cbgo/intent/infer" in status["queryables"]


def test_a_control_verb_takes_an_optional_payload(bus):
    assert bus.query("reload", None) == (True, {"reloaded": True, "asked": {}})
    assert bus.query("reload", {"path": "m.pt"}) == (True, {"reloaded": True,
                                                          "asked": {"path": "m.pt"}})


def test_timers_run_when_due_and_skip_missed_periods(bus):
    assert bus.tick(0.2) == []
    out = bus.tick(0.4)
    assert [suffix for suffix, _ in out] == ["gaze"]
    out = bus.tick(10.0)  # a long stall runs the timer once, not twenty times
    assert len(out) == 1
    assert bus.service.ticks == 2


def test_a_service_query_returns_the_reply_or_raises_query_error(bus):
    ctx = bus.service.ctx
    with pytest.raises(QueryError, match="no reply on cbgo/robot/act within 1 s"):
        ctx.query(keys.ROBOT_ACT, example("robot/act", "query"), timeout_s=1.0)
    bus.answer(keys.ROBOT_ACT, lambda q: example("robot/act", "reply"))
    assert ctx.query(keys.ROBOT_ACT, example("robot/act", "query"))["ok"] is True

    def refuse(query):
        raise QueryError("object cup9 does not exist")

    bus.answer(keys.ROBOT_ACT, refuse)
    with pytest.raises(QueryError, match="object cup9 does not exist"):
        ctx.query(keys.ROBOT_ACT, example("robot/act", "query"))


def test_a_malformed_reply_to_a_service_query_raises_query_error(bus):
    bus.answer(keys.ROBOT_ACT, lambda q: {"v": 1, "ok": "yes"})
    with pytest.raises(QueryError, match="malformed reply: cbgo/robot/act: ok: expected a bool"):
        bus.service.ctx.query(keys.ROBOT_ACT, example("robot/act", "query"))


def test_waiting_for_a_service_sees_its_liveliness(bus):
    ctx = bus.service.ctx
    assert ctx.wait_for_service("planner", timeout_s=0.1) is False
    bus.set_alive("planner")
    assert ctx.wait_for_service("planner", timeout_s=0.1) is True


def test_after_a_stall_queued_messages_run_before_the_timer_that_fell_due():
    # The episode's end-of-hand timer must see the frames that arrived while the process was
    # starved; otherwise it ends an episode whose next hand frames wait in the queue.
    from cbgo.runtime import Context, _EventLoop

    order = []
    loop = _EventLoop(lambda: None)
    ctx = Context(Echo(EchoSettings()), keys.Keys("cbgo"), transport=None, config={},
                  enqueue=loop.enqueue)

    def tick():
        order.append("timer")
        ctx.stopping.set()

    ctx.every(0.01, tick)
    loop.enqueue(lambda: order.append("frame 1"), True)
    loop.enqueue(lambda: order.append("frame 2"), True)
    time.sleep(0.02)  # the stall: the timer is due, two frames are queued
    loop.run(ctx)
    assert order == ["frame 1", "frame 2", "timer"]


class SlowStart(Service):
    """A service whose status fields exist only at the end of its setup."""

    name = "slow-start"

    def setup(self, ctx):
        self.seen_while_starting = ctx.status()  # a status poll that comes during setup
        self.model = "m1"

    def status_extra(self):
        return {"model": self.model}


def test_status_asked_during_setup_is_answered_without_the_services_own_fields():
    bus = FakeBus(SlowStart(None))
    early = bus.service.seen_while_starting
    wire.validate(early, wire.SERVICE_STATUS)
    assert "model" not in early
    ok, status = bus.query("status", None)
    assert ok and status["model"] == "m1"
