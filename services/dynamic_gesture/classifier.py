"""Templates and the calibrated classifier: DTW distances and ProMP likelihoods → probabilities.

A **template** is one dynamic gesture learned from demonstrations (observations of whole
strokes, `stroke.observation`): its ProMP, the ProMP's mean trajectory (as long as the median
demonstration), its **shape** (that trajectory scaled to unit extent: what DTW compares), and its
**scale** — the typical per-step DTW distance of its demonstrations' shapes to its shape, each
left out of the mean it is compared with (leave-one-out up to `LOO_MAX` takes), at least
`SCALE_FLOOR`. The scale makes distances comparable across templates, including a user's new
gesture taught with a few takes. It also keeps the median change of hand shape of its takes.

Shapes, not sizes, are compared: a window and the templates are scaled to unit extent before
DTW, and the ProMP likelihood is taken of the window scaled to the template's size. People
swipe short or long, slowly or fast; what makes a swipe up a swipe up is its shape. Size is
left to the "no gesture" alternative, where it separates a twitch from a stroke.

Probabilities come from a **conditional logit** (McFadden) whose few weights are shared by all
templates, so a template added later needs no retraining of the calibration. Each template and
"no gesture" gets a utility, ``p = softmax(u)`` over the templates plus ``none`` (sums to 1),
from these features (`features`):

- template k's match: ``log(d_k / s_k)``, ``d_k`` the per-step DTW distance of the window's
  shape to the template's, ``s_k`` its scale; ``ℓ_k`` the ProMP's robust log-likelihood per
  value (clipped at `LOGLIK_FLOOR`); ``|c − c_k|``, ``c`` the window's change of hand shape and
  ``c_k`` the template's (forming or releasing a static pose rolls the palm too); ``1 − cos
  φ_k``, ``φ_k`` the angle between the window's heading (start → farthest sample, roll
  included) and the template's: a swipe right of a real, jittery hand still heads right;
- the window's context: ``log(extent)``, the largest excursion from its start (mm, roll
  included as k·roll); ``[stroke still running]``; ``log(peak speed)`` (mm/s, likewise): a
  drift, a slow re-positioning or a preparation is slower than a gesture; ``log(path /
  extent)``: a gesture goes where it goes, a wobble or a shake wanders.

The shipped library uses `NeuralCalibration`: a template's utility is a small network (one
tanh layer and a linear part) of its match and the window's context, so how much a loose
match counts can depend on how large, fast and direct the window is (a real swipe, bowed and
rolled, next to a small loose preparation); none's utility is linear in the context. The
original linear form, `Calibration` (``u_k = θ₁·log(d_k / s_k) + θ₂·ℓ_k + θ₃·|c − c_k| +
θ₉·(1 − cos φ_k)``, ``u_none = θ₄ + θ₅·log(extent) + θ₆·[running] + θ₇·log(peak speed) +
θ₈·log(path / extent)``) still loads.

The weights are fitted by weighted maximum likelihood (`fit_neural_calibration`; the linear
form by `fit_calibration`) on every window the segmenter evaluates — mid-stroke and final — of
simulated users that the templates were not learned from and of real people, gestures and
non-gestures alike (a static pose formed or released, the roll back after rotate, the move out
of the field, twitches, real people's other gestures). A window's truth is what the person is
doing in it, so a window early in a stroke is that gesture, and the model learns how little of
a stroke it can tell apart from nothing. `cbgo train dynamic` fits them; `cbgo bench dynamic`
reports the calibration (ECE) on other users, whose styles lie outside the training range.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from cbgo.services.dynamic_gesture.dtw import (
    TemplateBank,
    compiled_dtw_distances,
    fastdtw_backend,
    fastdtw_distances,
)
from cbgo.services.dynamic_gesture.promp import ProMP
from cbgo.wire import NO_GESTURE

NONE = NO_GESTURE  # the no-gesture class of the wire vocabulary: preparation, return, twitch
SCALE_FLOOR = 0.02  # per-step shape distance, in units of the stroke's extent
LOO_MAX = 30
LOGLIK_FLOOR = -60.0
EXTENT_FLOOR_MM = 1.0
N_THETA = 9
SPEED_FLOOR_MM_S = 10.0
DTW_MODES = ("exact", "numpy", "fastdtw")
MIRROR_X = np.array([-1.0, 1.0, 1.0, 1.0])  # x negated; y, z and the anatomical roll kept
MIRROR = {"swipe_left": "swipe_right", "swipe_right": "swipe_left", "swipe_up": "swipe_up",
          "swipe_down": "swipe_down", "rotate": "rotate"}
"""Each default gesture's mirror image across the body's midline: the default templates are
learned in the right hand's space (real people's recordings are of right hands), and a left
hand's strokes are matched mirrored (`Template.mirror`). The roll is anatomical, so rotate is
its own mirror image."""


@dataclass
class Template:
    """One dynamic gesture; see the module docstring.

    Attributes:
        name: the gesture name on the wire.
        promp: the learned ProMP.
        trajectory: (m, 4) the ProMP mean, the DTW reference.
        scale: typical per-step DTW distance of its demonstrations' shapes to its shape.
        duration_s: median duration of its demonstrations.
        pose_change: median change of hand shape in its demonstrations (`Window.pose_change`).
        n_demos: how many demonstrations it was learned from.
        source: "default" (shipped) or "user" (taught with `cbgo gestures record`).
        user: who demonstrated it, if known.
        created: Unix time it was learned.
        mirror: the gesture that is this one's mirror image across the body's midline
            (swipe_left's is swipe_right, swipe_up's itself), for a template learned in the
            right hand's space (`Classifier` mirrors a left hand's windows into it); None: a
            template matched as performed, whichever the hand (a taught gesture).
    """

    name: str
    promp: ProMP
    trajectory: np.ndarray
    scale: float
    duration_s: float = 0.0
    pose_change: float = 0.0
    n_demos: int = 0
    source: str = "default"
    user: str | None = None
    created: float = field(default_factory=time.time)
    mirror: str | None = None

    @classmethod
    def learn(cls, name: str, demos: list[np.ndarray], durations: list[float] | None = None,
              pose_changes: list[float] | None = None, source: str = "default",
              user: str | None = None, rng_seed: int = 0, mirror: str | None = None
              ) -> Template:
        """Learns a template from demonstrations (n_i, 4).

        Raises:
            ValueError: no demonstrations, or malformed ones.
        """
        promp = ProMP.fit(demos)
        length = int(np.median([len(d) for d in demos]))
        trajectory = promp.mean(max(length, 3))
        scale = _scale(demos, trajectory, length, np.random.default_rng(rng_seed))
        return cls(name, promp, trajectory, scale,
                   float(np.median(durations)) if durations else 0.0,
                   float(np.median(pose_changes)) if pose_changes else 0.0, len(demos), source,
                   user, mirror=mirror)

    @property
    def extent_mm(self) -> float:
        """The template's size: its largest excursion from its start."""
        return extent_of(self.trajectory)

    @property
    def shape(self) -> np.ndarray:
        """The trajectory scaled to unit extent (what DTW compares)."""
        return normalised(self.trajectory)

    def to_dict(self) -> dict:
        """Returns plain data (JSON-safe)."""
        return {"name": self.name, "promp": self.promp.to_dict(),
                "trajectory": np.round(self.trajectory, 4).tolist(), "scale": self.scale,
                "duration_s": self.duration_s, "pose_change": self.pose_change,
                "n_demos": self.n_demos, "source": self.source, "user": self.user,
                "created": self.created, **({"mirror": self.mirror} if self.mirror else {})}

    @classmethod
    def from_dict(cls, data: dict) -> Template:
        """Rebuilds a template from `to_dict` data.

        Raises:
            ValueError: malformed data.
        """
        try:
            trajectory = np.asarray(data["trajectory"], dtype=float)
            if trajectory.ndim != 2 or trajectory.shape[1] != 4 or len(trajectory) < 2:
                raise ValueError("trajectory must be (m >= 2, 4)")
            return cls(str(data["name"]), ProMP.from_dict(data["promp"]), trajectory,
                       max(float(data["scale"]), SCALE_FLOOR),
                       float(data.get("duration_s", 0.0)), float(data.get("pose_change", 0.0)),
                       int(data.get("n_demos", 0)),
                       str(data.get("source", "default")), data.get("user"),
                       float(data.get("created", 0.0)),
                       str(data["mirror"]) if data.get("mirror") else None)
        except (KeyError, TypeError) as e:
            raise ValueError(f"malformed template: {e}") from None


