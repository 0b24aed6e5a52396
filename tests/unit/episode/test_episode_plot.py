"""`cbgo plot episode` draws the paper's episode figure from a recording."""

import pytest

from cbgo import wire
from cbgo.cli.main import main
from cbgo.recording import Recorder
from cbgo.services.episode import plot

PNG = b"\x89PNG\r\n\x1a\n"


def make_recording(drive, path, with_episode_messages=True):
    """Two episodes (point, then grab + swipe_down with a one-frame dropout) in an MCAP."""
    d = drive()
    recorder = Recorder(path)

    def write(key, payload):
        recorder.write(key, payload, int(wire.decode(payload)["ts"] * 1e9))

    feed_raw = d.bus.feed_raw

    def recording_feed_raw(topic, payload):
        write(d.bus.keys.of(topic), payload)
        return feed_raw(topic, payload)

    d.bus.feed_raw = recording_feed_raw
    d.empty(0.3)
    d.hold(0.8, "point")
    d.empty(0.4)
    d.hold(0.7, "grab")
    d.frame([])
    start = d.now
    d.hold(0.5, "none")
    d.dynamic("swipe_down", start, d.now)
    d.empty(0.4)
    if with_episode_messages:
        for key, payload in d.bus.transport.sent:
            write(key, payload)
    recorder.close()
    return d


def run_cli(*argv):
    with pytest.raises(SystemExit) as exit_info:
        main(["plot", "episode", *map(str, argv)])
    return exit_info.value.code


def test_the_episode_figure_is_drawn_from_a_recording(drive, tmp_path, capsys):
    path = tmp_path / "session.mcap"
    d = make_recording(drive, path)
    out = tmp_path / "episode.png"
    assert run_cli(path, "--episode", "1", "-o", out) == 0
    assert out.read_bytes()[:8] == PNG and out.stat().st_size > 20_000
    assert f"wrote {out}" in capsys.readouterr().out
    assert run_cli(path, "--list") == 0
    listing = capsys.readouterr().out.splitlines()
    assert len(listing) == 2 and "point" in listing[0] and "grab, swipe_down" in listing[1]
    assert d.summaries[1]["episode"] in listing[1]
    by_id = tmp_path / "by-id.png"
    assert run_cli(path, "--episode", d.summaries[0]["episode"], "-o", by_id) == 0
    assert by_id.read_bytes()[:8] == PNG


def test_without_episode_events_the_episodes_are_segmented_from_the_frames(drive, tmp_path):
    path = tmp_path / "gestures-only.mcap"
    make_recording(drive, path, with_episode_messages=False)
    traffic = plot.load(path)
    spans = plot.episodes(traffic, plot.EvidenceSettings())
    assert [s.recomputed for s in spans] == [True, True]
    assert [[t["gesture"] for t in s.triggers] for s in spans] == [["point"],
                                                                   ["grab", "swipe_down"]]
    out = tmp_path / "recomputed.png"
    assert run_cli(path, "-o", out) == 0 and out.read_bytes()[:8] == PNG


def test_an_unknown_episode_or_a_bad_file_is_an_error(drive, tmp_path, capsys):
    path = tmp_path / "session.mcap"
    make_recording(drive, path)
    assert run_cli(path, "--episode", "7", "-o", tmp_path / "x.png") == 1
    assert "no episode '7'" in capsys.readouterr().err
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file")
    assert run_cli(junk) == 1
    assert not (tmp_path / "x.png").exists()
