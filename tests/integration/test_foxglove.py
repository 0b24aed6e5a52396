"""Foxglove through real processes: the live bridge's WebSocket, JSON recordings, export.

The WebSocket client speaks Foxglove's protocol as the Foxglove app does (subprotocol
``foxglove.sdk.v1``): serverInfo and advertise come as JSON text, the client subscribes to
channel ids, message data comes as binary frames (opcode 1, subscription id u32, log time u64,
payload), all little-endian.
"""

from __future__ import annotations

import asyncio
import json
import signal
import struct
import subprocess
import sys
import time

import jsonschema
import pytest
import websockets
from mcap.reader import make_reader

from cbgo import wire
from cbgo.examples import example
from cbgo.recording import Recorder, read_recording
from cbgo.testing import free_port

CLI = [sys.executable, "-m", "cbgo.cli.main"]
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
MESSAGE_DATA = 0x01
HANDS, SCENE = "cbgo/hands/frame", "foxglove/scene"


async def _text(ws, op: str, timeout: float) -> dict:
    """Returns the next JSON message with this op (binary frames before it are skipped)."""
    async with asyncio.timeout(timeout):
        while True:
            frame = await ws.recv()
            if isinstance(frame, str) and json.loads(frame).get("op") == op:
                return json.loads(frame)


async def _advertised(ws, topics: set[str], timeout: float) -> dict[str, dict]:
    """Collects advertise messages until every topic is advertised; returns them by topic."""
    channels: dict[str, dict] = {}
    async with asyncio.timeout(timeout):
        while not topics <= set(channels):
            message = await _text(ws, "advertise", timeout)
            channels.update({c["topic"]: c for c in message["channels"]})
    return channels


async def _first_data(ws, wanted: dict[int, str], timeout: float,
                      accept=lambda topic, message: True) -> dict[str, dict]:
    """Returns the first message of each subscription that `accept` takes, by topic."""
    got: dict[str, dict] = {}
    async with asyncio.timeout(timeout):
        while len(got) < len(wanted):
            frame = await ws.recv()
            if isinstance(frame, str) or frame[0] != MESSAGE_DATA:
                continue
            subscription, _log_time = struct.unpack_from("<IQ", frame, 1)
            topic = wanted.get(subscription)
            message = json.loads(frame[13:])
            if topic is not None and topic not in got and accept(topic, message):
                got[topic] = message
    return got


def _has_hands(topic: str, message: dict) -> bool:
    if topic == HANDS:
        return bool(message["hands"])
    return any(e["id"] == "hands" and e["spheres"] for e in message["entities"])


async def _watch_live(url: str, timeout: float = 40.0):
    """Connects as Foxglove does, subscribes to hands and scene; returns what it saw."""
    async with websockets.connect(url, subprotocols=SUBPROTOCOLS, max_size=None) as ws:
        info = await _text(ws, "serverInfo", timeout)
        channels = await _advertised(ws, {HANDS, SCENE}, timeout)
        wanted = {1: HANDS, 2: SCENE}
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": channels[t]["id"]} for i, t in wanted.items()]}))
        data = await _first_data(ws, wanted, timeout, _has_hands)
    return info, channels, data


def _check_live(info, channels, data) -> None:
    assert info["name"] == "cbgo"
    scene = channels[SCENE]
    assert scene["schemaName"] == "foxglove.SceneUpdate"
    assert scene["encoding"] == "json" and scene["schemaEncoding"] == "jsonschema"
    assert channels[HANDS]["schemaName"] == "cbgo.hands.frame"
    for topic, message in data.items():
        jsonschema.validate(message, json.loads(channels[topic]["schema"]))
    assert wire.validate(data[HANDS], wire.HANDS_FRAME)
    hands = next(e for e in data[SCENE]["entities"] if e["id"] == "hands")
    assert hands["frame_id"] == "base" and hands["lines"]


def test_the_bridge_advertises_hands_and_the_scene_and_streams_both_after_subscribe(stack):
    port = free_port()
    stack.start_router()
    stack.start_service("foxglove-bridge", "--ws-port", str(port))
    stack.wait_alive(["router", "foxglove-bridge"], timeout=30)
    stack.start_service("leap-bridge", "--scenario", "demo", "--loop")
    info, channels, data = asyncio.run(_watch_live(f"ws://127.0.0.1:{port}"))
    _check_live(info, channels, data)
    status = stack.status("foxglove-bridge")
    assert status["forwarded"][HANDS] > 0 and status["derived"][SCENE] > 0
    assert status["websocket"] == f"ws://127.0.0.1:{port}"


def test_the_bridge_counts_a_malformed_message_and_keeps_serving(stack):
    port = free_port()
    stack.start_router()
    stack.start_service("foxglove-bridge", "--ws-port", str(port))
    stack.wait_alive(["router", "foxglove-bridge"], timeout=30)
    stack.put_raw("hands/frame", b"\xc1 not msgpack")
    stack.put("gaze", {"v": 1, "ts": 1.0, "point": [0.5, 0.0], "source": "simulated"})
    deadline = time.monotonic() + 10
    while stack.status("foxglove-bridge")["counters"]["rejected"] < 2:
        assert time.monotonic() < deadline, stack.logs(["foxglove-bridge"])
        time.sleep(0.05)
    code, _ = stack.stop("foxglove-bridge")
    assert code == 0, stack.logs(["foxglove-bridge"])


