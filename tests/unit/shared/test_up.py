"""`cbgo up`'s choice of router: its own on loopback, or one it is told to join."""

import argparse

import pytest

from cbgo.cli import up


def parse(*argv):
    parser = argparse.ArgumentParser()
    up.add_arguments(parser)
    return parser.parse_args(list(argv))


def test_by_default_up_starts_its_own_router_on_loopback_and_its_services_dial_it():
    assert up.network_of(parse()) == up.Network("tcp/127.0.0.1:7447", ["tcp/127.0.0.1:7447"])


@pytest.mark.parametrize("flag", ["--listen", "--router-listen"])
def test_listen_and_router_listen_are_one_option(flag):
    net = up.network_of(parse(flag, "tcp/0.0.0.0:7600"))
    assert net == up.Network("tcp/0.0.0.0:7600", ["tcp/127.0.0.1:7600"])


def test_connect_alone_joins_that_router_and_starts_none():
    assert up.network_of(parse("--connect", "tcp/10.0.0.5:7447")) == up.Network(
        None, ["tcp/10.0.0.5:7447"])
    assert up.network_of(parse("--no-router", "--connect", "tcp/10.0.0.5:7447")).listen is None


def test_listen_with_connect_may_only_name_the_router_up_starts(capsys):
    same = parse("--listen", "tcp/127.0.0.1:7600", "--connect", "tcp/127.0.0.1:7600")
    assert up.network_of(same).listen == "tcp/127.0.0.1:7600"
    with pytest.raises(SystemExit) as caught:
        up.network_of(parse("--listen", "tcp/127.0.0.1:7600", "--connect", "tcp/10.0.0.5:7447"))
    assert caught.value.code == 2
    assert "--connect alone to join one" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--no-router"],
                                  ["--no-router", "--connect", "tcp/a:1", "--listen", "tcp/b:2"]])
def test_no_router_needs_connect_and_no_listen(argv):
    with pytest.raises(SystemExit) as caught:
        up.network_of(parse(*argv))
    assert caught.value.code == 2


def test_the_zenoh_listen_flag_is_not_a_second_silent_option():
    listens = [a for a in up_actions() if "--listen" in a.option_strings]
    assert len(listens) == 1 and listens[0].dest == "router_listen"


def up_actions():
    parser = argparse.ArgumentParser()
    up.add_arguments(parser)
    return parser._actions