def _scale(demos: list[np.ndarray], trajectory: np.ndarray, length: int,
           rng: np.random.Generator) -> float:
    """Returns the median per-step DTW distance of demonstrations' shapes to the template's."""
    if len(demos) == 1:
        return SCALE_FLOOR
    if len(demos) <= LOO_MAX:  # leave each out of the mean it is compared with
        distances = []
        for i, demo in enumerate(demos):
            ref = ProMP.fit(demos[:i] + demos[i + 1:]).mean(max(length, 3))
            distances.append(TemplateBank([normalised(ref)]).distances(normalised(demo))[0])
    else:
        pick = rng.choice(len(demos), size=min(len(demos), 200), replace=False)
        bank = TemplateBank([normalised(trajectory)])
        distances = [bank.distances(normalised(demos[i]))[0] for i in pick]
    return max(SCALE_FLOOR, float(np.median(distances)))


def extent_of(obs: np.ndarray) -> float:
    """Returns a window's largest excursion from its first sample (mm, roll as k·roll)."""
    return max(EXTENT_FLOOR_MM, float(np.linalg.norm(obs - obs[0], axis=1).max()))


def path_of(obs: np.ndarray) -> float:
    """Returns the length of a window's path (mm, roll as k·roll), at least its extent."""
    return max(extent_of(obs), float(np.linalg.norm(np.diff(obs, axis=0), axis=1).sum()))


