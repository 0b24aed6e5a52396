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

Probabilities come from a **conditional logit** (McFadden) whose few weights θ are shared by all
templates, so a template added later needs no retraining of the calibration:

- template k's utility ``u_k = θ₁·log(d_k / s_k) + θ₂·ℓ_k + θ₃·|c − c_k| + θ₉·(1 − cos
  φ_k)``: ``d_k`` the per-step DTW distance of the window's shape to the template's, ``s_k``
  its scale, ``ℓ_k`` the ProMP's robust log-likelihood per value (clipped at
  `LOGLIK_FLOOR`), ``c`` the window's change of hand shape and ``c_k`` the template's (forming
  or releasing a static pose rolls the palm too), ``φ_k`` the angle between the window's
  heading (start → farthest sample, roll included) and the template's: a swipe right of a
  real, jittery hand still heads right;
- "no gesture" has ``u_none = θ₄ + θ₅·log(extent) + θ₆·[stroke still running] +
  θ₇·log(peak speed)``: the extent is the window's largest excursion from its start (mm, roll
  included as k·roll), the peak speed the stroke's highest (mm/s, likewise): a drift, a slow
  re-positioning or a preparation is slower than a gesture; and ``θ₈·log(path / extent)``: a
  gesture goes where it goes, a wobble or a shake wanders;
- ``p = softmax(u)``: a probability vector over the templates plus ``none`` that sums to 1.

θ is fitted by penalised maximum likelihood (`fit_calibration`) on every window the segmenter
evaluates — mid-stroke and final — of simulated users that the templates were not learned from,
gestures and non-gestures alike (a static pose formed or released, the roll back after rotate,
the move out of the field, twitches). A window's truth is what the person is doing in it, so a
window early in a stroke is that gesture, and the model learns how little of a stroke it can
tell apart from nothing. `cbgo train dynamic` fits θ; `cbgo bench dynamic` reports the
calibration (ECE) on other users, whose styles lie outside the training range.
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

    @classmethod
    def learn(cls, name: str, demos: list[np.ndarray], durations: list[float] | None = None,
              pose_changes: list[float] | None = None, source: str = "default",
              user: str | None = None, rng_seed: int = 0) -> Template:
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
                   user)

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
                "created": self.created}

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
                       float(data.get("created", 0.0)))
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


def normalised(obs: np.ndarray) -> np.ndarray:
    """Returns a trajectory relative to its start and scaled to unit extent (its shape)."""
    return (obs - obs[0]) / extent_of(obs)


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


class Classifier:
    """A template library plus its calibration: windows in, probability vectors out.

    Args:
        templates: the library (names unique).
        calibration: the shared weights.
        dtw: "exact" (fastdtw's compiled exact DTW if built, else numpy), "numpy" (the
            vectorised exact DTW) or "fastdtw" (approximate, radius 1); see `dtw`.
    """

    def __init__(self, templates: list[Template], calibration: Calibration,
                 dtw: str = "exact"):
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
                 peak_speed: float = 0.0) -> np.ndarray:
        """Returns the window's (K + 1, N_THETA) feature rows (see `probabilities`)."""
        obs = obs - obs[0]
        return features(obs, self.distances(obs), self.scales, self.log_likelihoods(obs),
                        np.abs(pose_change - self.pose_changes), final, peak_speed, self.reaches)

    def probabilities(self, obs: np.ndarray, final: bool = True, pose_change: float = 0.0,
                      peak_speed: float = 0.0) -> np.ndarray:
        """Returns (K + 1,) probabilities over `names` (templates, then none); they sum to 1.

        Args:
            obs: the window's observation (n, 4).
            final: whether the window ends its stroke (else it is one evaluated mid-stroke).
            pose_change: the window's change of hand shape (`stroke.Window.pose_change`).
            peak_speed: the stroke's highest speed (`stroke.Window.peak_speed`), mm/s.
        """
        return softmax_rows(self.features(obs, final, pose_change, peak_speed),
                            self.calibration.theta)

    def window_features(self, window) -> np.ndarray:
        """Returns the feature rows of a `stroke.Window`."""
        return self.features(window.obs, window.final, window.pose_change, window.peak_speed)

    def classify(self, window) -> np.ndarray:
        """Returns the probabilities of a `stroke.Window`."""
        return softmax_rows(self.window_features(window), self.calibration.theta)
