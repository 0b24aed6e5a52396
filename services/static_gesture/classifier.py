"""The static-gesture classifier: contract hands → 57 features → posterior-averaged probabilities.

Rules (the model files are written by ``cbgo.services.static_gesture.train``):

- A model is a ``cbgo.bayes`` deep ensemble of mean-field Bayesian MLPs (`bayes.BayesEnsemble`,
  ``members`` in the metadata; a file without it holds one `bayes.BayesMLP`) saved as ``<base>.pt``
  (state_dict) plus ``<base>.json`` (metadata). The metadata names everything needed to use it — the
  gesture ``names`` (output order, possibly with the no-gesture class ``none``), the ``inputs``
  (which of the 57 features feed the networks), the ``standardizer``, the ``feature_version`` — and
  pins the weights by their SHA-256 (``weights_sha256``, over the tensors, not the file). Loading
  checks all of it and refuses a model that does not fit (`ConfigError` naming the problem); the pin
  also catches a ``.pt`` and a ``.json`` from two different trainings, e.g. read while a trainer is
  replacing them.
- The model id is ``static-bnn-<first 8 hex of weights_sha256>``: the same weights give the same
  id on every machine.
- Features: ``cbgo.hands.features.hands_features(hands, to_recorded_side=True)``, so a right
  hand is mirrored into the left-hand space of the real recordings and one model serves both
  hands. The thumb-metacarpal features 2..5 follow the recording device's convention for a
  zero-length bone and are left out of ``inputs`` by the trainer (see ``train``).
- ``transform`` (optional): ``"invariant-1"`` makes the network read the 45 device-independent
  features derived from the 57 (``invariant.derive``), ``"invariant-2"`` the same with the
  proximal bones against the palm's axis (``invariant.derive_palm``), ``"invariant-3"`` those
  with each yaw difference as its sine and cosine (60, ``invariant.continuous``),
  ``"invariant-4"`` their proximal bones and distances with the joints' angles in 3-D (49,
  ``invariant.bends``), and
  ``inputs`` index those; absent or null, ``inputs`` index the 57 themselves (the trainer's
  ``raw`` feature set).
- Posterior averaging: at load, ``samples`` weight sets in all, shared out evenly among the
  members, are drawn from each member's variational posterior q(w) (seeded by the weights'
  hash, so the same model gives the same draws) and kept as stacked numpy arrays; a member's
  prediction is the mean of the softmax over its draws, and the model's the mean of its
  members'. Fixed
  draws make a frame's probabilities reproducible (the same hand twice gives the same vector)
  and keep the per-frame cost to a few matrix products (tens of µs for 32 draws on one frame;
  ``cbgo bench static`` prints the network's share) instead of torch's per-call overhead.
  Every row is renormalised in float64 so that it sums to 1 to rounding.
- Open set (optional, ``open_set`` in the metadata, written by the trainer for a model with
  ``none``: one rule per member, a list, or a single rule for a one-network model): a frame
  far, in a member's hidden layer, from every training gesture has that member's gestures'
  probabilities faded into ``none`` (`openset`), before the members are averaged. A malformed
  ``open_set`` refuses the model.
- Nothing here touches Zenoh; the service (``main``) wires it to the bus.
"""

from __future__ import annotations

import hashlib
import pickle
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import torch

from cbgo import bayes
from cbgo.config import data_dir
from cbgo.errors import ConfigError
from cbgo.hands import features as F
from cbgo.model_store import ModelStore
from cbgo.services.static_gesture import invariant
from cbgo.services.static_gesture.openset import OpenSet
from cbgo.wire import NO_GESTURE

KIND = "static-gesture"
NONE = NO_GESTURE  # the no-gesture class of the wire vocabulary: relaxed and transition poses
REJECT_BELOW = 0.5
"""A frame whose top probability is below this is no gesture, as if answered ``none`` (the
episode service's reading: its threshold, 0.6, is higher still)."""
MODEL_BASENAME = "static-gesture"
DEFAULT_SAMPLES = 32


def is_rejected(answer: np.ndarray, top: np.ndarray) -> np.ndarray:
    """Whether each answer is no gesture: ``none``, or a top probability below `REJECT_BELOW`.

    Args:
        answer: each frame's most probable name.
        top: its probability.
    """
    return (np.asarray(answer) == NONE) | (np.asarray(top) < REJECT_BELOW)


