"""The helpers integration tests share (cbgo.testing): Collector, Stack.put, wait_for_line.

A fake Zenoh session stands in for the router, so these run without cbgo processes; the
`wait_for_line` tests start tiny Python processes of their own.
"""

import os
import sys
import threading
from types import SimpleNamespace

import pytest

from cbgo import wire
from cbgo.testing import Process, Stack


class FakePublisher:
    def __init__(self, session, key):
        self.session, self.key = session, key
        self.sent: list[bytes] = []

    @property
    def matching_status(self):
        return SimpleNamespace(matching=self.key in self.session.listened)

    def put(self, payload: bytes) -> None:
        self.sent.append(payload)


class FakeSession:
    """Records declarations; `deliver` plays Zenoh's callback thread; publishers match the
    keys in `listened` (the keys some process subscribes to)."""

    def __init__(self):
        self.subscribers: dict[str, object] = {}
        self.publishers: dict[str, FakePublisher] = {}
        self.listened: set[str] = set()

    def declare_subscriber(self, key, callback):
        self.subscribers[key] = callback
        return object()

    def declare_publisher(self, key):
        self.publishers[key] = FakePublisher(self, key)
        return self.publishers[key]

    def deliver(self, key, message):
        payload = SimpleNamespace(to_bytes=lambda: wire.encode(message))
        self.subscribers[key](SimpleNamespace(payload=payload))


class OfflineStack(Stack):
    """A Stack whose test session is a FakeSession (no router, no processes)."""

    def __init__(self, workdir):
        super().__init__(workdir)
        self.fake = FakeSession()

    def session(self):
        return self.fake


@pytest.fixture
def offline(tmp_path):
    return OfflineStack(tmp_path)


def later(seconds, action):
    """Runs action on another thread after `seconds`, as a message from a process would come."""
    timer = threading.Timer(seconds, action)
    timer.start()
    return timer


# ============================================================================ Collector


def test_collect_subscribes_under_the_prefix_and_keeps_messages_in_arrival_order(offline):
    gaze = offline.collect("gaze")
    assert list(offline.fake.subscribers) == ["cbgo/gaze"]
    offline.fake.deliver("cbgo/gaze", {"n": 1})
    offline.fake.deliver("cbgo/gaze", {"n": 2})
    assert gaze.items() == [{"n": 1}, {"n": 2}]
    assert gaze.last() == {"n": 2}
    (t1, m1), (t2, m2) = gaze.arrivals()
    assert (m1, m2) == ({"n": 1}, {"n": 2}) and t1 <= t2


def test_last_fails_when_nothing_arrived(offline):
    with pytest.raises(AssertionError, match="nothing arrived on cbgo/user"):
        offline.collect("user").last()


def test_wait_returns_every_match_and_first_the_earliest(offline):
    plans = offline.collect("plan/status")
    for state in ("running", "success", "running", "failure"):
        offline.fake.deliver("cbgo/plan/status", {"state": state})
    done = plans.wait(lambda m: m["state"] != "running", timeout=1)
    assert done == [{"state": "success"}, {"state": "failure"}]
    assert plans.first(lambda m: m["state"] != "running", timeout=1) == {"state": "success"}
    assert plans.wait(timeout=1)[0] == {"state": "running"}  # no predicate: any message


def test_wait_returns_once_a_matching_message_arrives_from_another_thread(offline):
    scenes = offline.collect("scene/state")
    offline.fake.deliver("cbgo/scene/state", {"holding": None})
    later(0.2, lambda: offline.fake.deliver("cbgo/scene/state", {"holding": "cup1"}))
    assert scenes.first(lambda m: m["holding"] == "cup1", timeout=5) == {"holding": "cup1"}


def test_wait_count_waits_for_n_matches_and_returns_them_all(offline):
    summaries = offline.collect("episode/summary")
    timers = [later(0.05 * i, lambda i=i: offline.fake.deliver("cbgo/episode/summary",
                                                                {"n": i}))
              for i in range(1, 5)]
    got = summaries.wait_count(3, lambda m: m["n"] % 2 == 0 or m["n"] > 2, timeout=5)
    for timer in timers:
        timer.join()
    assert got == [{"n": 2}, {"n": 3}, {"n": 4}]


