"""Dynamic time warping: exact (fastdtw's compiled ``dtw`` or vectorised numpy) and fastdtw.

Classification compares one observed stroke's shape (n × 4) with every template's (m_k × 4) by
DTW: Euclidean point cost, steps (1,0), (0,1), (1,1), the accumulated cost of the best path
divided by ``n + m_k`` (a per-step distance, comparable across lengths).

Which DTW (measured on 120 real end-of-stroke windows, n median 13, templates 9–12 samples, the
5-template library, 2 shared cores; ``cbgo bench dynamic`` repeats it):

============================================  ==========  =================================
implementation                                exact?      ms per window, whole library
============================================  ==========  =================================
fastdtw's ``dtw``, compiled, ``dist=2``       exact       0.15
`TemplateBank` (vectorised numpy, below)      exact       0.33
fastdtw ``fastdtw``, compiled, ``dist=2``     approx.     0.33 (radius 1; 0 % error here)
fastdtw ``fastdtw``, compiled, ``dist=`` fn   approx.     7.4
plain Python loops (`dtw_naive`)              exact       2–7
fastdtw ``fastdtw``, pure Python, ``dist=2``  approx.     5.6
fastdtw's ``dtw``, pure Python, ``dist=2``    exact       9.0
============================================  ==========  =================================

fastdtw installs as pure Python unless it is built with Cython and numpy present and
``--no-build-isolation`` (the Makefile does); its compiled path also needs an integer ``dist``
(a p-norm) — a Python callable calls back into Python for every cell. At these lengths the
approximation buys nothing: exact DTW is as fast. So ``exact`` (the default) uses fastdtw's
compiled exact ``dtw`` with ``dist=2`` when the extension is there, and `TemplateBank` when it
is not (25× faster than fastdtw's pure-Python fallback); both equal `dtw_naive`. ``fastdtw``
(radius 1) stays available as the approximate mode.

`TemplateBank.costs` computes, per row ``i`` of the templates and for all of them at once,
``D[i, j] = C[i, j] + min(D[i-1, j-1], D[i-1, j], D[i, j-1])`` as a min-plus scan: with
``a_j = C[i, j] + min(D[i-1, j-1], D[i-1, j])`` and ``S_j = Σ_{l ≤ j} C[i, l]``,
``D[i, j] = S_j + min_{k ≤ j} (a_k − S_k)`` — a cumulative sum and a running minimum, so each
row is a few numpy calls over every template, and the Python loop has ``max(m_k)`` turns
whatever the observation's length. It equals `dtw_naive` up to float rounding. Templates of
different lengths are padded at their end; template ``k``'s cost is read at its own last row,
before any padding row is reached.
"""

from __future__ import annotations

import math

import numpy as np


def dtw_naive(a: np.ndarray, b: np.ndarray) -> float:
    """Returns the accumulated DTW cost of a (n, D) against b (m, D); the plain O(nm) loops.

    The reference the fast version is tested against.
    """
    n, m = len(a), len(b)
    acc = [[math.inf] * (m + 1) for _ in range(n + 1)]
    acc[0][0] = 0.0
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            cost = math.dist(a[i - 1], b[j - 1])
            acc[i][j] = cost + min(acc[i - 1][j - 1], acc[i - 1][j], acc[i][j - 1])
    return acc[n][m]


class TemplateBank:
    """Templates stacked and padded once, so each query is one batched DTW.

    Args:
        templates: the (m_k, D) template trajectories.
    """

    def __init__(self, templates: list[np.ndarray]):
        if not templates:
            raise ValueError("a template bank needs at least one template")
        self.lengths = np.array([len(t) for t in templates])
        width = int(self.lengths.max())
        dims = templates[0].shape[1]
        self.padded = np.zeros((len(templates), width, dims))
        for k, t in enumerate(templates):
            self.padded[k, :len(t)] = t
            self.padded[k, len(t):] = t[-1]  # finite padding, read by no template's result

    def __len__(self) -> int:
        return len(self.lengths)

    def costs(self, x: np.ndarray) -> np.ndarray:
        """Returns (K,) accumulated DTW costs of x (n, D) against every template."""
        x = np.asarray(x, dtype=float)
        # (K, M, n) point costs, all templates at once; rows run along the templates, so the
        # Python loop has max(m_k) turns whatever the observation's length.
        cost = np.sqrt(((self.padded[:, :, None, :] - x[None, None, :, :]) ** 2).sum(-1))
        out = np.empty(len(self))
        row = np.cumsum(cost[:, 0, :], axis=1)  # D[0, j]: only steps along x
        done = self.lengths == 1
        out[done] = row[done, -1]
        best = np.empty_like(row)
        for i in range(1, int(self.lengths.max())):
            c = cost[:, i, :]
            best[:, 0] = row[:, 0]
            np.minimum(row[:, 1:], row[:, :-1], out=best[:, 1:])  # min(up, diagonal)
            s = np.cumsum(c, axis=1)
            row = s + np.minimum.accumulate(c + best - s, axis=1)
            done = self.lengths == i + 1
            out[done] = row[done, -1]
        return out

    def distances(self, x: np.ndarray) -> np.ndarray:
        """Returns (K,) per-step DTW distances: cost / (n + m_k)."""
        return self.costs(x) / (len(x) + self.lengths)


def dtw_library(x: np.ndarray, templates: list[np.ndarray]) -> np.ndarray:
    """Returns the per-step DTW distances of x against each template (builds a bank)."""
    return TemplateBank(templates).distances(x)


def fastdtw_backend() -> str | None:
    """Returns which fastdtw is installed: "c" (compiled), "python" (fallback) or None."""
    try:
        import fastdtw  # noqa: F401
    except ImportError:
        return None
    try:
        from fastdtw import _fastdtw  # noqa: F401
    except ImportError:
        return "python"
    return "c"


def compiled_dtw_distances(x: np.ndarray, templates: list[np.ndarray]) -> np.ndarray:
    """Returns exact per-step distances by fastdtw's compiled ``dtw`` (``dist=2``).

    Raises:
        ImportError: fastdtw's compiled extension is not installed.
    """
    from fastdtw._fastdtw import dtw

    x = np.ascontiguousarray(x, dtype=np.float64)
    return np.array([dtw(x, t, dist=2)[0] / (len(x) + len(t)) for t in templates])


def fastdtw_distances(x: np.ndarray, templates: list[np.ndarray], radius: int = 1
                      ) -> np.ndarray:
    """Returns per-step distances by fastdtw (approximate), Euclidean via ``dist=2``.

    ``dist=2`` (the integer p-norm) keeps fastdtw's compiled extension on its C path; a Python
    callable would call back into Python for every cell.

    Raises:
        ImportError: fastdtw is not installed.
    """
    from fastdtw import fastdtw

    x = np.ascontiguousarray(x, dtype=np.float64)
    out = np.empty(len(templates))
    for k, t in enumerate(templates):
        cost, _ = fastdtw(x, np.ascontiguousarray(t, dtype=np.float64), radius=radius, dist=2)
        out[k] = cost / (len(x) + len(t))
    return out