def answers(names: list[str], probs: np.ndarray) -> np.ndarray:
    """Returns each frame's answer as a consumer reads it: its top name, ``none`` if rejected."""
    top = np.array(names)[probs.argmax(-1)]
    return np.where(is_rejected(top, probs.max(-1)), NONE, top)


MODEL_SUFFIXES = (".pt", ".json")  # one model: weights and metadata beside each other


def shipped_model_path() -> Path:
    """Returns the base path of the default model shipped with the package (no suffix)."""
    root = resources.files("cbgo.services.static_gesture") / "models" / MODEL_BASENAME
    return Path(str(root))


def user_model_path(env: Any = None) -> Path:
    """Returns the base path of the user's own model: ``data_dir()/models/static-gesture``."""
    return data_dir(env) / "models" / MODEL_BASENAME


USER_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.@-]{0,63}$")
"""User names a personal model may be stored under (a name on ``cbgo/user`` is any string: one
with a slash or starting with a dot is served the model of every user)."""


def personal_model_path(user: str, env: Any = None) -> Path | None:
    """Returns the base path of one user's own model, None for a name no file may carry.

    ``data_dir()/calibration/static-gesture/<user>/model`` (``.pt`` and ``.json``), beside the
    user's dynamic calibration (``data_dir()/calibration/<user>.json``).
    """
    if not USER_NAME.match(user):
        return None
    return data_dir(env) / "calibration" / MODEL_BASENAME / user / "model"


def default_model_path(env: Any = None) -> Path:
    """Returns the model the service loads by default: the user's if present, else the shipped.

    Args:
        env: the environment to read ``CBGO_DATA_DIR`` from (os.environ by default).
    """
    return ModelStore(shipped_model_path(), user_model_path(env), MODEL_SUFFIXES).path()


def model_files(path: str | Path) -> tuple[Path, Path]:
    """Returns the ``.pt`` and ``.json`` files of a model path given with or without suffix."""
    base = Path(path)
    if base.suffix in (".pt", ".json"):
        base = base.with_suffix("")
    return base.with_suffix(".pt"), base.with_suffix(".json")


def weights_sha256(state_dict: dict) -> str:
    """Returns the hex SHA-256 of a network's weights: names, dtypes, shapes and values.

    Computed on the tensors, not on the ``.pt`` file (whose zip records the file's own name),
    so that the same weights have the same hash wherever and however they were saved.
    """
    h = hashlib.sha256()
    for name in sorted(state_dict):
        tensor = state_dict[name].detach().cpu().contiguous()
        h.update(f"{name}:{tensor.dtype}:{tuple(tensor.shape)};".encode())
        h.update(tensor.numpy().tobytes())
    return h.hexdigest()


def model_id_of(weights_sha256: str) -> str:
    """Returns the model id published in every message: ``static-bnn-<hash8>``."""
    return f"static-bnn-{weights_sha256[:8]}"


