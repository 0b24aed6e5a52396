"""New static gestures by demonstration: capture poses from the live stream, check, retrain, reload.

``cbgo gestures record NAME --static`` runs `run`:

1. Capture: subscribes ``cbgo/hands/frame`` from any source (a Leap, a replay, the simulated
   user) and, per take, waits for a hand, lets it settle for ``--settle`` seconds (the frames
   where the hand is still forming the pose are not the gesture), then takes the features of
   the first hand of ``--frames`` frames (default 60, about half a second at 120 Hz). Between
   takes (``--takes``) the hand must leave the sensor's view, so each take is a fresh
   rendition. A hand lost mid-take pauses the take; it settles again when it is back.
   ``--simulate POSE`` first asks leap-bridge's simulated user (``@ctl/leap-bridge/play``) to
   show POSE once per take: a gesture of the vocabulary, or any pose as five finger curls
   (`simulate_pose`), so a new gesture is taught and tried without a sensor.
2. Check: the model served now reads the takes (`reading`). When `CLASH_SHARE` or more of
   their frames are answered as one other gesture (a "peace" shown as the ``two`` pose), the
   new name would lose to it: the share is reported and nothing is stored or retrained unless
   ``--force`` is given.
3. Store: the rows (the 57 features, right hands mirrored into the recordings' space, as the
   service computes them) go to ``data_dir()/gestures/static/NAME.npz`` with who recorded each
   take, when, from which device (``--user``, else the operator last seen on ``cbgo/user``).
   Recording a name again adds takes (``--replace`` starts over); a name of a known gesture
   adds examples of it, a new name becomes a new class.
4. Retrain: the real recordings + simulated hands + every recorded gesture
   (``cbgo.services.static_gesture.train``), written atomically as the user's model
   ``data_dir()/models/static-gesture.{pt,json}`` (``--epochs`` trades quality for time).
5. Reload: queries ``cbgo/@ctl/static-gesture/reload``; a running service answers with the new
   model id. None running is fine: the service loads the user's model when it starts, and a
   running one polls the file anyway. The service must see the same data directory (same
   machine or a shared volume) — the query says "reload", it does not carry the model; an
   answer with another model than the one written says so. ``cbgo gestures`` finds the running
   service's directory in its status before recording.

Only `run` touches the network (through ``cbgo.client.session``); `Capture` is plain logic.

Examples::

    cbgo gestures record horns --static --simulate 1,0,1,1,0 --takes 3   # no sensor needed
    cbgo gestures record horns --static                 # one take of 60 frames, retrain
    cbgo gestures record ok --static --takes 3 --frames 40 --user alice
    cbgo gestures list
"""

from __future__ import annotations

import argparse
import queue
import re
import sys
import time

import numpy as np

from cbgo import keys, wire
from cbgo.errors import ConfigError, QueryError, RejectedMessage
from cbgo.hands.features import hand_features
from cbgo.hands.poses import check_curls
from cbgo.services.static_gesture import train
from cbgo.services.static_gesture.classifier import (
    NONE,
    StaticClassifier,
    default_model_path,
    personal_model_path,
    user_model_path,
)
from cbgo.simuser.scenario import hold_scenario
from cbgo.wire import STATIC_GESTURES

DEFAULT_FRAMES = 60
DEFAULT_SETTLE_S = 0.5
# The simulated hand forms its pose as it comes into view (about 0.8 s at the default speed):
# a take of it starts later, on the formed pose.
SIMULATED_SETTLE_S = 1.0
SLOWEST_RATE_HZ = 30.0  # leap-bridge's lowest --rate-hz: a simulated hold lasts long enough
NAME_PATTERN = re.compile(r"^[a-z][a-z0-9_]{0,31}$")
RELOAD_TIMEOUT_S = 5.0
PLAY_TIMEOUT_S = 5.0
# A new gesture duplicates another when the model served now answers at least this share of
# its takes' frames as that other gesture: trained beside it, the new name loses to it live (a
# "peace" shown as the two pose; `cbgo gestures record peace --static --simulate two` prints
# the share the served model reads as two).
CLASH_SHARE = 0.5


def check_name(name: str) -> str:
    """Returns a valid gesture name or raises ValueError saying what a name may be."""
    if not NAME_PATTERN.match(name or ""):
        raise ValueError(f"gesture name {name!r}: use 1-32 lower-case letters, digits and '_', "
                         "starting with a letter (e.g. horns, ok_sign)")
    if name == NONE:
        raise ValueError(f"{NONE!r} is the no-gesture class; pick another name")
    return name


