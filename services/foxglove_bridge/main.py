"""foxglove-bridge: the live cbgo traffic as a Foxglove WebSocket server (foxglove-sdk).

Behaviour (the contract is services/foxglove_bridge/README.md):
- at start, opens a Foxglove WebSocket server on ``--ws-host``:``--ws-port`` (default
  ws://127.0.0.1:8765) and advertises one JSON channel per data key of the contract (topic =
  the key, schema from `cbgo.json_schema`) and the derived channels ``foxglove/scene``
  (``foxglove.SceneUpdate``), ``foxglove/transforms`` (``foxglove.FrameTransforms``) and
  ``foxglove/log`` (``foxglove.Log``), the same channels ``cbgo export`` writes;
- subscribes to every data key; each valid message is logged on its channel and on the derived
  channels it implies (`cbgo.foxglove.derive`); high-rate keys are thinned to ``--stream-hz``;
  a bad message is counted, logged and dropped by the runtime, as in every service;
- publishes nothing on Zenoh and answers no data queries; status carries the counts per key.

A port already in use is a configuration error (exit 2) naming the flag to change.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field

from cbgo import keys
from cbgo.config import described as _help
from cbgo.errors import ConfigError
from cbgo.foxglove.channels import (
    MESSAGE_ENCODING,
    SCHEMA_ENCODING,
    encode,
    foxglove_schema,
    wire_schema,
)
from cbgo.foxglove.derive import DERIVED_TOPICS
from cbgo.runtime import Service, main_for
from cbgo.services.foxglove_bridge.forward import Forwarder

DEFAULT_PORT = 8765  # Foxglove's default WebSocket port


@dataclass
class FoxgloveBridgeSettings:
    """Settings of foxglove-bridge (flags ``--ws-port`` ... or env ``CBGO_WS_PORT`` ...)."""

    ws_host: str = field(default="127.0.0.1", metadata=_help(
        "address the WebSocket server listens on (0.0.0.0: every interface, e.g. in a "
        "container)"))
    ws_port: int = field(default=DEFAULT_PORT, metadata=_help(
        "WebSocket port (0: any free port, logged at start)"))
    stream_hz: float = field(default=30.0, metadata=_help(
        "at most this many messages per second on each high-rate key (hands/frame, gaze, "
        "gestures/static, robot/state) and the scene they imply; 0: every message"))

    def __post_init__(self):
        if not 0 <= self.ws_port <= 65535:
            raise ConfigError(f"ws_port={self.ws_port} must be a TCP port, 0..65535")
        if self.stream_hz < 0:
            raise ConfigError(f"stream_hz={self.stream_hz} must be 0 (every message) or more")
        if not self.ws_host:
            raise ConfigError("ws_host must be an address, e.g. 127.0.0.1 or 0.0.0.0")


class FoxgloveBridge(Service):
    """Serves the live traffic to Foxglove over its WebSocket protocol."""

    name = "foxglove-bridge"
    description = ("The live cbgo traffic as a Foxglove WebSocket server: every key as JSON "
                   "with its schema, plus 3D scene, frame transforms and a log.")
    settings_class = FoxgloveBridgeSettings

    def __init__(self, settings: FoxgloveBridgeSettings):
        super().__init__(settings)
        self.forwarder = Forwarder(settings.stream_hz)
        self.server = None
        self.channels: dict[str, object] = {}
        self._lock = threading.Lock()  # the counts are read by status on Zenoh's thread

    def setup(self, ctx) -> None:
        """Called once before the liveliness token: starts the server, subscribes to data."""
        import foxglove  # here, not at import: `--help` needs no server library

        self.ctx = ctx
        # Kept for the process's life: the channels are lost with their context.
        self.context = context = foxglove.Context()
        self._open_channels(foxglove, context, ctx.keys)
        s = self.settings
        try:
            self.server = foxglove.start_server(name="cbgo", host=s.ws_host, port=s.ws_port,
                                                context=context)
        except RuntimeError as e:
            raise ConfigError(f"cannot serve on {s.ws_host}:{s.ws_port} ({e}); is another "
                              "bridge running? choose another --ws-port") from None
        ctx.log.info("Foxglove WebSocket server on ws://%s:%d (open it in Foxglove: "
                     "Open connection > Foxglove WebSocket)", s.ws_host, self.server.port)
        for topic in keys.DATA_TOPICS:
            ctx.subscribe(topic, lambda msg, t=topic: self.on_message(t, msg))

    def _open_channels(self, foxglove, context, names: keys.Keys) -> None:
        schemas = {names.of(t): wire_schema(names, names.of(t))
                   for t in keys.TOPICS.values() if not t.query}
        schemas.update({topic: (name, foxglove_schema(name))
                        for topic, name in DERIVED_TOPICS.items()})
        for topic, (name, schema) in schemas.items():
            self.channels[topic] = foxglove.Channel(
                topic, message_encoding=MESSAGE_ENCODING, context=context,
                schema=foxglove.Schema(name=name, encoding=SCHEMA_ENCODING,
                                       data=json.dumps(schema).encode()))

    def on_message(self, topic: keys.Topic, message: dict) -> None:
        """Called for each valid message on a data key: logs it and what it implies."""
        now = time.time_ns()
        with self._lock:
            out = self.forwarder.forward(topic, self.ctx.keys.of(topic), message)
        for channel_topic, out_message in out:
            channel = self.channels[channel_topic]
            if channel.has_sinks():  # nobody watching: the state is kept, nothing encoded
                channel.log(encode(out_message), log_time=now)

    def status_extra(self) -> dict:
        """Returns the server's address and the counts per key (called on Zenoh's thread)."""
        with self._lock:
            counts = self.forwarder.counts.as_dict()
        port = self.server.port if self.server is not None else None
        return {"websocket": f"ws://{self.settings.ws_host}:{port}", **counts}

    def shutdown(self) -> None:
        """Called once when the process stops: closes the WebSocket server."""
        if self.server is not None:
            self.server.stop()


main = main_for(FoxgloveBridge)
