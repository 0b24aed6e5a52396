"""leap-bridge's pacing: a scheduled frame carries its deadline, so a stall leaves no gap."""

import time

import numpy as np

from cbgo import wire
from cbgo.services.leap_bridge.main import LeapBridge, LeapBridgeSettings
from cbgo.testing import FakeBus

RATE_HZ = 60.0


def frames_sent(bus):
    return [wire.decode(p) for k, p in list(bus.transport.sent) if k.endswith("/hands/frame")]


def wait_for_frames(bus, n, timeout=20.0):
    deadline = time.monotonic() + timeout  # a bound on waiting, not a measurement
    while len(frames_sent(bus)) < n:
        assert time.monotonic() < deadline, f"only {len(frames_sent(bus))} frames"
        time.sleep(0.02)
    return frames_sent(bus)


def test_a_stall_in_the_bridge_delays_frames_but_leaves_no_gap_in_their_stamps():
    service = LeapBridge(LeapBridgeSettings(rate_hz=RATE_HZ))
    publish, stalled = service._publish, []

    def stalling_publish(frame, now):
        if len(stalled) == 0 and service.seq == 20:  # once: the process is descheduled
            stalled.append(time.time())
            time.sleep(0.3)
        publish(frame, now)

    service._publish = stalling_publish
    bus = FakeBus(service)
    try:
        frames = wait_for_frames(bus, 60)
    finally:
        bus.stop()
    assert stalled, "the stall never happened"
    gaps = np.diff([f["ts"] for f in frames])
    assert gaps.max() < 1.5 / RATE_HZ, f"a gap of {gaps.max() * 1e3:.0f} ms in the stamps"
    assert np.all(gaps > 0), "stamps go back"
