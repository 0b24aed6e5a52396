"""The static calibration bench's choice of takes: nested, spread, never the scored ones."""

import pytest

from cbgo_tools.static_gesture.calibration import KS, chosen_takes, scored_takes


@pytest.mark.parametrize("n", [2, 3, 6, 10, 11, 40])
def test_every_k_records_takes_the_largest_k_records_and_none_it_scores(n):
    largest = set(chosen_takes(n, max(KS)))
    scored = set(scored_takes(n))
    assert scored and not scored & largest
    assert scored | largest == set(range(n))
    for k in KS:
        recorded = chosen_takes(n, k)
        assert set(recorded) <= largest
        assert len(recorded) == min(k, len(largest))


def test_takes_spread_over_the_recording():
    assert chosen_takes(10, 3) == [2, 4, 8]
    assert chosen_takes(10, 1) == [4]
