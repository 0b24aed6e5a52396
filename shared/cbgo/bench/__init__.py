"""Benchmarks behind `cbgo bench <name>`: each module has `add_arguments` and `run`.

Benchmarks print figures; they do not assert speed (tests assert behaviour).
"""

BENCHES = {
    "wire": "encode/decode/validate cost per message and latency through a real router",
    "hands": "realism of the simulated hand against real Leap recordings",
    "bridge": "leap-bridge frame stream: rate and jitter at 30/60/120 Hz",
}
