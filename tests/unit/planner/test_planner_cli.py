"""`cbgo plan show`: its parser and how a plan/status is drawn."""

from cbgo.cli import plan
from cbgo.cli.main import build_parser
from cbgo.examples import example


def test_plan_show_parses_its_flags():
    args = build_parser("plan").parse_args(["plan", "show", "--once", "--timeout", "3"])
    assert (args.what, args.once, args.timeout, args.no_tree) == ("show", True, 3.0, False)


def test_a_status_is_drawn_with_its_steps_error_and_tree():
    status = example("plan/status")
    status["sequence"] = [
        {"action": "place", "object": "cup1", "params": {}, "state": "done"},
        {"action": "pour", "object": "cup2", "params": {"angle_deg": 60.0}, "state": "failed"}]
    status["state"], status["error"] = "failure", "pour(cup2) failed 2 times: spilled"
    text = plan.render(status)
    assert text.splitlines()[0].startswith("plan pick_up(cup1): failure")
    assert "   1. done     place(cup1)" in text
    assert "   2. failed   pour(cup2) {'angle_deg': 60.0}" in text
    assert "error: pour(cup2) failed 2 times: spilled" in text
    assert status["tree"] in text and status["tree"] not in plan.render(status, tree=False)
