"""The supervisor behind `cbgo up`, on real (tiny) child processes."""

import sys
import time

from cbgo.supervisor import AliveWatcher, Child, Supervisor


def supervise_for(sup, seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        sup.poll()
        time.sleep(0.02)


def test_a_crashing_child_is_restarted_with_a_doubling_back_off():
    said = []
    crasher = Child("crasher", [sys.executable, "-c", "import sys; sys.exit(3)"])
    sup = Supervisor([crasher], say=said.append)
    sup.start_all()
    supervise_for(sup, 2.5)
    sup.stop_all()
    exits = [s for s in said if "exited with code 3" in s]
    assert len(exits) >= 2
    assert "restarting in 0.5 s" in exits[0]
    assert "restarting in 1.0 s" in exits[1]
    assert crasher.restarts >= 2


def test_stop_all_terminates_children_and_stops_restarting(capsys):
    sleeper = Child("sleeper", [sys.executable, "-c", "import time; print('up', flush=True); "
                                                      "time.sleep(60)"])
    sup = Supervisor([sleeper], say=lambda s: None)
    sup.start_all()
    time.sleep(0.5)
    t0 = time.monotonic()
    sup.stop_all()
    assert time.monotonic() - t0 < 3.0
    assert sleeper.proc.returncode is not None
    supervise_for(sup, 0.3)
    assert sleeper.restarts == 0
    assert "sleeper | up" in capsys.readouterr().out


def test_the_alive_watcher_reports_ready_once_and_then_losses_and_returns():
    said = []
    watcher = AliveWatcher(["router", "episode"], said.append)
    watcher.on_token("router", True)
    assert not watcher.ready.is_set() and watcher.missing() == ["episode"]
    watcher.on_token("episode", True)
    assert watcher.ready.is_set()
    watcher.on_token("episode", False)
    watcher.on_token("episode", True)
    assert said[0].startswith("ready: episode, router alive after")
    assert said[1:] == ["episode lost its liveliness token", "episode is alive again"]


class SlowOutput:
    """A terminal that takes 2 ms a line: copying a child's output takes time."""

    def __init__(self):
        self.lines = []

    def write(self, text):
        time.sleep(0.002)
        self.lines.append(text)

    def flush(self):
        pass


def test_a_stopped_childs_last_lines_are_ours_before_stop_all_returns(monkeypatch):
    # `cbgo up` exits right after stop_all: what a child says as it stops must be out by then.
    # The child says 200 lines and exits at once; copying them takes about 0.4 s.
    script = ("import signal, sys, time\n"
              "def bye(*_):\n"
              "    print('\\n'.join(f'bye {i}' for i in range(200)), flush=True)\n"
              "    sys.exit(0)\n"
              "signal.signal(signal.SIGTERM, bye)\n"
              "print('up', flush=True)\n"
              "time.sleep(60)\n")
    out = SlowOutput()
    monkeypatch.setattr(sys, "stdout", out)
    talker = Child("talker", [sys.executable, "-c", script])
    sup = Supervisor([talker], say=lambda s: None)
    sup.start_all()
    while not any(line.endswith(" up\n") for line in out.lines):  # its handler is in place
        time.sleep(0.02)
    sup.stop_all()
    assert out.lines[-1].endswith("talker | bye 199\n")


def test_a_child_with_a_configuration_error_is_not_restarted():
    said = []
    misconfigured = Child("misconfigured", [sys.executable, "-c", "import sys; sys.exit(2)"])
    sup = Supervisor([misconfigured], say=said.append)
    sup.start_all()
    exits = []
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        exits += sup.poll()
        time.sleep(0.02)
    sup.stop_all()
    assert exits == [(misconfigured, 2)]
    assert misconfigured.restarts == 0 and misconfigured.gave_up
    assert "configuration error" in said[0] and "not restarting" in said[0]


def test_children_not_started_yet_are_left_alone_and_the_others_still_watched():
    said = []
    crasher = Child("crasher", [sys.executable, "-c", "import sys; sys.exit(3)"])
    later = Child("later", [sys.executable, "-c", "pass"])
    sup = Supervisor([later, crasher], say=said.append)
    sup.start(crasher)
    supervise_for(sup, 0.8)
    sup.stop_all()
    assert later.proc is None and crasher.restarts >= 1


def test_a_process_of_our_name_that_we_did_not_start_is_reported_once_and_not_counted():
    said = []
    watcher = AliveWatcher(["router", "dry-robot"], said.append)
    watcher.on_token("router", True)
    watcher.on_stranger("dry-robot", "pid 42 on host other")
    watcher.on_stranger("dry-robot", "pid 42 on host other")
    assert not watcher.ready.is_set() and watcher.missing() == ["dry-robot"]
    assert len(said) == 1 and "did not start" in said[0] and "pid 42 on host other" in said[0]