def test_a_wait_that_times_out_says_how_many_matched_and_what_came_last(offline):
    frames = offline.collect("hands/frame")
    offline.fake.deliver("cbgo/hands/frame", {"hands": [], "seq": 7})
    with pytest.raises(TimeoutError) as failed:
        frames.wait_count(2, lambda m: m["seq"] >= 7, timeout=0.1)
    assert "1 of 2 matching messages on cbgo/hands/frame within 0.1 s" in str(failed.value)
    assert "'seq': 7" in str(failed.value)
    with pytest.raises(TimeoutError, match="0 of 1 .* the newest: nothing"):
        offline.collect("gaze").wait(timeout=0.05)


def test_window_returns_only_what_arrived_during_it(offline):
    frames = offline.collect("hands/frame")
    offline.fake.deliver("cbgo/hands/frame", {"seq": 0})
    timers = [later(0.05, lambda: offline.fake.deliver("cbgo/hands/frame", {"seq": 1})),
              later(0.1, lambda: offline.fake.deliver("cbgo/hands/frame", {"seq": 2}))]
    got = frames.window(0.4)
    for timer in timers:
        timer.join()
    assert [m for _, m in got] == [{"seq": 1}, {"seq": 2}]
    assert got[0][0] < got[1][0]


# ============================================================================ Stack.put


def test_put_waits_for_a_subscriber_then_sends_the_encoded_message(offline):
    later(0.2, lambda: offline.fake.listened.add("cbgo/intent"))
    offline.put("intent", {"action": "open"}, timeout=5)
    assert [wire.decode(p) for p in offline.fake.publishers["cbgo/intent"].sent] == [
        {"action": "open"}]


def test_put_raw_sends_bytes_as_they_are_and_reuses_the_publisher(offline):
    offline.fake.listened.add("cbgo/user")
    offline.put_raw("user", b"\xc1 not msgpack")
    publisher = offline.fake.publishers["cbgo/user"]
    offline.put_raw("user", b"again")
    assert offline.fake.publishers["cbgo/user"] is publisher  # not declared a second time
    assert publisher.sent == [b"\xc1 not msgpack", b"again"]


def test_put_without_a_subscriber_fails_rather_than_losing_the_message(offline):
    with pytest.raises(TimeoutError, match="no subscriber on cbgo/robot/stop within 0.1 s"):
        offline.put("robot/stop", {"reason": "test"}, timeout=0.1)
    assert offline.fake.publishers["cbgo/robot/stop"].sent == []


# ============================================================================ wait_for_line


def python(tmp_path, code, name="child"):
    """A Process running `python -c code`, its log under tmp_path."""
    return Process(name, [sys.executable, "-c", code], tmp_path / f"{name}.log",
                   dict(os.environ))


@pytest.fixture
def spawned():
    procs = []
    yield procs
    for proc in procs:
        proc.signal(9)
        proc.wait(5)


def test_wait_for_line_returns_the_first_line_containing_the_text(tmp_path, spawned):
    proc = python(tmp_path, "import time; print('starting'); print('ready: a b', flush=True);"
                            " print('ready: again', flush=True); time.sleep(30)")
    spawned.append(proc)
    assert proc.wait_for_line("ready: ", timeout=10) == "ready: a b"


def test_wait_for_line_fails_at_once_when_the_process_exits_without_it(tmp_path, spawned):
    proc = python(tmp_path, "print('something else'); raise SystemExit(3)")
    spawned.append(proc)
    with pytest.raises(RuntimeError, match="child exited with 3 before printing 'ready: '"
                                           "(.|\n)*something else"):
        proc.wait_for_line("ready: ", timeout=30)


def test_wait_for_line_finds_a_line_printed_just_before_the_exit(tmp_path, spawned):
    proc = python(tmp_path, "print('done: 4 messages')")
    spawned.append(proc)
    proc.wait(10)
    assert proc.wait_for_line("done: ", timeout=0) == "done: 4 messages"


def test_wait_for_line_times_out_while_the_process_runs_on(tmp_path, spawned):
    proc = python(tmp_path, "import time; print('busy', flush=True); time.sleep(30)")
    spawned.append(proc)
    with pytest.raises(TimeoutError, match="'ready: ' not in the log of child after 0.5 s"):
        proc.wait_for_line("ready: ", timeout=0.5)
