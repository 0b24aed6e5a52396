"""The intent service's logic, without Zenoh: inputs → model → decision → intent message.

`IntentEngine.infer` takes the contract's inputs (a gesture vector ``{names, probs}``, a scene
body, a focus point, a user, params), checks what the schema cannot (semantics), runs the user's
model, decides, and returns the ``cbgo/intent`` message. It remembers the inputs of recent
inferences so that `IntentEngine.correct` can turn a ``cbgo/intent/feedback`` message into a
stored correction of the right observation.

Gesture names are matched to the model's vocabulary by name: unknown names are ignored, missing
gestures count 0, and the vector is normalised like the training data's. A user the model does
not know is read as the default profile until they correct it (`cbgo.services.intent.personal`).
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cbgo.services.intent.clarify import ANSWER_GESTURES, AnswerError, Clarification, Clarifications
from cbgo.services.intent.decide import DecisionConfig, action_params, decide
from cbgo.services.intent.models import Batch, OursModel, map_gestures
from cbgo.services.intent.personal import Correction, Personal, PersonalStore
from cbgo.wire import ACTIONS, SCHEMA_VERSION
from cbgo.world import OBJECT_AGNOSTIC, Scene

MODEL_ALIASES = ("default", "ours")
HISTORY = 64  # remembered inferences, for corrections by episode


class InputError(ValueError):
    """An input that is well-formed but cannot be interpreted (answered with an error)."""


@dataclass
class Record:
    """One inference as it was made: its input and the intent it produced."""

    user: str
    episode: str | None
    gestures: dict[str, Any]
    scene: dict[str, Any]
    focus: list[float] | None
    params: dict[str, Any]
    intent: dict[str, Any]
    context_object: str | None = None
    ts: float = field(default_factory=time.time)


class IntentEngine:
    """Inference, decision and corrections.

    Args:
        model: the default model.
        decision: the decision thresholds.
        personal: where users' corrections and models live (None: no personalisation).
        samples: posterior samples per prediction.
        default_profile: how users the model does not know are read.
    """

    def __init__(self, model: OursModel, decision: DecisionConfig | None = None,
                 personal: PersonalStore | None = None, samples: int = 32,
                 default_profile: str = "user1"):
        self.model, self.decision, self.personal = model, decision or DecisionConfig(), personal
        self.samples = samples
        self.gestures: list[str] = list(model.meta["gestures"])
        self.users: list[str] = list(model.meta["users"])
        self.default_profile = default_profile
        self.cell = float(model.meta["cell_size_m"])
        self.history: OrderedDict[str, Record] = OrderedDict()
        self.last_by_user: dict[str, Record] = {}
        self.last: Record | None = None
        self.clarifications = Clarifications()

    # ---------------------------------------------------------------- inputs

    def gesture_vector(self, gestures: Mapping[str, Any]) -> np.ndarray:
        """Returns g in the model's vocabulary.

        Raises:
            InputError: none of the model's gestures is named, or all of them have 0.
        """
        known = [n for n in gestures["names"] if n in self.gestures]
        if not known:
            raise InputError("gestures.names has none of the model's gestures (it knows "
                             f"{', '.join(self.gestures)})")
        g = map_gestures(gestures["names"], gestures["probs"], self.gestures)
        if not g.any():
            raise InputError(f"every known gesture ({', '.join(known)}) has probability 0")
        return g

    def user_model(self, user: str) -> tuple[OursModel, np.ndarray, Personal | None]:
        """Returns the model, the user vector and the personal model (if any) for a user."""
        personal = self.personal.get(user) if self.personal is not None else None
        if personal is not None:
            return personal.model, personal.user_vector, personal
        profile = user if user in self.users else self.default_profile
        return self.model, np.eye(len(self.users))[self.users.index(profile)], None

    @staticmethod
    def check_scene(scene_body: Mapping[str, Any]) -> Scene:
        """Returns the scene, or raises InputError naming its inconsistencies."""
        scene = Scene.from_dict(scene_body)
        problems = scene.problems()
        if problems:
            raise InputError("scene: " + "; ".join(problems[:3]))
        return scene

    @staticmethod
    def check_params(params: Mapping[str, Any]) -> None:
        """Raises InputError if a parameter the actions use has the wrong type."""
        for name in ("angle_deg", "distance"):
            value = params.get(name)
            if value is not None and (type(value) not in (int, float)):
                raise InputError(f"params.{name} must be a number, got {value!r}")
        if params.get("distance") is not None and not 0 < params["distance"] < 10:
            raise InputError(f"params.distance must be within (0, 10) m, got "
                             f"{params['distance']}")

    def check_model(self, name: str | None) -> None:
        """Raises InputError unless `name` is absent or names the served model."""
        if name is not None and name not in (*MODEL_ALIASES, self.model.name):
            raise InputError(f"unknown model {name!r}; this service serves "
                             f"{', '.join((self.model.name, *MODEL_ALIASES))}")

    # ---------------------------------------------------------------- inference

    def infer(self, gestures: Mapping[str, Any], scene: Mapping[str, Any],
              focus: list[float] | None, user: str, params: Mapping[str, Any] | None = None,
              episode: str | None = None, model: str | None = None,
              ask: bool = True) -> dict[str, Any]:
        """Returns the ``cbgo/intent`` message for one observation.

        With `ask`, an uncertain intent opens a clarification (`clarify`) and names it in
        ``clarification``; without (a query), its candidates are only in ``reason``.

        Raises:
            InputError: a semantically bad input (see the check_* methods).
        """
        params = dict(params or {})
        self.check_model(model)
        self.check_params(params)
        g = self.gesture_vector(gestures)
        world = self.check_scene(scene)
        net, user_vec, personal = self.user_model(user)
        name = net.name if personal is not None else self.model.name
        if not world.objects:
            message = self._message(episode, None, None, {}, {}, {}, 0.0, "infeasible",
                                    "the scene has no objects to read the gesture against",
                                    name)
            self._remember(Record(user, episode, dict(gestures), dict(scene), focus, params,
                                  message))
            return message
        batch = Batch.from_scene(world, g, user_vec, focus, self.cell)
        joint = net.predict(batch, samples=self.samples).joint[0]
        d = decide(joint, world.names, world, self.decision, params)
        status = "low_confidence" if d.status == "clarify" else d.status
        message = self._message(episode, d.action, d.object, d.params, d.p_action, d.p_object,
                                d.confidence, status, d.reason, name)
        context = d.object or (max(d.p_object, key=d.p_object.get) if d.p_object else None)
        record = Record(user, episode, dict(gestures), dict(scene), focus, params, message,
                        context)
        self._remember(record)
        if d.status == "clarify" and ask:
            asked = self.clarifications.ask(record, d.candidates, [
                action_params(c.action, params, self.decision.pour_angle_deg)
                for c in d.candidates])
            message["clarification"] = asked.id
        return message

    @staticmethod
    def _message(episode, action, obj, params, p_action, p_object, confidence, status, reason,
                 model) -> dict[str, Any]:
        return {"v": SCHEMA_VERSION, "ts": time.time(), "episode": episode, "action": action,
                "object": obj, "params": params, "p_action": p_action, "p_object": p_object,
                "confidence": confidence, "status": status, "reason": reason, "model": model}

    def _remember(self, record: Record) -> None:
        self.last = record
        self.last_by_user[record.user] = record
        if record.episode is not None:
            self.history[record.episode] = record
            self.history.move_to_end(record.episode)
            while len(self.history) > HISTORY:
                self.history.popitem(last=False)

    def from_summary(self, summary: Mapping[str, Any],
                     scene: Mapping[str, Any] | None) -> dict[str, Any]:
        """Returns the intent of an episode summary with the latest scene (never raises).

        A summary that cannot be read (no scene yet, no known gesture, an inconsistent scene)
        still gets an intent, with no action and the reason.
        """
        episode = summary["episode"]
        if scene is None:
            return self._message(episode, None, None, {}, {}, {}, 0.0, "infeasible",
                                 "no scene/state received yet", self.model.name)
        try:
            return self.infer(summary["gestures"], scene, summary.get("focus"), summary["user"],
                              summary.get("params"), episode)
        except InputError as e:
            status = "low_confidence" if str(e).startswith(("gestures", "every")) else \
                "infeasible"
            return self._message(episode, None, None, {}, {}, {}, 0.0, status,
                                 f"cannot read the episode: {e}", self.model.name)

    # ---------------------------------------------------------------- corrections

    def find(self, user: str, episode: str | None) -> Record | None:
        """Returns the inference a correction refers to: by episode, else the user's last."""
        if episode is not None and episode in self.history:
            return self.history[episode]
        return self.last_by_user.get(user)

    def correct(self, feedback: Mapping[str, Any]) -> tuple[Correction, Personal]:
        """Stores a ``cbgo/intent/feedback`` correction and updates the user's model.

        Raises:
            InputError: nothing to correct, an unknown action, or an object not in that scene,
                or personalisation is off.
        """
        if self.personal is None:
            raise InputError("personalisation is off (--no-personalise)")
        user, episode = feedback["user"], feedback.get("episode")
        record = self.find(user, episode)
        if record is None:
            raise InputError(f"no intent of user {user!r}" + (
                f" or episode {episode!r}" if episode else "") + " to correct")
        action, obj = feedback["action"], feedback.get("object")
        if action not in ACTIONS:
            raise InputError(f"unknown action {action!r} (known: {', '.join(ACTIONS)})")
        names = [o["name"] for o in record.scene.get("objects", [])]
        if obj is not None and obj not in names:
            raise InputError(f"object {obj!r} is not in the corrected scene ({', '.join(names)})")
        if action in OBJECT_AGNOSTIC:
            obj = None
        correction = Correction(
            user=user, action=action, object=obj, gestures=record.gestures, scene=record.scene,
            focus=record.focus, params=record.params, context_object=obj or record.context_object,
            episode=record.episode, predicted={"action": record.intent["action"],
                                               "object": record.intent["object"]},
            ts=time.time())
        return correction, self.personal.add(correction)

    # ---------------------------------------------------------------- asking back

    def answer(self, answer: Mapping[str, Any]) -> tuple[Clarification, dict[str, Any] | None]:
        """Applies a ``cbgo/intent/answer``: returns the clarification and the intent to publish.

        The intent, only when confirmed, is the accepted intent of the clarified episode.

        Raises:
            InputError: an unknown or closed clarification, another user's, a bad answer.
        """
        asked = self.clarifications.open.get(answer["id"])
        if asked is not None and asked.user != answer["user"]:
            raise InputError(f"clarification {answer['id']!r} asks {asked.user!r}, not "
                             f"{answer['user']!r}")
        try:
            asked = self.clarifications.answer(answer["id"], answer["answer"],
                                               answer.get("choice"))
        except AnswerError as e:
            raise InputError(str(e)) from None
        return asked, self._confirmed(asked, asked.record.episode)

    def answer_by_gesture(self, summary: Mapping[str, Any]) -> dict[str, Any] | None:
        """Returns the intent of a summary that answers the user's open clarification.

        While a clarification is open, the user's next gesture answers it when it is one of
        `ANSWER_GESTURES` (its strongest gesture): a thumbs-up gives the accepted intent of the
        highlighted candidate, a swipe a ``low_confidence`` intent that names the new highlight.
        Any other gesture returns None: it is read as a new request (which cancels the question).
        """
        asked = self.clarifications.of_user(summary["user"])
        if asked is None:
            return None
        try:
            g = self.gesture_vector(summary["gestures"])
        except InputError:
            return None
        answer = ANSWER_GESTURES.get(self.gestures[int(np.argmax(g))])
        if answer is None:
            return None
        self.clarifications.answer(asked.id, answer)
        episode = summary["episode"]
        confirmed = self._confirmed(asked, episode)
        if confirmed is not None:
            return confirmed
        shown = asked.candidates[asked.highlighted]
        return {**self._message(episode, None, None, {}, {}, {}, shown.p, "low_confidence",
                                f"answer to clarification {asked.id}: {answer}; highlighted "
                                f"{shown.label}", self.model.name), "clarification": asked.id}

    def _confirmed(self, asked: Clarification, episode: str | None) -> dict[str, Any] | None:
        if asked.state != "confirmed" or asked.chosen is None:
            return None
        chosen = asked.candidates[asked.chosen]
        intent = asked.record.intent
        return {**self._message(episode, chosen.action, chosen.object, asked.params[asked.chosen],
                                intent["p_action"], intent["p_object"], chosen.p, "accepted",
                                f"{chosen.label} confirmed by {asked.user} (asked with "
                                f"p={chosen.p:.2f})", intent["model"]),
                "clarification": asked.id}

    def learn_from(self, asked: Clarification) -> Correction | None:
        """Stores a confirmed answer as a correction of the user's model (None: not learnt).

        The confirmed candidate is what the gesture meant, in the scene it was made in. The
        model is not refitted here: the service refits on its worker thread, so that the
        next episode (often another user's) is not kept waiting for seconds.
        """
        if self.personal is None or asked.chosen is None:
            return None
        chosen, record = asked.candidates[asked.chosen], asked.record
        correction = Correction(
            user=record.user, action=chosen.action, object=chosen.object,
            gestures=record.gestures, scene=record.scene, focus=record.focus,
            params=record.params, context_object=chosen.object or record.context_object,
            episode=record.episode, predicted={"action": None, "object": None}, ts=time.time())
        self.personal.store(correction)
        return correction
