"""Teach a new dynamic gesture from demonstrations: ``cbgo gestures record NAME --dynamic``.

How a take is captured (the same segmenter as the service, so a take is exactly what the
service will later compare): show the hand, let it rest in the centre of the sensor's field,
perform the gesture once, take the hand out of view; repeat ``--takes`` times. Per appearance
of a hand, the **first** stroke that ends by slowing down and moves at least
`MIN_EXTENT_MM` (position, or roll as k·roll) is the take; later strokes of that appearance
(a roll back, the move out of the field) are ignored, so retractions never become takes.

Frames come live from ``cbgo/hands/frame`` — a person at a Leap Motion, or a leap-bridge
replaying a recording or playing a simulated user — or, with ``--file``, straight from an MCAP
recording. The template (ProMP + DTW reference + scale) is learned from the new takes plus the
takes recorded earlier under the same name (``--replace`` drops those), written with its takes to
``<data dir>/gestures/dynamic/<NAME>.json``, and ``@ctl/dynamic-gesture/reload`` is queried so
that a running service uses it at once (it would also find it within its ``--watch-s``). Learning
a ProMP takes milliseconds, so there is nothing to defer (``--no-train`` is ignored). Without
``--user``, the operator last announced on ``cbgo/user`` is recorded as the demonstrator.

Examples::

    cbgo gestures record swipe_diag --dynamic --takes 5
    python -m cbgo.services.dynamic_gesture.demonstrate lift --takes 3 --timeout 60
    python -m cbgo.services.dynamic_gesture.demonstrate lift --file takes.mcap
"""

from __future__ import annotations

import argparse
import queue
import sys
import time

import numpy as np

from cbgo import keys, wire
from cbgo.config import data_dir
from cbgo.errors import ConfigError, RejectedMessage
from cbgo.services.dynamic_gesture.classifier import Template, extent_of
from cbgo.services.dynamic_gesture.library import (
    check_name,
    read_takes,
    read_user_template,
    save_user_template,
    take_record,
    user_dir,
)
from cbgo.services.dynamic_gesture.stroke import Segmenter, SegmenterConfig, Window

MIN_EXTENT_MM = 40.0
SETTLE_S = 0.3  # a take starts no sooner after the hand came into view
DEFAULT_TAKES = 5
DEFAULT_TIMEOUT_S = 120.0


class TakeRecorder:
    """Turns hand frames into takes: the first real stroke of each hand appearance.

    Args:
        takes: how many takes to collect.
        config: the segmenter's settings (the service's defaults when None).
    """

    def __init__(self, takes: int, config: SegmenterConfig | None = None):
        self.wanted = takes
        self.segmenter = Segmenter(config)
        self.takes: list[Window] = []
        self._taken: set[int] = set()  # hand ids that already gave their take
        self._seen: dict[int, float] = {}  # hand id -> when it came into view

    @property
    def done(self) -> bool:
        """Whether enough takes were collected."""
        return len(self.takes) >= self.wanted

    def feed(self, t: float, hands: list[dict]) -> Window | None:
        """Feeds one frame; returns a new take when one was just captured.

        A take starts once the hand has been in view for `SETTLE_S`: strokes may start at
        first sight, and the move that brings the hand into the field is none.
        """
        for hand in hands:
            self._seen.setdefault(int(hand["id"]), t)
        new = None
        for window in self.segmenter.update(t, hands):
            settled = window.t_start - self._seen.get(window.hand_id, window.t_start) >= SETTLE_S
            if (window.final and window.ended == "slowed" and window.hand_id not in self._taken
                    and settled and extent_of(window.obs) >= MIN_EXTENT_MM and not self.done):
                self._taken.add(window.hand_id)
                self.takes.append(window)
                new = window
        return new

    def prompt(self) -> str:
        """What the person does for the next take."""
        return ("rest the hand in the centre, perform the gesture once, take the hand away; "
                "repeat")

    def records(self, user: str | None) -> list[dict]:
        """Returns the takes as plain data (`library.take_record`)."""
        return [take_record(w.obs, w.t_end - w.t_start, w.pose_change, user) for w in self.takes]

    def template(self, name: str, user: str | None, earlier: list[dict] | None = None
                 ) -> Template:
        """Returns the template learned from the takes plus `earlier` ones (plain data).

        Raises:
            ValueError: no takes.
        """
        return learn(name, (earlier or []) + self.records(user), user)


