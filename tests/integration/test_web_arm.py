"""The web page draws the arm itself, posed by robot/state's joints (Chromium, headless).

Against the router, web and a robot: mujoco-sim (measured joints: the arm the page computes
from them ends at the TCP mujoco-sim reports, and moves when the arm moves) and dry-robot (no
kinematics: the ready posture, drawn faded and labelled nominal). The page's scene says what it
drew on the canvas's ``data-arm`` (pose, the TCP it computed, the number of links).
Screenshots go to ``out/test-artifacts/web/`` (or ``$CBGO_TEST_ARTIFACTS/web``).

Without chromium the module is skipped, except in CI (``CI=true``), where that fails.
"""

import json

import chromium
import pytest
from chromium import shot

from cbgo import keys, registry
from cbgo.foxglove.arm import link_points
from cbgo.testing import Stack

playwright_api = chromium.require()

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def browser():
    with chromium.launched() as browser:
        yield browser


def open_page(browser, stack: Stack, robot: str):
    """Starts the router, `robot` and web; returns the live page (its errors collected)."""
    stack.start_router()
    stack.start_service(robot)
    stack.start_service("web")
    stack.wait_alive(["router", robot, "web"], timeout=120)
    return chromium.open_page(browser, stack.status("web")["url"], 1400, 1100)


def drawn_arm(page, after: dict | None = None) -> dict:
    """The arm the page's scene drew last (waits for one, or for one other than `after`)."""
    old = json.dumps(after) if after else ""
    page.wait_for_function(
        "(old) => { const a = document.querySelector('[data-testid=scene-3d]').dataset.arm;"
        " return a && (!old || JSON.stringify(JSON.parse(a)) !== old); }", arg=old,
        timeout=30000)
    return json.loads(page.locator("[data-testid=scene-3d]").get_attribute("data-arm"))


@pytest.mark.skipif(not registry.by_name("mujoco-sim").exists(),
                    reason="mujoco-sim is not installed")
def test_the_page_draws_mujoco_sims_arm_from_its_joints_ending_at_its_tcp(browser, tmp_path):
    with Stack(tmp_path) as stack:
        page = open_page(browser, stack, "mujoco-sim")  # the router first: then a session
        states = stack.collect("robot/state")
        arm = drawn_arm(page)
        state = states.first(lambda m: True, timeout=10)
        assert arm["pose"] == "measured" and arm["links"] == 9, arm
        assert arm["tcp"] == pytest.approx(link_points(state["joints"])[-1], abs=1e-3)
        assert arm["tcp"] == pytest.approx(state["tcp"], abs=0.005)  # the page's kinematics
        (ok, reply), = stack.query(stack.keys.of(keys.ROBOT_ACT), {
            "v": 1, "action": "move_down", "object": None, "params": {}}, timeout=120)
        assert ok and reply["ok"], reply
        done = states.last()["seq"]
        rest = states.first(lambda m: m["seq"] > done, timeout=10)  # published after the act
        page.wait_for_function(  # the page has caught up with the arm at rest
            "(z) => Math.abs(JSON.parse(document.querySelector('[data-testid=scene-3d]')"
            ".dataset.arm).tcp[2] - z) < 0.005", arg=rest["tcp"][2], timeout=30000)
        moved = drawn_arm(page)
        assert moved["tcp"][2] == pytest.approx(arm["tcp"][2] - 0.10, abs=0.01), (arm, moved)
        shot(page, "arm-mujoco-sim")
        assert not page.errors, page.errors
        page.close()


def test_a_robot_without_kinematics_is_drawn_in_the_nominal_pose_and_says_so(browser, tmp_path):
    with Stack(tmp_path) as stack:
        page = open_page(browser, stack, "dry-robot")
        arm = drawn_arm(page)
        assert arm["pose"] == "nominal", arm
        ready = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)  # what dry-robot publishes
        assert arm["tcp"] == pytest.approx(link_points(ready)[-1], abs=1e-3)
        labels = page.locator("[data-testid=scene-labels]")
        playwright_api.expect(labels).to_contain_text("arm: nominal pose (no kinematics)")
        shot(page, "arm-dry-robot")
        assert not page.errors, page.errors
        page.close()
