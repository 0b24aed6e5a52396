"""The open-set rule the classifier applies: a frame far from every training gesture is ``none``.

Why: the ``none`` class only knows the non-gestures it was shown, so a pose outside the vocabulary
that training never had goes wherever the network's boundaries happen to put it (``cbgo bench static
--folds 25 --no-latency`` prints how many of the unknown poses held out of training the networks
reject alone, and with this rule). A frame far from all training gesture frames is suspect whatever
the softmax says (the k-th-nearest-neighbour rule of Sun et al., "Out-of-distribution detection with
deep nearest neighbors", ICML 2022).

How:

- **Where distance is taken:** the network's hidden layer at the posterior mean weights
  (`Posterior.embed`), where the features that tell the gestures apart dominate. The mean
  weights, not the draws, so the references hold whatever ``--samples`` the service runs.
- **The distance:** to the `NEIGHBOURS`-th nearest of the references, which are training
  gesture frames: up to `REFERENCE_PER_CLASS` of each gesture (a gesture taught with a few
  takes is covered as the built-in ones are).
- **How far is far:** other training gesture frames, disjoint from the references (up to
  `CALIBRATION_PER_CLASS` of each gesture), give the distances an in-vocabulary frame has.
  A frame's conformal p-value is the share of them at least as far as it is,
  ``π = (1 + #{c ≥ d}) / (n + 1)``.
- **What it does to the probabilities:** the gestures' probabilities are multiplied by
  ``w = min(1, π / ALPHA)`` and ``none`` takes the rest. A frame nearer than 99 % of the
  training gesture frames (`ALPHA` = 0.01) is untouched; past that the gestures fade, and a
  frame farther than every calibration frame keeps a gesture probability of at most
  ``1 / ((n + 1)·ALPHA)``. Soft rather than a cut: a frame just past the line is only made
  less sure, and the probabilities stay a distribution.

The hidden units are tanh: a frame very far out saturates them and can land where training
frames do, so the rule catches most far frames, not all. A model without a ``none`` class has
nowhere to put the faded mass and applies no rule.

`cbgo bench static` reports what the rule adds (the network's answers with and without it).
"""

from __future__ import annotations

import base64
from dataclasses import dataclass

import numpy as np

ALPHA = 0.01
NEIGHBOURS = 10
REFERENCE_PER_CLASS = 750
CALIBRATION_PER_CLASS = 750
STORED = {"reference": np.float16, "calibration": np.float32}
"""How the arrays are stored in the model's JSON (base64, little-endian): the references are
tanh units in [-1, 1], which float16 holds to 0.001 (6000 × 32 of them: 0.5 MB, not 2 MB of
decimal text)."""
_CHUNK = 2000  # query rows per distance matrix (2000 × 6000 float64: 96 MB)


def fade_into_none(probs: np.ndarray, keep: np.ndarray, none_index: int) -> np.ndarray:
    """Returns (N, C) probabilities with each row's gestures faded into ``none``.

    ``keep`` (N,) in [0, 1] is the share of its gestures' probability a row keeps: 1 keeps the
    row, 0 makes it ``none``; the rest moves to ``none``, so rows still sum to 1.
    """
    out = probs * keep[:, None]
    out[:, none_index] = probs[:, none_index] + (1.0 - keep) * (1.0 - probs[:, none_index])
    return out


def kth_distance(reference: np.ndarray, query: np.ndarray, k: int,
                 ref_sq: np.ndarray | None = None) -> np.ndarray:
    """Returns each query row's Euclidean distance to its k-th nearest reference row (k ≥ 1).

    ``ref_sq``: the references' squared norms, if already known (they are most of the cost of
    one query row).
    """
    out = np.empty(len(query))
    ref_sq = (reference ** 2).sum(1) if ref_sq is None else ref_sq
    for i in range(0, len(query), _CHUNK):
        d2 = _squared_distances(reference, query[i:i + _CHUNK], ref_sq)
        out[i:i + _CHUNK] = np.sqrt(np.maximum(np.partition(d2, k - 1, 1)[:, k - 1], 0.0))
    return out


def _squared_distances(reference: np.ndarray, query: np.ndarray, ref_sq: np.ndarray
                       ) -> np.ndarray:
    """Returns the (Q, R) squared Euclidean distances (may round a hair below zero)."""
    return (query ** 2).sum(1)[:, None] + ref_sq[None] - 2.0 * query @ reference.T


