"""A minimal service for testing the runtime through real processes (never imported by cbgo).

It subscribes to `cbgo/user` and republishes each user as a `cbgo/gaze`-free echo on
`cbgo/episode/event` (kind "start", episode = the user name), answers `cbgo/intent/infer` with
a fixed-shape reply built from the query, and has a `slow` setting that makes its handler sleep,
to test that SIGTERM still ends the process within 2 s.
"""

import sys
import time
from dataclasses import dataclass, field

from cbgo import keys
from cbgo.errors import QueryError
from cbgo.runtime import Service, run


@dataclass
class ProbeSettings:
    slow_s: float = field(default=0.0, metadata={"help": "sleep this long in each handler"})


class Probe(Service):
    name = "probe"
    description = "Test service for the runtime."
    settings_class = ProbeSettings

    def setup(self, ctx):
        self.ctx = ctx
        ctx.subscribe(keys.USER, self.on_user)
        ctx.queryable(keys.INTENT_INFER, self.on_infer)
        ctx.publishes(keys.EPISODE_EVENT)

    def on_user(self, msg):
        time.sleep(self.settings.slow_s)
        return [(keys.EPISODE_EVENT, {"v": 1, "ts": time.time(), "episode": msg["user"],
                                      "kind": "start"})]

    def on_infer(self, query):
        if query["user"] == "nobody":
            raise QueryError("unknown user 'nobody'")
        best = max(zip(query["gestures"]["probs"], query["gestures"]["names"], strict=True))[1]
        return {"v": 1, "ts": time.time(), "episode": None, "action": None, "object": None,
                "params": {}, "p_action": {}, "p_object": {}, "confidence": 0.0,
                "status": "low_confidence", "reason": f"probe saw {best}", "model": "probe"}


if __name__ == "__main__":
    sys.exit(run(Probe, sys.argv[1:]))
