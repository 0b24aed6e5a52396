"""The few domain exceptions cbgo raises, one per kind of failure at a boundary.

- `RejectedMessage`: a message failed decoding or validation; the receiver counts, logs and
  drops it and keeps running.
- `QueryError`: a query cannot be answered; the runtime turns it into `reply_err(reason)`.
- `ConfigError`: bad configuration found at start-up; the message names the fix.
- `DeviceError`: a device (sensor, robot) failed; tolerated a few times, then the process exits
  non-zero so that its supervisor restarts it.

`zenoh_reason` turns a Zenoh error into text for people: Zenoh's messages end in the Rust
source file that raised them, which tells a user nothing.
"""

import re

# " at /root/.cargo/.../orchestrator.rs:388." : where in Zenoh's Rust sources an error arose.
_RUST_LOCATION = re.compile(r"\s+at\s+\S+?\.rs:\d+\.?")
# Json5Err(Message { msg: "...", location: ... }): a config value Zenoh could not parse.
_JSON5_MESSAGE = re.compile(r'Json5Err\(Message \{ msg: "(.*?)", location: .*\}\)', re.S)


class CbgoError(Exception):
    """Base class of every cbgo exception."""


class RejectedMessage(CbgoError):
    """A payload that failed decoding or validation.

    Attributes:
        key: the key expression (or topic) it arrived on, if known.
        path: where in the message the problem is, e.g. ``hands[0].palm_position[2]``.
        problem: what was expected and what was found.
    """

    def __init__(self, problem: str, path: str = "", key: str = ""):
        self.key, self.path, self.problem = key, path, problem
        super().__init__(self._text())

    def _text(self) -> str:
        where = f"{self.path}: " if self.path else ""
        on = f"{self.key}: " if self.key else ""
        return f"{on}{where}{self.problem}"

    def on_key(self, key: str) -> "RejectedMessage":
        """Returns the same rejection, labelled with the key it arrived on."""
        return RejectedMessage(self.problem, self.path, key)


class QueryError(CbgoError):
    """A query that cannot be answered; its text is sent back as the error reply."""


class ConfigError(CbgoError):
    """Invalid configuration, found at start-up; the message says how to fix it."""


class DeviceError(CbgoError):
    """A device fault (sensor or robot) that the service could not recover from."""


class RecordingError(CbgoError):
    """A recording (MCAP or toolbox JSON) that is missing, truncated, corrupt or malformed."""


def zenoh_reason(error: BaseException | str) -> str:
    """Returns a Zenoh error's message without Rust source locations and wrappers.

    ``Invalid Key Expr `a//b`: empty chunks are forbidden ... at /root/.cargo/.../borrowed.rs:777.``
    becomes ``Invalid Key Expr `a//b`: empty chunks are forbidden ...``.
    """
    text = _RUST_LOCATION.sub("", str(error))
    text = _JSON5_MESSAGE.sub(lambda m: m.group(1), text)
    return text.strip().rstrip(".")
