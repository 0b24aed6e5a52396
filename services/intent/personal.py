"""Personalisation: a user's corrections make that user's own model, learnt online.

Corrections are stored per user in ``<dir>/<user>/feedback.jsonl`` (one JSON object a line: the
inference input — gesture vector, scene, focus, params — the prediction, and the corrected
action and object), and the user's model in ``<dir>/<user>/model.pt`` + ``model.json``
(``<dir>`` is ``cbgo.config.data_dir()/intent`` by default). Each correction refits the user's
model from the default one and all of that user's corrections, in two stages:

1. **Profile.** The model reads a user as a vector over the known simulated users (one-hot for
   ``user1``/``user2``; a new user starts as the default profile). That vector, and nothing else,
   is fitted to the corrections (the networks frozen at their posterior mean): a user who
   gestures like another known user (D3's ``user2`` swaps left and right) is recognised from a
   handful of corrections, in every context at once.
2. **Fine-tuning**, only if some correction is still decided wrongly: a copy of the default
   networks is trained further (the same tempered ELBO) on the corrections, repeated to a third
   of the data, plus a replay of the profile's synthetic data (D4 drawn for the nearest known
   user, with repairable intents if the default model was trained with them, so that they are
   not forgotten) from which every observation is dropped whose context — target type, its
   state and the strongest gesture — a correction redefines.

A correction that names no object (moves, place, or the object left open) is learnt through the
marginal likelihood Σ_o p(object, action). A personal model is rebuilt from its feedback file
when the default model it was made from changes.
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from cbgo import bayes
from cbgo.errors import ConfigError
from cbgo.services.intent import datasets
from cbgo.services.intent.decide import DecisionConfig, decide
from cbgo.services.intent.models import Batch, OursModel, map_gestures, train_config
from cbgo.wire import ACTIONS
from cbgo.world import Scene

PROFILE_STEPS = 150
PROFILE_PRIOR = 0.01  # L2 pull of the profile logits towards the starting profile
REPLAY_SIZE = 600
CORRECTION_SHARE = 1 / 3


@dataclass
class Correction:
    """One correction with the input it corrects.

    Attributes:
        user: who corrected.
        action: the intended action.
        object: the intended object (None: not given, or the action ignores objects).
        gestures: the gesture vector of the corrected inference ({names, probs}).
        scene: its scene (contract scene body).
        focus: its focus point or None.
        params: its metric parameters.
        context_object: the object whose context the gesture was read in (the corrected
            object, else the most probable one at the time).
        episode: the corrected episode, if any.
        predicted: what had been decided ({action, object}).
        ts: when the correction arrived.
    """

    user: str
    action: str
    object: str | None
    gestures: dict[str, Any]
    scene: dict[str, Any]
    focus: list[float] | None
    params: dict[str, Any] = field(default_factory=dict)
    context_object: str | None = None
    episode: str | None = None
    predicted: dict[str, Any] = field(default_factory=dict)
    ts: float = 0.0

    def to_json(self) -> str:
        """Returns the correction as one JSON line (no newline)."""
        return json.dumps(asdict(self), separators=(",", ":"))

    @classmethod
    def from_json(cls, line: str) -> Correction:
        """Reads a line written by `to_json`."""
        return cls(**json.loads(line))


@dataclass
class Personal:
    """A user's model: the networks, the user vector they read the user as, how it was made."""

    model: OursModel
    user_vector: np.ndarray
    stage: str
    corrections: int


def safe_dirname(user: str) -> str:
    """Returns a directory name for a user id (other characters become '_', plus a hash)."""
    clean = re.sub(r"[^A-Za-z0-9_.\-]", "_", user)[:64]
    if clean == user and clean not in ("", ".", ".."):
        return clean
    return f"{clean}-{bayes.data_hash(np.frombuffer(user.encode(), np.uint8))[:8]}"


def trained_with_repairs(model: OursModel) -> bool:
    """Returns whether a model's training data held repairable intents (``--repairable``)."""
    return bool(model.meta.get("trained_on", {}).get("repairable", False))


def fingerprint(model: OursModel) -> str:
    """Returns a short hash of a model's weights (which default model a personal one extends)."""
    return bayes.data_hash(*[p.detach().numpy() for p in model.net.state_dict().values()])


