"""static-gesture: per frame and hand, the probability of every static gesture.

Behaviour (the contract is services/static_gesture/README.md; the design, with its reasons,
docs/design/static_gesture.md):
- for every hand of every ``cbgo/hands/frame``, the 57 features (right hands mirrored into the
  recordings' left-hand space) go through the model, a deep ensemble of Bayesian MLPs
  (`classifier`); all hands of a frame are one batch. One ``cbgo/gestures/static`` per hand: ``ts``
  and ``seq`` are the frame's (the moment the pose was seen, so consumers line gestures up with
  frames), ``hand_id`` and ``side`` the hand's, ``names``/``probs`` the model's full vector (with
  ``none``, the no-gesture class, when the model has it), ``model`` its id. There is no threshold:
  an uncertain hand gets its honest, flat vector. A frame with no hand gives no message;
- a hand whose fingers are moving is a pose forming, not held: each hand is followed by its
  side and id, and when its fingers moved more than ``--still-deg`` in the last 0.15 s (since
  its first frame, while it is younger) and its answer changed by ``--changed-tv`` its
  gestures fade into ``none``, wholly from ``--moving-deg`` (`motion`; 0 turns it off);
- ``--ignore`` names gestures the deployment does not use: their probability moves into
  ``none`` in every message (``names`` keep them, at 0), so that a pose meaning nothing here,
  an ok sign read as the paper's ``pinch`` for one, is no evidence of a gesture nobody made.
  A name the model lacks is a configuration error at start, and a reloaded model that lacks
  one is refused, the old model staying in service;
- the model: ``--model PATH``, else the own model of the person ``cbgo/user`` names
  (``cbgo gestures record NAME --static --user U --personal`` writes it) if they have one,
  else the user's model (``data_dir()/models/static-gesture``, what ``cbgo train static`` and
  ``cbgo gestures record`` write) if it exists, else the one shipped in the package. A model
  that does not load at start is a configuration error (exit 2);
- ``@ctl/static-gesture/reload`` loads the model again (optionally ``{model: PATH}`` to switch)
  and answers with its id; a model that does not load is an error reply and the old one keeps
  running. The model files are also polled every ``--watch-s`` seconds (their mtime and size;
  with no ``--model``, the default path is re-resolved each time, so the user's first own
  model is picked up): a change is loaded the same way, and a broken file is logged and counted
  once, the old model staying in service.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cbgo import keys, wire
from cbgo.config import data_dir
from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError
from cbgo.hands import features as F
from cbgo.model_store import WATCH_HELP, ModelStore, model_help
from cbgo.runtime import Service, main_for
from cbgo.services.static_gesture import invariant, motion
from cbgo.services.static_gesture.classifier import (
    DEFAULT_SAMPLES,
    MODEL_SUFFIXES,
    NONE,
    StaticClassifier,
    personal_model_path,
    shipped_model_path,
    user_model_path,
)
from cbgo.services.static_gesture.openset import fade_into_none

LOADED_MODELS = 8  # models kept loaded for people taking turns


@dataclass
class StaticGestureSettings:
    """Settings of static-gesture (flags ``--model`` ... or env ``CBGO_MODEL`` ...)."""

    model: str | None = field(default=None, metadata=_help(model_help(
        "model base path (.pt + .json)", "models/static-gesture", "one")))
    samples: int = field(default=DEFAULT_SAMPLES, metadata=_help(
        "posterior samples averaged per prediction, all the ensemble's networks together"))
    watch_s: float = field(default=1.0, metadata=_help(WATCH_HELP))
    still_deg: float = field(default=motion.STILL_DEG, metadata=_help(
        "a hand whose fingers moved less than this in the last 0.15 s keeps its answer "
        "(degrees, RMS over its 19 joint angles); more fades its gestures into none"))
    moving_deg: float = field(default=motion.MOVING_DEG, metadata=_help(
        "a hand whose fingers moved this much in the last 0.15 s is none: a pose forming, "
        "not held (degrees; 0: off, every frame read alone)"))
    changed_tv: float = field(default=motion.CHANGED_TV, metadata=_help(
        "only a hand whose answer changed this much in the last 0.15 s (total variation, "
        "0-1) is faded for its finger motion: a held pose's flicker keeps its answer "
        "(0: finger motion alone)"))
    ignore: list[str] = field(default_factory=list, metadata=_help(
        "gestures this deployment does not use, answered as none: their probability moves "
        "into none (comma-separated; e.g. pinch, where an ok sign means nothing)"))

    def __post_init__(self):
        if not 1 <= self.samples <= 1024:
            raise ConfigError(f"samples={self.samples} must be within 1-1024")
        if self.watch_s < 0:
            raise ConfigError(f"watch_s={self.watch_s} must be 0 (off) or positive")
        if self.moving_deg != 0 and not 0 <= self.still_deg < self.moving_deg:
            raise ConfigError(f"still_deg={self.still_deg} and moving_deg={self.moving_deg}: "
                              "need 0 <= still_deg < moving_deg, or moving_deg 0 (off)")
        if not 0 <= self.changed_tv <= 1:
            raise ConfigError(f"changed_tv={self.changed_tv} must be within 0-1 (0: finger "
                              "motion alone)")
        if NONE in self.ignore:
            raise ConfigError(f"ignore {self.ignore}: {NONE} is what ignored gestures become")


class StaticGesture(Service):
    """Classifies every hand of every frame into the static gestures."""

    name = "static-gesture"
    description = ("Publishes cbgo/gestures/static (per frame and hand: probabilities of every "
                   "static gesture from a Bayesian MLP) for each cbgo/hands/frame.")
    settings_class = StaticGestureSettings

    def __init__(self, settings: StaticGestureSettings):
        super().__init__(settings)
        self.classifier: StaticClassifier | None = None
        self.store: ModelStore | None = None
        self.hands = 0
        self.motion = motion.FingerMotion()
        self.moving = 0  # hands whose gestures faded for their fingers' motion
        self._loaded: dict[tuple, StaticClassifier] = {}
        self.user: str | None = None  # the person cbgo/user names

    def setup(self, ctx) -> None:
        """Called once before the service is announced alive: loads the model, declares I/O.

        A model that does not load raises `ConfigError` (the process exits with code 2).
        """
        self.ctx = ctx
        self.store = ModelStore(shipped_model_path(), user_model_path(), MODEL_SUFFIXES,
                                self.settings.model)
        path, stamps = self.store.snapshot()
        self._install(self._load(path), path, stamps)
        ctx.log.info("model %s loaded from %s: %s%s", self.classifier.model_id, path,
                     ", ".join(self.classifier.names),
                     f"; ignored: {', '.join(self.settings.ignore)}" if self.settings.ignore
                     else "")
        ctx.subscribe(keys.HANDS_FRAME, self.on_hands_frame)
        ctx.subscribe(keys.USER, self.on_user)
        ctx.publishes(keys.GESTURES_STATIC)
        ctx.control("reload", self.on_reload)
        if self.settings.watch_s > 0:
            ctx.every(self.settings.watch_s, self.on_watch)

    def _load(self, path: Path) -> StaticClassifier:
        """Loads a model and checks that it knows every ignored gesture.

        Raises:
            ConfigError: the model does not load, or lacks an ignored gesture or ``none``.
        """
        classifier = StaticClassifier.load(path, self.settings.samples)
        unknown = [g for g in self.settings.ignore if g not in classifier.names]
        if self.settings.ignore and (unknown or NONE not in classifier.names):
            raise ConfigError(f"ignore {', '.join(self.settings.ignore)}: model "
                              f"{classifier.model_id} ({path}) has no "
                              f"{', '.join(unknown) or NONE} among its classes "
                              f"{', '.join(classifier.names)}")
        return classifier

    def _install(self, classifier: StaticClassifier, path: Path, stamps: tuple) -> None:
        # The stamps were taken BEFORE loading (`ModelStore.snapshot`): files replaced meanwhile
        # are loaded again on the next poll (and the weights' hash refuses a mixed pair).
        self.classifier = classifier
        self.store.served(path, stamps)
        # People take turns: the models they were served stay loaded, so a turn is no reload
        self._loaded[(path, stamps)] = classifier
        while len(self._loaded) > LOADED_MODELS:
            self._loaded.pop(next(iter(self._loaded)))

    def on_hands_frame(self, msg: dict) -> list:
        """Called for each valid hands/frame: returns one gestures/static message per hand."""
        hands = msg["hands"]
        if not hands:
            return []
        x = F.hands_features(hands, to_recorded_side=True)
        bent = invariant.bends(x)  # once: the model reads them, and the motion rule
        probs = self.classifier.predict_features(x, bent=bent)
        ok = np.isfinite(probs).all(1)
        if not ok.all():  # degenerate geometry; the wire check cannot see it
            self.ctx.counters.add("rejected", int((~ok).sum()))
            self.ctx.rejects.warning("features", f"frame {msg['seq']}: a hand's features are "
                                     "not finite; hand skipped")
        if ok.any():
            probs[ok] = self._fade_moving([h for h, good in zip(hands, ok, strict=True) if good],
                                          msg["ts"], bent[ok], probs[ok])
            probs[ok] = self._ignored_into_none(probs[ok])
        self.hands += len(hands)
        clf = self.classifier
        return [(keys.GESTURES_STATIC, keys.GESTURES_STATIC.message(ts=msg["ts"], seq=msg["seq"],
            hand_id=hand["id"], side=hand["side"], names=clf.names,
            probs=row.tolist(), model=clf.model_id))
            for hand, row, good in zip(hands, probs, ok, strict=True) if good]

    def _fade_moving(self, hands: list[dict], ts: float, bent: np.ndarray, probs: np.ndarray
                     ) -> np.ndarray:
        """Returns the probabilities with changing hands' gestures faded into ``none``."""
        s = self.settings
        if s.moving_deg <= 0 or NONE not in self.classifier.names:
            return probs
        moved, changed = self.motion.measure(hands, ts, bent, probs)
        keep = motion.keep_share(moved, s.still_deg, s.moving_deg, changed, s.changed_tv)
        self.moving += int((keep < 1.0).sum())
        return fade_into_none(probs, keep, self.classifier.names.index(NONE))

    def _ignored_into_none(self, probs: np.ndarray) -> np.ndarray:
        """Returns the probabilities with the ignored gestures' moved into ``none``."""
        if not self.settings.ignore:
            return probs
        names = self.classifier.names
        ignored = [names.index(g) for g in self.settings.ignore]
        probs[:, names.index(NONE)] += probs[:, ignored].sum(1)
        probs[:, ignored] = 0.0
        return probs

    def on_user(self, msg: dict) -> None:
        """Called for each ``cbgo/user``: serves that person's own model if they have one."""
        self.user = msg["user"]
        personal = personal_model_path(self.user)
        if personal == self.store.personal:
            return
        self.store.personal = personal
        self.on_watch()

    def on_reload(self, query: dict) -> dict:
        """Called for each ``reload`` query: loads the model again (or ``{model: PATH}``).

        Raises:
            QueryError: the model does not load; the old one keeps serving.
        """
        path, stamps = self.store.reload_target(query)
        previous = self.classifier.model_id
        try:
            classifier = self._load(path)
        except ConfigError as e:
            self.ctx.counters.error("reload", str(e))
            raise QueryError(f"reload failed, still serving {previous}: {e}") from None
        if self.store.switch_to(query):
            self.settings.model = self.store.configured
        self._install(classifier, path, stamps)
        self.ctx.log.info("reloaded: %s -> %s (%s)", previous, classifier.model_id, path)
        return {"v": wire.SCHEMA_VERSION, "ok": True, "model": classifier.model_id,
                "previous": previous, "path": str(path), "names": classifier.names}

    def on_watch(self) -> None:
        """Called every ``--watch-s`` s and on a new user: reloads the model if it changed.

        It changed when its files did, or when another is to be served (a person's own).
        """
        if not self.store.changed():
            return
        path, stamps = self.store.snapshot()
        previous = self.classifier.model_id
        try:
            classifier = self._loaded.get((path, stamps)) or self._load(path)
        except ConfigError as e:
            self.store.served(path, stamps)  # report a broken file once
            self.ctx.counters.error("watch", str(e))
            self.ctx.log.error("model files changed but do not load; still serving %s: %s",
                               previous, e)
            return
        self._install(classifier, path, stamps)
        self.ctx.log.info("model files changed: %s -> %s (%s)", previous,
                          classifier.model_id, path)

    def status_extra(self) -> dict:
        """Adds the model, the hands classified and faded for moving, the ignored gestures.

        Also the data directory, where `cbgo gestures record` must write for the service to
        load what it teaches, the person `cbgo/user` names and whether their own model serves.
        """
        return {"model": self.classifier.describe() if self.classifier else None,
                "data_dir": str(data_dir()), "user": self.user,
                "personal": self.store is not None and self.store.personal is not None
                and self.store.served_path() == self.store.personal,
                "hands_classified": self.hands, "hands_moving": self.moving,
                "ignored": list(self.settings.ignore)}


main = main_for(StaticGesture)


if __name__ == "__main__":
    main()
