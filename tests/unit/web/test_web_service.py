"""web through FakeBus: the real runtime dispatch, the real HTTP server on a free port."""

import asyncio
import json
import socket

import pytest

from cbgo import keys
from cbgo.errors import ConfigError
from cbgo.examples import example
from cbgo.services.web.main import Web, WebSettings
from cbgo.testing import FakeBus


@pytest.fixture
def bus():
    bus = FakeBus(Web(WebSettings(http_port=0)))
    yield bus
    bus.stop()


def ws_url(bus) -> str:
    return bus.service.server.url.replace("http://", "ws://") + "ws"


async def talk(url: str, requests: list[dict], wanted: int) -> list[dict]:
    import aiohttp

    got = []
    async with aiohttp.ClientSession() as http, http.ws_connect(url) as ws:
        for request in requests:
            await ws.send_str(json.dumps(request))
        while len([m for m in got if m["topic"] == "@reply"]) < wanted:
            got.append(json.loads((await asyncio.wait_for(ws.receive(), 5)).data))
    return got


def test_a_new_page_gets_the_newest_scene_and_hands_in_the_base_frame(bus):
    bus.feed(keys.SCENE_STATE, example("scene/state"))
    bus.feed(keys.HANDS_FRAME, example("hands/frame"))
    got = asyncio.run(talk(ws_url(bus), [{"type": "nothing", "id": 1}], 1))
    topics = [m["topic"] for m in got]
    assert "scene/state" in topics and "@workspace" in topics
    hands = next(m for m in got if m["topic"] == "hands/frame")["msg"]["hands"]
    assert hands and "palm_position" not in hands[0] and len(hands[0]["palm"]) == 3


def test_stop_and_feedback_from_the_page_are_published_and_bad_requests_rejected(bus):
    summary = example("episode/summary")
    bus.feed(keys.EPISODE_SUMMARY, summary)
    requests = [{"type": "stop", "id": 1},
                {"type": "feedback", "id": 2, "action": "pick_up", "object": "cup1",
                 "episode": summary["episode"]},
                {"type": "feedback", "id": 3, "action": "teleport"}]
    replies = [m["msg"] for m in asyncio.run(talk(ws_url(bus), requests, 3))
               if m["topic"] == "@reply"]
    assert [(r["id"], r["ok"]) for r in replies] == [(1, True), (2, True), (3, False)]
    published = dict(bus.published)
    assert published["robot/stop"]["reason"] == "stop pressed on the web page"
    assert published["intent/feedback"]["user"] == summary["user"]
    assert bus.counters.rejected == 1
    ok, status = bus.query("status", None)
    assert ok and status["url"] == bus.service.server.url
    assert status["requests"] == {"stop": 1, "feedback": 1, "answer": 0, "mapping": 0,
                                  "rejected": 1}
    assert "teleport" in status["last_error"]["message"]


def test_a_port_in_use_fails_setup_with_the_fix():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(ConfigError, match="--http-port"):
            FakeBus(Web(WebSettings(http_port=port)))


@pytest.mark.parametrize("field, value", [("http_port", 70000), ("rate_hz", 0.5),
                                          ("http_host", ""), ("status_period_s", 0.1)])
def test_bad_settings_name_the_range(field, value):
    with pytest.raises(ConfigError, match=field):
        WebSettings(**{field: value})


def test_a_websocket_from_another_sites_page_is_refused(bus):
    import aiohttp

    async def connect(origin: str) -> int:
        async with aiohttp.ClientSession() as http:
            try:
                async with http.ws_connect(ws_url(bus), headers={"Origin": origin}):
                    return 101
            except aiohttp.WSServerHandshakeError as e:
                return e.status

    assert asyncio.run(connect("http://evil.example")) == 403
    own = bus.service.server.url.rstrip("/")
    assert asyncio.run(connect(own)) == 101


def test_stopping_with_a_page_connected_takes_well_under_two_seconds():
    import time

    import aiohttp

    bus = FakeBus(Web(WebSettings(http_port=0)))

    async def connected_then_stopped() -> float:
        async with aiohttp.ClientSession() as http, http.ws_connect(ws_url(bus)) as ws:
            await ws.receive()  # the first view: the page is connected
            t0 = time.monotonic()
            await asyncio.get_running_loop().run_in_executor(None, bus.stop)
            return time.monotonic() - t0

    assert asyncio.run(connected_then_stopped()) < 1.5


def test_a_robot_cells_status_gives_the_page_its_worlds_source_and_action_count():
    from cbgo.services.web.main import robot_cell_view

    status = {"name": "dry-robot", "scene_source": "seed 0",
              "actions": {"actions": 3, "ok": 2, "refused": 1, "stopped": 0}}
    assert robot_cell_view(status) == {"scene_source": "seed 0", "actions": 3}
    assert robot_cell_view({"name": "episode", "counters": {}}) == {}
    assert robot_cell_view({"scene_source": "scene", "actions": "bad"}) == {
        "scene_source": "scene", "actions": None}