def mirrored(obs: np.ndarray) -> np.ndarray:
    """Returns an observation mirrored across the body's midline (x negated).

    A left hand's stroke becomes the right hand's mirror image of it. The roll keeps its sign:
    it is anatomical on either hand (`stroke.palm_roll`).
    """
    return obs * MIRROR_X


def normalised(obs: np.ndarray) -> np.ndarray:
    """Returns a trajectory relative to its start and scaled to unit extent (its shape)."""
    return (obs - obs[0]) / extent_of(obs)


def mirror_rows(templates: list[Template]) -> np.ndarray:
    """Returns, per template, the index of its mirror image's template (-1: none).

    A template counts as learned in the right hand's space only with its mirror image in the
    library, itself so learned (both default swipes, say): a user's swipe_left replacing the
    default one leaves swipe_right matched as performed too, so no left-hand window is ever
    scored against half a pair.
    """
    index = {t.name: i for i, t in enumerate(templates)}
    rows = np.full(len(templates), -1)
    for i, t in enumerate(templates):
        j = index.get(t.mirror) if t.mirror else None
        if j is not None and templates[j].mirror == t.name:
            rows[i] = j
    return rows


@dataclass
class Calibration:
    """The shared weights θ of the conditional logit (see the module docstring)."""

    theta: np.ndarray = field(default_factory=lambda: np.zeros(N_THETA))

    def to_dict(self) -> dict:
        """Returns plain data (JSON-safe)."""
        return {"kind": "conditional-logit", "theta": [float(v) for v in self.theta],
                "features": ["log(d/s)", "loglik", "|pose change - template's|", "none:bias",
                             "none:log(extent)", "none:in-progress", "none:log(peak speed)",
                             "none:log(path / extent)", "1 - cos(reach, template's)"]}

    @classmethod
    def from_dict(cls, data: dict) -> Calibration:
        """Rebuilds a calibration from `to_dict` data.

        Raises:
            ValueError: malformed data.
        """
        theta = np.asarray(data.get("theta", ()), dtype=float)
        if theta.shape != (N_THETA,) or not np.isfinite(theta).all():
            raise ValueError(f"calibration theta must be {N_THETA} finite numbers")
        return cls(theta)

    def probabilities(self, feats: np.ndarray) -> np.ndarray:
        """Returns the probabilities of the alternatives (`features` rows)."""
        return softmax_rows(feats, self.theta)


