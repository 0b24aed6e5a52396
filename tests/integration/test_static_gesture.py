"""static-gesture through real processes: every static gesture from leap-bridge, and a gesture
taught by demonstration from the simulated user that the running service picks up (and one
that duplicates a known pose, refused)."""

import subprocess
import sys
import time
from collections import Counter, defaultdict

import numpy as np
import pytest

from cbgo.simuser.scenario import hold_scenario, load_scenario
from cbgo.simuser.user import SimulatedUser
from cbgo.wire import STATIC_GESTURES

CLI = [sys.executable, "-m", "cbgo.cli.main"]


def winner(message):
    return message["names"][int(np.argmax(message["probs"]))]


def test_every_static_gesture_streamed_by_leap_bridge_wins_the_frames_where_it_is_held(stack):
    rate, speed = 30.0, 3.0
    scenario = load_scenario("static-all")
    simulated = [f for f in SimulatedUser(scenario, rate).frames() if f.hands]
    label_of = {tuple(f.hands[0]["palm_position"]): f.label for f in simulated}
    last_palm = simulated[-1].hands[0]["palm_position"]
    stack.start_router()
    stack.wait_alive(["router"])
    frames, gestures = stack.collect("hands/frame"), stack.collect("gestures/static")
    stack.start_service("static-gesture")
    stack.wait_alive(["static-gesture"], timeout=60)
    stack.start_service("leap-bridge", "--scenario", "static-all", "--rate-hz", str(rate),
                        "--speed", str(speed), "--wait-for", "static-gesture")
    duration = SimulatedUser(scenario, rate).duration() / speed
    frames.wait(lambda m: m["hands"] and m["hands"][0]["palm_position"] == last_palm,
                timeout=duration + 60)
    time.sleep(1.0)  # the last gestures are on their way
    labels = {m["seq"]: label_of.get(tuple(m["hands"][0]["palm_position"]))
              for m in frames.items() if m["hands"]}
    by_hand = defaultdict(list)  # each episode's hand enters with a new id
    for m in gestures.items():
        by_hand[m["hand_id"]].append(m)
    assert len(by_hand) == len(STATIC_GESTURES), sorted(by_hand)
    for gesture, hand_id in zip(STATIC_GESTURES, sorted(by_hand), strict=True):
        episode = by_hand[hand_id]
        held = [winner(m) for m in episode if labels.get(m["seq"]) == gesture]
        assert len(held) >= 10, f"{gesture}: only {len(held)} held frames classified"
        assert held.count(gesture) > len(held) / 2, f"{gesture}: {Counter(held)}"
        # Over the whole episode, the held gesture is also what wins when anything does.
        poses = Counter(w for w in map(winner, episode) if w != "none")
        assert poses.most_common(1)[0][0] == gesture, f"{gesture}: {poses}"
        assert all(m["model"].startswith("static-bnn-") for m in episode)
    status = stack.status("static-gesture")
    assert status["counters"]["rejected"] == 0 and status["counters"]["errors"] == 0


HORNS = [1, 0, 1, 1, 0]  # finger curls thumb..pinky: index and little finger up


def record(stack, env, *argv):
    return subprocess.run([*CLI, "gestures", "record", *argv, "--static", "--timeout", "60"],
                          env=env, capture_output=True, text=True, timeout=400)


@pytest.mark.timeout(480)  # a hang guard for a loaded machine: retraining is most of it
def test_a_pose_taught_by_the_simulated_user_is_recognised_live_and_a_duplicate_refused(
        stack, tmp_path):
    data = tmp_path / "data"
    stack.start_router()
    # Polling off: the new model must arrive through the reload query of `cbgo gestures`.
    stack.start_service("static-gesture", "--watch-s", "0", env={"CBGO_DATA_DIR": str(data)})
    stack.start_service("leap-bridge")  # the simulated user, idle until asked to play
    stack.wait_alive(["router", "static-gesture", "leap-bridge"], timeout=60)
    before = stack.status("static-gesture")
    assert before["data_dir"] == str(data) and "horns" not in before["model"]["names"]
    # The CLI has no CBGO_DATA_DIR of its own: it finds the service's in its status.
    cli_env = {k: v for k, v in stack.env().items() if k != "CBGO_DATA_DIR"}
    cli_env["XDG_DATA_HOME"] = str(tmp_path / "elsewhere")

    # A "peace" shown as the two pose: reported with its share, nothing stored or swapped.
    peace = record(stack, cli_env, "peace", "--simulate", "two", "--frames", "30")
    assert peace.returncode == 1, peace.stdout + peace.stderr
    assert f"data directory: {data} (the running static-gesture's)" in peace.stdout
    assert "of the frames of 'peace' are already read as 'two'" in peace.stderr, peace.stderr
    assert not (data / "gestures" / "static" / "peace.npz").exists()
    assert stack.status("static-gesture")["model"]["model"] == before["model"]["model"]

    # Horns, a pose no model knows, given as finger curls: taught, reloaded, recognised.
    horns = record(stack, cli_env, "horns", "--simulate", ",".join(map(str, HORNS)),
                   "--takes", "3", "--frames", "30", "--epochs", "30", "--user", "tester")
    assert horns.returncode == 0, horns.stdout + horns.stderr
    assert "static-gesture now serves static-bnn-" in horns.stdout, horns.stdout
    status = stack.status("static-gesture")["model"]
    assert status["model"] != before["model"]["model"] and status["names"][-2:] == ["horns",
                                                                                     "none"]
    # The same simulated person shows horns three times more: renditions the model never saw.
    gestures = stack.collect("gestures/static")
    (ok, reply), = stack.query(f"{stack.prefix}/@ctl/leap-bridge/play",
                               hold_scenario("horns", HORNS, takes=3, hold_s=3.0, seed=0))
    assert ok, reply
    time.sleep(reply["duration_s"] + 1.0)
    by_take = defaultdict(Counter)  # each take's hand enters with a new id
    for m in gestures.items():
        if m["model"] == status["model"]:
            by_take[m["hand_id"]][winner(m)] += 1
    assert len(by_take) == 3, by_take
    recognised = [wins for wins in by_take.values() if wins["horns"] > 0.5 * wins.total()]
    assert len(recognised) >= 2, by_take  # the rest of a take: the hand coming and going
    for wins in by_take.values():  # no other gesture is read where horns is shown
        assert sum(n for g, n in wins.items() if g not in ("horns", "none")) < 0.05 * (
            wins.total()), by_take
    assert [p.name for p in (data / "gestures" / "static").glob("*.npz")] == ["horns.npz"]
    listing = subprocess.run([*CLI, "gestures", "list"], env={**cli_env,
                             "CBGO_DATA_DIR": str(data)}, capture_output=True, text=True,
                             timeout=60)
    assert "horns" in listing.stdout and "tester" in listing.stdout
