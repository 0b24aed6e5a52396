"""Episode boundaries: start on a hand, end after the debounce, by frame time or local clock."""

import pytest

from cbgo.services.episode.segmenter import Segmenter

P = 1 / 60


def feed(seg, visible, start=0.0):
    """Feeds frames at 60 Hz (ts = local clock); returns [(index, boundary)]."""
    out = []
    for i, v in enumerate(visible):
        t = start + i * P
        out += [(i, b) for b in seg.frame(t, t, v)]
    return out


def test_an_episode_starts_with_the_first_hand_frame():
    seg = Segmenter(0.15)
    (i, b), = feed(seg, [False, False, True, True])
    assert (i, b.kind, b.ts) == (2, "start", 2 * P) and seg.open


def test_it_ends_on_the_first_empty_frame_a_debounce_after_the_last_hand():
    seg = Segmenter(0.15)
    got = feed(seg, [True] * 10 + [False] * 20)
    (_, start), (i, end) = got
    assert end.kind == "end" and end.by == "frame" and end.ts == pytest.approx(9 * P)
    assert (i - 9) * P >= 0.15 > (i - 10) * P  # the first frame at least 150 ms later
    assert end.condition_at == pytest.approx(9 * P + 0.15)
    assert not seg.open


def test_a_dropout_shorter_than_the_debounce_does_not_split_the_episode():
    seg = Segmenter(0.15)
    got = feed(seg, [True] * 10 + [False] * 2 + [True] * 10 + [False] * 30)
    assert [b.kind for _, b in got] == ["start", "end"]


def test_a_frame_a_debounce_later_ends_it_though_its_stamp_jitters_a_little_early():
    seg = Segmenter(0.15)
    seg.frame(10.0, 0.0, True)
    assert seg.frame(10.140, 0.14, False) == []  # 10 ms short: not yet
    (end,) = seg.frame(10.1495, 0.15, False)  # the 9th frame at 60 Hz, stamped 0.5 ms early
    assert end.by == "frame" and end.ts == 10.0


def test_the_timer_ends_the_episode_when_frames_stop_coming():
    seg = Segmenter(0.15)
    feed(seg, [True] * 5)
    last = 4 * P
    assert seg.tick(last + 0.149) is None
    end = seg.tick(last + 0.151)
    assert end.kind == "end" and end.by == "clock" and end.ts == pytest.approx(last)
    assert seg.tick(last + 1.0) is None  # only once


def test_a_hand_after_a_long_gap_ends_the_old_episode_and_starts_a_new_one():
    seg = Segmenter(0.15)
    seg.frame(0.0, 0.0, True)
    got = seg.frame(0.5, 0.5, True)
    assert [(b.kind, b.ts) for b in got] == [("end", 0.0), ("start", 0.5)] and seg.open


def test_a_hand_after_frames_lost_on_the_network_continues_the_episode():
    # Ten frames (167 ms at 60 Hz) lost between publisher and service: no frame showed the
    # hand gone, so the gesture is not cut in two (seen in the compose demo on a loaded host).
    seg = Segmenter(0.15, clock_slack_s=2.0)
    seg.frame(0.0, 0.0, True)
    assert seg.frame(0.167, 0.167, True) == [] and seg.open
    assert seg.tick(0.167 + 2.0) is None  # the clock counts from the last hand frame
    (end,) = seg.frame(0.167 + 0.15, 0.167 + 0.15, False)  # an empty frame still ends it
    assert end.by == "frame" and end.ts == pytest.approx(0.167)


def test_a_hand_after_a_gap_as_long_as_the_clocks_wait_starts_a_new_episode():
    seg = Segmenter(0.15, clock_slack_s=2.0)
    seg.frame(0.0, 0.0, True)
    assert seg.frame(2.1, 0.2, True) == []  # 2.1 s on the frames' clock: within the wait
    got = seg.frame(2.1 + 2.15, 0.3, True)
    assert [(b.kind, b.ts) for b in got] == [("end", 2.1), ("start", 4.25)] and seg.open


def test_an_empty_frame_that_arrives_late_is_judged_by_the_local_clock():
    seg = Segmenter(0.15)
    seg.frame(10.0, 0.0, True)
    (end,) = seg.frame(10.05, 0.2, False)  # stamped 50 ms later, handled 200 ms later
    assert end.by == "clock" and end.condition_at == pytest.approx(0.15)


def test_with_a_clock_slack_frames_that_arrive_late_in_a_burst_keep_the_episode():
    seg = Segmenter(0.15, clock_slack_s=0.35)
    seg.frame(10.0, 0.0, True)
    # the process stalled for 0.3 s: its timer and an empty frame (a one-frame dropout) run
    # before the hand frames that were waiting
    assert seg.tick(0.3) is None
    assert seg.frame(10.02, 0.3, False) == []
    assert seg.frame(10.04, 0.3, True) == [] and seg.open
    assert seg.tick(0.5) is None
    end = seg.tick(0.3 + 0.5)  # frames really stopped: the clock ends it after both
    assert end.by == "clock" and end.ts == pytest.approx(10.04)
    assert end.condition_at == pytest.approx(0.3 + 0.5)  # the clock's condition, slack included


def test_the_debounce_must_be_positive():
    with pytest.raises(ValueError):
        Segmenter(0.0)
