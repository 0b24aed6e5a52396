"""New static gestures by demonstration: capture poses from the live stream, retrain, reload.

``cbgo gestures record NAME --static`` runs `run`:

1. Capture: subscribes ``cbgo/hands/frame`` from any source (a Leap, a replay, the simulated
   user) and, per take, waits for a hand, lets it settle for ``--settle`` seconds (the frames
   where the hand is still forming the pose are not the gesture), then takes the features of
   the first hand of ``--frames`` frames (default 60, about half a second at 120 Hz). Between
   takes (``--takes``) the hand must leave the sensor's view, so each take is a fresh
   rendition. A hand lost mid-take pauses the take; it settles again when it is back.
2. Store: the rows (the 57 features, right hands mirrored into the recordings' space, as the
   service computes them) go to ``data_dir()/gestures/static/NAME.npz`` with who recorded each
   take, when, from which device (``--user``, else the operator last seen on ``cbgo/user``).
   Recording a name again adds takes (``--replace`` starts over); a name of a known gesture
   adds examples of it, a new name becomes a new class.
3. Retrain: the real recordings + simulated hands + every recorded gesture
   (``cbgo.services.static_gesture.train``), written atomically as the user's model
   ``data_dir()/models/static-gesture.{pt,json}`` (``--epochs`` trades quality for time).
4. Reload: queries ``cbgo/@ctl/static-gesture/reload``; a running service answers with the new
   model id. None running is fine: the service loads the user's model when it starts, and a
   running one polls the file anyway. The service must see the same data directory (same
   machine or a shared volume) — the query says "reload", it does not carry the model.

Only `run` touches the network (through ``cbgo.client.session``); `Capture` is plain logic.

Examples::

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
from cbgo.errors import RejectedMessage
from cbgo.hands.features import hand_features
from cbgo.services.static_gesture import train
from cbgo.services.static_gesture.classifier import NONE, user_model_path

DEFAULT_FRAMES = 60
DEFAULT_SETTLE_S = 0.5
NAME_PATTERN = re.compile(r"^[a-z][a-z0-9_]{0,31}$")
RELOAD_TIMEOUT_S = 5.0


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


def _capture(args: argparse.Namespace, capture: Capture) -> str | None:
    """Feeds live frames to the capture until done or timeout; returns the operator seen."""
    from cbgo.client import session

    inbox: queue.Queue = queue.Queue()
    with session(args, "cbgo-gestures") as (sess, k):
        subs = [sess.declare_subscriber(k.of(topic), lambda s, t=topic: inbox.put(
            (t, s.payload.to_bytes()))) for topic in (keys.HANDS_FRAME, keys.USER)]
        operator, frames = None, 0
        deadline = time.monotonic() + args.timeout
        print(f"recording {args.name!r}: {capture.takes} take(s) of {capture.frames} frames; "
              "show the gesture to the sensor", flush=True)
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


def _reload(args: argparse.Namespace) -> str:
    """Asks a running static-gesture to reload; returns a line saying what happened."""
    from cbgo.client import query_all, session

    with session(args, "cbgo-gestures") as (sess, k):
        replies = query_all(sess, k.ctl("static-gesture", "reload"), timeout_s=RELOAD_TIMEOUT_S)
    if not replies:
        return ("no static-gesture service answered; it loads the new model when it starts "
                "(a running one on this machine also notices the file within its --watch-s)")
    lines = []
    for ok, answer in replies:
        if ok:
            lines.append(f"static-gesture now serves {answer['model']} "
                         f"({', '.join(answer['names'])})")
        else:
            lines.append(f"static-gesture could not reload: {answer}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Records, stores, retrains and reloads (see the module docstring); returns an exit code."""
    try:
        name = check_name(args.name)
    except ValueError as e:
        print(f"cbgo: {e}", file=sys.stderr)
        return 2
    frames = args.frames or DEFAULT_FRAMES
    settle_s = DEFAULT_SETTLE_S if getattr(args, "settle", None) is None else args.settle
    capture = Capture(frames, args.takes or 1, settle_s)
    try:
        operator = _capture(args, capture)
    except TimeoutError as e:
        print(f"cbgo: {e}", file=sys.stderr)
        return 1
    user = args.user or operator or "unknown"
    take = {"user": user, "ts": time.time(),
            "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "count": len(capture.rows), "device": capture.device}
    path = train.store_gesture(name, capture.features(), take,
                               replace=bool(getattr(args, "replace", False)))
    print(f"stored {len(capture.rows)} rows of {name!r} by {user} in {path}")
    if getattr(args, "no_train", False):
        print("not retrained (--no-train); run `cbgo train static` to include it")
        return 0
    options = train.TrainOptions()
    if getattr(args, "epochs", None):
        options.epochs = args.epochs
    trained, model_id = train.train_and_save(options, user_model_path(),
                                             progress="retraining static-gesture")
    print(f"retrained {model_id} in {trained.seconds:.1f} s: "
          f"{', '.join(trained.metadata['names'])}; wrote {user_model_path()}.pt/.json")
    print(_reload(args))
    return 0
