"""The web server's hub: what a page is sent first, and what happens to a page that lags."""

import asyncio

from cbgo.services.web.server import CLIENT_QUEUE, HISTORY, Hub


def drain(queue: asyncio.Queue) -> list[str]:
    out = []
    while not queue.empty():
        out.append(queue.get_nowait())
    return out


def test_a_page_opened_late_gets_its_whole_snapshot_intents_included():
    hub = Hub()
    for k in range(HISTORY["gestures/static"]):  # a long session's gesture history first
        hub.publish("gestures/static", f"static {k}")
    for k in range(HISTORY["@evidence"]):
        hub.publish("@evidence", f"evidence {k}")
    hub.publish("intent", "the newest intent")
    assert len(hub.snapshot()) > CLIENT_QUEUE  # what a bare 512-view queue would cut
    queue = hub.join(on_behind=lambda: None)
    sent = drain(queue)
    assert sent == hub.snapshot() and sent[-1] == "the newest intent"
    assert hub.dropped == 0 and hub.resets == 0


def test_a_page_that_falls_behind_is_reset_once_and_no_longer_fed():
    hub = Hub()
    resets = []
    lagging = hub.join(on_behind=lambda: resets.append("lagging"))
    keeping_up = hub.join(on_behind=lambda: resets.append("keeping up"))
    for k in range(CLIENT_QUEUE):
        hub.publish("hands/frame", f"frame {k}")
        drain(keeping_up)
    assert not resets
    hub.publish("intent", "an intent the lagging page has no room for")
    hub.publish("intent", "another")
    assert resets == ["lagging"]  # once: it is closed, to reconnect to a fresh snapshot
    assert lagging not in hub.pages and keeping_up in hub.pages
    assert hub.resets == 1 and hub.dropped == 1
    assert drain(keeping_up) == ["an intent the lagging page has no room for", "another"]
    # Its reconnection starts from the newest state.
    assert drain(hub.join(on_behind=lambda: None))[-1] == "another"


def test_a_page_that_leaves_is_forgotten():
    hub = Hub()
    queue = hub.join(on_behind=lambda: None)
    hub.leave(queue)
    hub.publish("intent", "after it left")
    assert queue.empty() and not hub.pages
