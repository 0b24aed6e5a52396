"""dynamic-gesture: strokes cut out of hand frames, classified against ProMP templates by DTW.

Behaviour (the contract is services/dynamic_gesture/README.md):
- every ``cbgo/hands/frame`` goes through the `stroke.Segmenter` (per hand id, on the frames'
  own ``ts`` clock): a stroke starts anywhere, from rest or slow motion, and ends when the hand
  slows down or turns back; the return move after a gesture is dropped (`stroke.ReturnFilter`);
- each evaluated window (every ``eval_period_s`` while a stroke runs, and at its end) is
  classified against the whole template library (`classifier.Classifier`) and published on
  ``cbgo/gestures/dynamic`` (a running stroke's window only when its top gesture has
  p ≥ `stroke.partial_p`): ``names`` are the templates plus ``none``, ``probs`` sum to 1,
  ``window`` is ``[t_start, t_end]`` in the frames' clock, ``seq`` counts publications;
- templates are the shipped defaults plus the user's (``<data dir>/gestures/dynamic/*.json``,
  taught with ``cbgo gestures record NAME --dynamic``); the control verb
  ``@ctl/dynamic-gesture/reload`` reloads them at once, and the default library
  (`cbgo.model_store`: ``--model``, else the one ``cbgo train dynamic`` wrote in the data dir,
  else the shipped one) and the user folder are polled every ``--watch-s`` for changes;
- while ``cbgo/user`` names a person calibrated with ``cbgo gestures calibrate``
  (``<data dir>/calibration/<user>.json``), strokes are judged by that person's slow-move
  lines (`pace`); the file is re-read when it changes.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cbgo import keys, wire
from cbgo.config import data_dir
from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError
from cbgo.model_store import WATCH_HELP, ModelStore, model_help
from cbgo.runtime import Service, main_for
from cbgo.services.dynamic_gesture.classifier import DTW_MODES
from cbgo.services.dynamic_gesture.library import (
    DEFAULT_PATH,
    Library,
    read_default,
    trained_path,
    user_dir,
)
from cbgo.services.dynamic_gesture.pace import Paces
from cbgo.services.dynamic_gesture.stroke import (
    ReturnFilter,
    Segmenter,
    SegmenterConfig,
    Window,
    reported,
)

MODEL = "promp-dtw-1"


@dataclass
class DynamicGestureSettings(SegmenterConfig):
    """Settings of dynamic-gesture: the segmenter's (see `stroke.SegmenterConfig`) and these."""

    model: str | None = field(default=None, metadata=_help(model_help(
        "the default template library (JSON)", "models/dynamic-gesture.json",
        "models/default.json")))
    user_dir: str | None = field(default=None, metadata=_help(
        "folder of user-taught gestures [default: <data dir>/gestures/dynamic, data dir from "
        "CBGO_DATA_DIR or ~/.local/share/cbgo]"))
    watch_s: float = field(default=2.0, metadata=_help(
        WATCH_HELP + "; also the user gestures"))
    dtw: str = field(default="exact", metadata=_help(
        "exact (fastdtw's compiled exact DTW, else vectorised numpy), numpy (always the "
        "numpy one) or fastdtw (approximate, radius 1)"))

    def __post_init__(self):
        super().__post_init__()
        if self.dtw not in DTW_MODES:
            raise ConfigError(f"dtw {self.dtw!r} is not one of {', '.join(DTW_MODES)}")
        if self.watch_s < 0:
            raise ConfigError(f"watch_s={self.watch_s} must not be negative (0 disables)")

    def segmenter(self) -> SegmenterConfig:
        """Returns the segmenter part of the settings."""
        names = SegmenterConfig.__dataclass_fields__
        return SegmenterConfig(**{name: getattr(self, name) for name in names})


