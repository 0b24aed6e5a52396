"""The bad-input battery against franka (dry run, through the real runtime dispatch).

Every query key franka answers gets malformed bytes, messages that break the contract and
well-formed requests the world forbids; its one input (``robot/stop``) gets junk. Each query
must get exactly one answer or one error reply, nothing may end in an unexpected exception
(the ``errors`` counter stays 0: every bad input is caught by a check, not by luck), and the
service still acts afterwards. `battery()` is reused against franky-sim by
tests/integration/test_franka.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import msgpack
import pytest

from cbgo import keys, wire
from cbgo.services.franka.main import Franka, FrankaSettings
from cbgo.testing import FakeBus, _FakeQuery

# the declared scene of every test here and of the bad-input battery
SCENE = json.loads((Path(__file__).parents[2] / "fixtures" / "franka" / "scene.json").read_text())
NAN = float("nan")


def _act(action, obj=None, **params) -> bytes:
    return wire.encode({"v": 1, "action": action, "object": obj, "params": params})


def _reset(scene) -> bytes:
    return msgpack.packb({"v": 1, "scene": scene})


def _with(**changes) -> dict:
    """SCENE with its first object changed."""
    return {**SCENE, "objects": [{**SCENE["objects"][0], **changes}, *SCENE["objects"][1:]]}


def battery() -> list[tuple[str, str, bytes | None]]:
    """Returns (label, key suffix, raw query payload) for every bad query."""
    junk = [("not msgpack", b"\xc1\xc1"), ("empty", b""), ("a list", msgpack.packb([1, 2])),
            ("a number", msgpack.packb(7)), ("over 1 MiB", b"\x00" * (1024 * 1024 + 1)),
            ("a newer version", msgpack.packb({"v": 99}))]
    cases = [(f"{key}: {what}", key, raw) for key in ("robot/act", "sim/reset", "sim/info",
                                                      "sim/render") for what, raw in junk]
    cases += [
        ("act without a payload", "robot/act", None),
        ("act without an action", "robot/act", msgpack.packb({"v": 1, "object": "box1"})),
        ("act of an unknown action", "robot/act", _act("fly", "box1")),
        ("act of an empty action", "robot/act", _act("")),
        ("act with an object that is a number", "robot/act",
         msgpack.packb({"v": 1, "action": "pick_up", "object": 42, "params": {}})),
        ("act with params that are a string", "robot/act",
         msgpack.packb({"v": 1, "action": "move_up", "object": None, "params": "far"})),
        ("act with a NaN distance", "robot/act",
         msgpack.packb({"v": 1, "action": "move_up", "object": None,
                        "params": {"distance": NAN}})),
        ("pick_up of an unknown object", "robot/act", _act("pick_up", "cup9")),
        ("pick_up without an object", "robot/act", _act("pick_up")),
        ("a move 3 m up", "robot/act", _act("move_up", distance=3.0)),
        ("a move of a negative distance", "robot/act", _act("move_down", distance=-0.1)),
        ("a move of a text distance", "robot/act", _act("move_left", distance="far")),
        ("pour of 1000 degrees", "robot/act", _act("pour", "cup1", angle_deg=1000)),
        ("open of a box", "robot/act", _act("open", "box1")),
        ("put_into with nothing held", "robot/act", _act("put_into", "drawer1")),
        ("reset to a negative seed", "sim/reset", msgpack.packb({"v": 1, "seed": -1})),
        ("reset to a text seed", "sim/reset", msgpack.packb({"v": 1, "seed": "x"})),
        ("reset to a scene that is a list", "sim/reset", msgpack.packb({"v": 1, "scene": []})),
        ("reset to a scene without objects", "sim/reset", _reset({"robot": {}})),
        ("reset with a NaN position", "sim/reset", _reset(_with(position=[NAN, 0.0, 0.0]))),
        ("reset with an object 3 m away", "sim/reset", _reset(_with(position=[3.0, 0, 0]))),
        ("reset with a 2 m box", "sim/reset", _reset(_with(size=2.0))),
        ("reset with a box of negative size", "sim/reset", _reset(_with(size=-0.05))),
        ("reset with an unknown type", "sim/reset", _reset(_with(type="sofa"))),
        ("reset with two objects of one name", "sim/reset", _reset(_with(name="cup1"))),
        ("reset with a box on a missing one", "sim/reset", _reset(_with(on="box9"))),
        ("reset holding a missing object", "sim/reset",
         _reset({**SCENE, "robot": {"holding": "cup9"}})),
        ("reset with 300 objects", "sim/reset", _reset({"objects": [
            {**SCENE["objects"][0], "name": f"box{i}"} for i in range(300)]})),
        ("render 1 pixel wide", "sim/render", msgpack.packb({"v": 1, "width": 1})),
        ("render", "sim/render", msgpack.packb({"v": 1})),
        ("info with a text version", "sim/info", msgpack.packb({"v": "one"})),
    ]
    return cases


STOP_JUNK = [b"", b"\xc1", msgpack.packb({"v": 1, "ts": NAN}), b"\x00" * (1024 * 1024 + 1)]


@pytest.fixture(scope="module")
def bus(tmp_path_factory):
    path = tmp_path_factory.mktemp("franka") / "scene.json"
    path.write_text(json.dumps(SCENE))
    bus = FakeBus(Franka(FrankaSettings(scene=str(path), dry_run=True)))
    yield bus
    bus.stop()


def ask(bus, suffix: str, payload: bytes | None) -> list[tuple[bool, bytes]]:
    """Sends one raw query; returns every reply it got."""
    query = _FakeQuery(payload)
    bus.transport.queryables[bus.keys.resolve(suffix)](query)
    return query.replies


@pytest.mark.parametrize("label,suffix,payload", battery(), ids=[c[0] for c in battery()])
def test_every_bad_query_gets_one_answer_or_one_error_reply(bus, label, suffix, payload):
    (ok, body), = ask(bus, suffix, payload)
    if ok:  # an answer: well formed, and a refusal says why
        reply = wire.decode(body, wire.MAX_BYTES_RENDER)
        wire.validate(reply, wire.REPLY_SCHEMAS[suffix], suffix)
        assert reply.get("ok") is not True or suffix == "sim/info", (label, reply)
        assert reply.get("ok") is not False or reply["error"], (label, reply)
    else:
        assert body.decode().strip(), label
    assert bus.counters.errors == 0, label


def test_after_the_battery_the_service_still_acts_and_nothing_moved(bus):
    for payload in STOP_JUNK:
        bus.feed_raw(keys.ROBOT_STOP, payload)  # any payload stops: nothing runs, no harm
    for _label, suffix, payload in battery():
        ask(bus, suffix, payload)
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "scene": SCENE})
    assert ok and reply["ok"], reply
    ok, reply = bus.query(keys.ROBOT_ACT, {"v": 1, "action": "pick_up", "object": "box1",
                                           "params": {}})
    assert ok and reply["ok"], reply
    counters = bus.counters
    assert counters.errors == 0 and counters.rejected > 0
    ok, status = bus.query("status", None)
    assert ok and status["actions"]["ok"] == 1
