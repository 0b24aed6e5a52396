"""The web page in a real browser: Chromium (Debian's) driven by Playwright, headless.

Against ``cbgo up --robot dry`` and ``cbgo demo --no-start --steps 1``:
the services panel lists the running services, the 3D canvas renders, the intent panel shows
the demo step's ``pick_up(cup1)``, STOP reaches ``cbgo/robot/stop`` and feedback reaches
``cbgo/intent/feedback``, a bad request is rejected and counted, the recording replays in the
same page (``cbgo web --replay``, or opened from the live page), and the page logs no error.
The first impression too: the robot panel shows the robot's own start state and where it comes
from, scene labels never overlap, numbers are rounded, a refused intent reads as refused with
its status and reason, the episode table and strip count the same episodes, and a service's
last error is shown in full.
Screenshots go to ``out/test-artifacts/web/`` (or ``$CBGO_TEST_ARTIFACTS/web``); look at them.

Without chromium the module is skipped, except in CI (``CI=true``), where that fails.
"""

import io
import re
import subprocess
import sys
import time
from pathlib import Path

import chromium
import pytest
from chromium import shot

from cbgo import registry
from cbgo.examples import example

CLI = [sys.executable, "-m", "cbgo.cli.main"]
playwright_api = chromium.require()
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
        stack.collectors = {k: stack.collect(k) for k in ("robot/stop", "intent/feedback",
                                                          "scene/state", "episode/summary")}
        yield stack, url, expected, work


@pytest.fixture(scope="module")
def browser():
    with chromium.launched() as browser:
        yield browser


@pytest.fixture(scope="module")
def page(system, browser):
    """The live page, with every console error and page error it logs collected."""
    _, url, _, _ = system
    page = chromium.open_page(browser, url, 1500, 1300)
    yield page
    page.close()


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


def label_boxes(page) -> list[dict]:
    """The scene labels on the page: text and box (CSS px) of each one shown."""
    return page.evaluate("""() => [...document.querySelectorAll('[data-testid=scene-labels] span')]
        .map((el) => { const r = el.getBoundingClientRect();
                       return {text: el.textContent, x: r.x, y: r.y, w: r.width, h: r.height}; })
        .filter((b) => b.w > 0 && b.h > 0)""")


def overlapping(boxes: list[dict]) -> list[tuple[str, str]]:
    return [(a["text"], b["text"]) for i, a in enumerate(boxes) for b in boxes[i + 1:]
            if a["x"] < b["x"] + b["w"] and b["x"] < a["x"] + a["w"]
            and a["y"] < b["y"] + b["h"] and b["y"] < a["y"] + a["h"]]


LONG_NUMBER = re.compile(r"\d\.\d{5,}")  # a float printed with all its digits


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


def test_before_anything_happened_the_robot_panel_shows_the_robots_own_start(page, system):
    stack, _, _, _ = system
    # What dry-robot itself reports: its start scene (the world model's scene of --seed, in
    # which it may hold an object and a drawer may be open), and no action since it started.
    holding = stack.collectors["scene/state"].wait()[-1]["robot"]["holding"]
    source = stack.status("dry-robot")["scene_source"]
    plan = page.locator("[data-testid=plan]")
    expect(plan).to_contain_text(f"holding {holding or 'nothing'}", timeout=20000)
    expect(plan.locator("[data-testid=world-source]")).to_contain_text(
        f"dry-robot's scene of {source} · no action since it started", timeout=20000)
    expect(page.locator("[data-testid=intent]")).to_contain_text("no intent yet")
    assert not page.errors, page.errors


def test_scene_labels_never_overlap(page):
    page.wait_for_function("document.querySelectorAll('[data-testid=scene-labels] span')"
                           ".length >= 5")
    boxes = label_boxes(page)
    assert {"robot base", "workspace grid"} <= {b["text"] for b in boxes}, boxes
    assert not overlapping(boxes), overlapping(boxes)
    page.mouse.move(400, 400)  # turned to another view, they are laid out again
    page.mouse.down()
    page.mouse.move(520, 430, steps=5)
    page.mouse.up()
    page.wait_for_timeout(300)
    assert not overlapping(label_boxes(page)), overlapping(label_boxes(page))
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
    assert not overlapping(label_boxes(page)), overlapping(label_boxes(page))
    assert not page.errors, page.errors


def test_numbers_are_rounded_and_the_episode_table_and_strip_agree(page):
    episodes = page.locator("[data-testid=episode-timeline]")
    expect(episodes.locator("td", has_text="distance").first).to_be_visible()
    text = page.locator("body").inner_text()
    assert not LONG_NUMBER.search(text), LONG_NUMBER.findall(text)
    rows = episodes.locator("tr[data-episode]").count()
    bars = int(episodes.locator("#chart-episodes").get_attribute("data-episodes"))
    assert rows == bars >= 1


