"""Replay an MCAP recording onto the network: each payload on its original key, in its rhythm.

What goes out. By default only what a sensor or a person produces: ``hands/frame``, ``gaze`` and
``user``. What the services derive from them and the commands (``episode/*``, ``gestures/*``,
``intent``, ``intent/feedback``, ``scene/state``, ``robot/*``, ``plan/status``, and any key of a
foreign file) go out only with ``--derived``. ``--keys`` chooses among them (relative to the
recording's prefix, wildcards allowed).

WARNING: a replay can move a robot. Recorded intents, scenes and stops act on a live system,
and live services read replayed hand frames as a user's gestures. So, unless given
``--yes-drive-robot``, replay refuses (exit code 2):

- ``--derived`` while a planner or a robot (mujoco-sim, dry-robot) is alive;
- hand frames while episode, intent and a planner are alive that does not say it refuses
  replayed intents (one started with ``--accept-replayed``, or another program).

Every message it sends is marked ``replayed: true`` (hand frames also ``source: "replay"``); the
episode service marks the summaries of episodes made of such frames, the intent service their
intents, and the planner refuses replayed intents unless it was started with
``--accept-replayed``. So hand frames replayed onto a live system show what the pipeline makes
of them (gestures, episodes, intents) and move nothing. Hand
frames from another publisher (a live leap-bridge, a second replay) that arrive meanwhile are
reported: the services would see both streams interleaved, one episode per few frames.

Timing. Messages go out in log-time order, each at the recorded time since the first message
divided by ``--speed`` (absolute deadlines on a monotonic clock, so timing errors do not add up
over a long file). Before the first message the replay waits up to ``--wait`` seconds for a
subscriber on every key, since a put made before any subscriber is known is lost. Known topics
keep the contract's delivery policy (hand frames: dropped under congestion, express; events,
intents, plans: never dropped). ``--restamp`` sets each message's ``ts`` to the time it is sent;
every other field stays as recorded, besides the mark. A payload that is not a msgpack map
cannot be marked and goes out as recorded. Both encodings play: a msgpack recording's payloads,
a JSON one's (``cbgo record --encoding json``, ``cbgo export``) re-encoded to the msgpack they
came from; its derived ``foxglove/*`` channels are not wire messages and are not replayed.

Examples::

    cbgo replay session.mcap                           # hands, gaze and user only
    cbgo replay session.mcap --speed 2 --keys hands/frame gaze
    cbgo replay hands.mcap --loop --restamp            # a live-looking hand stream, until Ctrl-C
    cbgo replay session.mcap --derived                 # everything, onto a system with no
                                                       # planner or robot (cbgo web, Foxglove)
    cbgo replay session.mcap --derived --yes-drive-robot   # everything, planner or robot alive
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time

from tqdm import tqdm

from cbgo import client, registry, wire
from cbgo.cli.common import add_network_arguments, fail, session
from cbgo.errors import ConfigError, RecordingError, RejectedMessage
from cbgo.keys import Keys
from cbgo.recording import KeyFilter, RecordedMessage, read_recording, recording_info

# No busy-waiting before a deadline: on a 2-core machine a spinning replay takes a core from
# the router and the subscribers, which then deliver late. A timed wait wakes ~0.1-0.3 ms late,
# about equally for every message, so the intervals barely change.
MAX_WAIT_S = 0.1  # longest single wait, so a stop request is seen quickly

SENSOR_KEYS = ("hands/frame", "gaze", "user")
"""What a sensor or a person produces: the keys replayed without --derived."""
HANDS = "hands/frame"
PIPELINE = ("episode", "intent", "planner")
"""Alive together, they turn hand frames into intents that the planner executes."""
ALIVE_TIMEOUT_S = 1.0
CONFIRM = "--yes-drive-robot"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds replay's flags."""
    parser.add_argument("file", metavar="FILE.mcap",
                        help="a recording (cbgo record or cbgo export; any MCAP file of msgpack "
                             "or JSON channels)")
    parser.add_argument("--speed", type=float, default=1.0, metavar="X",
                        help="play X times faster than recorded [1]")
    parser.add_argument("--loop", action="store_true", help="start again at the end, until "
                                                            "Ctrl-C")
    parser.add_argument("--keys", nargs="+", metavar="KEY",
                        help="replay only these keys (relative to the recording's prefix; "
                             "wildcards allowed)")
    parser.add_argument("--derived", action="store_true",
                        help="also replay what services derive and the commands (episode/*, "
                             "gestures/*, intent*, scene/state, robot/*, plan/status, other "
                             "keys); by default only hands/frame, gaze and user go out")
    parser.add_argument(CONFIRM, dest="yes_drive_robot", action="store_true",
                        help="replay even where it can move the robot: --derived while a planner "
                             "or a robot is alive, or hand frames while episode, intent and a "
                             "planner that accepts replayed intents are alive")
    parser.add_argument("--restamp", action="store_true",
                        help="set each message's ts to the time it is sent")
    parser.add_argument("--wait", type=float, default=2.0, metavar="S",
                        help="wait up to S seconds for subscribers before the first message [2]")
    add_network_arguments(parser)


