"""An open-set rule, measured beside the model: how far a frame is from every training gesture.

Why: the ``none`` class only knows the non-gestures it was shown, so a pose outside the
vocabulary that training never had goes wherever the network's boundaries happen to put it. A
frame far from all training gesture frames is suspect whatever the softmax says. The distance
is taken in the network's hidden layer (the first layer's activations averaged over the
posterior draws), where the features that tell the gestures apart dominate, and it is the
distance to the `NEIGHBOURS`-th nearest of `REFERENCE_ROWS` training gesture frames. The
threshold is calibrated on TRAINING frames only: the `QUANTILE` of the same distance for
`CALIBRATION_ROWS` other training gesture frames (a frame counts its own copy among the
references, so one more neighbour is taken for them).

The hidden units are tanh: a frame very far out saturates them and can land where training
frames do, so the rule catches most far frames, not all.

`crossval` reports what the rule would do (rejection of held-out unknown poses, accuracy of the
known gestures with a rejected frame counted wrong); the service does not apply it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cbgo.services.static_gesture.classifier import NONE, StaticClassifier

QUANTILE = 0.99
NEIGHBOURS = 10
REFERENCE_ROWS = 6000
CALIBRATION_ROWS = 3000
_CHUNK = 2000  # query rows per distance matrix (2000 × 6000 float64: 96 MB)


def kth_distance(reference: np.ndarray, query: np.ndarray, k: int) -> np.ndarray:
    """Returns each query row's Euclidean distance to its k-th nearest reference row (k ≥ 1)."""
    out = np.empty(len(query))
    ref_sq = (reference ** 2).sum(1)
    for i in range(0, len(query), _CHUNK):
        q = query[i:i + _CHUNK]
        d2 = (q ** 2).sum(1)[:, None] + ref_sq[None] - 2.0 * q @ reference.T
        out[i:i + _CHUNK] = np.sqrt(np.maximum(np.partition(d2, k - 1, 1)[:, k - 1], 0.0))
    return out


@dataclass
class OpenSet:
    """Reference hidden vectors and the calibrated distance threshold of one model."""

    reference: np.ndarray
    threshold: float

    @classmethod
    def fit(cls, clf: StaticClassifier, x57: np.ndarray, y: np.ndarray, names: list[str],
            rng: np.random.Generator, quantile: float = QUANTILE) -> OpenSet:
        """Calibrates on a model's training rows (``none`` rows are not references)."""
        known = np.flatnonzero(np.array(names)[y] != NONE)
        ref = known[rng.choice(len(known), min(REFERENCE_ROWS, len(known)), replace=False)]
        cal = known[rng.choice(len(known), min(CALIBRATION_ROWS, len(known)), replace=False)]
        reference = clf.posterior.hidden(clf.network_inputs(x57[ref]))
        own = clf.posterior.hidden(clf.network_inputs(x57[cal]))
        distance = kth_distance(reference, own, NEIGHBOURS + 1)
        return cls(reference, float(np.quantile(distance, quantile)))

    def novel(self, clf: StaticClassifier, x57: np.ndarray) -> np.ndarray:
        """Returns a bool per row: farther from the training gestures than the threshold."""
        hidden = clf.posterior.hidden(clf.network_inputs(x57))
        return kth_distance(self.reference, hidden, NEIGHBOURS) > self.threshold
