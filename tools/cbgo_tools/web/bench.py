"""Benchmark web under 120 Hz hands: its CPU share, and what the pages receive.

Starts a router, the leap-bridge (a simulated user looping a scenario, at ``--rate-hz``) and web
(any free port) as real processes, connects ``--pages`` WebSocket clients to web, and for
``--seconds`` measures web's CPU time (user + system, from ``/proc/<pid>/stat``) and the
messages each page gets per stream. Every frame web receives is decoded and validated as in
any service, turned into a base-frame skeleton when it is sent, and sent at most ``rate_hz``
times a second per stream (its setting); the figures say how much of one core that costs.

Linux only (``/proc``). Examples::

    cbgo bench web
    cbgo bench web --rate-hz 120 --seconds 30 --pages 3
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import tempfile
import time
from collections import Counter
from pathlib import Path

CLOCK_TICKS = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--rate-hz", type=float, default=120.0,
                        help="hand frames per second from the leap-bridge [120]")
    parser.add_argument("--seconds", type=float, default=20.0, help="measuring time [20]")
    parser.add_argument("--pages", type=int, default=1, help="WebSocket clients [1]")
    parser.add_argument("--scenario", default="demo", help="scenario the user loops [demo]")


def cpu_seconds(pid: int) -> float:
    """Returns a process's CPU time so far (user + system), s."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS  # utime, stime


async def _pages(url: str, pages: int, settle_s: float, seconds: float) -> list[Counter]:
    import aiohttp

    async def one() -> Counter:
        counts: Counter = Counter()
        async with aiohttp.ClientSession() as http, http.ws_connect(url) as ws:
            start = time.monotonic()
            async for message in ws:
                now = time.monotonic() - start
                if settle_s <= now:
                    counts[json.loads(message.data)["topic"]] += 1
                if now > settle_s + seconds:
                    break
        return counts

    return await asyncio.gather(*(one() for _ in range(pages)))


def measure(args: argparse.Namespace) -> dict:
    """Returns web's CPU share and the per-page rates over `args.seconds`."""
    from cbgo.testing import Stack

    with tempfile.TemporaryDirectory() as tmp, Stack(Path(tmp)) as stack:
        stack.start_router()
        stack.start_service("web")
        stack.start_service("leap-bridge", "--scenario", args.scenario, "--loop", "--rate-hz",
                            str(args.rate_hz))
        stack.wait_alive(["router", "web", "leap-bridge"], timeout=60)
        status = stack.status("web")
        url = status["url"].rstrip("/").replace("http://", "ws://") + "/ws"
        pid = status["pid"]
        frames = stack.collect("hands/frame")
        settle = 2.0
        cpu = {}

        async def run() -> list[Counter]:
            task = asyncio.ensure_future(_pages(url, args.pages, settle, args.seconds))
            await asyncio.sleep(settle)
            cpu["start"], cpu["t0"] = cpu_seconds(pid), time.monotonic()
            n0 = len(frames.items())
            await asyncio.sleep(args.seconds)
            cpu["end"], cpu["t1"] = cpu_seconds(pid), time.monotonic()
            cpu["frames"] = len(frames.items()) - n0
            return await task

        counts = asyncio.run(run())
        after = stack.status("web")
    wall = cpu["t1"] - cpu["t0"]
    return {"share": (cpu["end"] - cpu["start"]) / wall, "wall_s": wall,
            "frames_hz": cpu["frames"] / wall, "pages": counts, "seconds": args.seconds,
            "views": after["views"], "rejected": after["counters"]["rejected"]}


def run(args: argparse.Namespace) -> int:
    """Runs the benchmark and prints its figures."""
    result = measure(args)
    print(f"web under {result['frames_hz']:.1f} Hz hand frames (leap-bridge set to "
          f"{args.rate_hz:g} Hz, simulated user, scenario {args.scenario}), "
          f"{args.pages} page(s), {result['wall_s']:.1f} s:")
    print(f"  CPU share of web: {100 * result['share']:.1f} % of one core")
    for i, counts in enumerate(result["pages"], 1):
        rates = ", ".join(f"{topic} {n / result['seconds']:.1f}/s"
                          for topic, n in sorted(counts.items()))
        print(f"  page {i} received: {rates}")
    views = result["views"]
    print(f"  views passed {views['passed']}, downsampled away {views['downsampled']}, "
          f"dropped for slow pages {views['dropped']}; rejected inputs {result['rejected']}")
    return 0