class PersonalStore:
    """Per-user corrections and models on disk, loaded lazily and cached.

    Args:
        root: the directory of all users (None: keep everything in memory only).
        base: the default model.
        default_profile: the known user a new user starts as.
        steps: fine-tuning gradient steps per update.
        replay: replay observations for fine-tuning.
        seed: random seed of the replay and the training.
        accept_repairable: the service's decision lets repairable intents compete, so a
            correction naming one is explained once the model decides it that way.
    """

    def __init__(self, root: Path | None, base: OursModel, default_profile: str = "user1",
                 steps: int = 300, replay: int = REPLAY_SIZE, seed: int = 0,
                 accept_repairable: bool = False):
        self.root, self.base = root, base
        self.accept_repairable = accept_repairable
        self.users: list[str] = list(base.meta["users"])
        if default_profile not in self.users:
            raise ConfigError(f"default profile {default_profile!r} is not one of the model's "
                              f"users ({', '.join(self.users)})")
        self.default_profile, self.steps, self.replay, self.seed = (default_profile, steps,
                                                                    replay, seed)
        self.base_fingerprint = fingerprint(base)
        self._cache: dict[str, Personal | None] = {}
        self._memory: dict[str, list[Correction]] = {}
        self._replay: dict[str, datasets.Dataset] = {}

    def start_vector(self, user: str) -> np.ndarray:
        """Returns the user vector of a user without corrections."""
        profile = user if user in self.users else self.default_profile
        return np.eye(len(self.users))[self.users.index(profile)]

    def _dir(self, user: str) -> Path | None:
        return None if self.root is None else self.root / safe_dirname(user)

    def corrections(self, user: str) -> list[Correction]:
        """Returns a user's stored corrections, oldest first."""
        folder = self._dir(user)
        if folder is None:
            return list(self._memory.get(user, []))
        path = folder / "feedback.jsonl"
        if not path.exists():
            return []
        return [Correction.from_json(line) for line in path.read_text().splitlines() if line]

    def get(self, user: str) -> Personal | None:
        """Returns a user's personal model (None: the user has made no corrections)."""
        if user not in self._cache:
            self._cache[user] = self._load(user)
        return self._cache[user]

    def _load(self, user: str) -> Personal | None:
        folder = self._dir(user)
        if folder is not None and (folder / "model.json").exists():
            try:
                model = OursModel.load(folder / "model")
                if model.meta.get("base_fingerprint") == self.base_fingerprint:
                    return Personal(model, np.asarray(model.meta["user_vector"]),
                                    model.meta["stage"], int(model.meta["corrections"]))
            except ConfigError:
                pass  # unreadable: rebuild from the corrections below
        found = self.corrections(user)
        return self._update(user, found) if found else None

    def add(self, correction: Correction) -> Personal:
        """Stores a correction and refits that user's model; returns it."""
        folder = self._dir(correction.user)
        if folder is None:
            self._memory.setdefault(correction.user, []).append(correction)
        else:
            folder.mkdir(parents=True, exist_ok=True)
            with open(folder / "feedback.jsonl", "a") as f:
                f.write(correction.to_json() + "\n")
        self._cache[correction.user] = self._update(correction.user,
                                                    self.corrections(correction.user))
        return self._cache[correction.user]

    def _update(self, user: str, corrections: list[Correction]) -> Personal:
        personal = personalise(self.base, corrections, self.start_vector(user), self._replay_for,
                               steps=self.steps, seed=self.seed,
                               accept_repairable=self.accept_repairable)
        personal.model.meta.update(user=user, base_fingerprint=self.base_fingerprint,
                                   user_vector=personal.user_vector.tolist(),
                                   stage=personal.stage, corrections=personal.corrections,
                                   model_id=f"{self.base.name}+{user}", updated=time.time())
        folder = self._dir(user)
        if folder is not None:
            personal.model.save(folder / "model")
        return personal

    def _replay_for(self, user: str) -> datasets.Dataset:
        if user not in self._replay:
            self._replay[user] = datasets.make("D4", self.replay, self.seed, users=[user],
                                               repairable=trained_with_repairs(self.base))
        return self._replay[user]


# ==================================================================== fitting


