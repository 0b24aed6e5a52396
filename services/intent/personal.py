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

A user's **stated mapping** (``mapping.yaml`` beside the corrections; `mapping`) is a prior
of that user's model: the model is always fine-tuned (stage ``mapped``) on a replay drawn from
the profile's table with the mapping's rules written in (plus observations drawn in the stated
contexts), with the corrections on top. Without a profile fit: the mapping, not the default
users, says what the gestures mean. A file that does not load is refused with the reason and
the mapping in use stays (after a restart, the one stored in the user's model metadata).

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
from cbgo.services.intent import mapping as mapping_file
from cbgo.services.intent.decide import DecisionConfig, decide
from cbgo.services.intent.mapping import GestureMapping, apply
from cbgo.services.intent.models import Batch, OursModel, map_gestures, train_config
from cbgo.wire import ACTIONS
from cbgo.world import Scene

PROFILE_STEPS = 150
PROFILE_PRIOR = 0.01  # L2 pull of the profile logits towards the starting profile
REPLAY_SIZE = 600
CORRECTION_SHARE = 1 / 3
# A stated mapping is a prior the model is fine-tuned to: more replay and steps than a
# correction's refit, so that it is followed from the first episode (>= 99 % of the stated
# contexts for the D4 users of `cbgo bench intent-mapping`; about 10 s on a 2-core CPU).
MAPPING_REPLAY = 1200
MAPPING_STEPS = 800
STATED_REPLAY = 150  # extra replay observations drawn in the contexts a mapping states


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
        self._mappings: dict[str, GestureMapping] = {}
        self._mapping_stamps: dict[str, tuple[int, int] | None] = {}
        self.mapping_errors: dict[str, str] = {}  # user -> why their file is not in use

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
        """Returns a user's personal model (None: no corrections and no mapping)."""
        if user not in self._cache:
            self._cache[user] = self._load(user)
        return self._cache[user]

    def _saved(self, user: str) -> OursModel | None:
        folder = self._dir(user)
        if folder is None or not (folder / "model.json").exists():
            return None
        try:
            model = OursModel.load(folder / "model")
        except ConfigError:
            return None  # unreadable: rebuilt from the corrections and the mapping
        return model if model.meta.get("base_fingerprint") == self.base_fingerprint else None

    def _load(self, user: str) -> Personal | None:
        saved = self._saved(user)
        mapping = self.mapping(user, saved)
        if saved is not None and saved.meta.get("mapping_key", "") == (
                mapping.key() if mapping else ""):
            return Personal(saved, np.asarray(saved.meta["user_vector"]), saved.meta["stage"],
                            int(saved.meta["corrections"]))
        found = self.corrections(user)
        return self._update(user, found) if found or mapping else None

    # ------------------------------------------------------------ the user's stated mapping

    def mapping_path(self, user: str) -> Path | None:
        """Where a user's mapping file lives (None: the store keeps nothing on disk)."""
        folder = self._dir(user)
        return None if folder is None else folder / mapping_file.FILE_NAME

    def mapping(self, user: str, saved: OursModel | None = None) -> GestureMapping:
        """Returns the mapping in use for a user, reading the file the first time.

        A file that does not load is refused (the reason in `mapping_errors`); the mapping
        the user's saved model was fitted to then stays in use.
        """
        if user not in self._mappings:
            path = self.mapping_path(user)
            self._mapping_stamps[user] = None if path is None else mapping_file.stamp(path)
            try:
                self._mappings[user] = GestureMapping() if path is None else mapping_file.load(
                    path, self.base.meta["gestures"])
                self.mapping_errors.pop(user, None)
            except mapping_file.MappingError as e:
                self.mapping_errors[user] = str(e)
                fitted = (saved or self._saved(user) or OursModel(meta={})).meta.get("mapping")
                self._mappings[user] = mapping_file.parse(fitted, self.base.meta["gestures"])
        return self._mappings[user]

    def set_mapping(self, user: str, mapping: GestureMapping) -> Personal | None:
        """Puts a mapping in use for a user (not written to disk) and refits their model."""
        found = self.corrections(user)
        personal = self.fitted(user, found, mapping) if found or mapping else None
        self.install(user, mapping, personal)
        return personal

    def install(self, user: str, mapping: GestureMapping, personal: Personal | None) -> None:
        """Puts a mapping and the model fitted to it (`fitted`; None: the default) in use."""
        self._mappings[user] = mapping
        self.mapping_errors.pop(user, None)
        self._cache[user] = personal
        folder = self._dir(user)
        if personal is not None and folder is not None:
            personal.model.save(folder / "model")

    def watched_users(self) -> list[str]:
        """Users whose mapping file may change: those seen, and every folder with a mapping."""
        users = set(self._mappings)
        if self.root is not None and self.root.is_dir():
            users |= {p.parent.name for p in self.root.glob(f"*/{mapping_file.FILE_NAME}")
                      if safe_dirname(p.parent.name) == p.parent.name}
        return sorted(users)

    def poll_mappings(self, refit=None) -> list[tuple[str, str | None]]:
        """Reloads the mapping files that changed; returns (user, error or None) for each.

        A changed file that loads is put in use and the user's model refitted (by
        ``refit(user, mapping)`` when given, e.g. on a worker thread, else at once); one that
        does not is refused with the reason and the mapping in use stays.
        """
        changes = []
        for user in self.watched_users():
            path = self.mapping_path(user)
            now = mapping_file.stamp(path)
            if user in self._mapping_stamps and now == self._mapping_stamps[user]:
                continue
            self._mapping_stamps[user] = now
            try:
                mapping = mapping_file.load(path, self.base.meta["gestures"])
            except mapping_file.MappingError as e:
                self.mapping(user)  # the one in use stays (read from the model if need be)
                self.mapping_errors[user] = str(e)
                changes.append((user, str(e)))
                continue
            if user in self._mappings and mapping == self._mappings[user]:
                self.mapping_errors.pop(user, None)
                continue
            (refit or self.set_mapping)(user, mapping)
            changes.append((user, None))
        return changes

    def add(self, correction: Correction) -> Personal:
        """Stores a correction and refits that user's model; returns it."""
        self.store(correction)
        self._cache[correction.user] = self._update(correction.user,
                                                    self.corrections(correction.user))
        return self._cache[correction.user]

    def store(self, correction: Correction) -> None:
        """Stores a correction without refitting (the caller refits, e.g. on a worker thread)."""
        folder = self._dir(correction.user)
        if folder is None:
            self._memory.setdefault(correction.user, []).append(correction)
        else:
            folder.mkdir(parents=True, exist_ok=True)
            with open(folder / "feedback.jsonl", "a") as f:
                f.write(correction.to_json() + "\n")

    def mark_seen(self, user: str) -> None:
        """Notes the mapping file as read (a change written by the service is not polled again)."""
        path = self.mapping_path(user)
        self._mapping_stamps[user] = None if path is None else mapping_file.stamp(path)

    def _update(self, user: str, corrections: list[Correction]) -> Personal:
        personal = self.fitted(user, corrections, self.mapping(user))
        folder = self._dir(user)
        if folder is not None:
            personal.model.save(folder / "model")
        return personal

    def fitted(self, user: str, corrections: list[Correction],
               mapping: GestureMapping) -> Personal:
        """Returns the user's model fitted to a mapping and corrections (seconds of work).

        Changes nothing the service reads (only the replay cache), so it may run on a worker
        thread while the model in use keeps serving; `install` then puts it in use.
        """
        steps = max(self.steps, MAPPING_STEPS) if mapping else self.steps
        personal = personalise(self.base, corrections, self.start_vector(user), self._replay_for,
                               steps=steps, seed=self.seed,
                               accept_repairable=self.accept_repairable, mapping=mapping)
        personal.model.meta.update(user=user, base_fingerprint=self.base_fingerprint,
                                   user_vector=personal.user_vector.tolist(),
                                   stage=personal.stage, corrections=personal.corrections,
                                   mapping=mapping.to_dict(),
                                   mapping_key=mapping.key() if mapping else "",
                                   model_id=f"{self.base.name}+{user}", updated=time.time())
        return personal

    def _replay_for(self, user: str, mapping: GestureMapping | None = None) -> datasets.Dataset:
        mapping = mapping or GestureMapping()
        key = f"{user}+{mapping.key()}" if mapping else user
        if key not in self._replay:
            size = max(self.replay, MAPPING_REPLAY) if mapping else self.replay
            self._replay[key] = mapped_replay(user, mapping, size, self.seed,
                                              trained_with_repairs(self.base))
        return self._replay[key]


def mapped_replay(profile: str, mapping: GestureMapping, n: int, seed: int,
                  repairable: bool) -> datasets.Dataset:
    """Returns D4 drawn for `profile` with the mapping's rules written into its table.

    With rules, `STATED_REPLAY` more observations are drawn among the contexts the rules
    cover (some, like pouring, are rare in random scenes), so the stated meanings are seen.
    """
    if not mapping:
        return datasets.make("D4", n, seed, users=[profile], repairable=repairable)
    tables = apply(datasets.load_tables(), profile, mapping)
    stated = {(t, bit, r.gesture) for r in mapping.rules for t, bit in r.contexts()}
    items = list(datasets.samples("D4", n, seed, users=[profile], repairable=repairable,
                                  tables=tables))
    items += datasets.samples("D4", STATED_REPLAY, seed + 1, users=[profile],
                              repairable=repairable, tables=tables,
                              only=lambda _a, t, bit, g: (t, bit, g) in stated)
    return datasets.to_dataset(items, {"dataset": "D4", "seed": seed, "n": len(items),
                                       "repairable": repairable, "mapping": mapping.key()})


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
    config = DecisionConfig(min_confidence=0.0, accept_repairable=accept_repairable,
                            clarify=False)
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
                accept_repairable: bool = False,
                mapping: GestureMapping | None = None) -> Personal:
    """Returns the personal model that explains `corrections` (see the module docstring).

    Args:
        base: the default model (not changed).
        corrections: the user's corrections (may be empty when a mapping is given).
        start: the user vector to start from (the user's profile).
        replay_for: (known user name, mapping) -> its replay `Dataset` (D4 drawn from that
            user's table with the mapping's rules written in), for fine-tuning.
        steps: fine-tuning gradient steps.
        seed: training seed.
        accept_repairable: decide as the service does (see `PersonalStore`).
        mapping: the user's stated mapping (`cbgo.services.intent.mapping`): a prior the
            model is always fine-tuned to, from the first episode on.
    """
    mapping = mapping or GestureMapping()
    if not corrections and not mapping:
        return Personal(base.copy(), start, "default", 0)
    found = correction_batch(base, corrections) if corrections else None
    user = start
    if found is not None and not mapping:
        batch, action, target, scenes = found
        user = fit_user_vector(base, batch, action, target, start)
        if explains(base, batch.with_user(user), scenes, corrections, accept_repairable):
            return Personal(base.copy(), user, "profile", len(corrections))
    profile = base.meta["users"][int(np.argmax(user))]
    model = finetune(base, user, replay_for(profile, mapping), corrections, found, steps, seed)
    return Personal(model, user, "mapped" if mapping else "finetuned", len(corrections))


