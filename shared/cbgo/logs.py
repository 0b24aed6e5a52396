"""Structured logging: every line names its service; text for people, JSON for collectors.

Text:  ``2026-11-21T22:51:00.123 INFO  static-gesture  model loaded  path=... classes=8``
JSON:  ``{"ts": 1763765460.123, "level": "info", "service": "static-gesture",
"msg": "model loaded", "path": "...", "classes": 8}``

Structured fields are passed as ``extra={"fields": {...}}`` or through `kv()`.
`RateLimited` keeps a flood of identical warnings (a sender spamming bad frames) from drowning
the log: the first few are logged, then one summary per interval.
"""

from __future__ import annotations

import json
import logging
import sys
import threading
import time
from typing import Any

_LEVELS = {"debug": logging.DEBUG, "info": logging.INFO, "warning": logging.WARNING,
           "error": logging.ERROR}


def kv(**fields: Any) -> dict:
    """Returns the `extra` argument that attaches structured fields to a log record."""
    return {"fields": fields}


class _TextFormatter(logging.Formatter):
    def __init__(self, service: str):
        super().__init__()
        self.service = service

    def format(self, record: logging.LogRecord) -> str:
        stamp = time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime(record.created))
        fields = getattr(record, "fields", None) or {}
        tail = "".join(f"  {k}={v}" for k, v in fields.items())
        line = (f"{stamp}.{int(record.msecs):03d} {record.levelname:<7} {self.service}  "
                f"{record.getMessage()}{tail}")
        if record.exc_info:
            line += "\n" + self.formatException(record.exc_info)
        return line


class _JsonFormatter(logging.Formatter):
    def __init__(self, service: str):
        super().__init__()
        self.service = service

    def format(self, record: logging.LogRecord) -> str:
        entry = {"ts": round(record.created, 6), "level": record.levelname.lower(),
                 "service": self.service, "msg": record.getMessage(),
                 **(getattr(record, "fields", None) or {})}
        if record.exc_info:
            entry["exc"] = self.formatException(record.exc_info)
        return json.dumps(entry, default=str)


def setup_logging(service: str, level: str = "info", fmt: str = "text") -> logging.Logger:
    """Configures the root logger for one process and returns the service's logger.

    Logs go to stderr (stdout stays free for command output).
    """
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_JsonFormatter(service) if fmt == "json" else _TextFormatter(service))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(_LEVELS[level])
    return logging.getLogger(f"cbgo.{service}")


class RateLimited:
    """Logs the first `burst` events of a kind, then at most one summary per `interval_s`.

    Args:
        log: the logger to write to.
        burst: how many events of one kind are logged individually.
        interval_s: how often a summary of the suppressed ones is written.
    """

    def __init__(self, log: logging.Logger, burst: int = 5, interval_s: float = 10.0):
        self.log, self.burst, self.interval_s = log, burst, interval_s
        self._lock = threading.Lock()
        self._seen: dict[str, int] = {}
        self._suppressed: dict[str, int] = {}
        self._last_summary: dict[str, float] = {}

    def warning(self, kind: str, message: str, **fields: Any) -> None:
        """Logs one event of `kind` unless its burst is used up; summarises the rest."""
        now = time.monotonic()
        with self._lock:
            seen = self._seen[kind] = self._seen.get(kind, 0) + 1
            if seen > self.burst:
                self._suppressed[kind] = self._suppressed.get(kind, 0) + 1
                if now - self._last_summary.get(kind, 0.0) < self.interval_s:
                    return
                hidden, self._suppressed[kind] = self._suppressed[kind] - 1, 0
                self._last_summary[kind] = now
                if hidden:
                    message = f"{message} ({hidden} more like it were not logged)"
        self.log.warning(message, extra=kv(**fields))
