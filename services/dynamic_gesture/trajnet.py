"""A second opinion on a stroke: a small network that reads its whole path, blended with DTW.

The templates' conditional logit (`classifier.NeuralCalibration`) sees a window through a few
numbers per template: how far its shape is from the template's by DTW, the ProMP's likelihood,
the heading, the size and speed. A real swipe that bows forward, rolls its palm and ends off
its line matches its template loosely, and a tap or a shake that happens to head one way
matches one well enough; those few numbers cannot tell the two apart. The trajectory network
reads the path itself: the window resampled to `POINTS` points (position and k·roll, relative
to its start, in units of its extent), the steps between them, where it ends (mm), and the
window's context (size, directness, running or final, change of hand shape). Not its speed:
the templates' calibration reads that (`encode`).
It is an MLP over the shipped gestures plus ``none``, learned from the same windows as the
calibration (`fit`), in the right hand's space: a left hand's window is read mirrored.

The classifier multiplies the two opinions (`classifier.blend`): ``log p = w·log p_dtw + (1 − w)·log
p_net`` over the gestures the network knows and ``none``, renormalised (a product of experts:
a gesture must look right to both). A gesture the network does not know (one a user taught,
or a shipped one a user's own version replaced) keeps the DTW probability it had; the blend
shares out only the rest. Measured on the SHREC'17 train split's people, leave-people-out
(`cbgo train dynamic --real DIR --folds 4`; docs/design/dynamic_gesture.md).

Training needs torch (`fit`); the service runs the numpy forward pass (`TrajectoryNet`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cbgo.services.dynamic_gesture.classifier import (
    MIRROR,
    NONE,
    extent_of,
    mirrored,
    path_of,
)

POINTS = 16  # a window resampled to this many points: a swipe's bow and its end both show
HIDDEN = 64
EPOCHS = 60


def encode(obs: np.ndarray, final: bool, pose_change: float, side: str) -> np.ndarray:
    """Returns the network's input for one window, in the right hand's space.

    Its path and size, not its speed or duration: a network that reads them learns the
    training people's speeds and misses quick textbook strokes (`cbgo bench dynamic
    --plain-strokes 2`); speed is left to the templates' calibration, which reads the peak
    speed.

    Args:
        obs: the window's observation (n, 4): x, y, z, k·roll (mm).
        final: whether the window ends its stroke.
        pose_change: the window's change of hand shape (`stroke.Window.pose_change`).
        side: the hand's side; a left hand's window is mirrored.
    """
    obs = np.asarray(obs, dtype=float)
    obs = obs - obs[0]
    if side == "left":
        obs = mirrored(obs)
    extent = extent_of(obs)
    t = np.linspace(0.0, 1.0, len(obs))
    s = np.linspace(0.0, 1.0, POINTS)
    path = np.stack([np.interp(s, t, obs[:, k]) for k in range(obs.shape[1])], axis=1)
    context = [np.log(extent), np.log(path_of(obs) / extent), float(final), float(pose_change)]
    return np.concatenate([(path / extent).ravel(), (np.diff(path, axis=0) / extent).ravel(),
                           path[-1] / 100.0, context])


def label_index(names: list[str], truth: str, side: str) -> int:
    """Returns the index in `names` of a window's truth in the right hand's space."""
    if side == "left":
        truth = MIRROR.get(truth, truth)
    return names.index(truth) if truth in names else names.index(NONE)


@dataclass
class TrajectoryNet:
    """The trained network: standardisation, three layers, and the names of its outputs.

    Attributes:
        names: the gestures it tells apart, then ``none`` (right hand's space).
        mean, std: (D,) standardisation of `encode`'s output.
        layers: [(W, b), ...], ReLU between them, softmax after the last.
    """

    names: list[str]
    mean: np.ndarray
    std: np.ndarray
    layers: list[tuple[np.ndarray, np.ndarray]]

    def probabilities(self, obs: np.ndarray, final: bool = True, pose_change: float = 0.0,
                      peak_speed: float = 0.0, side: str = "right") -> np.ndarray:
        """Returns probabilities over `names` in the hand's own space.

        A left hand's window is read mirrored, and the answer mirrored back: its swipe_left is
        its swipe_left. The arguments are the classifier's (`classifier.Classifier`);
        ``peak_speed`` is not read (`encode`).
        """
        x = (encode(obs, final, pose_change, side) - self.mean) / self.std
        for k, (w, b) in enumerate(self.layers):
            x = x @ w + b
            if k < len(self.layers) - 1:
                x = np.maximum(x, 0.0)
        p = np.exp(x - x.max())
        p /= p.sum()
        if side == "left":
            p = p[[self.names.index(MIRROR.get(n, n)) for n in self.names]]
        return p

    def to_dict(self) -> dict:
        """Returns plain data (JSON-safe)."""
        return {"kind": "mlp", "names": list(self.names), "points": POINTS,
                "mean": np.round(self.mean, 6).tolist(), "std": np.round(self.std, 6).tolist(),
                "layers": [{"w": np.round(w, 6).tolist(), "b": np.round(b, 6).tolist()}
                           for w, b in self.layers]}

    @classmethod
    def from_dict(cls, data: dict) -> TrajectoryNet:
        """Rebuilds a network from `to_dict` data.

        Raises:
            ValueError: malformed data, or a network that reads another encoding.
        """
        try:
            if data.get("kind") != "mlp" or int(data.get("points", 0)) != POINTS:
                raise ValueError(f"not an mlp over {POINTS} points")
            names = [str(n) for n in data["names"]]
            layers = [(np.asarray(layer["w"], dtype=float), np.asarray(layer["b"], dtype=float))
                      for layer in data["layers"]]
            net = cls(names, np.asarray(data["mean"], dtype=float),
                      np.asarray(data["std"], dtype=float), layers)
        except (KeyError, TypeError, AttributeError) as e:
            raise ValueError(f"malformed trajectory network ({e})") from None
        width = len(net.mean)
        for w, b in layers:
            if w.ndim != 2 or w.shape[0] != width or b.shape != (w.shape[1],):
                raise ValueError("trajectory network layers do not chain")
            width = w.shape[1]
        if width != len(names) or NONE not in names or len(net.std) != len(net.mean):
            raise ValueError("trajectory network outputs do not match its names")
        return net


def fit(windows: list, truths: list[str], names: list[str], weights: np.ndarray,
        seed: int = 0, epochs: int = EPOCHS) -> TrajectoryNet:
    """Learns a `TrajectoryNet` from labelled windows (`stroke.Window`, truth) (torch).

    Args:
        windows: the windows (`stroke.Window`), either hand.
        truths: per window, the gesture it is (any name not in `names` is ``none``).
        names: the gestures to tell apart, ``none`` last.
        weights: per window, its weight in the loss (the calibration's ``none`` share).
        seed: initial weights and batch order (deterministic on one machine).
        epochs: passes over the windows, in batches of 256.
    """
    import torch  # noqa: PLC0415 (training only: the service runs the numpy forward pass)

    x = np.stack([encode(w.obs, w.final, w.pose_change, w.side) for w in windows])
    y = np.array([label_index(names, t, w.side) for w, t in zip(windows, truths, strict=True)])
    mean, std = x.mean(0), x.std(0) + 1e-6
    inputs = torch.tensor((x - mean) / std, dtype=torch.float32)
    targets = torch.tensor(y)
    weight = torch.tensor(np.asarray(weights, dtype=float), dtype=torch.float32)
    torch.manual_seed(seed)
    net = torch.nn.Sequential(torch.nn.Linear(x.shape[1], HIDDEN), torch.nn.ReLU(),
                              torch.nn.Dropout(0.2), torch.nn.Linear(HIDDEN, HIDDEN),
                              torch.nn.ReLU(), torch.nn.Linear(HIDDEN, len(names)))
    opt = torch.optim.AdamW(net.parameters(), lr=1e-3, weight_decay=1e-3)
    for _ in range(epochs):
        order = torch.randperm(len(y))
        for start in range(0, len(y), 256):
            idx = order[start:start + 256]
            loss = torch.nn.functional.cross_entropy(net(inputs[idx]), targets[idx],
                                                     reduction="none")
            loss = (loss * weight[idx]).sum() / weight[idx].sum()
            opt.zero_grad()
            loss.backward()
            opt.step()
    linear = [m for m in net if isinstance(m, torch.nn.Linear)]
    layers = [(m.weight.detach().numpy().T.astype(float), m.bias.detach().numpy().astype(float))
              for m in linear]
    return TrajectoryNet(list(names), mean, std, layers)