class Capture:
    """Collects ``takes`` × ``frames`` feature rows of the first hand from frame messages.

    Args:
        frames: rows per take.
        takes: how many takes.
        settle_s: seconds (frame time stamps) a hand must have been in view before its frames
            count, at the start of a take and after the hand was lost.
    """

    def __init__(self, frames: int, takes: int = 1, settle_s: float = 0.0):
        if frames < 1 or takes < 1 or settle_s < 0:
            raise ValueError("frames and takes must be at least 1, settle_s not negative")
        self.frames, self.takes, self.settle_s = frames, takes, settle_s
        self.rows: list[np.ndarray] = []
        self.take = 1
        self.device = ""
        self._since: float | None = None  # when the hand (re)appeared
        self._need_gap = False

    @property
    def done(self) -> bool:
        """Whether every take is complete."""
        return len(self.rows) >= self.frames * self.takes

    def features(self) -> np.ndarray:
        """Returns the captured rows (N, 57)."""
        return np.array(self.rows).reshape(-1, 57)

    def feed(self, msg: dict) -> str | None:
        """Takes one hands/frame message; returns a progress line when something happened."""
        if self.done:
            return None
        if not msg["hands"]:
            self._since = None
            if self._need_gap:
                self._need_gap = False
                return f"take {self.take}: show the gesture"
            return None
        if self._need_gap:
            return None
        if self._since is None:
            self._since = msg["ts"]
            if self.settle_s > 0:
                return f"take {self.take}: hand seen, settling for {self.settle_s:g} s"
        if msg["ts"] - self._since < self.settle_s:
            return None
        self.device = self.device or msg.get("device", "")
        self.rows.append(hand_features(msg["hands"][0], to_recorded_side=True))
        if len(self.rows) < self.frames * self.take:
            return None
        line = f"take {self.take}: {self.frames} frames captured"
        if not self.done:
            self.take += 1
            self._need_gap = True
            line += f"; take the hand away for take {self.take}"
        return line


def simulate_pose(text: str, name: str) -> tuple[str, list[float] | None]:
    """Reads ``--simulate``: a vocabulary gesture, or five finger curls ``thumb,...,pinky``.

    Returns:
        (the simulated step's gesture name, its curls or None).

    Raises:
        ValueError: neither, saying what it may be.
    """
    text = text.strip()
    if text in STATIC_GESTURES:
        return text, None
    try:
        curls = list(check_curls(text.replace(" ", "").split(",")))
    except ValueError:
        raise ValueError(f"--simulate {text!r}: give a static gesture "
                         f"({', '.join(STATIC_GESTURES)}) or five finger curls "
                         "thumb,index,middle,ring,pinky, each 0 (straight) to 1 (curled), "
                         "e.g. 1,0,1,1,0 for horns") from None
    return name, curls


def reading(classifier: StaticClassifier, rows: np.ndarray) -> dict[str, float]:
    """Returns the share of rows each name is the top answer for, largest first."""
    top = np.asarray(classifier.names)[classifier.predict_features(rows).argmax(1)]
    names, counts = np.unique(top, return_counts=True)
    shares = {str(n): float(c) / len(rows) for n, c in zip(names, counts, strict=True)}
    return dict(sorted(shares.items(), key=lambda kv: -kv[1]))


def rival(shares: dict[str, float], name: str) -> tuple[str, float] | None:
    """Returns the other gesture (not ``none``) read for at least `CLASH_SHARE` of the rows."""
    for other, share in shares.items():
        if other not in (name, NONE) and share >= CLASH_SHARE:
            return other, share
    return None


def percent(share: float) -> str:
    """Returns ``97 %`` for 0.97."""
    return f"{share:.0%}".replace("%", " %")


def describe_shares(shares: dict[str, float]) -> str:
    """Returns ``two 97 %, none 3 %``."""
    return ", ".join(f"{n} {percent(share)}" for n, share in shares.items())


def list_gestures() -> list[dict]:
    """Returns one row per recorded static gesture: name, rows, takes, users, last recorded."""
    out = []
    for g in train.load_user_gestures():
        out.append({"kind": "static", "name": g.name, "samples": len(g.x),
                    "takes": len(g.takes),
                    "users": sorted({t.get("user", "?") for t in g.takes}),
                    "last": max((t.get("time", "") for t in g.takes), default=""),
                    "path": str(g.path)})
    return out


