"""Benchmarks behind `cbgo bench <name>`: each module has `add_arguments` and `run`.

Benchmarks print figures; they do not assert speed (tests assert behaviour). A benchmark of one
service lives in that service's package and is declared in its manifest (`cbgo.manifest`);
the CLI finds it there (imported only when run).
"""

from cbgo import registry

# name -> (module, one-line summary): the benchmarks of no single service, then every
# service's own (its manifest's ``benches``)
SHARED_BENCHES = {
    "wire": ("cbgo.bench.wire",
             "encode/decode/validate cost per message and latency through a real router"),
    "hands": ("cbgo.bench.hands", "realism of the simulated hand against real Leap recordings"),
    "latency": ("cbgo.bench.latency", "end to end: end condition -> intent -> robot action"),
    "replay": ("cbgo.bench.replay", "how closely `cbgo replay` keeps a recording's rhythm"),
}
BENCHES = {**SHARED_BENCHES, **registry.tools("benches")}
