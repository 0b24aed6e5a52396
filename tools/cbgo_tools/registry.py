"""What `cbgo bench`, `cbgo train` and `cbgo data convert` can run: name -> (module, summary).

Each module has ``add_arguments(parser)`` and ``run(args) -> int`` and is imported only when it
runs (torch, MuJoCo). Benchmarks print figures; they do not assert speed (tests assert
behaviour). ``cbgo bench NAME --write FILE`` also writes what a benchmark printed as a results
document (`cbgo_tools.results`).
"""

from __future__ import annotations

BENCHES: dict[str, tuple[str, str]] = {
    "wire": ("cbgo_tools.bench.wire",
             "encode/decode/validate cost per message and latency through a real router"),
    "hands": ("cbgo_tools.bench.hands",
              "realism of the simulated hand against real Leap recordings"),
    "latency": ("cbgo_tools.bench.latency",
                "end to end: end condition -> intent -> robot action"),
    "replay": ("cbgo_tools.bench.replay", "how closely `cbgo replay` keeps a recording's rhythm"),
    "bridge": ("cbgo_tools.bench.bridge",
               "leap-bridge frame stream: rate and jitter at 30/60/120 Hz"),
    "static": ("cbgo_tools.static_gesture.bench", "static gestures: accuracy, ECE, latency"),
    "dynamic": ("cbgo_tools.dynamic_gesture.bench", "dynamic gestures: accuracy, ECE, latency"),
    "episode": ("cbgo_tools.episode.bench",
                "episode end condition -> summary latency through real processes"),
    "intent": ("cbgo_tools.intent.bench",
               "paper's M1-M5 vs ours on D1-D5, learning curve"),
    "intent-check": ("cbgo_tools.intent.evaluate",
                     "an intent model on fresh D4 draws, repairable intents and the demo's "
                     "decisions"),
    "intent-clarify": ("cbgo_tools.intent.clarify_bench",
                       "asking back vs refusing vs acting on the argmax on D4/D5: intended "
                       "actions, wrong actions, share asked"),
    "intent-mapping": ("cbgo_tools.intent.mapping_bench",
                       "a stated gesture mapping vs learning it from corrections, on D4 users "
                       "with swapped meanings"),
    "sim": ("cbgo_tools.mujoco_sim.bench", "mujoco-sim: success and speed of every action"),
    "web": ("cbgo_tools.web.bench", "web's CPU share under 120 Hz hands, page rates"),
    "camera": ("cbgo_tools.camera.bench",
               "camera-bridge: labelled images/videos through the live recognisers, latency, "
               "per-frame time, CPU at 30 fps"),
}

TRAINERS: dict[str, tuple[str, str]] = {
    # The static model is also retrained at run time, from a user's demonstrations, so its
    # trainer is the service's own module.
    "static": ("cbgo.services.static_gesture.train", "static-gesture Bayesian MLP"),
    "dynamic": ("cbgo_tools.dynamic_gesture.train", "dynamic-gesture templates + calibration"),
    "intent": ("cbgo_tools.intent.train", "intent model (order-invariant Bayesian) on D4"),
    "hands": ("cbgo_tools.hands.calibrate",
              "the simulated hand's poses, calibrated against the real Leap recordings"),
}

# Figures beside the services' own (`cbgo plot NAME`).
FIGURES: dict[str, tuple[str, str]] = {
    "foxglove-scene": ("cbgo_tools.docs.foxglove_figure",
                       "one moment of a JSON recording's foxglove/scene, drawn with matplotlib"),
}

# Which service each benchmark and trainer measures or trains (`cbgo up --list` shows them).
SERVICE_OF: dict[str, str] = {
    "bridge": "leap-bridge", "static": "static-gesture", "dynamic": "dynamic-gesture",
    "episode": "episode", "intent": "intent", "intent-check": "intent",
    "intent-clarify": "intent", "intent-mapping": "intent", "sim": "mujoco-sim",
    "web": "web", "camera": "camera-bridge",
}


def tools_of(service: str) -> list[str]:
    """Returns the ``cbgo train|bench NAME`` commands that belong to one service."""
    out = [f"cbgo train {name}" for name in TRAINERS if SERVICE_OF.get(name) == service]
    return out + [f"cbgo bench {name}" for name in BENCHES if SERVICE_OF.get(name) == service]