def reach_of(obs: np.ndarray) -> np.ndarray:
    """Returns the unit vector from a window's start to its farthest sample (its heading)."""
    delta = obs - obs[0]
    far = delta[int(np.argmax(np.linalg.norm(delta, axis=1)))]
    return far / max(float(np.linalg.norm(far)), 1e-9)


def features(obs: np.ndarray, distances: np.ndarray, scales: np.ndarray, logliks: np.ndarray,
             pose_gaps: np.ndarray, final: bool = True, peak_speed: float = 0.0,
             reaches: np.ndarray | None = None) -> np.ndarray:
    """Returns (K + 1, N_THETA) feature rows: one per template, then the none row."""
    k = len(distances)
    out = np.zeros((k + 1, N_THETA))
    out[:k, 0] = np.log(np.maximum(distances, 1e-6) / scales)
    out[:k, 1] = np.maximum(logliks, LOGLIK_FLOOR)
    out[:k, 2] = pose_gaps
    if reaches is not None:
        out[:k, 8] = 1.0 - reaches @ reach_of(obs)
    out[k, 3] = 1.0
    out[k, 4] = np.log(extent_of(obs))
    out[k, 5] = 0.0 if final else 1.0
    out[k, 6] = np.log(max(peak_speed, SPEED_FLOOR_MM_S))
    out[k, 7] = np.log(path_of(obs) / extent_of(obs))
    return out


