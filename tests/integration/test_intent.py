"""intent through real processes: infer queries and their error replies, summary -> intent,
`cbgo feedback` correcting the last intent, and bad answers to a question it asked back."""

import subprocess
import sys
import time

from cbgo import wire
from cbgo.examples import example

CLI = [sys.executable, "-m", "cbgo.cli.main"]


def start_intent(stack, tmp_path, **env):
    stack.start_router()
    stack.start_service("intent", env={"CBGO_DATA_DIR": str(tmp_path / "data"), **env})
    stack.wait_alive(["router", "intent"], timeout=60)


def test_infer_answers_valid_queries_and_gives_error_replies_to_bad_ones(stack, tmp_path):
    start_intent(stack, tmp_path)
    (ok, reply), = stack.query("cbgo/intent/infer", example("intent/infer", "query"))
    assert ok, reply
    wire.validate(reply, wire.INTENT, "cbgo/intent/infer")
    assert (reply["action"], reply["object"], reply["status"]) == ("pick_up", "cup1", "accepted")
    malformed = example("intent/infer", "query")
    del malformed["scene"]
    (ok, reason), = stack.query("cbgo/intent/infer", malformed)
    assert not ok and "scene: missing required field" in reason
    (ok, reason), = stack.query("cbgo/intent/infer", None)
    assert not ok and "rejected" in reason
    unknown = example("intent/infer", "query", gestures={"names": ["wave"], "probs": [1.0]})
    (ok, reason), = stack.query("cbgo/intent/infer", unknown)
    assert not ok and "none of the model's gestures" in reason
    status = stack.status("intent")
    assert status["counters"]["rejected"] == 2 and status["model"] == "intent-ours-1"


def test_by_default_the_service_accepts_put_into_a_closed_drawer(stack, tmp_path):
    from cbgo_tools.intent.evaluate import demo_scene

    start_intent(stack, tmp_path)
    scene = demo_scene()  # the robot holds full cup1; drawer1 is closed
    query = example("intent/infer", "query", gestures={"names": ["five"], "probs": [0.9]},
                    scene=scene.to_dict(), focus=list(scene.get("drawer1").position),
                    user="user1")
    (ok, reply), = stack.query("cbgo/intent/infer", query)
    assert ok, reply
    assert (reply["status"], reply["action"], reply["object"]) == ("accepted", "put_into",
                                                                   "drawer1")
    assert stack.status("intent")["config"]["settings"]["accept_repairable"] is True


def test_a_summary_becomes_an_intent_and_cbgo_feedback_corrects_it(stack, tmp_path):
    start_intent(stack, tmp_path, CBGO_ASK_BELOW="0")  # acts on p >= 0.5, asks nothing back
    intents = stack.collect("intent")
    stack.put("scene/state", example("scene/state"))
    summary = example("episode/summary", episode="ep-7", user="carol",
                      gestures={"names": ["swipe_left"], "probs": [0.95]})
    deadline = time.monotonic() + 10
    while stack.status("intent").get("has_scene") is not True:
        assert time.monotonic() < deadline, "the scene never arrived"
        time.sleep(0.05)
    stack.put("episode/summary", summary)
    (intent,) = intents.wait(lambda m: m["episode"] == "ep-7")
    assert (intent["action"], intent["status"]) == ("move_left", "accepted")
    done = subprocess.run([*CLI, "feedback", "--action", "move_right", "--connect",
                           stack.endpoint], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "correcting move_left(None) of carol, episode ep-7" in done.stdout
    folder = tmp_path / "data" / "intent" / "carol"
    deadline = time.monotonic() + 30
    while not (folder / "model.json").exists():
        assert time.monotonic() < deadline, stack.logs(["intent"])
        time.sleep(0.1)
    stack.put("episode/summary", {**summary, "episode": "ep-8"})
    (again,) = intents.wait(lambda m: m["episode"] == "ep-8", timeout=30)
    assert (again["action"], again["model"]) == ("move_right", "intent-ours-1+carol")


def wait_for_scene(stack):
    deadline = time.monotonic() + 10
    while stack.status("intent").get("has_scene") is not True:
        assert time.monotonic() < deadline, "the scene never arrived"
        time.sleep(0.05)


def test_bad_answers_are_rejected_and_counted_and_the_question_stays_answerable(stack,
                                                                                tmp_path):
    from cbgo_tools.intent.evaluate import two_cups_scene

    start_intent(stack, tmp_path)
    intents, asked = stack.collect("intent"), stack.collect("intent/clarify")
    stack.put("scene/state", {"v": 1, "ts": 1.0, "seq": 1, **two_cups_scene().to_dict()})
    wait_for_scene(stack)
    stack.put("episode/summary", example("episode/summary", episode="ep-ask", user="ann",
                                         focus=[0.44, 0.0, 0.05],
                                         gestures={"names": ["grab"], "probs": [0.9]}))
    (question,) = asked.wait(lambda m: m["episode"] == "ep-ask")
    answer = example("intent/answer", id=question["id"], user="ann", choice=None)
    del answer["choice"]
    bad = [{**answer, "answer": "maybe"}, {**answer, "choice": -1}, {**answer, "id": ""},
           {k: v for k, v in answer.items() if k != "user"},  # malformed: the runtime refuses
           {**answer, "id": "no-such-question"}, {**answer, "user": "bob"},
           {**answer, "choice": 7}]  # well-formed, but nothing to apply: the service refuses
    for message in bad:
        stack.put("intent/answer", message)
    stack.put("intent/answer", {**answer, "choice": 1})
    (confirmed,) = intents.wait(lambda m: m.get("clarification") == question["id"]
                                and m["status"] == "accepted", timeout=30)
    chosen = question["candidates"][1]
    assert (confirmed["action"], confirmed["object"]) == (chosen["action"], chosen["object"])
    assert stack.status("intent")["counters"]["rejected"] == len(bad)
