"""Benchmarks behind `cbgo bench <name>`: each module has `add_arguments` and `run`.

Benchmarks print figures; they do not assert speed (tests assert behaviour). A benchmark of one
service lives in that service's package; this table is how the CLI finds it (imported only
when run).
"""

# name -> (module, one-line summary)
BENCHES = {
    "static": ("cbgo.services.static_gesture.bench", "static gestures: accuracy, ECE, latency"),
    "intent": ("cbgo.services.intent.bench", "paper's M1-M5 vs ours on D1-D5, learning curve"),
    "dynamic": ("cbgo.services.dynamic_gesture.bench", "dynamic gestures: accuracy, ECE, latency"),
    "wire": ("cbgo.bench.wire",
             "encode/decode/validate cost per message and latency through a real router"),
    "hands": ("cbgo.bench.hands", "realism of the simulated hand against real Leap recordings"),
    "bridge": ("cbgo.bench.bridge", "leap-bridge frame stream: rate and jitter at 30/60/120 Hz"),
    "sim": ("cbgo.services.mujoco_sim.bench", "mujoco-sim: success and speed of every action"),
    "episode": ("cbgo.services.episode.bench",
                "episode end condition -> summary latency through real processes"),
    "latency": ("cbgo.bench.latency", "end to end: end condition -> intent -> robot action"),
    "web": ("cbgo.services.web.bench", "web's CPU share under 120 Hz hands, page rates"),
}