class DynamicGesture(Service):
    """Segments strokes and publishes dynamic-gesture probabilities per evaluated window."""

    name = "dynamic-gesture"
    description = ("Cuts strokes out of cbgo/hands/frame and publishes cbgo/gestures/dynamic: "
                   "ProMP templates compared by dynamic time warping, calibrated probabilities.")
    settings_class = DynamicGestureSettings

    def __init__(self, settings: DynamicGestureSettings):
        super().__init__(settings)
        self.segmenter_config = settings.segmenter()  # the lines of a user without a pace
        self.segmenter = Segmenter(self.segmenter_config)
        self.paces = Paces(data_dir())
        self.user: str | None = None
        self.returns = ReturnFilter(settings.return_s)
        self.store = ModelStore(DEFAULT_PATH, trained_path(data_dir()), ("",), settings.model)
        self.library = Library(self.store.path(), Path(settings.user_dir) if settings.user_dir
                               else user_dir(data_dir()))
        self.classifier = None
        self.seq = 0
        self.windows = 0
        self.reloads = 0
        self.classify_ms: deque[float] = deque(maxlen=1000)

    def setup(self, ctx) -> None:
        """Loads the templates, subscribes to hand frames, declares reload and polling.

        Called once, before the liveliness token is declared.

        Raises:
            ConfigError: the default library is missing or malformed, or was learned with
                another roll scale than the one configured.
        """
        self.ctx = ctx
        _, _, data = read_default(self.library.default_path)
        scale = float(data.get("observation", {}).get("roll_scale_mm_per_rad", 0.0))
        if scale and abs(scale - self.settings.roll_scale_mm_per_rad) > 1e-9:
            raise ConfigError(f"roll_scale_mm_per_rad={self.settings.roll_scale_mm_per_rad} "
                              f"differs from the {scale} the templates were learned with")
        self._load()
        ctx.subscribe(keys.HANDS_FRAME, self.on_frame)
        ctx.subscribe(keys.USER, self.on_user)
        ctx.publishes(keys.GESTURES_DYNAMIC)
        ctx.control("reload", self.on_reload)
        if self.settings.watch_s > 0:
            ctx.every(self.settings.watch_s, self.poll)

    def _load(self) -> None:
        path, stamps = self.store.snapshot()
        self.library.default_path = path
        try:
            self.library.load()
        finally:
            self.store.served(path, stamps)  # a broken library is reported once, not each poll
        self.classifier = self.library.classifier(self.settings.dtw)
        self.returns.forget_running()  # their windows' probabilities were over the old names
        for name, reason in self.library.skipped.items():
            self.ctx.log.warning("skipped user gesture file %s: %s", name, reason)
        self.ctx.log.info("templates: %s", ", ".join(
            f"{t.name} ({t.source})" for t in self.library.templates))

    def on_frame(self, msg: dict) -> list:
        """Feeds one hand frame to the segmenter; returns a message per window to report.

        Windows of a return move (`stroke.ReturnFilter`) are not reported.
        """
        windows = self.segmenter.update(msg["ts"], msg["hands"])
        return [(keys.GESTURES_DYNAMIC, self.message(window, probs))
                for window, probs in reported(windows, self.returns, self.classify)]

    def on_user(self, msg: dict) -> None:
        """Judges strokes by the named person's pace from now on (the defaults without one)."""
        if msg["user"] != self.user:
            self.ctx.log.info("user %s", msg["user"])
        self.user = msg["user"]
        self._apply_pace()

    def _apply_pace(self) -> None:
        pace = self.paces.get(self.user) if self.user else None
        base = self.segmenter_config
        self.segmenter.retune(pace.applied(base) if pace else base)

    def classify(self, window: Window) -> np.ndarray:
        """Returns the probabilities of one window, timing the classification."""
        t0 = time.perf_counter()
        probs = self.classifier.classify(window)
        self.classify_ms.append((time.perf_counter() - t0) * 1e3)
        return probs

    def message(self, window: Window, probs: np.ndarray) -> dict:
        """Returns the ``cbgo/gestures/dynamic`` message of a classified window."""
        self.windows += 1
        msg = keys.GESTURES_DYNAMIC.message(ts=time.time(), seq=self.seq,
               hand_id=window.hand_id, side=window.side,
               names=list(self.classifier.names), probs=[float(p) for p in probs],
               window=[window.t_start, window.t_end], final=window.final, model=MODEL)
        self.seq += 1
        return msg

    def on_reload(self, _query: dict) -> dict:
        """Control verb ``reload``: re-reads the default and user templates.

        Raises:
            QueryError: the default library cannot be read (the old one stays in use).
        """
        try:
            self._load()
        except ConfigError as e:
            raise QueryError(str(e)) from None
        self.reloads += 1
        return {"v": wire.SCHEMA_VERSION, "ok": True, "gestures": self.library.names,
                "skipped": self.library.skipped, "model": MODEL}

    def poll(self) -> None:
        """Timer: reloads when the library or user gesture files were added, changed, removed.

        The current user's calibration is re-read too when its file changed.
        """
        self._apply_pace()
        if self.store.changed() or self.library.changed():
            self.ctx.log.info("templates changed; reloading")
            try:
                self._load()
                self.reloads += 1
            except ConfigError as e:
                self.ctx.counters.error("reload", str(e))

    def status_extra(self) -> dict:
        """Adds the templates in use, the data directory and the classification cost."""
        ms = np.asarray(self.classify_ms) if self.classify_ms else np.zeros(1)
        return {"gestures": [{"name": t.name, "source": t.source, "demos": t.n_demos}
                             for t in self.library.templates],
                "skipped": self.library.skipped, "strokes": self.segmenter.strokes,
                "user": self.user,
                # the slow-move lines and start speed in use: the user's pace, or the settings'
                "lines_mm_s": {"final": self.segmenter.config.min_peak_speed_mm_s,
                               "running": self.segmenter.config.mid_peak_speed_mm_s,
                               "first": self.segmenter.config.first_peak_speed_mm_s,
                               "start": self.segmenter.config.start_speed_mm_s},
                "calibration_skipped": self.paces.skipped,
                "tracking_jumps": self.segmenter.jumps,
                "returns": self.returns.returns,
                "windows": self.windows, "reloads": self.reloads,
                # where taught gestures are stored: `cbgo gestures record` must write there
                "data_dir": str(data_dir()),
                "dtw": self.classifier.implementation,
                "second_opinion": self.classifier.second_opinion,
                "classify_ms": {"p50": float(np.median(ms)),
                                "p99": float(np.percentile(ms, 99))}}


main = main_for(DynamicGesture)

if __name__ == "__main__":
    main()
