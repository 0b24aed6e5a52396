"""The web page in a real browser: Chromium (Debian's) driven by Playwright, headless.

Against ``cbgo up --robot dry`` and ``cbgo demo --no-start --steps 1`` (issue 19's check):
the services panel lists the running services, the 3D canvas renders, the intent panel shows
the demo step's ``pick_up(cup1)``, STOP reaches ``cbgo/robot/stop`` and feedback reaches
``cbgo/intent/feedback``, a bad request is rejected and counted, the recording replays in the
same page (``cbgo web --replay``, or opened from the live page), and the page logs no error.
Screenshots go to ``out/test-artifacts/web/`` (or ``$CBGO_TEST_ARTIFACTS/web``); look at them.

Without chromium the module is skipped, except in CI (``CI=true``), where that fails.
"""

import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from cbgo import registry
from cbgo.examples import example

REPO = Path(__file__).resolve().parents[2]
CHROMIUM = "/usr/bin/chromium"
CLI = [sys.executable, "-m", "cbgo.cli.main"]
ARTIFACTS = Path(os.environ.get("CBGO_TEST_ARTIFACTS", REPO / "out" / "test-artifacts")) / "web"

if not Path(CHROMIUM).exists() or shutil.which("chromium") is None:
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"CI must run the browser tests: {CHROMIUM} is missing "
                    "(apt-get install -y chromium; .ci/run does)", pytrace=False)
    pytest.skip(f"{CHROMIUM} is missing (apt-get install -y chromium)", allow_module_level=True)

playwright_api = pytest.importorskip("playwright.sync_api")
expect = playwright_api.expect

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def system(tmp_path_factory):
    """`cbgo up --robot dry` (web on a free port) and the page's URL."""
    from cbgo.testing import Stack

    work = tmp_path_factory.mktemp("web")
    with Stack(work) as stack:
        env = {"CBGO_DATA_DIR": str(work / "data")}  # feedback must not reach the user's models
        stack.spawn("up", [*CLI, "up", "--no-color", "--robot", "dry", "--router-listen",
                           stack.endpoint], env=env)
        expected = [s.name for s in registry.swap(registry.available(),
                                                  registry.by_name("dry-robot"))]
        stack.wait_alive(["router", *expected], timeout=120)
        url = stack.status("web")["url"]
        # Collect from the start, so the subscriptions have long reached the router when the
        # page publishes.
        stack.collectors = {k: stack.collect(k) for k in ("robot/stop", "intent/feedback")}
        yield stack, url, expected, work


@pytest.fixture(scope="module")
def browser():
    with playwright_api.sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=CHROMIUM, headless=True)
        yield chromium
        chromium.close()


@pytest.fixture(scope="module")
def page(system, browser):
    """The live page, with every console error and page error it logs collected."""
    _, url, _, _ = system
    page = browser.new_page(viewport={"width": 1500, "height": 1300})
    page.errors = []
    page.on("pageerror", lambda e: page.errors.append(f"page error: {e}"))
    page.on("console", lambda m: m.type == "error" and page.errors.append(f"console: {m.text}"))
    page.goto(url)
    yield page
    page.close()


def shot(page, name: str) -> Path:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    page.screenshot(path=str(path), full_page=True)
    return path


def shown(page, stack, locator, timeout: float = 30000) -> None:
    """Waits for a locator to be visible; if it never is, fails with what the page and the
    web service saw (the link, the views sent and dropped, the page's errors)."""
    try:
        expect(locator).to_be_visible(timeout=timeout)
    except AssertionError as e:
        link = page.locator("#link").text_content()
        views = stack.status("web")["views"]
        raise AssertionError(f"{e}\nlink: {link}; web views: {views}; page errors: "
                             f"{page.errors}") from None


def distinct_colours(png: bytes) -> int:
    from PIL import Image

    image = Image.open(io.BytesIO(png)).convert("RGB")
    return len(image.getcolors(maxcolors=image.width * image.height))


def test_the_services_panel_lists_every_running_service(page, system):
    _, _, expected, _ = system
    services = page.locator("[data-testid=services]")
    for name in ["router", *expected]:
        expect(services.locator(f"tr[data-service='{name}'] .dot.on")).to_be_visible(
            timeout=20000)
    expect(services).to_contain_text("intent")
    assert not page.errors, page.errors


def test_the_scene_canvas_renders_the_workspace(page):
    canvas = page.locator("[data-testid=scene-3d]")
    expect(canvas).to_be_visible()
    # A blank canvas is one colour; the table, grid, robot base and labels give hundreds.
    page.wait_for_function("document.querySelector('[data-testid=scene-3d]').width > 0")
    assert distinct_colours(canvas.screenshot()) > 50
    assert not page.errors, page.errors


def test_after_a_demo_step_the_intent_panel_shows_pick_up_cup1(page, system):
    stack, _, _, work = system
    out = work / "demo"
    done = subprocess.run([*CLI, "demo", "--no-start", "--robot", "dry", "--steps", "1",
                           "--connect", stack.endpoint, "-o", str(out)],
                          capture_output=True, text=True, timeout=240, env=stack.env())
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    intent = page.locator("[data-testid=intent]")
    expect(intent).to_contain_text("pick_up(cup1)", timeout=20000)
    expect(intent).to_contain_text("accepted")
    expect(page.locator("[data-testid=plan]")).to_contain_text("success", timeout=20000)
    expect(page.locator("[data-testid=episode-timeline] table")).to_contain_text("user1")
    expect(page.locator("[data-testid=scene-3d]")).to_be_visible()
    shot(page, "live-after-demo-step")
    assert not page.errors, page.errors


