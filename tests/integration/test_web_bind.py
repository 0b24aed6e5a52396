"""web as a process: a taken port is a clear, logged start-up failure (exit 2), never a hang."""

import socket
import sys

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
