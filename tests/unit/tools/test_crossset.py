"""The cross-set table: segmenter overrides, and a real set's row from its trials."""

import pytest

from cbgo.services.dynamic_gesture.library import DEFAULT_PATH, Library
from cbgo.services.dynamic_gesture.stroke import SegmenterConfig
from cbgo_tools.dynamic_gesture import crossset
from cbgo_tools.dynamic_gesture.bench import replay_trial


def test_overrides_are_typed_as_the_segmenters_fields():
    out = crossset.parse_overrides(["min_peak_speed_mm_s=150", "min_samples=6",
                                    "centre_rule=true"])
    assert out == {"min_peak_speed_mm_s": 150.0, "min_samples": 6, "centre_rule": True}


@pytest.mark.parametrize("item", ["nosuch=1", "min_peak_speed_mm_s"])
def test_an_unknown_or_malformed_override_names_the_known_fields(item):
    with pytest.raises(ValueError, match="min_peak_speed_mm_s"):
        crossset.parse_overrides([item])


def test_a_sets_row_scores_its_train_peoples_swipes(tmp_path, midair_set):
    root = midair_set(tmp_path / "set")
    classifier = Library(DEFAULT_PATH, None).load().classifier()
    row = crossset.trial_row(classifier, "gesturemidair", root, SegmenterConfig(), replay_trial)
    assert row["device"] == "gesturemidair" and row["swipes"] == 2 and row["people"] == 1
    assert 0.0 <= row["balanced_accuracy"] <= 1.0
    assert row["silent"] + sum(1 for m in row["misses"] if "nothing" not in m) <= 2
    lines = []
    crossset.print_table([{**row, "what": "synthetic"}], [], lines.append)
    assert any(line.startswith("| gesturemidair | synthetic | 1 | 2 |") for line in lines)


def test_a_persons_calibration_never_uses_the_recording_it_scores():
    import numpy as np

    from cbgo.services.dynamic_gesture.pace import PACE_SHARE
    from cbgo.services.dynamic_gesture.stroke import Window
    from cbgo_tools.dynamic_gesture import calibration

    def take(speed):
        obs = np.zeros((6, 4))
        obs[:, 0] = np.linspace(0, -120, 6)
        return Window(1, "right", 1, np.arange(6) * 0.05, obs, True, 0.0, "slowed", speed,
                      np.zeros(3), speed, 0.0, 1.0)

    takes = [(0, "swipe_left", take(150.0)), (1, "swipe_left", take(170.0))]
    rng = np.random.default_rng(0)
    assert calibration.person_config([takes[0]], 1, rng, "ann", leave_out=0) is None
    config = calibration.person_config(takes, 1, rng, "ann", leave_out=0)
    assert config.min_peak_speed_mm_s == pytest.approx(PACE_SHARE * 170.0)