def test_a_busy_port_is_a_configuration_error_naming_the_flag(stack):
    import socket

    stack.start_router()
    stack.wait_alive(["router"])
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = subprocess.run([*CLI, "foxglove", "--ws-port", str(port), "--connect",
                               stack.endpoint], capture_output=True, text=True, timeout=60,
                              env=stack.env())
    assert done.returncode == 2, done.stderr
    assert "--ws-port" in done.stderr


def validate_json_recording(path) -> dict[str, int]:
    """Checks every channel is json/jsonschema and every message fits; returns counts."""
    counts: dict[str, int] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        validators = {}
        for schema, channel, message in reader.iter_messages():
            assert channel.message_encoding == "json", channel.topic
            assert schema is not None and schema.encoding == "jsonschema", channel.topic
            if channel.id not in validators:
                validators[channel.id] = jsonschema.Draft202012Validator(json.loads(schema.data))
            validators[channel.id].validate(json.loads(message.data))
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


def test_a_msgpack_recording_exported_to_json_replays_the_same_wire_messages(stack, tmp_path):
    source, exported = tmp_path / "session.mcap", tmp_path / "foxglove.mcap"
    t0 = time.time()
    sent = []
    with Recorder(source) as rec:
        for i, suffix in enumerate(["hands/frame", "gaze", "scene/state", "intent",
                                    "episode/event", "plan/status", "hands/frame"] * 5):
            payload = wire.encode({**example(suffix, ts=t0 + i * 0.01), "n": i})
            rec.write(f"cbgo/{suffix}", payload, int((t0 + i * 0.01) * 1e9))
            sent.append((f"cbgo/{suffix}", payload))
        rec.write("cbgo/gaze", b"\xc1", int((t0 + 1) * 1e9))  # a bad record: reported, skipped
    done = subprocess.run([*CLI, "export", str(source), "-o", str(exported)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stderr  # complete, but one message was left out
    assert "left out 1 message on cbgo/gaze" in done.stdout
    counts = validate_json_recording(exported)
    assert counts[SCENE] > 0 and counts["foxglove/log"] > 0
    assert [(m.key, m.payload) for m in read_recording(exported)] == sent

    stack.start_router()
    stack.wait_alive(["router"])
    arrivals = []
    sub = stack.session().declare_subscriber(
        "cbgo/**", lambda s: arrivals.append((str(s.key_expr), s.payload.to_bytes())))
    try:
        replay = subprocess.run([*CLI, "replay", str(exported), "--derived", "--speed", "4",
                                 "--wait", "10", "--connect", stack.endpoint],
                                capture_output=True, text=True, timeout=60, env=stack.env())
        assert replay.returncode == 0, replay.stderr
        deadline = time.monotonic() + 5
        while len(arrivals) < len(sent) and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        sub.undeclare()
    unmarked = [(k, {f: v for f, v in wire.decode(p).items() if f != "replayed"})
                for k, p in arrivals]  # every replayed message says so
    assert unmarked == [(k, {**wire.decode(p), "source": "replay"} if k == "cbgo/hands/frame"
                         else wire.decode(p)) for k, p in sent]


@pytest.mark.timeout(240)
def test_acceptance_record_json_and_the_live_bridge_against_cbgo_up(stack, tmp_path):
    """The issue's check: `cbgo up --robot dry --foxglove` with a simulated user playing."""
    port = free_port()
    env = {"CBGO_WS_PORT": str(port), "CBGO_SCENARIO": "demo", "CBGO_LOOP": "true"}
    up = stack.spawn("up", [*CLI, "up", "--robot", "dry", "--foxglove", "--router-listen",
                            stack.endpoint], env={**env, "ZENOH_CONNECT": ""})
    up.wait_for_line("ready: ", timeout=180)
    path = tmp_path / "F.mcap"
    rec = subprocess.run([*CLI, "record", "--encoding", "json", "-o", str(path), "--duration",
                          "4", "--connect", stack.endpoint], capture_output=True, text=True,
                         timeout=60, env={**stack.env(), **{k: "" for k in env}})
    assert rec.returncode == 0, rec.stderr
    counts = validate_json_recording(path)
    assert counts.get(HANDS, 0) > 0 and counts.get(SCENE, 0) > 0, counts
    with open(path, "rb") as f:
        scenes = [json.loads(m.data) for _s, c, m in make_reader(f).iter_messages(
            topics=[SCENE])]
    assert sum(len(s["entities"]) for s in scenes) > 0
    _check_live(*asyncio.run(_watch_live(f"ws://127.0.0.1:{port}", timeout=60)))
    code, _ = stack.stop("up", signal.SIGINT, timeout=20)
    assert code == 0, up.log()


def test_record_encoding_json_writes_valid_messages_and_lists_what_it_left_out(stack, tmp_path):
    path = tmp_path / "live.mcap"
    stack.start_router()
    stack.wait_alive(["router"])
    rec = stack.spawn("record", [*CLI, "record", "--encoding", "json", "-o", str(path),
                                 "--count", "2", "--connect", stack.endpoint])
    rec.wait_for_line("recording ")
    # One session puts in order: the bad gaze reaches the recorder before the two that stop it.
    stack.put_raw("gaze", b"\xc1", timeout=10)
    stack.put("hands/frame", example("hands/frame", ts=time.time()), timeout=10)
    stack.put("scene/state", example("scene/state", ts=time.time()), timeout=10)
    assert rec.wait(20) == 0, rec.log()
    assert "left out 1 message on cbgo/gaze that break the contract" in rec.log()
    counts = validate_json_recording(path)
    assert counts[HANDS] == 1 and counts["cbgo/scene/state"] == 1 and counts[SCENE] == 2