def _file_keys(prefix: str | None, fallback: Keys) -> Keys:
    """Keys under the recording's own prefix (its metadata), else under --prefix."""
    try:
        return Keys(prefix) if prefix else fallback
    except ConfigError:
        return fallback


# ---------------------------------------------------------------- what goes out, and whether


def choose_keys(matching: list[str], keys: Keys, derived: bool) -> tuple[list[str], list[str]]:
    """Splits the recording's matching keys into those to replay and those held back.

    Args:
        matching: the keys of the recording that --keys selects (all, without --keys).
        keys: the recording's keys.
        derived: --derived: every key goes out.

    Returns:
        (keys to replay, derived keys held back for want of --derived).
    """
    sensors = {keys.resolve(s) for s in SENSOR_KEYS}
    chosen = [k for k in matching if derived or k in sensors]
    return chosen, [k for k in matching if k not in chosen]


def robot_risks(chosen: list[str], keys: Keys, alive: set[str],
                planner_refuses_replayed: bool) -> list[str]:
    """Returns why replaying `chosen` onto a system where `alive` runs could move the robot.

    Args:
        chosen: the keys about to be replayed.
        keys: the recording's keys (its prefix is where the messages go).
        alive: the services whose liveliness token is present under that prefix.
        planner_refuses_replayed: the live planner said (its status) that it refuses replayed
            intents; the intents that replayed hand frames lead to are marked replayed too.
    """
    sensors = {keys.resolve(s) for s in SENSOR_KEYS}
    derived = [_short(keys, k) for k in chosen if k not in sensors]
    movers = sorted(alive & {"planner", *registry.ROBOTS.values()})
    risks = []
    if derived and movers:
        risks.append(f"{_listed(movers)} {'is' if len(movers) == 1 else 'are'} alive, and the "
                     f"derived keys ({_listed(derived, 6)}) would act on them: recorded intents, "
                     "scenes and stops")
    if keys.resolve(HANDS) in chosen and set(PIPELINE) <= alive and not planner_refuses_replayed:
        risks.append(f"{_listed(list(PIPELINE))} are alive and the planner does not say that it "
                     "refuses replayed intents (--accept-replayed, or not cbgo's planner): it "
                     "would execute the intents the replayed hand frames lead to")
    return risks


def planner_refuses_replayed(sess, keys: Keys) -> bool:
    """Returns whether the live planner's status says it refuses replayed intents."""
    reply = client.status(sess, keys, "planner", timeout_s=ALIVE_TIMEOUT_S * 3).get("planner")
    return bool(reply) and reply.get("config", {}).get("accept_replayed") is False


def _short(keys: Keys, key: str) -> str:
    """Returns a key relative to the prefix, as the user types it."""
    head = keys.prefix + "/"
    return key[len(head):] if key.startswith(head) else key


def _listed(names: list[str], most: int = 0) -> str:
    shown = names[:most] if most else names
    more = f" and {len(names) - len(shown)} more" if len(names) > len(shown) else ""
    return ", ".join(shown) + more


def _refuse_to_drive(sess, keys: Keys, chosen: list[str], confirmed: bool) -> None:
    """Ends the command (exit 2) where the replay could move the robot and nobody confirmed."""
    if confirmed:
        return
    alive = client.alive(sess, keys, ALIVE_TIMEOUT_S)
    refuses = "planner" in alive and planner_refuses_replayed(sess, keys)
    risks = robot_risks(chosen, keys, alive, refuses)
    if risks:
        fail(f"not replaying: it could move the robot. {'; '.join(risks)}. Add {CONFIRM} to "
             "replay anyway (the planner still refuses replayed intents unless started with "
             "--accept-replayed), replay fewer keys (--keys gaze user; no --derived), or replay "
             "onto a system without them", 2)


