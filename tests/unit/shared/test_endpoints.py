"""Listening endpoints: parsed, checked before Zenoh binds them, and judged for exposure."""

import socket

import pytest

from cbgo import endpoints
from cbgo.config import DEFAULT_ROUTER_LISTEN
from cbgo.errors import ConfigError


def test_endpoints_parse_with_brackets_metadata_and_without_a_port():
    assert endpoints.parse("tcp/[::1]:7447?prio=1") == endpoints.Endpoint(
        "tcp/[::1]:7447?prio=1", "tcp", "::1", 7447)
    assert endpoints.parse("tls/router:7447#iface=eth0").host == "router"
    assert endpoints.parse("unixsock-stream//tmp/zenoh.sock") is None


@pytest.mark.parametrize(("endpoint", "exposed"), [
    (DEFAULT_ROUTER_LISTEN, False), ("tcp/localhost:7447", False), ("tcp/[::1]:7447", False),
    ("tcp/0.0.0.0:7447", True), ("tcp/[::]:7447", True), ("udp/0.0.0.0:7447", True),
    ("tls/0.0.0.0:7447", False), ("quic/0.0.0.0:7447", False),
])
def test_only_non_loopback_endpoints_without_tls_are_exposed(endpoint, exposed):
    assert (endpoints.exposed_without_tls([endpoint]) == [endpoint]) is exposed


def test_the_default_router_listens_on_loopback_only():
    assert DEFAULT_ROUTER_LISTEN == "tcp/127.0.0.1:7447"
    assert endpoints.exposure_warning([DEFAULT_ROUTER_LISTEN]) is None


def test_the_exposure_warning_names_the_secured_deployment():
    warning = endpoints.exposure_warning(["tcp/0.0.0.0:7447", "tls/0.0.0.0:7448"])
    assert warning.startswith("listening on tcp/0.0.0.0:7447 without TLS")
    assert "tls/0.0.0.0:7448" not in warning
    for name in ("cbgo certs", "deploy/compose.tls.yaml", "deploy/tls/", "robot/act"):
        assert name in warning


def test_a_busy_port_is_named_with_the_option_that_moves_it():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(ConfigError) as caught:
            endpoints.check_can_listen([f"tcp/127.0.0.1:{port}"], "--listen",
                                       hint="Join it instead.")
    message = str(caught.value)
    assert f"port {port} is in use" in message and "--listen tcp/127.0.0.1:PORT" in message
    assert "Join it instead." in message
    endpoints.check_can_listen([f"tcp/127.0.0.1:{port}"])  # free again once closed


def test_an_address_of_another_host_is_refused_with_a_local_example():
    with pytest.raises(ConfigError, match=r"192\.0\.2\.1 is not an address of this host.*"
                                          r"--listen tcp/127\.0\.0\.1:7447"):
        endpoints.check_can_listen(["tcp/192.0.2.1:7447"])  # TEST-NET-1: never local


def test_port_zero_and_unix_sockets_are_not_probed():
    endpoints.check_can_listen(["tcp/127.0.0.1:0", "unixsock-stream//tmp/x.sock"])


def test_a_local_process_dials_a_wildcard_listener_on_loopback():
    assert endpoints.local_endpoint("tcp/0.0.0.0:7447") == "tcp/127.0.0.1:7447"
    assert endpoints.local_endpoint("tcp/[::]:7447") == "tcp/[::1]:7447"
    assert endpoints.local_endpoint("tcp/10.0.0.5:7447") == "tcp/10.0.0.5:7447"


def test_the_listeners_of_a_zenoh_config_follow_its_mode():
    zenoh = pytest.importorskip("zenoh")
    conf = zenoh.Config()
    conf.insert_json5("mode", '"router"')
    assert endpoints.listen_endpoints(conf) == ["tcp/[::]:7447"]  # Zenoh's own default
    conf.insert_json5("listen/endpoints", '["tcp/127.0.0.1:9"]')
    assert endpoints.listen_endpoints(conf) == ["tcp/127.0.0.1:9"]
    conf.insert_json5("mode", '"client"')
    assert endpoints.listen_endpoints(conf) == []
