"""web as a process: `cbgo web` serves live; a taken port is a logged exit 2, never a hang."""

import signal
import socket
import sys
import urllib.request

from cbgo.testing import Stack


def test_web_on_a_port_in_use_logs_why_and_exits_2(tmp_path):
    with Stack(tmp_path) as stack, socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        stack.start_router()
        stack.wait_alive(["router"])
        web = stack.spawn("web", [sys.executable, "-m", "cbgo.services.web"],
                          env={"CBGO_HTTP_PORT": str(port)})
        assert web.popen.wait(30) == 2
        line = web.wait_for_line("configuration error")
        assert f"cannot serve HTTP on 127.0.0.1:{port}" in line and "--http-port" in line
        assert "web" not in stack.alive()


def test_cbgo_web_serves_the_page_live_and_stops_on_sigterm(tmp_path):
    with Stack(tmp_path) as stack:
        stack.start_router()
        # No --http-port: the stack's CBGO_HTTP_PORT=0 must apply (env < flags, not defaults).
        web = stack.spawn("web", [sys.executable, "-m", "cbgo.cli.main", "web", "--connect",
                                  stack.endpoint])
        stack.wait_alive(["router", "web"])
        url = stack.status("web")["url"]
        assert url in web.wait_for_line("serving the page at") and ":8080/" not in url
        with urllib.request.urlopen(url, timeout=5) as page:
            assert 'data-testid="scene-3d"' in page.read().decode()
        with urllib.request.urlopen(url + "static/vendor/three/LICENSE", timeout=5) as licence:
            assert "MIT License" in licence.read().decode()
        code, seconds = stack.stop("web", signal.SIGTERM)
        assert code == 0 and seconds < 2.5
