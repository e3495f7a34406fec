"""A fault in a request is answered 500 with an id it is logged under, and the keep-alive connection stays open: the
next request on the same socket is answered (it met "connection reset" before), through a real uvicorn."""

from __future__ import annotations

import socket
import threading

import pytest
import uvicorn

from backend.serve import bind
from tests.helpers.api import make_api

pytestmark = pytest.mark.wallclock     # a real server on a thread: the connection is the subject


def _exchange(sock: socket.socket, path: str) -> bytes:
    sock.sendall(f"GET {path} HTTP/1.1\r\nHost: test\r\nConnection: keep-alive\r\n\r\n".encode())
    data = b""
    while b"\r\n\r\n" not in data:
        data += sock.recv(65536)
    head, _, body = data.partition(b"\r\n\r\n")
    length = int(next(line.split(b":")[1] for line in head.split(b"\r\n") if line.lower().startswith(b"content-length")))
    while len(body) < length:
        body += sock.recv(65536)
    return head.split(b"\r\n")[0] + b" " + body


def test_a_fault_is_answered_and_the_connection_stays_open(tmp_path, model, migrated_sqlite, caplog):
    api, _client = make_api(tmp_path / "faults", lambda: model, template=migrated_sqlite)
    app = api.client.app

    def boom() -> None:
        raise RuntimeError("a fault no handler knows")

    app.add_api_route("/api/test-fault", boom, methods=["GET"])
    listener = bind("127.0.0.1", 0)
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning", lifespan="off"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [listener]}, daemon=True)
    thread.start()
    try:
        assert server_started(server)
        with socket.create_connection(listener.getsockname()[:2], timeout=10) as sock:
            first = _exchange(sock, "/api/test-fault")
            assert first.startswith(b"HTTP/1.1 500") and b"logged as" in first
            second = _exchange(sock, "/api/health")                       # the same socket: still open
            assert second.startswith(b"HTTP/1.1 200")
        assert any("a fault no handler knows" in r.exc_text for r in caplog.records if r.exc_text)
    finally:
        server.should_exit = True
        thread.join(10)
        listener.close()


def server_started(server: uvicorn.Server) -> bool:
    from tests.helpers.device import until

    until(lambda: server.started, 10.0, poll_s=0.05)
    return True