def split_per_class(y: np.ndarray, classes: list[int], rng: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Returns disjoint row indices per class: references and calibration rows.

    Each class gives up to `REFERENCE_PER_CLASS` references and `CALIBRATION_PER_CLASS`
    calibration rows; a class with fewer rows splits them in half.
    """
    reference, calibration = [], []
    for c in classes:
        rows = rng.permutation(np.flatnonzero(y == c))
        n_ref = min(REFERENCE_PER_CLASS, (len(rows) + 1) // 2)
        reference.append(rows[:n_ref])
        calibration.append(rows[n_ref:n_ref + CALIBRATION_PER_CLASS])
    return np.concatenate(reference), np.concatenate(calibration)


@dataclass
class OpenSet:
    """References in the hidden layer and the distances of in-vocabulary frames.

    Attributes:
        reference: (R, H) hidden vectors of training gesture frames.
        calibration: (n,) sorted k-th neighbour distances of other training gesture frames.
        neighbours: k.
        alpha: the p-value below which gestures fade.
    """

    reference: np.ndarray
    calibration: np.ndarray
    neighbours: int = NEIGHBOURS
    alpha: float = ALPHA

    def __post_init__(self):
        self._ref_sq = (self.reference ** 2).sum(1)
        # The distance up to which a frame keeps its probabilities (its p-value reaches alpha):
        # the fewest calibration distances at least as far that make p / alpha ≥ 1, counted
        # with the very arithmetic `apply` uses.
        n = len(self.calibration)
        enough = (1.0 + np.arange(n + 1)) / (n + 1.0) / self.alpha >= 1.0
        least = int(np.argmax(enough)) if enough.any() else n + 1
        self._keeps_up_to = (np.inf if least == 0 else
                             -np.inf if least > n else float(self.calibration[n - least]))

    @classmethod
    def fit(cls, hidden: np.ndarray, y: np.ndarray, gesture_classes: list[int],
            rng: np.random.Generator) -> OpenSet:
        """Calibrates on a model's training rows (their hidden vectors and labels).

        Raises:
            ValueError: fewer than ``neighbours`` reference rows or no calibration row.
        """
        ref, cal = split_per_class(y, gesture_classes, rng)
        if len(ref) < NEIGHBOURS or len(cal) == 0:
            raise ValueError(f"open set needs at least {NEIGHBOURS} reference and one "
                             f"calibration gesture row, got {len(ref)} and {len(cal)}")
        reference = _stored("reference", hidden[ref])
        distance = _stored("calibration", kth_distance(reference, hidden[cal], NEIGHBOURS))
        return cls(reference, np.sort(distance))

    @property
    def threshold(self) -> float:
        """The distance past which gestures start to fade (the calibration's 1 − alpha quantile)."""
        return float(np.quantile(self.calibration, 1.0 - self.alpha))

    def p_values(self, hidden: np.ndarray) -> np.ndarray:
        """Returns each row's conformal p-value: how ordinary its distance is for a gesture."""
        distance = kth_distance(self.reference, hidden, self.neighbours, self._ref_sq)
        farther = len(self.calibration) - np.searchsorted(self.calibration, distance, "left")
        return (1.0 + farther) / (len(self.calibration) + 1.0)

    def apply(self, probs: np.ndarray, hidden: np.ndarray, none_index: int) -> np.ndarray:
        """Returns the probabilities with far frames' gestures faded into ``none``.

        Only the frames past the line get their p-value: a frame with ``neighbours``
        references within it keeps its answer, and counting them is cheaper than ranking every
        reference (most frames are ordinary; half the cost of a frame's classification).
        """
        keep = np.ones(len(hidden))
        far = ~self._near(hidden)
        if far.any():
            keep[far] = np.minimum(1.0, self.p_values(hidden[far]) / self.alpha)
        return fade_into_none(probs, keep, none_index)

    def _near(self, hidden: np.ndarray) -> np.ndarray:
        """Returns whether each row's k-th nearest reference lies within the keeping line."""
        if np.isinf(self._keeps_up_to):
            return np.full(len(hidden), self._keeps_up_to > 0)
        near = np.empty(len(hidden), dtype=bool)
        for i in range(0, len(hidden), _CHUNK):
            d = np.sqrt(np.maximum(_squared_distances(self.reference, hidden[i:i + _CHUNK],
                                                      self._ref_sq), 0.0))
            near[i:i + _CHUNK] = (d <= self._keeps_up_to).sum(1) >= self.neighbours
        return near

    def to_dict(self) -> dict:
        """Returns plain data (JSON-safe) for the model's metadata."""
        return {"rule": "kth-neighbour-conformal", "neighbours": self.neighbours,
                "alpha": self.alpha, "reference": _pack("reference", self.reference),
                "calibration": _pack("calibration", self.calibration)}

    @classmethod
    def from_dict(cls, data: dict, width: int) -> OpenSet:
        """Rebuilds the rule from `to_dict` data for a hidden layer of ``width`` units.

        Raises:
            ValueError: malformed data.
        """
        reference = _unpack("reference", data["reference"])
        calibration = np.sort(_unpack("calibration", data["calibration"]))
        neighbours, alpha = int(data["neighbours"]), float(data["alpha"])
        if reference.ndim != 2 or reference.shape[1] != width:
            raise ValueError(f"open-set references must be (R, {width})")
        if not 1 <= neighbours <= len(reference) or calibration.ndim != 1 or not len(calibration):
            raise ValueError("open set needs 1 <= neighbours <= references and calibration "
                             "distances")
        if not 0.0 < alpha < 1.0 or not (np.isfinite(reference).all()
                                        and np.isfinite(calibration).all()):
            raise ValueError("open-set alpha must lie in (0, 1), and every value be finite")
        return cls(reference, calibration, neighbours, alpha)


def _stored(name: str, values: np.ndarray) -> np.ndarray:
    """Returns values as they come back from the model file (rounded to their stored type)."""
    return np.asarray(values).astype(STORED[name]).astype(np.float64)


def _pack(name: str, values: np.ndarray) -> dict:
    array = np.ascontiguousarray(values, dtype=np.dtype(STORED[name]).newbyteorder("<"))
    return {"dtype": array.dtype.name, "shape": list(array.shape),
            "base64": base64.b64encode(array.tobytes()).decode("ascii")}


def _unpack(name: str, packed: dict) -> np.ndarray:
    """Reads a `_pack`ed array back.

    Raises:
        ValueError: another dtype, or a size that does not match the shape.
    """
    dtype = np.dtype(STORED[name]).newbyteorder("<")
    if packed["dtype"] != dtype.name:
        raise ValueError(f"open-set {name} must be stored as {dtype.name}")
    shape = tuple(int(n) for n in packed["shape"])
    raw = base64.b64decode(packed["base64"], validate=True)
    if len(raw) != int(np.prod(shape)) * dtype.itemsize:
        raise ValueError(f"open-set {name}: {len(raw)} bytes do not hold shape {shape}")
    return np.frombuffer(raw, dtype=dtype).reshape(shape).astype(np.float64)