# --------------------------------------------------------------------------- run (network)


def _capture(args: argparse.Namespace, capture: Capture, play: dict | None = None
             ) -> str | None:
    """Feeds live frames to the capture until done or timeout; returns the operator seen.

    With `play` (scenario data), leap-bridge's simulated user is asked to perform it once
    the frames are subscribed.

    Raises:
        TimeoutError: the takes were not complete in time.
        QueryError: leap-bridge did not take the scenario.
    """
    from cbgo.client import session

    inbox: queue.Queue = queue.Queue()
    with session(args, "cbgo-gestures") as (sess, k):
        subs = [sess.declare_subscriber(k.of(topic), lambda s, t=topic: inbox.put(
            (t, s.payload.to_bytes()))) for topic in (keys.HANDS_FRAME, keys.USER)]
        operator, frames = None, 0
        deadline = time.monotonic() + args.timeout
        if play is None:
            print(f"recording {args.name!r}: {capture.takes} take(s) of {capture.frames} "
                  "frames; show the gesture to the sensor", flush=True)
        else:
            seconds = _play(sess, k, play)
            deadline = max(deadline, time.monotonic() + seconds + 15.0)
            print(f"recording {args.name!r}: {capture.takes} take(s) of {capture.frames} "
                  f"frames; the simulated user shows it ({seconds:.0f} s at speed 1)",
                  flush=True)
        while not capture.done and time.monotonic() < deadline:
            try:
                topic, payload = inbox.get(timeout=0.2)
                msg = wire.decode_checked(payload, topic.schema)
            except queue.Empty:
                continue
            except RejectedMessage as e:
                print(f"ignoring an invalid message: {e}", file=sys.stderr)
                continue
            if topic is keys.USER:
                operator = msg["user"]
                continue
            frames += 1
            line = capture.feed(msg)
            if line:
                print(line, flush=True)
        for sub in subs:
            sub.undeclare()
    if not capture.done:
        seen = "no hand frames at all (is leap-bridge running?)" if frames == 0 else (
            f"{frames} frames, {len(capture.rows)} rows captured")
        raise TimeoutError(f"not enough frames within {args.timeout:g} s: {seen}")
    return operator


def _play(sess, k, scenario: dict) -> float:
    """Asks leap-bridge to play a scenario; returns its length in seconds (at speed 1)."""
    from cbgo.client import query

    answer = query(sess, k.ctl("leap-bridge", "play"), scenario, timeout_s=PLAY_TIMEOUT_S,
                   hint="is leap-bridge running with --source simulated, as `cbgo up` starts "
                        "it?")
    return float(answer.get("duration_s", 0.0))


def _served_model(args: argparse.Namespace) -> StaticClassifier | None:
    """Returns the model the running service serves (its status says which), else the default.

    None when no model loads here (the check is then skipped, and says so).
    """
    path = getattr(args, "served_model", None) or default_model_path()
    try:
        return StaticClassifier.load(path)
    except ConfigError:
        try:
            return StaticClassifier.load(default_model_path())
        except ConfigError:
            return None


def check_takes(args: argparse.Namespace, name: str, rows: np.ndarray) -> bool:
    """Reports how the served model reads the takes; returns False for a duplicate not forced.

    A duplicate: `CLASH_SHARE` or more of the frames answered as one other gesture.
    """
    classifier = _served_model(args)
    if classifier is None:
        print("not checked: no model loads here to read the takes with")
        return True
    shares = reading(classifier, rows)
    print(f"the served model {classifier.model_id} reads the {len(rows)} frames as: "
          f"{describe_shares(shares)}")
    clash = rival(shares, name)
    if clash is None:
        return True
    other, share = clash
    warning = (f"{percent(share)} of the frames of {name!r} are already read as {other!r}: taught "
               f"beside it, {name} would lose to it")
    if getattr(args, "force", False):
        print(f"warning: {warning}; taught anyway (--force)")
        return True
    print(f"cbgo: {warning}. Not stored, not retrained, the model not swapped: show a pose "
          f"that differs from {other}, record it as {other} to add examples of it, or rerun "
          "with --force to teach it anyway.", file=sys.stderr)
    return False