def test_a_refused_intent_shows_as_refused_with_its_status_and_reason(page, system):
    stack, _, _, _ = system
    episode = stack.collectors["episode/summary"].last()["episode"]  # the demo step's
    reason = "no feasible intent in this scene: cup1 is out of reach"
    # As the intent service refuses: no action, no object. The planner acts on none of it.
    stack.put("intent", example("intent", episode=episode, status="infeasible", action=None,
                                object=None, confidence=0.0, p_action={}, p_object={},
                                reason=reason))
    intent = page.locator("[data-testid=intent]")
    expect(intent).to_contain_text("refused", timeout=20000)
    expect(intent).to_contain_text("infeasible")
    expect(intent).to_contain_text(reason)
    expect(intent).not_to_contain_text("()")
    row = page.locator(f"[data-testid=episode-timeline] tr[data-episode='{episode}']")
    expect(row).to_contain_text("refused")
    expect(row).to_contain_text("infeasible")
    expect(row).to_contain_text(reason)
    expect(row).not_to_contain_text("()")
    shot(page, "live-refused-intent")
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


def test_the_camera_preview_is_drawn_with_its_landmarks_beside_the_3d_hand(page, system):
    from PIL import Image

    stack, _, _, _ = system
    photo = next((Path(__file__).parents[1] / "fixtures" / "camera" / "thumbs_up_photos").iterdir())
    image = Image.open(photo).convert("RGB")
    image = image.resize((320, round(image.height * 320 / image.width)))
    jpeg = io.BytesIO()
    image.save(jpeg, "JPEG", quality=70)
    preview = example("camera/preview", ts=time.time(), width=image.width, height=image.height,
                      jpeg=jpeg.getvalue())
    stack.put("camera/preview", preview)
    shown(page, stack, page.locator("[data-testid=camera-view]"))
    expect(page.locator("#camera-caption")).to_contain_text("right hand")
    size = page.evaluate("[document.getElementById('camera').width, "
                         "document.getElementById('camera').height]")
    assert size == [image.width, image.height]
    # the landmarks are drawn over the photo in the right hand's colour (#f778ba)
    drawn = Image.open(io.BytesIO(page.locator("[data-testid=camera-image]").screenshot()))
    pink = [c for _, c in drawn.convert("RGB").getcolors(maxcolors=1 << 20)
            if abs(c[0] - 0xf7) < 12 and abs(c[1] - 0x78) < 12 and abs(c[2] - 0xba) < 12]
    assert pink, "no landmark drawn in the right hand's colour"
    shot(page, "live-camera-preview")
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
        # the page redraws on its own clock; on a loaded machine that can take seconds
        expect(panel).to_contain_text(f"episode {episode}", timeout=20_000)
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


def test_a_services_last_error_is_shown_in_full(page):
    # The bad request above is web's last error; the services poll brings it to the page.
    panel = page.locator("[data-testid=services]")
    error = panel.locator("tr[data-error-of=web]")
    expect(error).to_contain_text("got 'fly'", timeout=20000)
    # Measured in one go: the panel is redrawn at every status poll.
    row, inside = page.evaluate("""() => [document.querySelector(
            '[data-testid=services] tr[data-error-of=web]'),
            document.querySelector('[data-testid=services]')]
        .map((el) => { const r = el.getBoundingClientRect(); return [r.left, r.right]; })""")
    assert inside[0] <= row[0] and row[1] <= inside[1], (row, inside)
    assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
    assert page.evaluate("""() => { const b = document.getElementById('services-body');
                                    return b.scrollWidth <= b.clientWidth; }""")
    shot(page, "live-services-last-error")
    assert not page.errors, page.errors


def test_the_demo_recording_replays_in_the_same_panels(system, browser):
    stack, _, _, work = system
    recording = work / "demo" / "session.mcap"
    server = stack.spawn("web-replay", [*CLI, "web", "--replay", str(recording),
                                        "--http-port", "0"])
    url = server.wait_for_line("serving ", timeout=60).rsplit(" at ", 1)[1].strip()
    page = chromium.open_page(browser, url, 1500, 1300)
    errors = page.errors
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
    page = chromium.open_page(browser, url, 1500, 1300)
    errors = page.errors
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


def grab_without_a_look(episode: str, gesture: str = "grab", user: str = "ann") -> dict:
    return example("episode/summary", episode=episode, user=user, focus=None,
                   focus_source=None, params={},
                   gestures={"names": [gesture], "probs": [0.95]}, triggers=[])


