"""leap-bridge through real processes: rate, validity, gaze resolution, play on demand."""

import sys
from pathlib import Path

import numpy as np
import pytest

from cbgo import wire
from cbgo.examples import example

CLI = [sys.executable, "-m", "cbgo.cli.main"]


@pytest.mark.parametrize("rate", [60, 120])
def test_cbgo_up_leap_bridge_streams_valid_frames_at_the_configured_rate(stack, rate):
    stack.spawn("up", [*CLI, "up", "leap-bridge", "--router-listen", stack.endpoint],
                env={"CBGO_SCENARIO": "demo", "CBGO_LOOP": "true", "CBGO_RATE_HZ": str(rate)})
    stack.wait_alive(["router", "leap-bridge"])
    frames = stack.collect("hands/frame")
    frames.wait(lambda m: m["hands"])
    got = frames.window(4.0)
    stamps = np.array([t for t, _ in got])
    measured = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    assert abs(measured - rate) / rate < 0.05, f"{measured:.2f} Hz for {rate} Hz"
    for _, message in got:
        wire.validate(message, wire.HANDS_FRAME, "cbgo/hands/frame")
    seqs = [m["seq"] for _, m in got]
    assert all(b > a for a, b in zip(seqs, seqs[1:], strict=False)), "out of order or repeated"
    # hands/frame is a DROP key (docs/protocol.md: under congestion the newest frame wins), so
    # on a loaded machine the transport may lose a frame on its way here; the bridge numbers
    # every frame it publishes, so the gaps are the frames lost, and they must stay rare.
    lost = seqs[-1] - seqs[0] + 1 - len(seqs)
    assert lost <= 0.01 * len(seqs), f"{lost} of {len(seqs) + lost} frames lost"
    assert all(m["source"] == "simulated" and len(m["to_base"]) == 16 for _, m in got)
    assert any(m["hands"] for _, m in got)


def test_gaze_follows_an_object_named_in_the_scene(stack):
    stack.start_router()
    stack.start_service("leap-bridge", "--scenario", "demo", "--loop")
    stack.wait_alive(["router", "leap-bridge"])
    gaze = stack.collect("gaze")
    scene = example("scene/state")
    stack.put("scene/state", scene)
    cup = np.array(next(o["position"] for o in scene["objects"] if o["name"] == "cup1"))
    found = gaze.first(lambda m: np.linalg.norm(np.array(m["point"]) - cup) < 0.06)
    assert found["source"] == "simulated"
    assert stack.collect("user").first()["user"] == "user1"


def test_the_simulated_user_idles_until_asked_to_play_a_scenario(stack):
    stack.start_router()
    stack.start_service("leap-bridge")
    stack.wait_alive(["router", "leap-bridge"])
    frames = stack.collect("hands/frame")
    idle = frames.window(1.0)
    assert idle and not any(m["hands"] for _, m in idle)
    (ok, reply), = stack.query("cbgo/@ctl/leap-bridge/play",
                               {"episodes": [{"gestures": ["grab"], "pause_s": 0.2}]})
    assert ok and reply["episodes"] == 1 and 2.0 < reply["duration_s"] < 6.0
    frames.wait(lambda m: m["hands"] and m["hands"][0]["grab_strength"] > 0.6)
    (ok, reason), = stack.query("cbgo/@ctl/leap-bridge/play", {"episodes": [{"gestures":
                                                                              ["wave"]}]})
    assert not ok and "unknown gesture 'wave'" in reason


def test_a_replay_without_a_file_is_a_configuration_error(stack):
    proc = stack.start_service("leap-bridge", "--source", "replay")
    assert proc.wait(20) == 2
    assert "--source replay needs a recording" in proc.log()


def test_a_missing_leap_driver_is_reported_with_what_to_install(stack):
    stack.start_router()
    proc = stack.start_service("leap-bridge", "--source", "leap")
    assert proc.wait(20) == 2
    assert "Ultraleap Python bindings are not installed" in proc.log()


TOOLBOX_JSON = Path(__file__).parents[1] / "artifacts" / "toolbox" / "two_hands.json"


def test_a_toolbox_json_recording_is_replayed_as_contract_frames(stack):
    stack.start_router()
    stack.wait_alive(["router"])
    frames = stack.collect("hands/frame")
    stack.start_service("leap-bridge", "--source", "replay", str(TOOLBOX_JSON),
                        "--loop")
    stack.wait_alive(["leap-bridge"])
    message = frames.first(lambda m: len(m["hands"]) == 2)
    wire.validate(message, wire.HANDS_FRAME)
    assert message["source"] == "replay" and message["device"] == "two_hands.json"
    assert {h["side"] for h in message["hands"]} == {"left", "right"}


def test_an_mcap_recording_is_replayed_with_its_hands_order_and_pace(stack, tmp_path):
    from cbgo.recording import Recorder
    from cbgo.simuser.scenario import load_scenario
    from cbgo.simuser.user import SimulatedUser

    path = tmp_path / "static.mcap"
    recorded = [f for f in SimulatedUser(load_scenario("static-all"), 60.0).frames()][:240]
    with Recorder(path) as recorder:
        for i, frame in enumerate(recorded):
            message = {"v": 1, "ts": 1000.0 + frame.t, "seq": i, "source": "simulated",
                       "device": "sim", "hands": frame.hands}
            recorder.write("cbgo/hands/frame", wire.encode(message), int((1000 + frame.t) * 1e9))
    stack.start_router()
    stack.wait_alive(["router"])
    frames = stack.collect("hands/frame")
    stack.start_service("leap-bridge", "--source", "replay", str(path))
    first = next(i for i, f in enumerate(recorded) if f.hands)
    # Frames are published in order, numbered from 0, so a frame's number names the recorded
    # frame it carries; the whole recording has been published once a frame numbered past its
    # end arrives (idle frames follow it).
    frames.wait(lambda m: m["seq"] >= len(recorded))
    items = [(t, m) for t, m in frames.arrivals() if first <= m["seq"] < len(recorded)]
    replayed = [(t, m, recorded[m["seq"]]) for t, m in items]
    assert all(m["hands"] == [] if not f.hands else
               m["hands"][0]["palm_position"] == f.hands[0]["palm_position"]
               for _, m, f in replayed)
    assert [m["seq"] for _, m, _ in replayed] == sorted(m["seq"] for _, m, _ in replayed)
    # Hand frames are dropped under congestion by contract (docs/protocol.md, "Delivery
    # policy"), so a loaded machine may lose a few; losing many would be a fault.
    assert len(replayed) >= 0.9 * (len(recorded) - first)
    # The pace is the service's schedule: each frame is stamped when it was due (its capture
    # time), so the stamps follow the recording exactly whatever the machine's load.
    offsets = np.array([m["ts"] - f.t for _, m, f in replayed])
    assert np.ptp(offsets) < 0.005
    # and it is a schedule kept, not stamps written on a burst: a frame never arrives before
    # it is due, so the arrivals span at least the schedule less the first frame's lateness
    stamps = np.array([m["ts"] for _, m, _ in replayed])
    arrivals = np.array([t for t, _, _ in replayed])
    assert arrivals[-1] - arrivals[0] >= 0.9 * (stamps[-1] - stamps[0])
    assert all(m["source"] == "replay" for _, m in items)
