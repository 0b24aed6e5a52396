"""The benches' figures: the people interval of a balanced accuracy, the goals' lines."""

import numpy as np

from cbgo.metrics import balanced_accuracy, format_goals, people_interval


def test_people_who_are_all_right_leave_no_doubt():
    y = np.array([0, 1, 0, 1, 0, 1])
    assert people_interval(y, y, np.array([1, 1, 2, 2, 3, 3])) == (1.0, 1.0)


def test_the_interval_draws_whole_people_and_holds_the_figure():
    rng = np.random.default_rng(3)
    people = np.repeat(np.arange(10), 20)
    y_true = rng.integers(0, 2, len(people))
    y_pred = y_true.copy()
    y_pred[people == 4] = 1 - y_pred[people == 4]  # one person read wrong throughout
    figure = balanced_accuracy(y_true, y_pred, 2)
    lo, hi = people_interval(y_true, y_pred, people)
    assert lo < figure < hi and hi == 1.0  # drawn without person 4, everything is right
    assert lo > 0.7  # person 4 drawn three times or more is rare
    assert people_interval(y_true, y_pred, people) == (lo, hi)  # deterministic
    # the same errors spread over every person are a surer figure
    spread = y_true.copy()
    spread[np.arange(0, len(people), 10)] = 1 - spread[np.arange(0, len(people), 10)]
    s_lo, s_hi = people_interval(y_true, spread, people)
    assert s_hi - s_lo < hi - lo


def test_goals_are_printed_passed_missed_or_not_measured():
    text = format_goals([("a ≥ 95 %", True, "96 %"), ("b ≤ 1/min", False, "2/min"),
                         ("c", None, "skipped")])
    assert text.splitlines() == ["  PASS  a ≥ 95 %: 96 %", "  MISS  b ≤ 1/min: 2/min",
                                 "  ----  c: skipped"]
