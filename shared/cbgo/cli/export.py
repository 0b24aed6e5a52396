"""Convert a recording into an MCAP file Foxglove can open: JSON channels with schemas.

Reads a recording (``cbgo record``, ``cbgo demo``'s ``session.mcap``, msgpack or json encoded)
and writes what ``cbgo record --encoding json`` would have written live: every key's messages
as JSON with the key's JSON Schema (topic, log time and order kept), plus the derived channels
``foxglove/scene`` (hands as skeletons in the robot base frame, objects as cubes and cylinders,
the TCP, the gaze or pointing ray, the target object highlighted), ``foxglove/transforms``
(robot base and Leap frame) and ``foxglove/log`` (episode, intent and plan events).

A message that is not msgpack or breaks its key's contract cannot be written as valid JSON:
it is left out, and the messages left out are listed per key with the last reason. The rest
is written. A file that turns out corrupt mid-way keeps what was read before the damage.

Exit status: 0 every message converted; 1 the output is complete but messages were left out
or the input was damaged; 2 a usage error or an unreadable input.

Examples::

    cbgo export out/demo-20261122-021700/session.mcap -o foxglove.mcap
    cbgo export session.mcap -o hands.mcap --keys hands/frame gaze --force
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cbgo.cli.common import fail
from cbgo.cli.record import summary
from cbgo.errors import ConfigError, RecordingError
from cbgo.keys import DEFAULT_PREFIX, Keys
from cbgo.recording import COMPRESSIONS, Recorder, read_recording, recording_info


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds export's flags."""
    parser.add_argument("input", metavar="IN.mcap", help="a cbgo recording")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.mcap",
                        help="the JSON MCAP file to write")
    parser.add_argument("-f", "--force", action="store_true",
                        help="overwrite the output file if it exists")
    parser.add_argument("--keys", nargs="+", metavar="KEY",
                        help="export only these keys (relative to the recording's prefix; "
                             "wildcards allowed) [all]")
    parser.add_argument("--compression", choices=list(COMPRESSIONS), default="zstd",
                        help="chunk compression [zstd]")


def _prefix(info) -> str:
    try:
        return Keys(info.prefix or DEFAULT_PREFIX).prefix
    except ConfigError:
        return DEFAULT_PREFIX


def run(args: argparse.Namespace) -> int:
    """Converts the file; returns the exit status described in the module docstring."""
    source, target = Path(args.input), Path(args.output)
    if target.exists() and not args.force:
        fail(f"{target} exists; use --force to overwrite it", 2)
    if target.resolve() == source.resolve():
        fail("the output must be another file than the input", 2)
    try:
        info = recording_info(source)
        prefix = _prefix(info)
        filters = [Keys(prefix).resolve(k) for k in args.keys] if args.keys else None
        messages = read_recording(source, filters)
        recorder = Recorder(target, prefix=prefix, keys=filters or [f"{prefix}/**"],
                            compression=args.compression, encoding="json",
                            metadata={"exported_from": str(source)})
    except RecordingError as e:
        fail(str(e), 2)
    damaged = _copy(messages, recorder)
    print(summary(recorder), flush=True)  # ends with the keys whose messages were left out
    if damaged:
        print(f"cbgo: warning: {damaged}; the messages before it are exported",
              file=sys.stderr)
    return 1 if damaged or recorder.rejected else 0


def _copy(messages, recorder: Recorder) -> str | None:
    """Writes every message into the recorder and closes it; returns a damage report or None."""
    try:
        for recorded in messages:
            recorder.write(recorded.key, recorded.payload, recorded.log_time_ns)
    except RecordingError as e:
        return str(e)
    finally:
        recorder.close()
    return None
