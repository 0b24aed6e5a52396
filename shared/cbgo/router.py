"""The Zenoh router every cbgo service connects to, as a Python process (no external binary).

It runs Zenoh in ``mode: router``, listens on ``tcp/127.0.0.1:7447`` by default (loopback: only
processes on this host can join) and enables the admin space (``@/<zid>/router/**``), which
`cbgo ls` and `zenoh network` read. It is also a cbgo service like the others: it declares
``<prefix>/@alive/router`` and answers ``<prefix>/@ctl/router/status``, so the supervisor and
`cbgo ls` treat it the same way.

Run it with ``cbgo router`` (or ``python -m cbgo.router``). ``--listen`` sets where it listens:
``--listen tcp/0.0.0.0:7447`` lets services on other hosts join (deploy/README.md, "Several
machines"); listening beyond loopback without TLS is logged as a warning that names the secured
deployment (`cbgo certs`, deploy/compose.tls.yaml). A port already in use ends it at once with
exit code 2 and a message naming the port and ``--listen``. ``--connect`` joins other routers.
"""

from __future__ import annotations

from cbgo.config import DEFAULT_ROUTER_LISTEN
from cbgo.runtime import Service, main_for


class Router(Service):
    """The Zenoh router of a cbgo network."""

    name = "router"
    description = ("The Zenoh router of a cbgo network: services connect to it by endpoint; "
                   "its admin space is on. It listens on loopback unless --listen says "
                   "otherwise (e.g. --listen tcp/0.0.0.0:7447 for other hosts).")
    zenoh_defaults = {"mode": "router", "connect": [], "listen": [DEFAULT_ROUTER_LISTEN]}


main = main_for(Router)

if __name__ == "__main__":
    main()