def replayed_message(recorded: RecordedMessage, hands_key: str) -> dict | None:
    """Returns the message as it is replayed (marked), or None for a payload that is no map."""
    try:
        message = recorded.message
    except RejectedMessage:
        return None
    marked = {**message, wire.REPLAYED: True}
    if recorded.key == hands_key:
        marked["source"] = "replay"  # the contract's value for a replayed recording
    return marked


# ---------------------------------------------------------------- a second hand source


class SecondSource:
    """Counts the hand frames that another publisher sends on the key during the replay.

    Its subscriber takes remote samples only (`watch_hands`), so our own frames never reach it.

    Args:
        key: the hands/frame key the replay publishes on.
        say: where the first sighting is reported.
    """

    def __init__(self, key: str, say=print):
        self.key = key
        self.foreign = 0
        self._say = say
        self._lock = threading.Lock()

    def on_frame(self) -> None:
        """Called for each hand frame another session published on the key."""
        with self._lock:
            self.foreign += 1
            first = self.foreign == 1
        if first:
            self._say(f"cbgo: warning: hand frames from another publisher are arriving on "
                      f"{self.key} (a live leap-bridge? `cbgo ls` shows it): the services see "
                      "them interleaved with the replayed ones, which cuts episodes into "
                      "pieces. Stop that source, or replay other keys (--keys gaze user)")

    def summary(self) -> str | None:
        """Returns the end-of-replay report, or None when no other frame came."""
        if not self.foreign:
            return None
        return (f"cbgo: warning: {self.foreign} hand frame{'s' if self.foreign != 1 else ''} "
                f"from another publisher arrived on {self.key} during the replay")


def watch_hands(sess, watch: SecondSource):
    """Subscribes `watch` to the frames of other sessions only.

    Declared once the replay's own publishers have found their subscribers: a local subscriber
    counts as a match for them, and would end that wait at once.
    """
    import zenoh

    return sess.declare_subscriber(watch.key, lambda _sample: watch.on_frame(),
                                   allowed_origin=zenoh.Locality.REMOTE)


# ---------------------------------------------------------------- publishing


def _declare(sess, keys: Keys, key: str):
    """Returns a publisher on key with its topic's delivery policy (BLOCK for unknown keys)."""
    import zenoh

    topic = keys.topic_of(key)
    reliable = topic is None or topic.reliable
    return sess.declare_publisher(
        key, express=bool(topic and topic.express),
        congestion_control=(zenoh.CongestionControl.BLOCK if reliable
                            else zenoh.CongestionControl.DROP))


def _declare_all(sess, keys: Keys, chosen: list[str]) -> dict:
    import zenoh

    publishers = {}
    for key in chosen:
        try:
            publishers[key] = _declare(sess, keys, key)
        except zenoh.ZError as e:  # a foreign file's topic need not be a key expression
            print(f"cbgo: warning: skipping {key!r}: not a Zenoh key ({e})", file=sys.stderr)
    if not publishers:
        fail("no key of the recording can be published", 2)
    return publishers


def _wait_for_subscribers(publishers: dict, wait_s: float) -> None:
    client.wait_matched(*publishers.values(), timeout_s=wait_s)
    for key, pub in publishers.items():
        if not pub.matching_status.matching:
            print(f"cbgo: warning: no subscriber on {key}; publishing anyway", file=sys.stderr)


def _sleep_until(deadline: float, stop: threading.Event) -> bool:
    """Waits until perf_counter() reaches deadline; returns True if asked to stop first."""
    while True:
        remaining = deadline - time.perf_counter()
        if remaining <= 0:
            return stop.is_set()
        if stop.wait(min(remaining, MAX_WAIT_S)):
            return True


