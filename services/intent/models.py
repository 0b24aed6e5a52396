"""Intent models, all Bayesian (mean-field Gaussian weights, Normal priors, VI; `cbgo.bayes`).

Input for every model is a `Batch`: per observation the gesture vector g, the user (one-hot
over the known users, or a soft mix of them), the focus point and the scene's objects
(type, state bit, held, position) padded to K slots.

**The paper's M1–M5** (`SlotModel`) read objects through fixed slots, as the paper's code did:
slot i is the i-th object of the scene list, so their inputs depend on the object order.

=====  =================================================  =============
model  input                                              hidden (tanh)
=====  =================================================  =============
M1     g                                                  25
M2     g + focus field per slot                           25, 25
M3     g + user                                           25, 25
M4     g + focus field + user                             25, 25
M5     g + focus field + user + state bit per slot        25, 25
=====  =================================================  =============

The focus field of a slot is exp(−d⁴ / (2·0.2²)), d the object's distance to the focus in grid
cells (the paper's code); empty slots are 0. Output: p(action) over the eleven actions.

**cbgo's model** (`OursModel`) is invariant to the order and number of objects. Two Bayesian
networks share one posterior sample per scene:

- an object scorer s(o) applied to every object — inputs: type × state one-hot, held, hidden
  (inside a closed drawer), the focus distance (d, d², d − min d, exp(−d²/(2·0.25²)), nearest,
  and the Gaussian log-likelihood −d²/(2·0.1²); all 0 with ``has_focus`` 0 when there is no
  focus), g and the user (g and user standardised) — with p(object) = softmax over the scene's
  objects;
- an action head p(action | object) from the candidate object's type × state and held, g and
  the user.

The joint is p(action, object) = p(object) · p(action | object); moves and place, which ignore
the object, are scored by their marginal Σ_o p(action, o) (`cbgo.services.intent.decide`).
Training maximises the ELBO of log p(target) + log p(action | target) (the target of a move or
place being the object looked at); a target of −1 (a correction without an object) uses the
marginal log Σ_o p(action, o). Predictions average the joint over posterior samples, drawn
all at once and evaluated in one batched pass (`IntentNet.forward_drawn`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from cbgo import bayes
from cbgo.errors import ConfigError
from cbgo.wire import ACTIONS, OBJECT_TYPES
from cbgo.world import Scene

N_ACTIONS = len(ACTIONS)
FIELD_WIDTH = 0.2  # the paper's focus field: exp(-d^4 / (2 * 0.2^2)), d in grid cells
SCORER_SIGMA = 0.25  # grid cells: the soft-nearest feature of cbgo's object scorer
FOCUS_SIGMA = 0.1  # grid cells: the focus noise the scorer's log-likelihood feature assumes
LOGLIK_FLOOR = -50.0
SLOT_KINDS = ("M1", "M2", "M3", "M4", "M5")
SLOT_INPUTS = {"M1": ("g",), "M2": ("g", "field"), "M3": ("g", "user"),
               "M4": ("g", "field", "user"), "M5": ("g", "field", "user", "state")}
SLOT_HIDDEN = {"M1": [25], "M2": [25, 25], "M3": [25, 25], "M4": [25, 25], "M5": [25, 25]}
MODEL_KINDS = (*SLOT_KINDS, "ours")


@dataclass
class Batch:
    """Model input for N observations with objects padded to K slots.

    Attributes:
        g: (N, G) gesture vectors.
        user: (N, U) user vectors (one-hot over the known users, or a soft mix).
        focus: (N, 3) focus points (m); ignored where ``has_focus`` is False.
        has_focus: (N,) whether a focus point is known.
        obj_type: (N, K) index into `OBJECT_TYPES`, −1 for an empty slot.
        obj_state: (N, K) state bit.
        obj_held: (N, K) held by the robot.
        obj_hidden: (N, K) inside a closed drawer.
        obj_pos: (N, K, 3) positions (m).
        cell: the grid cell size (m) distances are measured in.
    """

    g: np.ndarray
    user: np.ndarray
    focus: np.ndarray
    has_focus: np.ndarray
    obj_type: np.ndarray
    obj_state: np.ndarray
    obj_held: np.ndarray
    obj_hidden: np.ndarray
    obj_pos: np.ndarray
    cell: float

    @property
    def n(self) -> int:
        """Number of observations."""
        return len(self.g)

    @property
    def mask(self) -> np.ndarray:
        """(N, K) True where a slot holds an object."""
        return self.obj_type >= 0

    def subset(self, index: np.ndarray) -> Batch:
        """Returns the observations at `index`."""
        return Batch(**{k: (v[index] if isinstance(v, np.ndarray) else v)
                        for k, v in self.__dict__.items()})

    def with_user(self, user: np.ndarray) -> Batch:
        """Returns the same observations with every user vector replaced by `user`."""
        out = self.subset(np.arange(self.n))
        out.user = np.broadcast_to(np.asarray(user, np.float32), self.user.shape).copy()
        return out

    @classmethod
    def from_scene(cls, scene: Scene, g: np.ndarray, user: np.ndarray,
                   focus: Sequence[float] | None, cell: float) -> Batch:
        """Builds a one-observation batch from a scene (objects in scene order, K = their count).

        Args:
            scene: the world.
            g: (G,) gesture vector in the model's gesture order.
            user: (U,) user vector.
            focus: the focus point, or None when unknown.
            cell: grid cell size (m).
        """
        objects = scene.objects
        return cls(
            g=np.asarray(g, np.float32)[None], user=np.asarray(user, np.float32)[None],
            focus=np.asarray(focus if focus is not None else (0.0, 0.0, 0.0), np.float32)[None],
            has_focus=np.array([focus is not None]),
            obj_type=np.array([[OBJECT_TYPES.index(o.type) for o in objects]], np.int64
                              ).reshape(1, len(objects)),
            obj_state=np.array([[scene.state_bit(o.name) for o in objects]], np.float32
                               ).reshape(1, len(objects)),
            obj_held=np.array([[scene.is_held(o.name) for o in objects]], np.float32
                              ).reshape(1, len(objects)),
            obj_hidden=np.array([[scene.is_hidden(o.name) for o in objects]], np.float32
                                ).reshape(1, len(objects)),
            obj_pos=np.array([[o.position for o in objects]], np.float32).reshape(
                1, len(objects), 3),
            cell=cell)

    @classmethod
    def concat(cls, batches: Sequence[Batch], k: int | None = None) -> Batch:
        """Stacks batches, padding their objects to k slots (the largest by default)."""
        k = k or max(b.obj_type.shape[1] for b in batches)

        def pad(a: np.ndarray, value: float) -> np.ndarray:
            width = [(0, 0), (0, k - a.shape[1])] + [(0, 0)] * (a.ndim - 2)
            return np.pad(a, width, constant_values=value)

        return cls(g=np.concatenate([b.g for b in batches]),
                   user=np.concatenate([b.user for b in batches]),
                   focus=np.concatenate([b.focus for b in batches]),
                   has_focus=np.concatenate([b.has_focus for b in batches]),
                   obj_type=np.concatenate([pad(b.obj_type, -1) for b in batches]),
                   obj_state=np.concatenate([pad(b.obj_state, 0) for b in batches]),
                   obj_held=np.concatenate([pad(b.obj_held, 0) for b in batches]),
                   obj_hidden=np.concatenate([pad(b.obj_hidden, 0) for b in batches]),
                   obj_pos=np.concatenate([pad(b.obj_pos, 0) for b in batches]),
                   cell=batches[0].cell)

    @classmethod
    def from_dataset(cls, ds: Any) -> Batch:
        """Builds a batch from a `cbgo.services.intent.datasets.Dataset`."""
        n_users = len(ds.meta["users"])
        return cls(g=ds.g.astype(np.float32), user=np.eye(n_users, dtype=np.float32)[ds.user],
                   focus=ds.focus.astype(np.float32), has_focus=np.ones(len(ds), bool),
                   obj_type=ds.obj_type.astype(np.int64), obj_state=ds.obj_state.astype(
                       np.float32), obj_held=ds.obj_held.astype(np.float32),
                   obj_hidden=ds.obj_hidden.astype(np.float32),
                   obj_pos=ds.obj_pos.astype(np.float32), cell=float(ds.meta["cell_size_m"]))

    def distances(self) -> np.ndarray:
        """(N, K) object-to-focus distances in grid cells (inf for empty slots)."""
        d = np.linalg.norm(self.obj_pos - self.focus[:, None, :], axis=-1) / self.cell
        return np.where(self.mask, d, np.inf)


@dataclass
class Prediction:
    """Posterior-averaged outputs for N observations.

    Attributes:
        p_action: (N, A) p(action), marginal over objects.
        p_object: (N, K) p(object), None for models that do not predict objects.
        joint: (N, K, A) p(object, action), None likewise.
    """

    p_action: np.ndarray
    p_object: np.ndarray | None = None
    joint: np.ndarray | None = None


# ==================================================================== the paper's M1-M5


def focus_field(batch: Batch) -> np.ndarray:
    """(N, K) the paper's focus field exp(−d⁴/(2·0.2²)) per slot; 0 for empty slots."""
    d = batch.distances()
    out = np.exp(-np.minimum(d, 10.0) ** 4 / (2 * FIELD_WIDTH ** 2))
    return np.where(batch.mask & batch.has_focus[:, None], out, 0.0)