def finetune(base: OursModel, user: np.ndarray, replay: datasets.Dataset,
             corrections: Sequence[Correction], found: tuple | None, steps: int,
             seed: int) -> OursModel:
    """Returns a copy of `base` trained further on the replay and the corrections.

    Replay observations whose context (target type, state, strongest gesture) a correction
    redefines are dropped; the corrections are repeated to `CORRECTION_SHARE` of the data.
    """
    model = base.copy()
    keep = np.ones(len(replay), bool)
    if found is not None:
        batch, _, _, scenes = found
        keys = {context_key(s, c.object or c.context_object, batch.g[i])
                for i, (s, c) in enumerate(zip(scenes, corrections, strict=True))}
        keep = np.array([replay_context(replay, i) not in keys for i in range(len(replay))])
    index = np.flatnonzero(keep)
    parts = [Batch.from_dataset(replay.subset(index))]
    actions, targets = [replay.action[index]], [replay.target[index]]
    if found is not None:
        batch, action, target, _ = found
        repeats = max(1, round(CORRECTION_SHARE * len(index) / (1 - CORRECTION_SHARE)
                               / len(corrections)))
        again = np.tile(np.arange(len(corrections)), repeats)
        parts.append(batch.subset(again))
        actions.append(action[again])
        targets.append(target[again])
    data = Batch.concat(parts).with_user(user)
    config = train_config(data.n, steps=steps, lr=0.005, seed=seed, time_limit_s=30.0)
    model.fit(data, np.concatenate(actions), np.concatenate(targets), config)
    return model


def replay_context(replay: datasets.Dataset, i: int) -> tuple[str, int, int]:
    """(type, state bit, strongest gesture) of a replay observation's target."""
    slot = replay.target[i]
    return (datasets.OBJECT_TYPES[replay.obj_type[i, slot]], int(replay.obj_state[i, slot]),
            int(np.argmax(replay.g[i])))