def learn(name: str, takes: list[dict], user: str | None) -> Template:
    """Returns a user template learned from stored takes (`library.take_record` data)."""
    return Template.learn(name, [np.asarray(t["obs"], dtype=float) for t in takes],
                          [t["duration_s"] for t in takes], [t["pose_change"] for t in takes],
                          source="user", user=user)


def list_gestures() -> list[dict]:
    """Returns one row per user-taught dynamic gesture (for ``cbgo gestures list``)."""
    rows = []
    for path in sorted(user_dir(data_dir()).glob("*.json")):
        takes = read_takes(path)
        try:
            template = read_user_template(path)
        except ValueError:
            continue
        users = sorted({t.get("user") or "?" for t in takes} or {template.user or "?"})
        last = max([t.get("recorded", 0.0) for t in takes] or [template.created])
        rows.append({"kind": "dynamic", "name": template.name,
                     "samples": sum(len(t["obs"]) for t in takes), "takes": template.n_demos,
                     "users": users,
                     "last": time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(last))})
    return rows


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds this module's flags (the ``cbgo gestures record`` verb has its own)."""
    from cbgo.client import add_network_arguments

    parser.add_argument("name", help="the new gesture's name, e.g. swipe_diag")
    parser.add_argument("--takes", type=int, default=DEFAULT_TAKES,
                        help=f"demonstrations to record [{DEFAULT_TAKES}]")
    parser.add_argument("--user", default=None, help="who demonstrates (stored in the template)")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S,
                        help=f"give up after S seconds [{DEFAULT_TIMEOUT_S:g}]")
    parser.add_argument("--file", default=None,
                        help="read hand frames from an MCAP recording instead of the network")
    parser.add_argument("--replace", action="store_true",
                        help="drop earlier takes of NAME instead of adding to them")
    add_network_arguments(parser)


def say(text: str) -> None:
    """Tells the person at the sensor what happened or what to do next."""
    print(text, flush=True)


def record_from_file(recorder, path: str) -> None:
    """Feeds the hand frames of an MCAP recording to a recorder until it has its takes.

    Raises:
        ConfigError: the recording cannot be read.
    """
    from cbgo.errors import RecordingError
    from cbgo.recording import read_recording

    try:
        for item in read_recording(path, "**/hands/frame"):
            try:
                frame = wire.validate(item.message, wire.HANDS_FRAME, item.key)
            except RejectedMessage:
                continue
            window = recorder.feed(frame["ts"], frame["hands"])
            if window is not None:
                say(_captured(recorder, window))
            if recorder.done:
                return
    except RecordingError as e:
        raise ConfigError(str(e)) from None


def record_live(recorder, session, prefix_keys, timeout: float) -> str | None:
    """Records takes from the network; returns the operator announced on cbgo/user, if any."""
    frames: queue.Queue = queue.Queue(maxsize=4096)
    operator: list[str] = []
    key = prefix_keys.of(keys.HANDS_FRAME)

    def on_frame(sample) -> None:
        try:
            frames.put_nowait(sample.payload.to_bytes())
        except queue.Full:
            pass  # newest-wins stream; a backlog this deep means we are far behind anyway

    def on_user(sample) -> None:
        try:
            operator.append(wire.decode_checked(sample.payload.to_bytes(), wire.USER)["user"])
        except RejectedMessage:
            pass

    subscribers = [session.declare_subscriber(key, on_frame),
                   session.declare_subscriber(prefix_keys.of(keys.USER), on_user)]
    deadline = time.monotonic() + timeout
    say(f"recording {recorder.wanted} take(s) on {key}: " + recorder.prompt())
    try:
        while not recorder.done and time.monotonic() < deadline:
            try:
                payload = frames.get(timeout=0.2)
            except queue.Empty:
                continue
            try:
                frame = wire.decode_checked(payload, wire.HANDS_FRAME, key)
            except RejectedMessage:
                continue
            window = recorder.feed(frame["ts"], frame["hands"])
            if window is not None:
                say(_captured(recorder, window))
    finally:
        for subscriber in subscribers:
            subscriber.undeclare()
    return operator[-1] if operator else None