def slot_features(kind: str, batch: Batch) -> np.ndarray:
    """Returns the fixed-slot input vector of model `kind` (M1-M5)."""
    parts = {"g": lambda: batch.g, "user": lambda: batch.user, "field": lambda: focus_field(batch),
             "state": lambda: np.where(batch.mask, batch.obj_state, 0.0)}
    return np.concatenate([parts[p]() for p in SLOT_INPUTS[kind]], axis=1).astype(np.float32)


class SlotModel:
    """One of the paper's fixed-slot models M1-M5.

    Args:
        kind: M1..M5.
        net: a trained network (None: untrained).
        standardizer: the input standardisation learnt with it.
        meta: metadata stored with it.
    """

    def __init__(self, kind: str, net: bayes.BayesMLP | None = None,
                 standardizer: bayes.Standardizer | None = None, meta: dict | None = None):
        if kind not in SLOT_KINDS:
            raise ConfigError(f"unknown slot model {kind!r}; choose one of {', '.join(SLOT_KINDS)}")
        self.kind, self.net, self.standardizer = kind, net, standardizer
        self.meta = meta or {}

    @property
    def name(self) -> str:
        """The model's id, e.g. ``intent-M5``."""
        return f"intent-{self.kind}"

    def fit(self, batch: Batch, action: np.ndarray, config: bayes.TrainConfig,
            progress: bool | str = False) -> list[float]:
        """Trains on (batch, action) by VI; returns the −ELBO per epoch."""
        x = slot_features(self.kind, batch)
        self.standardizer = bayes.Standardizer.fit(x)
        arch = bayes.Architecture(x.shape[1], SLOT_HIDDEN[self.kind], N_ACTIONS, "tanh")
        torch.manual_seed(config.seed)  # the initial weights too follow the seed
        self.net = bayes.BayesMLP(arch)
        return bayes.train(self.net, self.standardizer(x), np.asarray(action), config, progress)

    def predict(self, batch: Batch, samples: int = 32) -> Prediction:
        """Returns p(action), averaged over `samples` posterior draws."""
        x = self.standardizer(slot_features(self.kind, batch))
        return Prediction(bayes.predict_proba(self.net, x, samples))

    def save(self, path: str | Path) -> None:
        """Writes ``<path>.pt`` and ``<path>.json``."""
        bayes.save(path, self.net, {"kind": self.kind, "standardizer": self.standardizer,
                                    **self.meta})

    @classmethod
    def load(cls, path: str | Path) -> SlotModel:
        """Reads a model written by `save`."""
        loaded = bayes.load(path)
        return cls(loaded.metadata["kind"], loaded.model, loaded.standardizer, loaded.metadata)


