"""Benchmarks behind `cbgo bench <name>`: each module has `add_arguments` and `run`.

Benchmarks print figures; they do not assert speed (tests assert behaviour). A benchmark of one
service lives in that service's package; this table is how the CLI finds it (imported only
when run).
"""

# name -> (module, one-line summary)
BENCHES = {
    "wire": ("cbgo.bench.wire",
             "encode/decode/validate cost per message and latency through a real router"),
    "hands": ("cbgo.bench.hands", "realism of the simulated hand against real Leap recordings"),
    "bridge": ("cbgo.bench.bridge", "leap-bridge frame stream: rate and jitter at 30/60/120 Hz"),
    "episode": ("cbgo.services.episode.bench",
                "episode end condition -> summary latency through real processes"),
}
