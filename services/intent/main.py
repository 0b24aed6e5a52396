"""intent: from the gesture vector and its context to the intended action, object and params.

Behaviour (the contract is services/intent/README.md):
- on each ``cbgo/episode/summary``, infers the intent from the summary's gesture vector, focus,
  params and user with the latest ``cbgo/scene/state``, and publishes it on ``cbgo/intent``
  (BLOCK: every summary gets exactly one intent, with a reason when nothing is to be done);
- answers ``cbgo/intent/infer`` queries the same way, the context given in the query;
  malformed queries are refused by the runtime, semantically bad ones with the reason;
- ``cbgo/intent/feedback`` corrects an earlier intent (by episode, else the user's last): the
  correction is stored and that user's model refitted (`personal`), which takes a second or
  two on the event loop;
- control verb ``@ctl/intent/last``: the last intent (optionally ``{user}``'s), its episode and
  user — what ``cbgo feedback`` corrects by default;
- the model (`cbgo.model_store`, the same rule as the gesture services'): ``--model``, else
  ``<data dir>/models/intent-ours`` once ``cbgo train intent`` wrote it, else the shipped one;
  its files are polled every ``--watch-s`` and ``@ctl/intent/reload`` reloads at once
  (optionally ``{model: PATH}``); a model that does not load keeps the old one in service. The
  intents already published stay correctable (the history moves to the new model).
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import torch

from cbgo import keys, wire
from cbgo.config import data_dir
from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError
from cbgo.model_store import WATCH_HELP, ModelStore, model_help
from cbgo.runtime import Service, main_for
from cbgo.services.intent import mapping as mapping_file
from cbgo.services.intent.decide import DecisionConfig
from cbgo.services.intent.engine import InputError, IntentEngine
from cbgo.services.intent.mapping import GestureMapping
from cbgo.services.intent.models import OursModel
from cbgo.services.intent.personal import PersonalStore

CLARIFY_CLOCK_S = 0.25  # how often open clarifications are checked for expiry


def default_model_path() -> Path:
    """Returns the shipped default model (``services/intent/models/ours``)."""
    return Path(str(resources.files("cbgo.services.intent").joinpath("models", "ours.json")))


def user_model_path(kind: str = "ours", env=None) -> Path:
    """Returns where `cbgo train intent` writes a model of `kind` (no suffix).

    ``<data dir>/models/intent-<kind>`` (``.pt`` + ``.json``), beside the static-gesture
    service's ``<data dir>/models/static-gesture``: trainers never write into the package.
    """
    return data_dir(env) / "models" / f"intent-{kind.lower()}"


def model_store(configured: str | None = None, env=None) -> ModelStore:
    """Returns where the served model comes from (`cbgo.model_store`)."""
    return ModelStore(default_model_path().with_suffix(""), user_model_path("ours", env),
                      (".pt", ".json"), configured)


def served_model_path(env=None) -> Path:
    """Returns the model the service serves by default: the user's trained one, else shipped.

    The user's is ``<data dir>/models/intent-ours`` when both its ``.pt`` and ``.json`` exist.
    """
    return model_store(env=env).path().with_suffix(".json")


@dataclass
class IntentSettings(DecisionConfig):
    """Settings of the intent service (flags ``--min-confidence`` ... or env ``CBGO_...``).

    The decision's own (``min_confidence``, ``accept_repairable``, ``pour_angle_deg``) are
    declared once, in `decide.DecisionConfig`, and inherited.
    """

    model: str | None = field(default=None, metadata=_help(model_help(
        "the model to serve (<base>.pt + <base>.json, from `cbgo train intent`)",
        "models/intent-ours", "services/intent/models/ours")))
    watch_s: float = field(default=1.0, metadata=_help(WATCH_HELP))
    posterior_samples: int = field(default=32, metadata=_help(
        "posterior samples averaged per prediction"))
    personalise: bool = field(default=True, metadata=_help(
        "learn from cbgo/intent/feedback corrections, per user"))
    personal_dir: str | None = field(default=None, metadata=_help(
        "where users' corrections and models live; default <data dir>/intent (CBGO_DATA_DIR)"))
    default_profile: str = field(default="user1", metadata=_help(
        "how a user the model does not know is read until they correct it"))
    update_steps: int = field(default=300, metadata=_help(
        "gradient steps of a personal model's fine-tuning"))
    clarify_timeout_s: float = field(default=20.0, metadata=_help(
        "an unanswered cbgo/intent/clarify expires after this many seconds (each step of the "
        "highlight restarts it); nothing moves"))

    def __post_init__(self):
        super().__post_init__()
        if not 1 <= self.posterior_samples <= 1024:
            raise ConfigError(f"posterior_samples={self.posterior_samples} must be within "
                              "1-1024")
        if self.update_steps < 1:
            raise ConfigError("update_steps must be at least 1")
        if self.watch_s < 0:
            raise ConfigError(f"watch_s={self.watch_s} must be 0 (off) or positive")
        if not 1.0 <= self.clarify_timeout_s <= 600.0:
            raise ConfigError(f"clarify_timeout_s={self.clarify_timeout_s} must be within "
                              "1-600")



class Intent(Service):
    """The intent service."""

    name = "intent"
    description = ("Infers the intended action, object and params from episode summaries and "
                   "their context; publishes cbgo/intent, answers cbgo/intent/infer.")
    settings_class = IntentSettings

    def __init__(self, settings: IntentSettings):
        super().__init__(settings)
        self.scene: dict[str, Any] | None = None
        self.user: str | None = None
        self.feedback = {"stored": 0, "refused": 0}
        # Mapping refits take seconds: one worker thread fits while the model in use serves.
        self.refits = ThreadPoolExecutor(1, thread_name_prefix="intent-refit")
        self.pending: dict[str, tuple[GestureMapping, int, Future, PersonalStore]] = {}

    def setup(self, ctx) -> None:
        """Loads the model and declares inputs, outputs, the infer queryable and ``last``.

        Called once before the service is announced alive.
        """
        torch.set_num_threads(1)  # tiny networks: threads only cost (2-core machines)
        self.ctx = ctx
        self.store = model_store(self.settings.model)
        path, stamps = self.store.snapshot()
        self.engine = self.build_engine(OursModel.load(path.with_suffix(".json")))
        self.store.served(path, stamps)
        ctx.subscribe(keys.SCENE_STATE, self.on_scene)
        ctx.subscribe(keys.USER, self.on_user)
        ctx.subscribe(keys.EPISODE_SUMMARY, self.on_summary)
        ctx.subscribe(keys.INTENT_FEEDBACK, self.on_feedback)
        ctx.subscribe(keys.INTENT_ANSWER, self.on_answer)
        ctx.queryable(keys.INTENT_INFER, self.on_infer)
        ctx.control("last", self.on_last)
        ctx.control("reload", self.on_reload)
        ctx.control("mapping", self.on_mapping)
        ctx.publishes(keys.INTENT, keys.INTENT_CLARIFY)
        if self.settings.watch_s > 0:
            ctx.every(self.settings.watch_s, self.on_watch)
        ctx.every(CLARIFY_CLOCK_S, self.on_clarify_clock)
        ctx.every(CLARIFY_CLOCK_S, self.collect_refits)
        ctx.log.info("serving model %s from %s", self.engine.model.name, path)

    def shutdown(self) -> None:
        """Called once at exit: a refit under way is abandoned (its file is read next start)."""
        self.refits.shutdown(wait=False, cancel_futures=True)

    def build_engine(self, model: OursModel) -> IntentEngine:
        """Returns the engine serving `model`, with the users' personal models on top of it."""
        s = self.settings
        personal = None
        if s.personalise:
            root = Path(s.personal_dir) if s.personal_dir else data_dir() / "intent"
            personal = PersonalStore(root, model, s.default_profile, s.update_steps,
                                     accept_repairable=s.accept_repairable)
        engine = IntentEngine(model, s.decision(), personal, s.posterior_samples,
                              s.default_profile)
        engine.clarifications.timeout_s = s.clarify_timeout_s
        return engine

    def _swap(self, path: Path) -> IntentEngine:
        """Loads the model at `path` and puts it in service; returns the previous engine.

        Raises:
            ConfigError: it does not load (the old one stays).
        """
        engine = self.build_engine(OursModel.load(path.with_suffix(".json")))
        previous, self.engine = self.engine, engine
        # the intents published so far stay correctable by cbgo feedback
        engine.history, engine.last, engine.last_by_user = (previous.history, previous.last,
                                                            previous.last_by_user)
        engine.clarifications = previous.clarifications  # open questions stay answerable
        return previous

    def on_reload(self, query: dict) -> dict:
        """Control verb ``reload``: loads the model again (or ``{model: PATH}``).

        Raises:
            QueryError: the model does not load; the old one keeps serving.
        """
        path, stamps = self.store.reload_target(query)
        try:
            previous = self._swap(path)
        except ConfigError as e:
            self.ctx.counters.error("reload", str(e))
            raise QueryError(f"reload failed, still serving {self.engine.model.name}: "
                             f"{e}") from None
        if self.store.switch_to(query):
            self.settings.model = self.store.configured
        self.store.served(path, stamps)
        self.ctx.log.info("reloaded: %s -> %s (%s)", previous.model.name,
                          self.engine.model.name, path)
        return {"v": wire.SCHEMA_VERSION, "ok": True, "model": self.engine.model.name,
                "previous": previous.model.name, "path": str(path)}

    def on_watch(self) -> None:
        """Called every ``--watch-s`` s: reloads users' mappings and the model that changed."""
        self.poll_mappings()
        if not self.store.changed():
            return
        path, stamps = self.store.snapshot()
        self.store.served(path, stamps)  # a broken file is reported once, not at each poll
        try:
            previous = self._swap(path)
        except ConfigError as e:
            self.ctx.counters.error("watch", str(e))
            self.ctx.log.error("model files changed but do not load; still serving %s: %s",
                               self.engine.model.name, e)
            return
        self.ctx.log.info("model files changed: %s -> %s (%s)", previous.model.name,
                          self.engine.model.name, path)

    def poll_mappings(self) -> None:
        """Puts changed mapping files in use; a bad one is refused, counted and logged."""
        personal = self.engine.personal
        if personal is None:
            return
        for user, error in personal.poll_mappings(self.refit_mapping):
            if error is not None:
                self.ctx.counters.error("mapping", error)
                self.ctx.log.error("mapping of %s refused, the one in use stays: %s", user,
                                   error)

    def refit_mapping(self, user: str, mapping: GestureMapping) -> None:
        """Fits the user's model to a new mapping on the worker thread (`collect_refits`)."""
        personal = self.engine.personal
        corrections = personal.corrections(user)
        future = self.refits.submit(personal.fitted, user, corrections, mapping)
        self.pending[user] = (mapping, len(corrections), future, personal)
        self.ctx.log.info("mapping of %s changed: %s; refitting the user's model", user,
                          "; ".join(r.label for r in mapping.rules) or "no rules")

    def collect_refits(self) -> None:
        """Puts the refits that finished in use (on the event loop, between intents)."""
        for user, (mapping, seen, future, personal) in list(self.pending.items()):
            if not future.done():
                continue
            del self.pending[user]
            if personal is not self.engine.personal:
                continue  # the model changed meanwhile: the new store reads the file itself
            try:
                fitted = future.result()
            except Exception as e:  # noqa: BLE001 - a failed fit keeps the model in use
                self.ctx.counters.error("mapping", f"refit of {user} failed: {e}")
                self.ctx.log.exception("refit of %s failed; the model in use stays", user)
                continue
            if len(personal.corrections(user)) != seen:  # a correction came in meanwhile
                self.refit_mapping(user, mapping)
                continue
            personal.install(user, mapping, fitted if (mapping or seen) else None)
            self.ctx.log.info("mapping of %s in use: %s", user,
                              "; ".join(r.label for r in mapping.rules) or "no rules")

    def on_mapping(self, query: dict) -> dict:
        """Control verb ``mapping``: shows or edits a user's mapping (the web page's table).

        ``{user, op: show|set|unset, gesture, action, on, state}``; set and unset write the
        user's mapping file and refit the model on the worker thread (the reply does not wait).

        Raises:
            QueryError: no user, an unknown op, a bad rule, a file that does not load.
        """
        personal = self.engine.personal
        if personal is None:
            raise QueryError("personalisation is off (--no-personalise): no mappings")
        user, op = query.get("user"), query.get("op", "show")
        if not isinstance(user, str) or not 0 < len(user) <= 64:
            raise QueryError("user: expected a user name of 1-64 characters")
        if op not in ("show", "set", "unset"):
            raise QueryError(f"op: expected show, set or unset, got {op!r}")
        if op != "show":
            self.edit_mapping(personal, user, op, query)
        return self.mapping_reply(personal, user)

    def edit_mapping(self, personal: PersonalStore, user: str, op: str, query: dict) -> None:
        """Applies a set or unset to the user's file, then refits (see `on_mapping`)."""
        path = personal.mapping_path(user)
        if path is None:
            raise QueryError("this service keeps no files (no personal dir)")
        gestures = self.engine.gestures
        personal.mapping(user)  # the mapping in use stays the file's old one until the refit
        fields = {k: query.get(k) for k in mapping_file.RULE_FIELDS}
        try:
            current = mapping_file.load(path, gestures)
            if op == "set":
                changed = current.with_rule(mapping_file.parse_rule(
                    {k: v for k, v in fields.items() if v is not None}, "rule", gestures))
            else:
                changed, removed = current.without(fields["gesture"], fields["on"],
                                                   fields["state"])
                if not removed:
                    raise QueryError(f"{user} has no rule for {fields['gesture']!r}"
                                     + (f" on {fields['on']}" if fields["on"] else "")
                                     + (f" ({fields['state']})" if fields["state"] else ""))
        except mapping_file.MappingError as e:
            raise QueryError(str(e)) from None
        mapping_file.save(path, changed)
        personal.mark_seen(user)
        self.refit_mapping(user, changed)

    def mapping_reply(self, personal: PersonalStore, user: str) -> dict:
        """The user's mapping: the file's rules, the ones in use, and what is under way."""
        path = personal.mapping_path(user)
        try:
            stated = mapping_file.load(path, self.engine.gestures) if path else None
        except mapping_file.MappingError:
            stated = None
        in_use = personal.mapping(user)
        pending = self.pending.get(user)
        return {"v": wire.SCHEMA_VERSION, "user": user,
                "rules": (in_use if stated is None else stated).to_dict()["rules"],
                "in_use": in_use.to_dict()["rules"],
                "refitting": pending is not None,
                "error": personal.mapping_errors.get(user),
                "path": None if path is None else str(path),
                "known": {"gestures": list(self.engine.gestures), "actions": list(wire.ACTIONS),
                          "states": {t: list(s) for t, s in mapping_file.STATE_NAMES.items()}}}

    def on_scene(self, msg: dict) -> None:
        """Keeps the latest scene for the next summary."""
        self.scene = msg

    def on_user(self, msg: dict) -> None:
        """Keeps who is operating (served in status)."""
        self.user = msg["user"]

    def on_summary(self, msg: dict):
        """Publishes the intent of a finished episode (marked replayed if its episode was).

        While the user has an open clarification, a thumbs-up or a swipe answers it (the
        episode's intent is then the confirmed one, or names the new highlight); any other
        gesture is a new request.
        """
        replayed = msg.get(wire.REPLAYED) is True  # from recorded hands: no planner may act
        self.engine.clarifications.cancel_others(msg["user"])
        answered = None if replayed else self.engine.answer_by_gesture(msg)
        intent = answered or self.engine.from_summary(msg, self.scene)
        if replayed:
            intent = {**intent, wire.REPLAYED: True}
        self.ctx.publish(keys.INTENT, intent)
        self.publish_clarifications()
        if answered is not None and answered["status"] == "accepted":
            self.learn(answered["clarification"])

    def on_answer(self, msg: dict) -> None:
        """Applies a clarification's answer; a confirmed one goes out as an accepted intent."""
        try:
            asked, intent = self.engine.answer(msg)
        except InputError as e:
            self.ctx.rejects.warning("answer", f"answer not applied: {e}")
            self.ctx.counters.add("rejected")
            return
        if intent is not None:
            self.ctx.publish(keys.INTENT, intent)
        self.publish_clarifications()
        self.ctx.log.info("clarification %s of %s: %s (%s)", asked.id, asked.user, asked.state,
                          asked.reason)
        if intent is not None:
            self.learn(asked.id)

    def learn(self, ident: str) -> None:
        """Stores a confirmed answer as a correction of the user's model (after publishing)."""
        asked = self.engine.clarifications.recent.get(ident)
        learnt = self.engine.learn_from(asked) if asked is not None else None
        if learnt is not None:
            self.feedback["stored"] += 1
            self.ctx.log.info("confirmed %s(%s) stored for %s; refitting on the worker thread",
                              learnt.action, learnt.object, learnt.user)
            self.refit_mapping(learnt.user, self.engine.personal.mapping(learnt.user))

    def on_clarify_clock(self) -> None:
        """Closes the clarifications whose time is up (nothing moves)."""
        for asked in self.engine.clarifications.expire():
            self.ctx.log.info("clarification %s of %s expired unanswered", asked.id, asked.user)
        self.publish_clarifications()

    def publish_clarifications(self) -> None:
        """Publishes every queued change of a clarification on ``cbgo/intent/clarify``."""
        for message in self.engine.clarifications.drain():
            self.ctx.publish(keys.INTENT_CLARIFY, message)

    def on_infer(self, query: dict) -> dict:
        """Answers ``cbgo/intent/infer``: the intent for the query's gesture vector and context.

        A query asks no one back: its clarification candidates are in ``reason``, none opens.
        """
        try:
            return self.engine.infer(query["gestures"], query["scene"], query["focus"],
                                     query["user"], query.get("params"), None,
                                     query.get("model"), ask=False)
        except InputError as e:
            raise QueryError(str(e)) from None

    def on_feedback(self, msg: dict) -> None:
        """Stores a correction and refits the user's model."""
        try:
            correction, personal = self.engine.correct(msg)
        except InputError as e:
            self.feedback["refused"] += 1
            self.ctx.rejects.warning("feedback", f"correction not applied: {e}")
            return
        self.feedback["stored"] += 1
        self.ctx.log.info("correction from %s: %s(%s) -> %s(%s); model %s (%s, %d corrections)",
                          correction.user, correction.predicted.get("action"),
                          correction.predicted.get("object"), correction.action,
                          correction.object, personal.model.name, personal.stage,
                          personal.corrections)

    def on_last(self, query: dict) -> dict:
        """Control verb ``last``: the last intent (of ``query.user`` if given)."""
        user = query.get("user")
        record = self.engine.last_by_user.get(user) if user else self.engine.last
        if record is None:
            return {"v": wire.SCHEMA_VERSION, "intent": None, "user": user, "episode": None}
        return {"v": wire.SCHEMA_VERSION, "intent": record.intent, "user": record.user,
                "episode": record.episode}

    def status_extra(self) -> dict:
        """Adds the served model, the current user and the corrections seen."""
        last = self.engine.last
        personal = self.engine.personal
        return {"model": self.engine.model.name, "user": self.user, "feedback": self.feedback,
                "mapping_errors": dict(personal.mapping_errors) if personal else {},
                "refitting": sorted(self.pending),
                "has_scene": self.scene is not None,
                "last_status": last.intent["status"] if last else None}


main = main_for(Intent)

if __name__ == "__main__":
    main()
