"""Trainers behind `cbgo train <name>`: each module has `add_arguments` and `run`.

A trainer of one service's model lives in that service's package; this table is how the CLI
finds it (imported only when run).
"""

# name -> (module, one-line summary)
TRAINERS: dict[str, tuple[str, str]] = {
    "static": ("cbgo.services.static_gesture.train", "static-gesture Bayesian MLP"),
    "intent": ("cbgo.services.intent.train", "intent model (order-invariant Bayesian) on D4"),
    "dynamic": ("cbgo.services.dynamic_gesture.train", "dynamic-gesture templates + calibration"),
}