def softmax_rows(feats: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Returns the probabilities of the alternatives (rows) under θ."""
    u = feats @ theta
    u = np.exp(u - u.max())
    return u / u.sum()


def _objective(samples: list[np.ndarray], labels: list[int], weights: np.ndarray,
               theta: np.ndarray, ridge: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Returns the weighted, penalised log-likelihood, its gradient and Hessian at θ."""
    value = -0.5 * ridge * float(theta @ theta)
    grad = -ridge * theta
    hess = -ridge * np.eye(len(theta))
    for feats, y, w in zip(samples, labels, weights, strict=True):
        p = softmax_rows(feats, theta)
        value += w * float(np.log(max(p[y], 1e-300)))
        mean = p @ feats
        grad += w * (feats[y] - mean)
        hess -= w * ((feats * p[:, None]).T @ feats - np.outer(mean, mean))
    return value, grad, hess


def fit_calibration(samples: list[np.ndarray], labels: list[int], ridge: float = 1.0,
                    iterations: int = 100, weights=None) -> Calibration:
    """Fits θ by penalised maximum likelihood (damped Newton); the objective is concave.

    The ridge keeps θ finite where the calibration windows are separable (most simulated
    strokes are): it is the prior N(0, 1/ridge) on each weight.

    Args:
        samples: per window, its (K_i + 1, N_THETA) `features` (K_i may differ).
        labels: per window, the index of the true alternative (K_i for none).
        ridge: L2 penalty on θ.
        iterations: Newton steps at most.
        weights: per window, its weight in the likelihood (None: 1 each).
    """
    weights = np.ones(len(labels)) if weights is None else np.asarray(weights, dtype=float)
    theta = np.zeros(N_THETA)
    value, grad, hess = _objective(samples, labels, weights, theta, ridge)
    for _ in range(iterations):
        step = np.linalg.solve(hess, grad)
        t = 1.0
        while t > 1e-6:  # backtrack until the objective improves
            trial = theta - t * step
            new = _objective(samples, labels, weights, trial, ridge)
            if new[0] >= value:
                break
            t /= 2
        else:
            break
        done = np.abs(trial - theta).max() < 1e-7
        theta, (value, grad, hess) = trial, new
        if done:
            break
    return Calibration(theta)


MATCH = [0, 1, 2, 8]  # a template row's own columns: log(d/s), loglik, pose gap, 1 - cos
CONTEXT = [4, 5, 6, 7]  # the window's: log(extent), in progress, log(peak speed), log(path/ext.)
N_INPUT = len(MATCH) + len(CONTEXT)


def neural_inputs(feats: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Returns a window's (K, 8) template inputs (match, then context) and its (4,) context."""
    context = feats[-1, CONTEXT]
    match = feats[:-1][:, MATCH]
    return np.hstack([match, np.broadcast_to(context, (len(match), len(CONTEXT)))]), context


@dataclass
class NeuralCalibration:
    """A conditional logit whose template utility is a small network shared by all templates.

    ``u_k = w₂·tanh(W₁x_k + b₁) + s·x_k + b``, with ``x_k`` template k's match features
    (`MATCH`) and the window's context (`CONTEXT`), standardised; ``u_none = v·c``, linear in
    the standardised context. The linear model (`Calibration`) weighs how well a window
    matches a template the same way whatever the window: a real swipe that is large, fast and
    direct but matches the template's shape loosely (a bowed or rolled one) loses to "none"
    as a small, loose preparation does. Here the weight of the match may depend on the
    context. Still one set of weights for every template, so a gesture taught later needs no
    retraining. None is kept linear: a network there learned that the training people's
    extents and speeds are the only ones a gesture has (held-out simulated users' small
    swipes went to "none").

    Attributes:
        mean, std: (8,) standardisation of the template inputs (the context's are the last 4).
        w1: (8, H), b1: (H,), w2: (H,) the hidden layer and its output weights.
        skip: (8,) the linear part; bias: the templates' common offset.
        none_w: (4,) the none utility's weights on the standardised context.
    """

    mean: np.ndarray
    std: np.ndarray
    w1: np.ndarray
    b1: np.ndarray
    w2: np.ndarray
    skip: np.ndarray
    bias: float
    none_w: np.ndarray

    def utilities(self, feats: np.ndarray) -> np.ndarray:
        """Returns the (K + 1,) utilities of a window's `features` rows."""
        x, context = neural_inputs(feats)
        x = (x - self.mean) / self.std
        c = (context - self.mean[len(MATCH):]) / self.std[len(MATCH):]
        u = np.tanh(x @ self.w1 + self.b1) @ self.w2 + x @ self.skip + self.bias
        return np.append(u, c @ self.none_w)

    def probabilities(self, feats: np.ndarray) -> np.ndarray:
        """Returns the probabilities of the alternatives (`features` rows)."""
        u = self.utilities(feats)
        u = np.exp(u - u.max())
        return u / u.sum()

    def to_dict(self) -> dict:
        """Returns plain data (JSON-safe)."""
        out = {"kind": "neural-logit", "bias": float(self.bias),
               "inputs": ["log(d/s)", "loglik", "|pose change - template's|",
                          "1 - cos(reach, template's)", "log(extent)", "in-progress",
                          "log(peak speed)", "log(path / extent)"]}
        for name in ("mean", "std", "w1", "b1", "w2", "skip", "none_w"):
            out[name] = np.round(getattr(self, name), 6).tolist()
        return out

    @classmethod
    def from_dict(cls, data: dict) -> NeuralCalibration:
        """Rebuilds a calibration from `to_dict` data.

        Raises:
            ValueError: malformed data.
        """
        try:
            arrays = {name: np.asarray(data[name], dtype=float)
                      for name in ("mean", "std", "w1", "b1", "w2", "skip", "none_w")}
            bias = float(data["bias"])
        except (KeyError, TypeError) as e:
            raise ValueError(f"malformed neural calibration: {e}") from None
        hidden = arrays["b1"].shape[0] if arrays["b1"].ndim == 1 else -1
        shapes = {"mean": (N_INPUT,), "std": (N_INPUT,), "w1": (N_INPUT, hidden),
                  "b1": (hidden,), "w2": (hidden,), "skip": (N_INPUT,),
                  "none_w": (len(CONTEXT),)}
        for name, shape in shapes.items():
            if arrays[name].shape != shape or not np.isfinite(arrays[name]).all():
                raise ValueError(f"neural calibration {name} must be {shape} finite numbers")
        if not (arrays["std"] > 0).all() or not np.isfinite(bias):
            raise ValueError("neural calibration std must be positive, bias finite")
        return cls(bias=bias, **arrays)


def calibration_from_dict(data: dict) -> Calibration | NeuralCalibration:
    """Rebuilds either kind of calibration from its `to_dict` data.

    Raises:
        ValueError: malformed data.
    """
    if data.get("kind") == "neural-logit":
        return NeuralCalibration.from_dict(data)
    return Calibration.from_dict(data)


def fit_neural_calibration(samples: list[np.ndarray], labels: list[int], weights=None,
                           hidden: int = 6, epochs: int = 400, weight_decay: float = 1e-3,
                           seed: int = 0) -> NeuralCalibration:
    """Fits a `NeuralCalibration` by weighted maximum likelihood (Adam, full batch, torch).

    Args:
        samples: per window, its (K_i + 1, N_THETA) `features` (K_i may differ).
        labels: per window, the index of the true alternative (K_i for none).
        weights: per window, its weight in the likelihood (None: 1 each).
        hidden: units of the hidden layer.
        epochs: full-batch steps.
        weight_decay: L2 penalty (Adam's), which keeps the network near smooth.
        seed: the initial weights' seed (the fit is deterministic on one machine).
    """
    import torch  # noqa: PLC0415 (training only: the service runs the numpy forward pass)

    weights = np.ones(len(labels)) if weights is None else np.asarray(weights, dtype=float)
    groups: dict[int, list[int]] = {}  # windows by number of alternatives, batched together
    for i, feats in enumerate(samples):
        groups.setdefault(len(feats), []).append(i)
    inputs = [neural_inputs(f) for f in samples]
    stacked = np.vstack([x for x, _ in inputs])
    mean, std = stacked.mean(0), stacked.std(0) + 1e-6
    batches = []
    for idx in groups.values():
        x = torch.tensor((np.stack([inputs[i][0] for i in idx]) - mean) / std,
                         dtype=torch.float32)
        c = torch.tensor((np.stack([inputs[i][1] for i in idx]) - mean[len(MATCH):])
                         / std[len(MATCH):], dtype=torch.float32)
        batches.append((x, c, torch.tensor([labels[i] for i in idx]),
                        torch.tensor(weights[idx], dtype=torch.float32)))
    torch.manual_seed(seed)
    layer = torch.nn.Linear(N_INPUT, hidden)
    out = torch.nn.Linear(hidden, 1, bias=False)
    skip = torch.nn.Linear(N_INPUT, 1)
    none = torch.nn.Linear(len(CONTEXT), 1, bias=False)
    params = [*layer.parameters(), *out.parameters(), *skip.parameters(), *none.parameters()]
    opt = torch.optim.Adam(params, lr=0.01, weight_decay=weight_decay)
    total = float(weights.sum())
    for _ in range(epochs):
        opt.zero_grad()
        loss = 0.0
        for x, c, y, w in batches:
            u = torch.cat([(out(torch.tanh(layer(x))) + skip(x)).squeeze(-1), none(c)], 1)
            loss = loss + (torch.nn.functional.cross_entropy(u, y, reduction="none")
                           * w).sum() / total
        loss.backward()
        opt.step()

    def array(t) -> np.ndarray:
        return t.detach().numpy().astype(float)

    return NeuralCalibration(mean, std, array(layer.weight).T, array(layer.bias),
                             array(out.weight)[0], array(skip.weight)[0],
                             float(skip.bias.item()), array(none.weight)[0])


DTW_WEIGHT = {False: 0.5, True: 0.85}
"""The templates' share of the blended log-probability (`blend`) of a running window and of a
final one; the network's is the rest. The templates weigh more on a final window: with an
equal share, more real swipes' final windows stay unsure. Measured on the SHREC'17 train
split's people, leave-people-out, over several seeds (`cbgo train dynamic --real DIR --folds 4
--calibration-seed K`)."""


def net_rows(names: list[str], net_names: list[str], known: set[str]
             ) -> tuple[np.ndarray, np.ndarray]:
    """Returns where the alternatives the network speaks for stand in `names` and `net_names`.

    Args:
        names: the classifier's alternatives (templates, then ``none``).
        net_names: the network's alternatives (its gestures, then ``none``).
        known: the names whose template is the one the network learned with (a user's own
            version of a shipped gesture is not); ``none`` always is.
    """
    shared = [i for i, n in enumerate(names) if n in net_names and (n in known or n == NONE)]
    return np.array(shared, dtype=int), np.array([net_names.index(names[i]) for i in shared],
                                                 dtype=int)


def blend(probs: np.ndarray, net_probs: np.ndarray, rows: tuple[np.ndarray, np.ndarray],
          dtw_weight: float = DTW_WEIGHT[False]) -> np.ndarray:
    """Returns the templates' probabilities with the trajectory network's multiplied in.

    Args:
        probs: the templates' probabilities over the classifier's alternatives.
        net_probs: the network's probabilities over its own.
        rows: where the alternatives the network speaks for stand in each (`net_rows`).
        dtw_weight: the templates' share of the blended log-probability.
    """
    shared, theirs = rows
    mass = float(probs[shared].sum())
    if len(shared) < 2 or mass <= 0.0:
        return probs
    theirs = net_probs[theirs]
    log = (dtw_weight * np.log(np.maximum(probs[shared] / mass, 1e-12))
           + (1.0 - dtw_weight) * np.log(np.maximum(theirs / theirs.sum(), 1e-12)))
    mixed = np.exp(log - log.max())
    out = probs.copy()
    out[shared] = mass * mixed / mixed.sum()
    return out


class Classifier:
    """A template library plus its calibration: windows in, probability vectors out.

    Args:
        templates: the library (names unique).
        calibration: the shared weights.
        dtw: "exact" (fastdtw's compiled exact DTW if built, else numpy), "numpy" (the
            vectorised exact DTW) or "fastdtw" (approximate, radius 1); see `dtw`.
        net: a second opinion that reads the whole path (`trajnet.TrajectoryNet`: names and
            ``probabilities(obs, final, pose_change, peak_speed, side)``), multiplied in by
            `blend`; None: the templates alone.
        net_known: the template names the network learned with (None: all); a user's own
            version of a shipped gesture is left out, and keeps the templates' probability.
    """

    def __init__(self, templates: list[Template],
                 calibration: Calibration | NeuralCalibration, dtw: str = "exact",
                 net=None, net_known: set[str] | None = None):
        if not templates:
            raise ValueError("a classifier needs at least one template")
        names = [t.name for t in templates]
        if len(set(names)) != len(names) or NONE in names:
            raise ValueError(f"template names must be unique and not {NONE!r}: {names}")
        self.templates, self.calibration, self.dtw = templates, calibration, dtw
        self.names = [*names, NONE]
        if dtw not in DTW_MODES:
            raise ValueError(f"dtw {dtw!r} is not one of {', '.join(DTW_MODES)}")
        self.shapes = [np.ascontiguousarray(t.shape) for t in templates]
        self.bank = TemplateBank(self.shapes)
        self.compiled = fastdtw_backend() == "c"
        self.scales = np.array([t.scale for t in templates])
        self.extents = np.array([t.extent_mm for t in templates])
        self.pose_changes = np.array([t.pose_change for t in templates])
        self.reaches = np.array([reach_of(t.trajectory) for t in templates])
        self.mirror_rows = mirror_rows(templates)
        self.handed = self.mirror_rows >= 0  # templates learned in the right hand's space
        self.net = net
        self.net_known = set(names) if net_known is None else set(net_known)
        self.net_rows = None if net is None else net_rows(self.names, net.names, self.net_known)

    @property
    def second_opinion(self) -> list[str]:
        """The gestures the trajectory network gives an opinion on ([]: no network)."""
        if self.net_rows is None:
            return []
        return [self.names[i] for i in self.net_rows[0] if self.names[i] != NONE]

    @property
    def implementation(self) -> str:
        """Which DTW computes the distances: "fastdtw-compiled", "numpy" or "fastdtw-approx"."""
        if self.dtw == "fastdtw":
            return "fastdtw-approx"
        return "fastdtw-compiled" if self.dtw == "exact" and self.compiled else "numpy"

    def distances(self, obs: np.ndarray) -> np.ndarray:
        """Returns the per-step DTW distance of a window's shape to every template's."""
        shape = normalised(obs)
        if self.dtw == "fastdtw":
            return fastdtw_distances(shape, self.shapes)
        if self.dtw == "exact" and self.compiled:
            return compiled_dtw_distances(shape, self.shapes)
        return self.bank.distances(shape)

    def log_likelihoods(self, obs: np.ndarray) -> np.ndarray:
        """Returns each ProMP's log-likelihood of the window scaled to the template's size."""
        size = extent_of(obs)
        return np.array([t.promp.log_likelihood(obs * (extent / size))
                         for t, extent in zip(self.templates, self.extents, strict=True)])

    def features(self, obs: np.ndarray, final: bool = True, pose_change: float = 0.0,
                 peak_speed: float = 0.0, side: str = "right") -> np.ndarray:
        """Returns the window's (K + 1, N_THETA) feature rows (see `probabilities`).

        A left hand's window is matched with the templates learned in the right hand's space
        mirrored: the row of swipe_left is swipe_right's row of the mirrored window.
        """
        obs = obs - obs[0]
        rows = self._rows(obs, final, pose_change, peak_speed)
        if side == "left" and self.handed.any():
            rows[:-1][self.handed] = self._rows(mirrored(obs), final, pose_change,
                                                peak_speed)[self.mirror_rows[self.handed]]
        return rows

    def _rows(self, obs: np.ndarray, final: bool, pose_change: float, peak_speed: float
              ) -> np.ndarray:
        return features(obs, self.distances(obs), self.scales, self.log_likelihoods(obs),
                        np.abs(pose_change - self.pose_changes), final, peak_speed, self.reaches)

    def probabilities(self, obs: np.ndarray, final: bool = True, pose_change: float = 0.0,
                      peak_speed: float = 0.0, side: str = "right") -> np.ndarray:
        """Returns (K + 1,) probabilities over `names` (templates, then none); they sum to 1.

        Args:
            obs: the window's observation (n, 4).
            final: whether the window ends its stroke (else it is one evaluated mid-stroke).
            pose_change: the window's change of hand shape (`stroke.Window.pose_change`).
            peak_speed: the stroke's highest speed (`stroke.Window.peak_speed`), mm/s.
            side: the hand's side ("left" or "right").
        """
        probs = self.calibration.probabilities(self.features(obs, final, pose_change,
                                                             peak_speed, side))
        if self.net is None:
            return probs
        return blend(probs, self.net.probabilities(obs, final, pose_change, peak_speed, side),
                     self.net_rows, DTW_WEIGHT[bool(final)])

    def window_features(self, window) -> np.ndarray:
        """Returns the feature rows of a `stroke.Window`."""
        return self.features(window.obs, window.final, window.pose_change, window.peak_speed,
                             window.side)

    def classify(self, window) -> np.ndarray:
        """Returns the probabilities of a `stroke.Window`."""
        return self.probabilities(window.obs, window.final, window.pose_change,
                                  window.peak_speed, window.side)