def _reload(args: argparse.Namespace, written: str) -> str:
    """Asks a running static-gesture to reload; returns a line saying what happened."""
    from cbgo.client import query_all, session

    with session(args, "cbgo-gestures") as (sess, k):
        replies = query_all(sess, k.ctl("static-gesture", "reload"), timeout_s=RELOAD_TIMEOUT_S)
    if not replies:
        return ("no static-gesture service answered; it loads the new model when it starts "
                "(a running one on this machine also notices the file within its --watch-s)")
    lines = []
    for ok, answer in replies:
        if not ok:
            lines.append(f"static-gesture could not reload: {answer}")
        elif answer["model"] != written:
            lines.append(f"warning: static-gesture serves {answer['model']} from "
                         f"{answer.get('path')}, not the model written ({written}, "
                         f"{user_model_path()}): it reads another data directory or runs "
                         "with --model; give both the same CBGO_DATA_DIR")
        else:
            lines.append(f"static-gesture now serves {answer['model']} "
                         f"({', '.join(answer['names'])})")
    return "\n".join(lines)


def check_personal(user: str | None) -> None:
    """Checks that ``--personal`` names a user whose model a file may hold.

    Raises:
        ValueError: no ``--user``, or a name with other characters than letters, digits and
            ``_ . @ -``.
    """
    if not user or personal_model_path(user) is None:
        raise ValueError("--personal needs --user NAME, a name of letters, digits and _ . @ - "
                         "(whose own model is trained)")


def run(args: argparse.Namespace) -> int:
    """Records, checks, stores, retrains and reloads (see the module docstring).

    Returns:
        0 done, 1 takes incomplete, leap-bridge not playing or a duplicate refused, 2 a bad
        name or ``--simulate``.
    """
    try:
        name = check_name(args.name)
        simulated = getattr(args, "simulate", None)
        pose = simulate_pose(simulated, name) if simulated else None
    except ValueError as e:
        print(f"cbgo: {e}", file=sys.stderr)
        return 2
    if getattr(args, "personal", False):
        try:
            check_personal(args.user)
        except ValueError as e:
            print(f"cbgo: {e}", file=sys.stderr)
            return 2
    frames = args.frames or DEFAULT_FRAMES
    settle_s = getattr(args, "settle", None)
    if settle_s is None:
        settle_s = SIMULATED_SETTLE_S if pose else DEFAULT_SETTLE_S
    capture = Capture(frames, args.takes or 1, settle_s)
    play = None
    if pose is not None:
        hold_s = settle_s + frames / SLOWEST_RATE_HZ + 0.5
        play = hold_scenario(pose[0], pose[1], capture.takes, hold_s)
    try:
        operator = _capture(args, capture, play)
    except TimeoutError as e:
        print(f"cbgo: {e}", file=sys.stderr)
        return 1
    except QueryError as e:
        print(f"cbgo: leap-bridge did not play the pose: {e}", file=sys.stderr)
        return 1
    rows = capture.features()
    if not check_takes(args, name, rows):
        return 1
    user = args.user or operator or "unknown"
    take = {"user": user, "ts": time.time(),
            "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "count": len(capture.rows), "device": capture.device,
            **({"personal": True} if getattr(args, "personal", False) else {})}
    replace = bool(getattr(args, "replace", False))
    path = train.store_gesture(name, rows, take, replace=replace)
    print(f"stored {len(capture.rows)} rows of {name!r} by {user} in {path}")
    if getattr(args, "no_train", False):
        print("not retrained (--no-train); run `cbgo train static` to include it")
        return 0
    options = train.TrainOptions()
    if getattr(args, "epochs", None):
        options.epochs = args.epochs
    out, takes = user_model_path(), None
    if getattr(args, "personal", False):
        out, takes = personal_model_path(user), train.load_user_gestures(user=user)
    trained, model_id = train.train_and_save(options, out, progress="retraining static-gesture",
                                             user=takes)
    whose = f"{user}'s own model, served while cbgo/user names {user}" if takes is not None \
        else "the model of every user"
    print(f"retrained {model_id} in {trained.seconds:.1f} s: "
          f"{', '.join(trained.metadata['names'])}; wrote {out}.pt/.json ({whose})")
    print(_reload(args, model_id) if takes is None else
          "static-gesture loads it within its --watch-s whenever cbgo/user names "
          f"{user} (the next time they are named, if they are now)")
    return 0