def correction_batch(base: OursModel, corrections: Sequence[Correction]
                     ) -> tuple[Batch, np.ndarray, np.ndarray, list[Scene]]:
    """Returns the corrections as model input: batch, action, target slot (−1: none), scenes."""
    gestures = base.meta["gestures"]
    scenes = [Scene.from_dict(c.scene) for c in corrections]
    batches = [Batch.from_scene(s, map_gestures(c.gestures["names"], c.gestures["probs"],
                                                gestures),
                                np.zeros(len(base.meta["users"])), c.focus,
                                float(base.meta["cell_size_m"]))
               for s, c in zip(scenes, corrections, strict=True)]
    action = np.array([ACTIONS.index(c.action) for c in corrections])
    target = np.array([s.names.index(c.object) if c.object and s.has(c.object) else -1
                       for s, c in zip(scenes, corrections, strict=True)])
    return Batch.concat(batches), action, target, scenes


def explains(model: OursModel, batch: Batch, scenes: Sequence[Scene],
             corrections: Sequence[Correction], accept_repairable: bool = False) -> bool:
    """Returns whether the model now decides every correction as corrected."""
    joint = model.predict(batch, samples=16).joint
    config = DecisionConfig(min_confidence=0.0, accept_repairable=accept_repairable)
    for i, (scene, c) in enumerate(zip(scenes, corrections, strict=True)):
        d = decide(joint[i, :len(scene.objects)], scene.names, scene, config, c.params)
        if d.action != c.action or (c.object is not None and d.object not in (None, c.object)):
            return False
    return True


def fit_user_vector(model: OursModel, batch: Batch, action: np.ndarray, target: np.ndarray,
                    start: np.ndarray, steps: int = PROFILE_STEPS) -> np.ndarray:
    """Fits the user vector (softmax of logits) to corrections, the networks frozen."""
    logits0 = torch.as_tensor(np.log(np.clip(start, 0.02, None)), dtype=torch.float32)
    logits = logits0.clone().requires_grad_(True)
    optimiser = torch.optim.Adam([logits], lr=0.1)
    log_likelihood = model.user_likelihood(batch, action, target)
    for _ in range(steps):
        loss = -log_likelihood(torch.softmax(logits, 0)).mean() + PROFILE_PRIOR * (
            (logits - logits0) ** 2).sum()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    return torch.softmax(logits.detach(), 0).numpy().astype(np.float64)


def context_key(scene: Scene, obj: str | None, g: np.ndarray) -> tuple | None:
    """Returns (type, state bit, strongest gesture) of the object a gesture was read for."""
    if obj is None or not scene.has(obj):
        return None
    return scene.get(obj).type, scene.state_bit(obj), int(np.argmax(g))


def personalise(base: OursModel, corrections: Sequence[Correction], start: np.ndarray,
                replay_for, steps: int = 300, seed: int = 0,
                accept_repairable: bool = False) -> Personal:
    """Returns the personal model that explains `corrections` (see the module docstring).

    Args:
        base: the default model (not changed).
        corrections: the user's corrections.
        start: the user vector to start from (the user's profile).
        replay_for: known user name -> its replay `Dataset` (D4), for fine-tuning.
        steps: fine-tuning gradient steps.
        seed: training seed.
        accept_repairable: decide as the service does (see `PersonalStore`).
    """
    batch, action, target, scenes = correction_batch(base, corrections)
    user = fit_user_vector(base, batch, action, target, start)
    if explains(base, batch.with_user(user), scenes, corrections, accept_repairable):
        return Personal(base.copy(), user, "profile", len(corrections))
    model = base.copy()
    profile = base.meta["users"][int(np.argmax(user))]
    replay = replay_for(profile)
    keys = {context_key(s, c.object or c.context_object, batch.g[i])
            for i, (s, c) in enumerate(zip(scenes, corrections, strict=True))}
    keep = np.array([(datasets.OBJECT_TYPES[replay.obj_type[i, replay.target[i]]],
                      int(replay.obj_state[i, replay.target[i]]), int(np.argmax(replay.g[i])))
                     not in keys for i in range(len(replay))])
    replay_batch = Batch.from_dataset(replay.subset(np.flatnonzero(keep)))
    repeats = max(1, round(CORRECTION_SHARE * len(replay_batch.g) / (1 - CORRECTION_SHARE)
                           / len(corrections)))
    index = np.tile(np.arange(len(corrections)), repeats)
    data = Batch.concat([replay_batch, batch.subset(index)]).with_user(user)
    config = train_config(data.n, steps=steps, lr=0.005, seed=seed, time_limit_s=30.0)
    model.fit(data, np.concatenate([replay.action[keep], action[index]]),
              np.concatenate([replay.target[keep], target[index]]), config)
    return Personal(model, user, "finetuned", len(corrections))
