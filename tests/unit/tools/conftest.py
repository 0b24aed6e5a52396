"""Fixtures of the offline tools' tests."""

import numpy as np
import pytest


def _write_set(root, people_train=("ann",), people_test=("bob",)):
    root.mkdir(parents=True, exist_ok=True)
    (root / "train_gestures.txt").write_text("\n".join(people_train) + "\n")
    (root / "test_gestures.txt").write_text("\n".join(people_test) + "\n")
    t = np.arange(0, 1500, 16.7)
    for person in (*people_train, *people_test):
        folder = root / person
        folder.mkdir()
        for name, sign in (("left-swipe", -1), ("right-swipe", 1)):
            x = sign * 120.0 * np.clip(t / 1200.0, 0, 1)
            rows = np.column_stack([x, np.full_like(t, 230.0), np.zeros_like(t), 1e12 + t])
            np.savetxt(folder / f"{name}.csv", rows, fmt="%.3f")
        (folder / "circle.csv").write_text("0 230 0 1000000000000\n1 231 0 1000000000017\n")
    return root


@pytest.fixture
def midair_set():
    """Writes a tiny GestureMidAir-like folder (one train and one test person); returns a maker."""
    return _write_set