@dataclass
class Posterior:
    """Networks drawn from the variational posteriors of an ensemble's members, stacked.

    Every member contributes the same number of draws, member by member along S, so that one
    product per layer runs them all (an ensemble costs what one network with as many draws
    does).

    Attributes:
        weights: per layer, (S, n_in, n_out), S = members × draws per member.
        biases: per layer, (S, 1, n_out) (zeros for a layer without bias).
        activation: ``tanh`` or ``relu`` between layers.
        mean_first: the members' first-layer posterior mean weights side by side, (n_in, M·H),
            and biases (M·H,), for `embed`.
        members: M.
    """

    weights: list[np.ndarray]
    biases: list[np.ndarray]
    activation: str
    mean_first: tuple[np.ndarray, np.ndarray]
    members: int = 1

    @classmethod
    def draw(cls, networks: bayes.BayesMLP | list[bayes.BayesMLP], samples: int,
             seed: int) -> Posterior:
        """Draws ``samples`` weight sets w = mu + sigma·eps from every layer's q(w), per network.

        Network i draws from seed ``seed + i``. The draws are `cbgo.bayes.BayesMLP.draw`'s (the
        same ones torch's batched forward would use), kept transposed to (S, n_in, n_out) for
        numpy's x @ w.
        """
        networks = [networks] if isinstance(networks, bayes.BayesMLP) else list(networks)
        weights, biases, firsts = [], [], []
        for i, model in enumerate(networks):
            with torch.no_grad():
                draws = model.draw(samples, torch.Generator().manual_seed(seed + i))
            weights.append([w.transpose(1, 2).double().numpy() for w, _ in draws])
            biases.append([np.zeros((samples, 1, w.shape[1])) if b is None
                           else b[:, None, :].double().numpy() for w, b in draws])
            first = model.layers[0]
            firsts.append((first.w_mu.detach().double().numpy().T,
                           np.zeros(first.w_mu.shape[0]) if first.b_mu is None
                           else first.b_mu.detach().double().numpy()))
        return cls([np.concatenate(layer) for layer in zip(*weights, strict=True)],
                   [np.concatenate(layer) for layer in zip(*biases, strict=True)],
                   networks[0].arch.activation,
                   (np.concatenate([w for w, _ in firsts], axis=1),
                    np.concatenate([b for _, b in firsts])), len(networks))

    def __post_init__(self):
        # The first layer of all draws as one (n_in, S·n_out) matrix: one product for every
        # draw at once instead of S small ones (2× faster on batches, as fast on one frame).
        w = self.weights[0]
        self._first = np.ascontiguousarray(w.transpose(1, 0, 2).reshape(w.shape[1], -1))
        self._first_bias = self.biases[0].reshape(-1)

    def _first_layer(self, x: np.ndarray) -> np.ndarray:
        """Returns (S, N, H) first-layer pre-activations of every drawn network."""
        x = np.asarray(x, dtype=np.float64)
        samples = len(self.weights[0])
        return (x @ self._first + self._first_bias).reshape(len(x), samples, -1).transpose(1, 0, 2)

    def _activate(self, h: np.ndarray) -> np.ndarray:
        return np.tanh(h) if self.activation == "tanh" else np.maximum(h, 0.0)

    def embed(self, x: np.ndarray) -> np.ndarray:
        """Returns (M, N, H) first-layer activations at each member's posterior mean weights.

        What the open-set rule measures distances in: the same for a model whatever the number
        of draws it runs with.
        """
        w, b = self.mean_first
        h = self._activate(np.asarray(x, dtype=np.float64) @ w + b)
        return h.reshape(len(h), self.members, -1).transpose(1, 0, 2)

    def predict_members(self, x: np.ndarray) -> np.ndarray:
        """Returns (M, N, C) probabilities: each member's softmax averaged over its draws."""
        h = self._first_layer(x)
        for w, b in zip(self.weights[1:], self.biases[1:], strict=True):
            h = self._activate(h) @ w + b
        h = h - h.max(-1, keepdims=True)
        np.exp(h, out=h)
        h /= h.sum(-1, keepdims=True)
        probs = h.reshape(self.members, -1, *h.shape[1:]).mean(1)
        return probs / probs.sum(-1, keepdims=True)

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Returns (N, C) probabilities: the softmax averaged over every drawn network."""
        probs = self.predict_members(x).mean(0)
        return probs / probs.sum(-1, keepdims=True)


@dataclass
class StaticClassifier:
    """A loaded static-gesture model, ready to classify hands.

    Attributes:
        names: gesture names in output order.
        model_id: ``static-bnn-<hash8>``.
        metadata: the model's JSON metadata.
        posterior: the draws of every member of the ensemble.
        open_sets: each member's open-set rule (`openset`), from the metadata's ``open_set``;
            None each for a model without one or without ``none``.
        path: the base path it was loaded from (None when built in memory).
        samples: posterior draws asked for, all members together (each member draws its
            share rounded up: 32 over three members are 11 each).
    """

    names: list[str]
    model_id: str
    metadata: dict
    posterior: Posterior = field(repr=False)
    open_sets: list[OpenSet | None] = field(repr=False)
    inputs: np.ndarray = field(repr=False)
    mean: np.ndarray = field(repr=False)
    std: np.ndarray = field(repr=False)
    path: Path | None = None
    samples: int = DEFAULT_SAMPLES
    transform: str | None = None

    @classmethod
    def from_model(cls, model: bayes.BayesEnsemble | bayes.BayesMLP, metadata: dict,
                   samples: int = DEFAULT_SAMPLES, path: Path | None = None) -> StaticClassifier:
        """Builds a classifier from an ensemble (or one network) and its metadata (checked).

        Raises:
            ConfigError: the metadata is incomplete or does not fit the network.
        """
        check_metadata(metadata, model.arch)
        if samples < 1:
            raise ConfigError(f"samples must be at least 1, got {samples}")
        networks = list(model.members) if isinstance(model, bayes.BayesEnsemble) else [model]
        open_sets = _open_sets(metadata, len(networks), bayes.layer_sizes(model.arch)[1])
        sha = metadata["weights_sha256"]
        posterior = Posterior.draw(networks, -(-samples // len(networks)), int(sha[:8], 16))
        return cls(names=list(metadata["names"]), model_id=model_id_of(sha), metadata=metadata,
                   posterior=posterior, open_sets=open_sets,
                   inputs=np.asarray(metadata["inputs"], dtype=np.int64),
                   transform=metadata.get("transform"),
                   mean=np.asarray(metadata["standardizer"]["mean"], dtype=np.float64),
                   std=np.asarray(metadata["standardizer"]["std"], dtype=np.float64),
                   path=path, samples=samples)

    @classmethod
    def load(cls, path: str | Path, samples: int = DEFAULT_SAMPLES) -> StaticClassifier:
        """Loads a model saved by the trainer (path with or without suffix).

        Raises:
            ConfigError: missing or unreadable files, another kind of model, an old feature
                version, or a ``.pt`` that is not the one the ``.json`` was written with.
        """
        pt, js = model_files(path)
        try:
            model, meta = bayes.load_module(pt, build_network)
        except (pickle.UnpicklingError, EOFError, ValueError, TypeError, KeyError) as e:
            # load_module names missing files and misfits; a garbled file fails deeper.
            raise ConfigError(f"cannot load model {pt.with_suffix('')}: {type(e).__name__}: "
                              f"{str(e).splitlines()[0] if str(e) else ''}") from None
        if meta.get("kind") != KIND:
            raise ConfigError(f"{js} is not a {KIND} model (kind {meta.get('kind')!r})")
        if meta.get("weights_sha256") != weights_sha256(model.state_dict()):
            raise ConfigError(f"{pt} is not the weights file {js} was written with (SHA-256 "
                              "mismatch; being rewritten? retrain with `cbgo train static`)")
        try:
            return cls.from_model(model, meta, samples, pt.with_suffix(""))
        except (TypeError, ValueError, KeyError, AttributeError) as e:
            raise ConfigError(f"{js}: malformed metadata ({type(e).__name__}: {e})") from None

    def predict_features(self, features: np.ndarray, open_set: bool = True,
                         bent: np.ndarray | None = None) -> np.ndarray:
        """Returns (N, C) probabilities for (N, 57) features (already on the recorded side).

        The members' answers averaged, each with its open-set rule applied unless ``open_set``
        is False (the networks' own answer, for benches that show what the rule adds).
        ``bent``: the rows' `invariant.bends`, where the caller has computed them already.
        """
        x = np.atleast_2d(np.asarray(features, dtype=np.float64))
        if len(x) == 0:
            return np.zeros((0, len(self.names)))
        inputs = self.network_inputs(x, bent)
        probs = self.posterior.predict_members(inputs)
        if open_set and self.open_sets[0] is not None:
            none_index = self.names.index(NONE)
            probs = np.stack([rule.apply(p, hidden, none_index) for rule, p, hidden in zip(
                self.open_sets, probs, self.posterior.embed(inputs), strict=True)])
        probs = probs.mean(0)
        return probs / probs.sum(-1, keepdims=True)

    def network_inputs(self, features: np.ndarray, bent: np.ndarray | None = None
                       ) -> np.ndarray:
        """Returns what the network reads for (N, 57) features: derived, selected, standardised.

        ``bent``: the rows' `invariant.bends`, if computed already (`invariant.transform`).
        """
        x = np.atleast_2d(np.asarray(features, dtype=np.float64))
        if self.transform in invariant.TRANSFORMS:
            x = invariant.transform(x, self.transform, bent)
        return (x[:, self.inputs] - self.mean) / self.std

    def classify_hands(self, hands: list[dict]) -> np.ndarray:
        """Returns (N, C) probabilities for contract hands (both sides; one batch)."""
        if not hands:
            return np.zeros((0, len(self.names)))
        return self.predict_features(F.hands_features(hands, to_recorded_side=True))

    def describe(self) -> dict:
        """Returns what status replies show about the model."""
        return {"model": self.model_id, "path": str(self.path) if self.path else None,
                "names": self.names, "samples": self.samples,
                "members": self.posterior.members,
                "trained_at": self.metadata.get("trained_at"),
                "data_hash": self.metadata.get("data_hash"),
                "open_set": None if self.open_sets[0] is None else {
                    "neighbours": self.open_sets[0].neighbours, "alpha": self.open_sets[0].alpha,
                    "thresholds": [round(rule.threshold, 4) for rule in self.open_sets]}}


def build_network(meta: dict) -> bayes.BayesEnsemble | bayes.BayesMLP:
    """Returns the untrained network a model's metadata describes (for `bayes.load_module`)."""
    arch = bayes.Architecture(**meta["architecture"])
    if "members" not in meta:  # a model of one network
        return bayes.BayesMLP(arch)
    return bayes.BayesEnsemble(arch, int(meta["members"]))


def _open_sets(meta: dict, members: int, width: int) -> list[OpenSet | None]:
    """Returns each member's open-set rule from the metadata (None each: the model has none).

    Raises:
        ConfigError: malformed, or not one rule per member.
    """
    stored = meta.get("open_set")
    if stored is None or NONE not in meta["names"]:
        return [None] * members
    rules = stored if isinstance(stored, list) else [stored]
    if len(rules) != members:
        raise ConfigError(f"model open_set holds {len(rules)} rules for {members} networks; "
                          "retrain with `cbgo train static`")
    try:
        return [OpenSet.from_dict(rule, width) for rule in rules]
    except (KeyError, TypeError, ValueError) as e:
        raise ConfigError(f"model open_set is malformed ({type(e).__name__}: {e}); "
                          "retrain with `cbgo train static`") from None


REQUIRED_METADATA = ("kind", "names", "inputs", "standardizer", "feature_version",
                     "weights_sha256", "data_hash")


def check_metadata(meta: dict, arch: bayes.Architecture) -> None:
    """Checks that a model's metadata is complete and fits its network.

    Raises:
        ConfigError: naming the first problem found.
    """
    missing = [k for k in REQUIRED_METADATA if k not in meta]
    if missing:
        raise ConfigError(f"model metadata lacks {missing}; retrain with `cbgo train static`")
    if meta["feature_version"] != F.FEATURE_VERSION:
        raise ConfigError(f"model was trained on feature version {meta['feature_version']}, "
                          f"this cbgo computes version {F.FEATURE_VERSION}; retrain with "
                          "`cbgo train static`")
    names = meta["names"]
    if len(names) != arch.n_out or len(set(names)) != len(names) or not all(names):
        raise ConfigError(f"model names {names} do not match its {arch.n_out} outputs "
                          "(or are not unique)")
    transform = meta.get("transform")
    if transform is not None and transform not in invariant.TRANSFORMS:
        raise ConfigError(f"model feature transform {transform!r} is unknown to this cbgo "
                          f"(knows {', '.join(invariant.TRANSFORMS)}); retrain with "
                          "`cbgo train static`")
    width = F.N_FEATURES if transform is None else len(invariant.names_of(transform))
    inputs = meta["inputs"]
    if len(inputs) != arch.n_in or not all(0 <= int(i) < width for i in inputs):
        raise ConfigError(f"model inputs must be {arch.n_in} feature indices in 0..{width - 1}")
    std = meta["standardizer"]
    if len(std.get("mean", ())) != arch.n_in or len(std.get("std", ())) != arch.n_in:
        raise ConfigError(f"model standardizer must have {arch.n_in} means and stds")
    if min(std["std"]) <= 0:
        raise ConfigError("model standardizer has a non-positive std")