def play(path: str, filters: list[str] | None, puts: dict, args: argparse.Namespace,
         stop: threading.Event, bar: tqdm, hands_key: str = "") -> int:
    """Publishes one pass over the recording with its timing; returns the messages sent.

    Args:
        path: the recording.
        filters: key expressions to replay (None: all).
        puts: the put function of each key to replay.
        args: the verb's flags (speed, restamp).
        stop: set by Ctrl-C or SIGTERM; the pass ends at the next message.
        bar: the progress bar to advance.
        hands_key: the recording's hands/frame key (its frames also get ``source: "replay"``).

    Raises:
        RecordingError: the file turned out corrupt mid-way.
    """
    sent, origin = 0, None
    for recorded in read_recording(path, filters):
        put = puts.get(recorded.key)
        if put is None:
            continue
        if origin is None:
            origin = (time.perf_counter(), recorded.log_time_ns)
        deadline = origin[0] + (recorded.log_time_ns - origin[1]) / 1e9 / args.speed
        message = replayed_message(recorded, hands_key)  # decoded ahead of time
        restamp = args.restamp and message is not None and "ts" in message
        payload = recorded.payload if message is None else (
            None if restamp else wire.encode(message))
        if _sleep_until(deadline, stop):
            break
        if payload is None:
            payload = wire.encode({**message, "ts": time.time()})
        put(payload)
        sent += 1
        bar.update(1)
    return sent


def run(args: argparse.Namespace) -> int:
    """Replays once (or until Ctrl-C with --loop); returns 0, or 2 for an unusable file."""
    if args.speed <= 0:
        fail("--speed must be > 0", 2)
    try:
        info = recording_info(args.file)
    except RecordingError as e:
        fail(str(e), 2)
    with session(args, "cbgo-replay") as (sess, net_keys):
        keys = _file_keys(info.prefix, net_keys)
        filters = [keys.resolve(k) for k in args.keys] if args.keys else None
        try:
            matching = [k for k in info.counts if KeyFilter(filters)(k) and info.counts[k]]
        except RecordingError as e:
            fail(str(e), 2)
        if not matching:
            fail(f"no messages in {args.file} match {filters or 'any key'}", 2)
        chosen = _chosen_or_fail(args, matching, keys)
        _refuse_to_drive(sess, keys, chosen, args.yes_drive_robot)
        hands_key = keys.resolve(HANDS)
        publishers = _declare_all(sess, keys, chosen)
        _wait_for_subscribers(publishers, args.wait)
        watch = SecondSource(hands_key, say=lambda text: tqdm.write(text, file=sys.stderr))
        watching = watch_hands(sess, watch) if hands_key in publishers else None
        stop = threading.Event()
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: stop.set())
        total = sum(info.counts[k] for k in publishers)
        puts = {k: p.put for k, p in publishers.items()}
        code = _loop(args, filters, puts, total, stop, hands_key)
        if watching is not None:
            watching.undeclare()
        if watch.summary():
            print(watch.summary(), file=sys.stderr)
        return code


def _chosen_or_fail(args: argparse.Namespace, matching: list[str], keys: Keys) -> list[str]:
    """Returns the keys to replay; says which derived keys stay back, or fails if all do."""
    chosen, held_back = choose_keys(matching, keys, args.derived)
    names = _listed([_short(keys, k) for k in held_back], 8)
    if not chosen:
        fail(f"{args.file} has no sensor key to replay here ({', '.join(SENSOR_KEYS)}), only "
             f"derived or command keys: {names}. --derived replays them (read the warning in "
             "`cbgo replay --help` first)", 2)
    if held_back:
        print(f"cbgo: not replaying derived and command keys ({names}); --derived replays "
              "them", file=sys.stderr)
    return chosen


def _loop(args: argparse.Namespace, filters, puts: dict, total: int,
          stop: threading.Event, hands_key: str) -> int:
    started, sent, passes = time.monotonic(), 0, 0
    with tqdm(total=total, unit="msg", file=sys.stderr, disable=None, leave=False) as bar:
        while not stop.is_set():
            bar.reset(total)
            try:
                sent += play(args.file, filters, puts, args, stop, bar, hands_key)
            except RecordingError as e:
                fail(f"{e} (after {sent} messages)", 2)
            passes += 1
            if not args.loop:
                break
    time.sleep(0.1)  # let the last puts leave before the session closes
    print(f"replayed {sent} messages on {len(puts)} key{'s' if len(puts) != 1 else ''} in "
          f"{time.monotonic() - started:.2f} s ({passes} pass{'es' if passes != 1 else ''}, "
          f"speed {args.speed:g})",
          file=sys.stderr)
    return 0
