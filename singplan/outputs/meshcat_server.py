"""meshcat's ZMQ / web server, listening on one chosen address (run as a script by viewer.py).

meshcat 0.3.2 takes a ``host`` but only uses it in its URLs and its ZMQ address: its web
server listens on every interface (tornado's default). This subclass makes the web server
listen on ``host`` only and keeps the command socket on loopback whatever ``host`` is (it
accepts scene commands from anyone who can reach it).

Usage: ``python meshcat_server.py HOST`` prints ``zmq_url=...`` and ``web_url=...`` (as
meshcat's own server does) or ``error=...``, then serves until killed or until its standard
input closes. The process that starts it keeps the other end of that pipe and never writes to
it, so when that process ends in any way (SIGKILL and the OOM killer included: the kernel closes
its descriptors) the server sees end-of-file and exits; no server outlives its replay.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading

if __name__ == "__main__":  # run by path: this folder must not shadow top-level modules
    sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(os.path.abspath(__file__))]

from typing import Any

import tornado.web
from meshcat.servers.zmqserver import (
    VIEWER_HTML,
    VIEWER_ROOT,
    StaticFileHandlerNoCache,
    WebSocketHandler,
    ZMQWebSocketBridge,
)

_COMMAND_HOST = "127.0.0.1"


class _BoundApplication(tornado.web.Application):
    """A tornado application whose ``listen`` binds one address instead of all of them."""

    def __init__(self, address: str, handlers: list[Any]) -> None:
        super().__init__(handlers)
        self.address = address

    def listen(self, port: int, address: str | None = None, **kwargs: Any) -> Any:
        return super().listen(port, address=self.address if address is None else address, **kwargs)


class BoundBridge(ZMQWebSocketBridge):
    """meshcat's bridge with its web server on ``web_host`` and its command socket on loopback."""

    def __init__(self, web_host: str) -> None:
        self.web_host = web_host
        super().__init__(host=_COMMAND_HOST)
        shown = f"[{web_host}]" if ":" in web_host else web_host
        self.web_url = f"http://{shown}:{self.fileserver_port}/static/"

    def make_app(self) -> tornado.web.Application:
        return _BoundApplication(self.web_host, [
            (r"/static/(.*)", StaticFileHandlerNoCache, {"path": VIEWER_ROOT, "default_filename": VIEWER_HTML}),
            (r"/", WebSocketHandler, {"bridge": self}),
        ])


def main(argv: list[str]) -> int:
    try:
        bridge = BoundBridge(argv[0])
    except Exception as exc:  # reported to the parent, which turns it into an error naming the host
        print(f"error={type(exc).__name__}: {exc}", flush=True)
        return 1
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - nobody reads the pipe any more
    threading.Thread(target=_exit_with_parent, name="parent-watch", daemon=True).start()
    with contextlib.suppress(KeyboardInterrupt):
        bridge.run()
    return 0


def _exit_with_parent() -> None:
    """Exit (at once, whatever the event loop is doing) when standard input reaches end-of-file:
    the parent that holds the pipe's other end has gone."""
    with contextlib.suppress(OSError):
        while sys.stdin.buffer.read(4096):
            pass
    os._exit(0)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