def test_a_clarification_is_listed_and_confirmed_by_a_click_or_a_gesture_and_run(page, system):
    stack, _, _, _ = system
    asked, plans = stack.collect("intent/clarify"), stack.collect("plan/status")
    panel = page.locator("[data-testid=clarify]")
    # a grab without a look: the intent service asks back which object was meant
    stack.put("episode/summary", grab_without_a_look("ep-web-ask-1"))
    question = asked.first(lambda m: m["episode"] == "ep-web-ask-1", timeout=30)
    assert question["state"] == "open" and len(question["candidates"]) >= 2
    expect(panel).to_contain_text("which one did you mean", timeout=20000)
    first = question["candidates"][0]
    expect(panel.locator("[data-testid=clarify-candidate-0]")).to_contain_text(
        f"{first['action']}({first['object'] or ''})")
    shot(page, "live-clarification")
    chosen = question["candidates"][1]
    panel.locator("[data-testid=clarify-candidate-1]").click()
    expect(panel.locator("#clarify-result")).to_contain_text("sent to cbgo/intent/answer")
    run = plans.first(lambda m: m["intent"].get("clarification") == question["id"], timeout=30)
    assert (run["intent"]["action"], run["intent"]["object"]) == (chosen["action"],
                                                                  chosen["object"])
    expect(panel).to_contain_text("confirmed", timeout=20000)
    # the same question answered by a gesture: a thumbs-up confirms the highlighted candidate
    # (asked of another user: ann's confirmed answer taught her model what her grab means)
    stack.put("episode/summary", grab_without_a_look("ep-web-ask-2", user="bea"))
    second = asked.first(lambda m: m["episode"] == "ep-web-ask-2", timeout=30)
    expect(panel).to_contain_text("which one did you mean", timeout=20000)
    stack.put("episode/summary", grab_without_a_look("ep-web-answer", "thumbsup", "bea"))
    run = plans.first(lambda m: m["intent"].get("clarification") == second["id"], timeout=30)
    highlighted = second["candidates"][second["highlighted"]]
    assert (run["intent"]["action"], run["intent"]["object"]) == (highlighted["action"],
                                                                  highlighted["object"])
    assert not page.errors, page.errors


def mapping_of(stack, user: str) -> dict:
    (ok, reply), = stack.query("cbgo/@ctl/intent/mapping", {"user": user}, timeout=10)
    assert ok, reply
    return reply


def refitted(stack, user: str, timeout: float) -> dict:
    """Asks the intent service until the user's refit is in use; returns its mapping."""
    deadline = time.monotonic() + timeout
    while (reply := mapping_of(stack, user))["refitting"]:
        assert time.monotonic() < deadline, f"{user}'s refit still running after {timeout} s"
        time.sleep(0.5)
    return reply


def test_a_new_page_shows_the_current_users_mapping_without_asking(system, browser):
    stack, url, _, _ = system
    page = chromium.open_page(browser, url, 1500, 1300)
    try:
        panel = page.locator("[data-testid=mapping]")
        # leap-bridge names the current user every 2 s; nothing is clicked
        expect(panel.locator("[data-testid=mapping-user]")).not_to_have_value("", timeout=20000)
        user = panel.locator("[data-testid=mapping-user]").input_value()
        expect(panel.locator("[data-testid=mapping-table]")).to_be_visible(timeout=20000)
        expect(panel.locator("[data-testid=mapping-result]")).to_contain_text(
            f"intent/{user}/mapping.yaml")
    finally:
        page.close()


def test_the_mapping_table_shows_sets_and_unsets_a_users_rules(page, system):
    stack, _, _, work = system
    panel = page.locator("[data-testid=mapping]")
    panel.locator("[data-testid=mapping-user]").fill("cleo")
    panel.locator("[data-testid=mapping-show]").click()
    expect(panel.locator("[data-testid=mapping-table]")).to_contain_text("no rules",
                                                                         timeout=20000)
    panel.locator("[data-testid=mapping-gesture]").select_option("thumbsup")
    panel.locator("[data-testid=mapping-action]").select_option("pour")
    panel.locator("[data-testid=mapping-on]").select_option("cup")
    panel.locator("[data-testid=mapping-set]").click()
    expect(panel.locator("[data-testid=mapping-rule-0]")).to_contain_text("pour", timeout=20000)
    expect(panel.locator("[data-testid=mapping-result]")).to_contain_text("set: written to")
    path = work / "data" / "intent" / "cleo" / "mapping.yaml"
    assert "thumbsup" in path.read_text() and "pour" in path.read_text()
    # the intent service refits cleo's model on its worker thread, then serves it
    assert refitted(stack, "cleo", 240)["in_use"] == [{"gesture": "thumbsup", "action": "pour",
                                                       "on": "cup"}]
    panel.locator("[data-testid=mapping-show]").click()
    expect(panel.locator("[data-testid=mapping-state]")).to_contain_text("in use", timeout=20000)
    shot(page, "live-mapping")
    # a rule the intent service refuses: the reason is shown, the table stays as it was
    panel.locator("[data-testid=mapping-gesture]").select_option("grab")
    panel.locator("[data-testid=mapping-action]").select_option("open")
    panel.locator("[data-testid=mapping-on]").select_option("cup")
    panel.locator("[data-testid=mapping-set]").click()
    expect(panel.locator("[data-testid=mapping-result]")).to_contain_text(
        "open never applies to a cup", timeout=20000)
    expect(panel.locator("[data-testid=mapping-rule-0]")).to_contain_text("thumbsup")
    panel.locator("[data-testid=mapping-unset-0]").click()
    expect(panel.locator("[data-testid=mapping-table]")).to_contain_text("no rules",
                                                                         timeout=20000)
    assert "rules: []" in path.read_text()
    assert not page.errors, page.errors