def _captured(recorder, window: Window) -> str:
    """What to say when a take was captured: which, how long, and what to do next."""
    text = (f"take {len(recorder.takes)}/{recorder.wanted} captured "
            f"({window.t_end - window.t_start:.2f} s, {len(window.obs)} samples)")
    return text if recorder.done else f"{text}; {recorder.prompt()}"


def _reload(session, prefix_keys) -> None:
    from cbgo.client import query_all

    key = prefix_keys.ctl("dynamic-gesture", "reload")
    for ok, answer in query_all(session, key, {"v": wire.SCHEMA_VERSION}, timeout_s=5.0):
        if ok:
            say(f"dynamic-gesture reloaded: {', '.join(answer.get('gestures', []))}")
        else:
            say(f"dynamic-gesture could not reload: {answer}")
        return
    say("dynamic-gesture is not running; it loads the gesture when it starts")


def run(args: argparse.Namespace) -> int:
    """Records the takes, learns and saves the template, asks the service to reload.

    Args:
        args: ``name``, ``takes``, ``user``, ``timeout``, optionally ``file`` and ``replace``,
            and the Zenoh flags of `cbgo.client.add_network_arguments`.

    Returns:
        0 on success, 1 if the takes were not all captured in time, 2 for a bad name or file.
    """
    try:
        name = check_name(args.name)
    except ConfigError as e:
        print(f"cbgo: {e}", file=sys.stderr)
        return 2
    recorder = TakeRecorder(int(getattr(args, "takes", None) or DEFAULT_TAKES))
    timeout = float(getattr(args, "timeout", None) or DEFAULT_TIMEOUT_S)
    replace = bool(getattr(args, "replace", False))
    user = getattr(args, "user", None)
    if getattr(args, "file", None):
        try:
            record_from_file(recorder, args.file)
        except ConfigError as e:
            print(f"cbgo: {e}", file=sys.stderr)
            return 2
        return _finish(recorder, name, user, replace, None, None)
    from cbgo.client import session

    with session(args, "cbgo-gestures-record") as (sess, prefix_keys):
        operator = record_live(recorder, sess, prefix_keys, timeout)
        return _finish(recorder, name, user or operator, replace, sess, prefix_keys)


def _finish(recorder: TakeRecorder, name: str, user: str | None, replace: bool, sess,
            prefix_keys) -> int:
    if not recorder.done:
        print(f"cbgo: only {len(recorder.takes)} of {recorder.wanted} takes captured in time; "
              "nothing saved", file=sys.stderr)
        return 1
    folder = user_dir(data_dir())
    earlier = [] if replace else read_takes(folder / f"{name}.json")
    template = recorder.template(name, user, earlier)
    path = save_user_template(folder, template, earlier + recorder.records(user))
    say(f"saved {name} ({template.n_demos} takes, {len(earlier)} of them earlier; scale "
         f"{template.scale:.3f}) to {path}")
    if sess is not None:
        _reload(sess, prefix_keys)
    return 0


def main(argv: list[str] | None = None) -> None:
    """Entry point of ``python -m cbgo.services.dynamic_gesture.demonstrate``."""
    parser = argparse.ArgumentParser(prog="python -m cbgo.services.dynamic_gesture.demonstrate",
                                     description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(parser)
    sys.exit(run(parser.parse_args(argv)))


if __name__ == "__main__":
    main()
