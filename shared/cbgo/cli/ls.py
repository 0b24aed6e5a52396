"""List the live services: name, host, pid, uptime, and the keys each one uses.

Names come from the liveliness tokens (``<prefix>/@alive/*``), host/pid/uptime from each
service's status, and the keys from the router's admin space (``@/<router>/router/
{publisher,subscriber,queryable}/**``), matched to services by their Zenoh session id.

Examples::

    cbgo ls
    cbgo ls --json
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict

from cbgo import client
from cbgo.cli.common import add_network_arguments, session
from cbgo.cli.get import decode_reply
from cbgo.cli.status import format_uptime

ROLES = ("publisher", "subscriber", "queryable")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds ls's flags."""
    parser.add_argument("--timeout", type=float, default=2.0, help="seconds to wait [2]")
    parser.add_argument("--all-keys", action="store_true",
                        help="also list control keys (@ctl) and keys of non-cbgo sessions")
    parser.add_argument("--json", action="store_true", help="print one JSON object a service")
    add_network_arguments(parser)


def keys_by_session(sess, timeout: float) -> dict[str, dict[str, list[str]]]:
    """Returns {zenoh session id: {role: [keys]}} from the routers' admin space."""
    found: dict[str, dict[str, list[str]]] = defaultdict(lambda: defaultdict(list))
    for role in ROLES:
        for reply in client.replies(sess, f"@/*/router/{role}/**", timeout_s=timeout):
            if not reply.ok:
                continue
            key = reply.key.split(f"/router/{role}/", 1)[1]
            holders = decode_reply(reply.payload)
            if not isinstance(holders, dict):
                continue
            for zid in holders.get("clients", []) + holders.get("peers", []):
                if key not in found[zid][role]:
                    found[zid][role].append(key)
    return found


def collect(sess, keys, timeout: float, all_keys: bool) -> list[dict]:
    """Returns one record per live service: status fields plus the keys it declared."""
    alive = client.alive(sess, keys, timeout)
    statuses = client.status(sess, keys, "*", timeout)
    declared = keys_by_session(sess, timeout)
    records = []
    for name in sorted(alive | set(statuses)):
        status = statuses.get(name, {})
        mine = declared.get(status.get("zid", ""), {})
        roles = {role: sorted(k for k in mine.get(role, []) if all_keys or "/@" not in k)
                 for role in ROLES}
        if not any(roles.values()) and status:
            # A router's own declarations are not listed as client sessions: use its status.
            roles = {"publisher": status.get("outputs", []),
                     "subscriber": status.get("inputs", []),
                     "queryable": [k for k in status.get("queryables", [])
                                   if all_keys or "/@" not in k]}
        records.append({"name": name, "alive": name in alive, "host": status.get("host"),
                        "pid": status.get("pid"), "uptime_s": status.get("uptime_s"),
                        "zid": status.get("zid"), **roles})
    return records


def run(args: argparse.Namespace) -> int:
    """Prints the live services; returns 1 if there are none."""
    with session(args, "cbgo-ls") as (sess, keys):
        records = collect(sess, keys, args.timeout, args.all_keys)
    if not records:
        print(f"no live services under {keys.alive('*')}")
        return 1
    for r in records:
        if args.json:
            print(json.dumps(r))
            continue
        uptime = format_uptime(r["uptime_s"]) if r["uptime_s"] is not None else "?"
        state = "" if r["alive"] else "  (no liveliness token)"
        print(f"{r['name']:<16} host={r['host']}  pid={r['pid']}  up {uptime}{state}")
        for role, label in (("publisher", "publishes"), ("subscriber", "subscribes"),
                            ("queryable", "answers")):
            if r[role]:
                print(f"  {label:<11} {', '.join(r[role])}")
    return 0
