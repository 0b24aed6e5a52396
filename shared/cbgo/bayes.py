"""Bayesian neural networks by variational inference, in torch: the paper's method done properly.

The paper fits its "probabilistic neural networks" with PyMC's ADVI: every weight gets a
Gaussian posterior q(w) = N(mu, sigma²) (mean-field), a Normal prior p(w) = N(0, prior_sigma²),
and training maximises the evidence lower bound

    ELBO = E_q[log p(y | x, w)] - KL(q(w) || p(w)).

Here the KL term is computed in closed form (both Gaussian) and the expected log-likelihood is
estimated with the local reparameterisation trick (sample pre-activations, not weights: lower
variance, one sample per example). Predictions average the softmax over posterior samples, so
every input gets a probability vector that carries the model's uncertainty.

Networks whose rows must see the same network (a scene's objects scored against each other)
are averaged over whole weight sets instead: `BayesMLP.draw` draws S sets at once, stacked
along a leading sample axis, and `BayesMLP.forward_drawn` runs all S networks in one batched
product per layer (einsum over the sample axis) rather than S forward passes in a Python loop.

Models are saved as a torch ``state_dict`` (``.pt``) plus JSON metadata (``.json``) that says how
to rebuild them — never pickled code. Loading refuses files whose metadata does not match.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from cbgo.errors import ConfigError

FORMAT = "cbgo-bnn/1"
ACTIVATIONS = {"tanh": nn.Tanh, "relu": nn.ReLU}

Draw = tuple[torch.Tensor, torch.Tensor | None]
"""S weight sets of one layer: weights (S, n_out, n_in) and biases (S, n_out) (None: no bias)."""


class BayesLinear(nn.Module):
    """A linear layer with a mean-field Gaussian posterior over weights and biases.

    Args:
        n_in: input size.
        n_out: output size.
        prior_sigma: standard deviation of the Normal(0, σ²) prior of every parameter.
        bias: whether the layer has a bias.
    """

    def __init__(self, n_in: int, n_out: int, prior_sigma: float = 1.0, bias: bool = True):
        super().__init__()
        self.prior_sigma = prior_sigma
        scale = 1.0 / math.sqrt(n_in)
        self.w_mu = nn.Parameter(torch.empty(n_out, n_in).uniform_(-scale, scale))
        self.w_rho = nn.Parameter(torch.full((n_out, n_in), -5.0))  # softplus(-5) ≈ 0.0067
        self.b_mu = nn.Parameter(torch.zeros(n_out)) if bias else None
        self.b_rho = nn.Parameter(torch.full((n_out,), -5.0)) if bias else None

    @staticmethod
    def _sigma(rho: torch.Tensor) -> torch.Tensor:
        return nn.functional.softplus(rho)

    def forward(self, x: torch.Tensor, sample: bool = True, shared: bool = False) -> torch.Tensor:
        """Returns pre-activations: sampled, or at the posterior mean (``sample=False``).

        By default each row gets its own sample of the pre-activations (local
        reparameterisation: lowest variance, rows independent). ``shared=True`` draws one weight
        sample for the whole call instead, so that rows that must see the same network (the
        objects of one scene scored against each other) do; `draw` and `forward_drawn` do the
        same for many samples at once.
        """
        # Training's one shared sample stays on this path, not draw(1): adding the bias in
        # another order would round differently and no longer reproduce the trained models.
        if sample and shared:
            w = self.w_mu + self._sigma(self.w_rho) * torch.randn_like(self.w_mu)
            out = x @ w.T
            if self.b_mu is not None:
                out = out + self.b_mu + self._sigma(self.b_rho) * torch.randn_like(self.b_mu)
            return out
        mean = x @ self.w_mu.T
        if self.b_mu is not None:
            mean = mean + self.b_mu
        if not sample:
            return mean
        var = (x * x) @ (self._sigma(self.w_rho) ** 2).T
        if self.b_rho is not None:
            var = var + self._sigma(self.b_rho) ** 2
        return mean + torch.sqrt(var + 1e-12) * torch.randn_like(mean)

    def draw(self, n: int, generator: torch.Generator | None = None) -> Draw:
        """Returns `n` weight sets drawn from q: w = mu + sigma·eps, all weights before biases.

        Args:
            n: how many sets.
            generator: the random source (None: torch's global one).
        """
        eps = torch.randn((n, *self.w_mu.shape), generator=generator, dtype=self.w_mu.dtype)
        w = self.w_mu + self._sigma(self.w_rho) * eps
        if self.b_mu is None:
            return w, None
        eps = torch.randn((n, *self.b_mu.shape), generator=generator, dtype=self.b_mu.dtype)
        return w, self.b_mu + self._sigma(self.b_rho) * eps

    @staticmethod
    def forward_drawn(x: torch.Tensor, draw: Draw, per_sample: bool) -> torch.Tensor:
        """Returns pre-activations (S, ..., n_out) of x under each of the S weight sets.

        Args:
            x: (..., n_in), one input for every set, or (S, ..., n_in) with `per_sample`.
            draw: the layer's S weight sets (`draw`).
            per_sample: whether x has the leading sample axis (every layer but the first).
        """
        w, b = draw
        out = torch.einsum("s...i,soi->s...o" if per_sample else "...i,soi->s...o", x, w)
        if b is None:
            return out
        return out + b.reshape(len(b), *[1] * (out.ndim - 2), b.shape[-1])

    def kl(self) -> torch.Tensor:
        """Returns KL(q || prior) in closed form, summed over the layer's parameters."""
        total = _kl_normal(self.w_mu, self._sigma(self.w_rho), self.prior_sigma)
        if self.b_mu is not None:
            total = total + _kl_normal(self.b_mu, self._sigma(self.b_rho), self.prior_sigma)
        return total


def _kl_normal(mu: torch.Tensor, sigma: torch.Tensor, prior_sigma: float) -> torch.Tensor:
    ratio = (sigma / prior_sigma) ** 2
    return 0.5 * (ratio + (mu / prior_sigma) ** 2 - 1.0 - torch.log(ratio)).sum()


@dataclass
class Architecture:
    """How to rebuild a network (stored in the metadata)."""

    n_in: int
    hidden: list[int]
    n_out: int
    activation: str = "tanh"
    prior_sigma: float = 1.0
    bias: bool = True

    def __post_init__(self):
        if self.activation not in ACTIVATIONS:
            raise ConfigError(f"activation {self.activation!r} is not one of "
                              f"{', '.join(ACTIVATIONS)}")


class BayesMLP(nn.Module):
    """A fully connected Bayesian network: BayesLinear layers with an activation between.

    Args:
        arch: the layer sizes and prior.
    """

    def __init__(self, arch: Architecture):
        super().__init__()
        self.arch = arch
        sizes = [arch.n_in, *arch.hidden, arch.n_out]
        self.layers = nn.ModuleList(BayesLinear(a, b, arch.prior_sigma, arch.bias)
                                    for a, b in zip(sizes[:-1], sizes[1:], strict=True))
        self.act = ACTIVATIONS[arch.activation]()

    def forward(self, x: torch.Tensor, sample: bool = True, shared: bool = False) -> torch.Tensor:
        """Returns logits for a batch of any leading shape.

        Sampling draws one posterior sample per example, or one for the whole call with
        ``shared=True`` (see `BayesLinear.forward`).
        """
        for layer in self.layers[:-1]:
            x = self.act(layer(x, sample, shared))
        return self.layers[-1](x, sample, shared)

    def draw(self, n: int, generator: torch.Generator | None = None) -> list[Draw]:
        """Returns `n` networks drawn from q: per layer, its `n` weight sets (layer by layer)."""
        return [layer.draw(n, generator) for layer in self.layers]

    def forward_drawn(self, x: torch.Tensor, draws: Sequence[Draw]) -> torch.Tensor:
        """Returns logits (S, ..., n_out): x, of any leading shape, through each drawn network.

        One batched product per layer for all S networks; the same as running them one by one
        (up to float rounding).
        """
        for i, (layer, draw) in enumerate(zip(self.layers, draws, strict=True)):
            x = layer.forward_drawn(self.act(x) if i else x, draw, per_sample=i > 0)
        return x

    def kl(self) -> torch.Tensor:
        """Returns KL(q || prior) of the whole network."""
        return sum(layer.kl() for layer in self.layers)


class BayesEnsemble(nn.Module):
    """Bayesian networks of one architecture trained apart: a deep ensemble.

    Each member is a `BayesMLP` trained from its own initialisation on its own draw of the data;
    a prediction averages theirs. Why several: one network's boundaries between nearby classes
    depend on its seed (Lakshminarayanan et al., "Simple and scalable predictive uncertainty
    estimation using deep ensembles", NeurIPS 2017); a mean-field posterior stays near one
    mode and does not average that out.

    Args:
        arch: every member's architecture.
        members: how many.
    """

    def __init__(self, arch: Architecture, members: int):
        super().__init__()
        if members < 1:
            raise ConfigError(f"an ensemble needs at least one member, got {members}")
        self.arch = arch
        self.members = nn.ModuleList(BayesMLP(arch) for _ in range(members))

    @classmethod
    def of(cls, members: Sequence[BayesMLP]) -> BayesEnsemble:
        """Returns an ensemble holding these trained networks (one architecture)."""
        arch = members[0].arch
        if any(m.arch != arch for m in members):
            raise ConfigError("ensemble members must share one architecture")
        ensemble = cls(arch, len(members))
        ensemble.members = nn.ModuleList(members)
        return ensemble


@dataclass
class TrainConfig:
    """Settings of variational training."""

    epochs: int = 200
    batch_size: int = 256
    lr: float = 0.01
    seed: int = 0
    kl_scale: float = 1.0  # 1.0 is the true ELBO; < 1 tempers the prior (recorded in metadata)
    time_limit_s: float | None = None  # stop after the epoch that crosses this budget
    lr_final: float | None = None  # cosine decay from lr to this by the last epoch (None: constant)


def train(model: BayesMLP, x: np.ndarray, y: np.ndarray, config: TrainConfig,
          progress: bool | str = False, weights: np.ndarray | None = None) -> list[float]:
    """Maximises the ELBO on (x, y); returns the negative ELBO per example, per epoch.

    Args:
        model: the network to train (in place).
        x: (N, n_in) standardised inputs.
        y: (N,) integer class labels.
        config: epochs, batch size, learning rate, seed, KL scale.
        progress: show a tqdm bar (True, or a description string).
        weights: optional per-example weights of the likelihood (mean 1).
    """
    xt = torch.as_tensor(x, dtype=torch.float32)
    yt = torch.as_tensor(y, dtype=torch.long)
    return fit(model, len(yt),
               lambda batch: nn.functional.cross_entropy(model(xt[batch]), yt[batch],
                                                         reduction="none"),
               config, progress, weights)


def fit(module: nn.Module, n: int, batch_nll: Callable[[torch.Tensor], torch.Tensor],
        config: TrainConfig, progress: bool | str = False,
        weights: np.ndarray | None = None) -> list[float]:
    """Maximises the ELBO of any module made of Bayesian layers; returns −ELBO per example.

    The likelihood is whatever `batch_nll` computes, so structured models (several networks
    combined in one forward pass) train exactly like `BayesMLP`.

    Args:
        module: has parameters and ``kl()`` (the KL of its whole posterior to its prior).
        n: the number of training examples.
        batch_nll: given example indices (a LongTensor), returns their negative
            log-likelihoods under one posterior sample, shape (len(indices),).
        config: epochs, batch size, learning rate (and its decay), seed, KL scale, time limit.
        progress: show a tqdm bar (True, or a description string).
        weights: optional per-example weights of the likelihood (mean 1).
    """
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    wt = torch.as_tensor(weights if weights is not None else np.ones(n), dtype=torch.float32)
    optimiser = torch.optim.Adam(module.parameters(), lr=config.lr)
    schedule = None if config.lr_final is None else torch.optim.lr_scheduler.CosineAnnealingLR(
        optimiser, T_max=max(1, config.epochs), eta_min=config.lr_final)
    history: list[float] = []
    started = time.monotonic()
    bar = tqdm(range(config.epochs), desc=progress if isinstance(progress, str) else "training",
               disable=not progress, leave=False)
    module.train()
    for _ in bar:
        order = torch.as_tensor(rng.permutation(n))
        total = 0.0
        for start in range(0, n, config.batch_size):
            batch = order[start:start + config.batch_size]
            # ELBO per example: the likelihood of the batch scaled to the data set, the KL once.
            loss = (batch_nll(batch) * wt[batch]).mean() + config.kl_scale * module.kl() / n
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item() * len(batch)
        history.append(total / n)
        if schedule is not None:
            schedule.step()
        bar.set_postfix(neg_elbo=f"{history[-1]:.4f}")
        if config.time_limit_s is not None and time.monotonic() - started > config.time_limit_s:
            break
    module.eval()
    return history


@torch.no_grad()
def predict_proba(model: BayesMLP, x: np.ndarray, samples: int = 32,
                  seed: int | None = 0) -> np.ndarray:
    """Returns (N, n_out) class probabilities averaged over `samples` posterior draws."""
    if seed is not None:
        torch.manual_seed(seed)
    xt = torch.as_tensor(np.asarray(x), dtype=torch.float32)
    if xt.ndim == 1:
        xt = xt[None]
    batch = xt.repeat(samples, 1)
    probs = torch.softmax(model(batch), dim=-1).reshape(samples, len(xt), -1).mean(0)
    return probs.numpy().astype(np.float64)


@dataclass
class Standardizer:
    """Per-feature standardisation fitted on training data (stored in the metadata)."""

    mean: list[float]
    std: list[float]

    @classmethod
    def fit(cls, x: np.ndarray, floor: float = 1e-6) -> Standardizer:
        """Fits mean and std (std floored, so constant features do not explode)."""
        return cls(x.mean(0).tolist(), np.maximum(x.std(0), floor).tolist())

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Returns standardised inputs."""
        return (np.asarray(x, dtype=np.float64) - self.mean) / self.std


def data_hash(*arrays: np.ndarray) -> str:
    """Returns a short SHA-256 of training arrays (provenance in the metadata)."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


@dataclass
class ModelFile:
    """A saved model: the network plus everything needed to use it."""

    model: BayesMLP
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def standardizer(self) -> Standardizer | None:
        """The input standardisation, if the metadata has one."""
        s = self.metadata.get("standardizer")
        return Standardizer(**s) if s else None


def save(path: str | Path, model: nn.Module, metadata: dict[str, Any]) -> tuple[Path, Path]:
    """Writes ``<path>.pt`` (state_dict) and ``<path>.json`` (architecture + metadata).

    Any module with a dataclass ``arch`` can be saved (a `BayesMLP`, or a model built of
    several); `load_module` reads it back.

    Returns:
        The two paths written.
    """
    base = Path(path).with_suffix("")
    base.parent.mkdir(parents=True, exist_ok=True)
    meta = {"format": FORMAT, "architecture": asdict(model.arch), **metadata}
    pt, js = base.with_suffix(".pt"), base.with_suffix(".json")
    torch.save(model.state_dict(), pt)
    js.write_text(json.dumps(meta, indent=1, default=_plain) + "\n")
    return pt, js


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if hasattr(value, "__dataclass_fields__"):
        return asdict(value)
    raise TypeError(f"cannot store {type(value).__name__} in model metadata")


def load(path: str | Path) -> ModelFile:
    """Reads a `BayesMLP` saved by `save` (``path`` with or without suffix).

    Raises:
        ConfigError: missing files, another format, or weights that do not fit the architecture.
    """
    model, meta = load_module(path, lambda m: BayesMLP(Architecture(**m["architecture"])))
    return ModelFile(model, meta)


def load_module(path: str | Path, build: Callable[[dict[str, Any]], nn.Module]
                ) -> tuple[nn.Module, dict[str, Any]]:
    """Reads any module saved by `save`: `build` makes it from the metadata, then weights load.

    Args:
        path: ``<base>``, ``<base>.pt`` or ``<base>.json``.
        build: returns an untrained module from the metadata (its ``architecture`` entry).

    Returns:
        The module (in eval mode) and its metadata.

    Raises:
        ConfigError: missing files, another format, or weights that do not fit.
    """
    base = Path(path).with_suffix("")
    pt, js = base.with_suffix(".pt"), base.with_suffix(".json")
    try:
        meta = json.loads(js.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ConfigError(f"cannot load model {base}: {e}") from None
    try:
        state = torch.load(pt, weights_only=True)
    except Exception as e:  # noqa: BLE001 - a torn or foreign file fails in any of the unpickler's ways
        raise ConfigError(f"cannot load model {base}: weights {pt.name} unreadable "
                          f"({type(e).__name__}: {e})") from None
    if meta.get("format") != FORMAT:
        raise ConfigError(f"{js} is not a {FORMAT} model (format {meta.get('format')!r})")
    try:
        model = build(meta)
        model.load_state_dict(state)
    except (RuntimeError, TypeError, KeyError) as e:
        raise ConfigError(f"{pt} does not fit the architecture in {js}: {e}") from None
    model.eval()
    return model, meta


def layer_sizes(arch: Architecture) -> Sequence[int]:
    """Returns [n_in, *hidden, n_out]."""
    return [arch.n_in, *arch.hidden, arch.n_out]