def test_stop_publishes_robot_stop(page, system):
    stack, _, _, _ = system
    stops = stack.collectors["robot/stop"]
    page.locator("[data-testid=stop]").click()
    message = stops.first(timeout=10)
    assert message["reason"] == "stop pressed on the web page" and message["v"] == 1
    expect(page.locator("#stop-result")).to_contain_text("STOP sent on cbgo/robot/stop")
    page.keyboard.press("Escape")
    stops.wait_count(2, timeout=10)
    assert not page.errors, page.errors


def test_feedback_publishes_intent_feedback_for_the_episodes_user(page, system):
    stack, _, _, _ = system
    feedback = stack.collectors["intent/feedback"]
    panel = page.locator("[data-testid=feedback]")
    panel.locator("#fb-action").select_option("pick_up")
    panel.locator("#fb-object").select_option("cup2")
    panel.locator("[data-testid=feedback-send]").click()
    message = feedback.first(timeout=10)
    assert (message["action"], message["object"], message["user"]) == ("pick_up", "cup2",
                                                                      "user1")
    expect(panel).to_contain_text("sent to cbgo/intent/feedback")
    assert not page.errors, page.errors


def low_confidence(episode: str) -> dict:
    return example("intent", episode=episode, status="low_confidence", confidence=0.3,
                   action="pick_up", object="cup2",
                   p_object={"cup2": 0.4, "cup1": 0.35, "box1": 0.25},
                   reason="p(object) is spread over three objects")


def test_a_low_confidence_intent_can_be_confirmed_or_rejected_from_the_page(page, system):
    stack, _, _, _ = system
    feedback = stack.collectors["intent/feedback"]
    panel = page.locator("[data-testid=feedback]")
    for episode in ("ep-web-confirm", "ep-web-reject"):
        # The planner ignores low_confidence intents: nothing moves.
        stack.put("intent", low_confidence(episode))
        expect(panel).to_contain_text(f"episode {episode}")
        expect(panel).to_contain_text("did you mean pick_up(cup2)")
    shot(page, "live-low-confidence")
    panel.locator("[data-testid=feedback-reject]").click()
    expect(panel).not_to_contain_text("did you mean")
    stack.put("intent", low_confidence("ep-web-confirm"))
    confirm = panel.locator("[data-testid=feedback-confirm]")
    shown(page, stack, confirm)
    confirm.click()
    # The page's answer first: if the server refused, its reason is in the failure message.
    expect(panel.locator("#fb-result")).to_contain_text("sent to cbgo/intent/feedback")
    confirmed = feedback.first(lambda m: m["episode"] == "ep-web-confirm", timeout=10)
    assert (confirmed["action"], confirmed["object"], confirmed["user"]) == (
        "pick_up", "cup2", "user1")  # the current user: no summary of this episode was seen
    assert not [m for m in feedback.items() if m["episode"] == "ep-web-reject"]
    assert not page.errors, page.errors


def test_a_bad_request_from_a_page_is_rejected_counted_and_answered(page, system):
    stack, _, _, _ = system
    before = stack.status("web")["counters"]["rejected"]
    answer = page.evaluate("""() => new Promise((resolve) => {
        const ws = new WebSocket(`ws://${location.host}/ws`);
        ws.onopen = () => ws.send(JSON.stringify({type: "feedback", action: "fly", id: 7}));
        ws.onmessage = (e) => { const m = JSON.parse(e.data);
            if (m.topic === "@reply") { ws.close(); resolve(m.msg); } };
    })""")
    assert answer["ok"] is False and answer["id"] == 7 and "action" in answer["error"]
    status = stack.status("web")
    assert status["counters"]["rejected"] == before + 1
    assert "fly" in status["last_error"]["message"]
    assert not page.errors, page.errors


def test_the_demo_recording_replays_in_the_same_panels(system, browser):
    stack, _, _, work = system
    recording = work / "demo" / "session.mcap"
    server = stack.spawn("web-replay", [*CLI, "web", "--replay", str(recording),
                                        "--http-port", "0"])
    url = server.wait_for_line("serving ", timeout=60).rsplit(" at ", 1)[1].strip()
    page = browser.new_page(viewport={"width": 1500, "height": 1300})
    errors = []
    page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
    page.on("console", lambda m: m.type == "error" and errors.append(f"console: {m.text}"))
    page.goto(url)
    expect(page.locator("[data-testid=replay]")).to_be_visible()
    expect(page.locator("[data-testid=intent]")).to_contain_text("pick_up(cup1)")
    page.locator("#scrub").fill("0")  # back to the start: no intent yet
    expect(page.locator("[data-testid=intent]")).not_to_contain_text("pick_up(cup1)")
    page.locator("#scrub").fill("1000")
    expect(page.locator("[data-testid=intent]")).to_contain_text("pick_up(cup1)")
    shot(page, "replay-end")
    page.close()
    stack.stop("web-replay")
    assert not errors, errors


def test_a_recording_opened_from_the_live_page_replays_in_it(system, browser):
    stack, url, _, work = system
    page = browser.new_page(viewport={"width": 1500, "height": 1300})
    errors = []
    page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
    page.on("console", lambda m: m.type == "error" and errors.append(f"console: {m.text}"))
    page.goto(url)
    expect(page.locator("#link")).to_contain_text("live")
    page.locator("[data-testid=open-recording]").set_input_files(
        str(work / "demo" / "session.mcap"))
    expect(page.locator("[data-testid=replay]")).to_be_visible(timeout=30000)
    expect(page.locator("#mode")).to_contain_text("replay · session.mcap")
    expect(page.locator("[data-testid=intent]")).to_contain_text("pick_up(cup1)")
    page.locator("#scrub").fill("0")
    expect(page.locator("[data-testid=intent]")).not_to_contain_text("pick_up(cup1)")
    page.close()
    assert not errors, errors