# ==================================================================== cbgo's order-invariant model

N_OBJECT_FEATURES = 2 * len(OBJECT_TYPES) + 9
N_ACTOR_FEATURES = 2 * len(OBJECT_TYPES) + 1
PREDICT_ROWS = 1 << 16  # samples × observations × objects evaluated in one batched pass


@dataclass
class IntentArch:
    """How to rebuild an `IntentNet` (stored in the model's metadata)."""

    n_gestures: int
    n_users: int
    hidden_obj: list[int] = field(default_factory=lambda: [32])
    hidden_act: list[int] = field(default_factory=lambda: [32])
    activation: str = "tanh"
    prior_sigma: float = 1.0


@dataclass
class IntentDraws:
    """S networks drawn from an `IntentNet`'s posterior, per layer (`cbgo.bayes.BayesMLP.draw`)."""

    scorer: list[bayes.Draw]
    actor: list[bayes.Draw]


def _with_context(per_object: torch.Tensor, ctx: torch.Tensor) -> torch.Tensor:
    """(N, K, F + C): every object's features followed by its observation's context."""
    return torch.cat([per_object, ctx[:, None, :].expand(-1, per_object.shape[1], -1)], -1)


def _log_softmax_objects(score: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Returns log p(object) from (..., N, K) scores: a softmax over each scene's objects."""
    return torch.log_softmax(score.masked_fill(~mask, -math.inf), dim=-1)


class IntentNet(nn.Module):
    """The object scorer and the action head; see the module docstring."""

    def __init__(self, arch: IntentArch):
        super().__init__()
        self.arch = arch
        n_ctx = arch.n_gestures + arch.n_users
        self.scorer = bayes.BayesMLP(bayes.Architecture(
            N_OBJECT_FEATURES + n_ctx, arch.hidden_obj, 1, arch.activation, arch.prior_sigma))
        self.actor = bayes.BayesMLP(bayes.Architecture(
            N_ACTOR_FEATURES + n_ctx, arch.hidden_act, N_ACTIONS, arch.activation,
            arch.prior_sigma))

    def forward(self, obj: torch.Tensor, act: torch.Tensor, ctx: torch.Tensor,
                mask: torch.Tensor, sample: bool = True) -> torch.Tensor:
        """Returns log p(object, action), shape (N, K, A); −inf for empty slots.

        One weight sample is shared by all objects of the call when sampling.
        """
        log_obj = self.log_p_object(obj, ctx, mask, sample)
        logits = self.actor(_with_context(act, ctx), sample, shared=True)
        return log_obj[..., None] + torch.log_softmax(logits, dim=-1)

    def log_p_object(self, obj: torch.Tensor, ctx: torch.Tensor, mask: torch.Tensor,
                     sample: bool = True) -> torch.Tensor:
        """Returns log p(object), shape (N, K); −inf for empty slots."""
        score = self.scorer(_with_context(obj, ctx), sample, shared=True).squeeze(-1)
        return _log_softmax_objects(score, mask)

    def draw(self, n: int, generator: torch.Generator | None = None) -> IntentDraws:
        """Returns `n` networks drawn from the posterior (scorer and action head)."""
        return IntentDraws(self.scorer.draw(n, generator), self.actor.draw(n, generator))

    def forward_drawn(self, obj: torch.Tensor, act: torch.Tensor, ctx: torch.Tensor,
                      mask: torch.Tensor, draws: IntentDraws) -> torch.Tensor:
        """Returns log p(object, action) under each of S drawn networks, shape (S, N, K, A).

        What `forward` gives for one sample, for all S in one batched pass (−inf for empty
        slots; every observation and object of the call sees the same S networks).
        """
        score = self.scorer.forward_drawn(_with_context(obj, ctx), draws.scorer).squeeze(-1)
        logits = self.actor.forward_drawn(_with_context(act, ctx), draws.actor)
        return (_log_softmax_objects(score, mask)[..., None]
                + torch.log_softmax(logits, dim=-1))

    def log_likelihood(self, obj: torch.Tensor, act: torch.Tensor, ctx: torch.Tensor,
                       mask: torch.Tensor, action: torch.Tensor,
                       target: torch.Tensor) -> torch.Tensor:
        """Returns log p(target, action) per row, or log Σ_o p(o, action) where target is −1.

        One posterior sample for the whole call. When every target is known the action head
        runs on the targets only (the cheap path training takes).
        """
        if bool((target < 0).any()):
            return _log_likelihood(self(obj, act, ctx, mask), action, target)
        rows = torch.arange(len(action))
        log_obj = self.log_p_object(obj, ctx, mask)[rows, target]
        logits = self.actor(torch.cat([act[rows, target], ctx], -1), True, shared=True)
        return log_obj + torch.log_softmax(logits, -1)[rows, action]

    def kl(self) -> torch.Tensor:
        """Returns KL(q || prior) of both networks."""
        return self.scorer.kl() + self.actor.kl()


def _type_state(batch: Batch) -> np.ndarray:
    index = np.where(batch.mask, batch.obj_type * 2 + batch.obj_state.astype(np.int64), 0)
    onehot = np.eye(2 * len(OBJECT_TYPES), dtype=np.float32)[index]
    return onehot * batch.mask[..., None]


def object_features(batch: Batch, with_focus: bool = True) -> np.ndarray:
    """(N, K, F) the object scorer's per-object features (see the module docstring)."""
    d = np.minimum(batch.distances(), 3.0)
    nearest = d == d.min(1, keepdims=True)
    loglik = np.maximum(-d * d / (2 * FOCUS_SIGMA ** 2), LOGLIK_FLOOR)
    focus = np.stack([np.ones_like(d), d, np.minimum(d * d, 1.0),
                      np.minimum(d - d.min(1, keepdims=True), 3.0),
                      np.exp(-d * d / (2 * SCORER_SIGMA ** 2)), nearest.astype(float),
                      loglik], -1)
    known = (batch.has_focus[:, None] & batch.mask)[..., None] & with_focus
    focus = np.where(known, focus, 0.0)
    flags = np.stack([batch.obj_held, batch.obj_hidden], -1) * batch.mask[..., None]
    return np.concatenate([_type_state(batch), flags, focus], -1).astype(np.float32)


def actor_features(batch: Batch) -> np.ndarray:
    """(N, K, F) the action head's per-object features: type × state one-hot and held."""
    return np.concatenate([_type_state(batch), (batch.obj_held * batch.mask)[..., None]],
                          -1).astype(np.float32)


def context_features(batch: Batch) -> np.ndarray:
    """(N, G + U) the context every object is scored in: g and the user vector."""
    return np.concatenate([batch.g, batch.user], 1).astype(np.float32)


def _tensors(batch: Batch, ctx_std: bayes.Standardizer) -> dict[str, torch.Tensor]:
    return {"obj": torch.as_tensor(object_features(batch)),
            "obj_nofocus": torch.as_tensor(object_features(batch, with_focus=False)),
            "act": torch.as_tensor(actor_features(batch)),
            "ctx": torch.as_tensor(ctx_std(context_features(batch)).astype(np.float32)),
            "mask": torch.as_tensor(batch.mask)}


class OursModel:
    """cbgo's order-invariant Bayesian intent model.

    Args:
        net: the network (None: untrained).
        meta: metadata stored with it (gestures, users, provenance).
    """

    kind = "ours"

    def __init__(self, net: IntentNet | None = None, meta: dict | None = None):
        self.net, self.meta = net, dict(meta or {})

    @property
    def name(self) -> str:
        """The model's id as published in intents, e.g. ``intent-ours-1``."""
        return self.meta.get("model_id", "intent-ours")

    @property
    def context_standardizer(self) -> bayes.Standardizer:
        """The standardisation of g and the user vector learnt with the network."""
        std = self.meta.get("context_standardizer")
        if isinstance(std, dict):
            std = bayes.Standardizer(**std)
        if std is None:
            n = self.net.arch.n_gestures + self.net.arch.n_users
            std = bayes.Standardizer([0.0] * n, [1.0] * n)
        return std

    def fit(self, batch: Batch, action: np.ndarray, target: np.ndarray,
            config: bayes.TrainConfig, progress: bool | str = False,
            weights: np.ndarray | None = None, focus_dropout: float = 0.05,
            arch: IntentArch | None = None) -> list[float]:
        """Trains by VI; keeps the current network as the starting point if there is one.

        Args:
            batch: the observations.
            action: (N,) intended action indices.
            target: (N,) intended object slots; −1 where unknown (marginal likelihood).
            config: training settings.
            progress: show a tqdm bar.
            weights: per-observation likelihood weights.
            focus_dropout: share of observations shown without their focus, per step, so
                that the model also answers when no focus is known.
            arch: the architecture of a new network (defaults sized to the batch).
        """
        if self.net is None:
            torch.manual_seed(config.seed)  # the initial weights too follow the seed
            self.net = IntentNet(arch or IntentArch(batch.g.shape[1], batch.user.shape[1]))
            # Standardised context: a clear gesture then needs no large weights, which the
            # prior would fight (the network came out underconfident without it).
            self.meta["context_standardizer"] = bayes.Standardizer.fit(context_features(batch),
                                                                       floor=0.05)
        t = _tensors(batch, self.context_standardizer)
        a = torch.as_tensor(np.asarray(action), dtype=torch.long)
        o = torch.as_tensor(np.asarray(target), dtype=torch.long)
        generator = torch.Generator().manual_seed(config.seed + 1)

        def batch_nll(idx: torch.Tensor) -> torch.Tensor:
            drop = torch.rand(len(idx), generator=generator) < focus_dropout
            obj = torch.where(drop[:, None, None], t["obj_nofocus"][idx], t["obj"][idx])
            return -self.net.log_likelihood(obj, t["act"][idx], t["ctx"][idx], t["mask"][idx],
                                            a[idx], o[idx])

        return bayes.fit(self.net, batch.n, batch_nll, config, progress, weights)

    @torch.no_grad()
    def predict(self, batch: Batch, samples: int = 32, seed: int | None = 0) -> Prediction:
        """Returns the joint, p(action) and p(object), averaged over `samples` posterior draws.

        The networks are drawn once per call (from `seed`, or torch's global random state if
        None), so every observation of the call sees the same ones, and all of them run in one
        batched pass per chunk of observations.
        """
        generator = None if seed is None else torch.Generator().manual_seed(seed)
        draws = self.net.draw(samples, generator)
        t = _tensors(batch, self.context_standardizer)
        # Chunks bound the (samples, chunk, K, hidden) activations of large evaluation batches.
        chunk = max(1, PREDICT_ROWS // (samples * max(1, batch.obj_type.shape[1])))
        parts = [self._mean_joint({k: v[i:i + chunk] for k, v in t.items()}, draws)
                 for i in range(0, batch.n, chunk)]
        joint = torch.cat(parts).numpy().astype(np.float64)
        return Prediction(joint.sum(1), joint.sum(2), joint)

    def _mean_joint(self, t: dict[str, torch.Tensor], draws: IntentDraws) -> torch.Tensor:
        """(N, K, A) the joint averaged over the drawn networks."""
        return torch.exp(self.net.forward_drawn(t["obj"], t["act"], t["ctx"], t["mask"],
                                                draws)).mean(0)

    def user_likelihood(self, batch: Batch, action: np.ndarray, target: np.ndarray
                        ) -> Callable[[torch.Tensor], torch.Tensor]:
        """Returns f(user) = log p(target, action) per observation, for a differentiable user.

        The features are computed once; the networks are evaluated at their posterior mean
        (used to fit a user's profile by gradient descent on the user vector alone).
        """
        t = _tensors(batch, self.context_standardizer)
        std, n_g = self.context_standardizer, batch.g.shape[1]
        mean = torch.as_tensor(std.mean[n_g:], dtype=torch.float32)
        scale = torch.as_tensor(std.std[n_g:], dtype=torch.float32)
        a = torch.as_tensor(np.asarray(action), dtype=torch.long)
        o = torch.as_tensor(np.asarray(target), dtype=torch.long)

        def log_likelihood(user: torch.Tensor) -> torch.Tensor:
            users = ((user - mean) / scale)[None].expand(batch.n, -1)
            ctx = torch.cat([t["ctx"][:, :n_g], users], 1)
            return _log_likelihood(self.net(t["obj"], t["act"], ctx, t["mask"], sample=False),
                                   a, o)

        return log_likelihood

    def save(self, path: str | Path) -> None:
        """Writes ``<path>.pt`` (state_dict) and ``<path>.json`` (architecture, metadata)."""
        bayes.save(path, self.net, {"kind": self.kind, **self.meta})

    @classmethod
    def load(cls, path: str | Path) -> OursModel:
        """Reads a model written by `save`.

        Raises:
            ConfigError: missing or broken files.
        """
        def build(meta: dict) -> IntentNet:
            if meta.get("kind") != cls.kind:
                raise ConfigError(f"{path} is a {meta.get('kind')!r} model, not {cls.kind!r}")
            return IntentNet(IntentArch(**meta["architecture"]))

        net, meta = bayes.load_module(path, build)
        return cls(net, {k: v for k, v in meta.items() if k not in ("format", "architecture")})

    def copy(self) -> OursModel:
        """Returns an independent copy (for a user's personal model)."""
        net = IntentNet(IntentArch(**asdict(self.net.arch)))
        net.load_state_dict(self.net.state_dict())
        net.eval()
        return OursModel(net, dict(self.meta))


def _log_likelihood(log_joint: torch.Tensor, action: torch.Tensor,
                    target: torch.Tensor) -> torch.Tensor:
    """Log p(target, action), or log Σ_o p(o, action) where target is −1."""
    rows = torch.arange(len(action))
    marginal = torch.logsumexp(log_joint[rows, :, action], dim=-1)
    known = log_joint[rows, target.clamp(min=0), action]
    return torch.where(target >= 0, known, marginal)


# Training defaults shared by every model of the comparison (one budget for all). The KL term
# is tempered (kl_scale 0.1, a "cold" posterior): with the full KL the mean-field posterior
# stays so wide that posterior-averaged predictions come out underconfident (their mean
# confidence well below their accuracy on D4), while its mean network is calibrated.
STEPS, BATCH_SIZE, LR, LR_FINAL, KL_SCALE = 2000, 128, 0.02, 0.001, 0.1


def train_config(n: int, steps: int = STEPS, batch_size: int = BATCH_SIZE, lr: float = LR,
                 seed: int = 0, time_limit_s: float | None = 60.0,
                 kl_scale: float = KL_SCALE) -> bayes.TrainConfig:
    """Returns a TrainConfig that makes about `steps` gradient steps whatever the data size.

    The learning rate decays (cosine) to `LR_FINAL`; training stops early after
    `time_limit_s` seconds.
    """
    per_epoch = max(1, math.ceil(n / batch_size))
    return bayes.TrainConfig(epochs=max(1, math.ceil(steps / per_epoch)), batch_size=batch_size,
                             lr=lr, seed=seed, time_limit_s=time_limit_s, kl_scale=kl_scale,
                             lr_final=LR_FINAL)


def new_model(kind: str) -> SlotModel | OursModel:
    """Returns an untrained model of `kind` (M1..M5 or ours)."""
    if kind == "ours":
        return OursModel()
    return SlotModel(kind)


def map_gestures(names: Sequence[str], probs: Sequence[float],
                 vocabulary: Sequence[str]) -> np.ndarray:
    """Returns a gesture vector in the model's vocabulary, matched by name, normalised.

    Names the model does not know are ignored; its gestures missing from `names` count 0. The
    result sums to 1 like the training data's vectors (all zeros if nothing matched).
    """
    index = {name: i for i, name in enumerate(vocabulary)}
    g = np.zeros(len(vocabulary))
    for name, p in zip(names, probs, strict=True):
        if name in index:
            g[index[name]] = max(g[index[name]], float(p))
    return g / g.sum() if g.sum() > 0 else g
