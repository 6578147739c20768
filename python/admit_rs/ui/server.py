"""Serving the page on 127.0.0.1: in the foreground (``admit-rs ui``) or on a background
thread (``ar.ui.tuner`` in Jupyter, tests). BokehJS comes from the server itself
(``/static``), so the page needs no network beyond the loopback."""

from __future__ import annotations

import asyncio
import os
import socket
import threading
from dataclasses import dataclass, field
from functools import partial
from typing import Any

from admit_rs.config import Scenario

HOST = "127.0.0.1"


def free_port() -> int:
    """A TCP port nobody listens on at this moment."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((HOST, 0))
        return int(s.getsockname()[1])


def _server(start_name: str | None, start: Scenario, port: int, io_loop: Any) -> Any:
    os.environ.setdefault("BOKEH_RESOURCES", "server")  # BokehJS from this server, no CDN
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server

    from admit_rs.ui import page

    app = Application(FunctionHandler(partial(page.build, start_name=start_name, start=start)))
    return Server(
        {"/": app},
        io_loop=io_loop,
        address=HOST,
        port=port,
        allow_websocket_origin=[f"{HOST}:{port}", f"localhost:{port}"],
        check_unused_sessions_milliseconds=5_000,
        unused_session_lifetime_milliseconds=15_000,
    )


@dataclass
class Running:
    """A page served on a background thread: ``url``, and ``stop()``."""

    url: str
    port: int
    _loop: Any = field(repr=False)
    _server: Any = field(repr=False)
    _thread: threading.Thread = field(repr=False)

    def stop(self) -> None:
        """Stops the server and its thread."""
        if not self._thread.is_alive():
            return

        def shutdown() -> None:
            self._server.stop()
            self._loop.stop()

        self._loop.add_callback(shutdown)
        self._thread.join(timeout=10)


def serve_in_thread(start_name: str | None, start: Scenario, port: int | None = None) -> Running:
    """Serves the page on a daemon thread with its own event loop; returns once it listens."""
    from tornado.ioloop import IOLoop

    port = free_port() if port is None else port
    ready = threading.Event()
    box: dict[str, Any] = {}

    def main() -> None:
        asyncio.set_event_loop(asyncio.new_event_loop())
        loop = IOLoop.current()
        try:
            server = _server(start_name, start, port, loop)
            server.start()
        except BaseException as e:  # reported to the caller, not lost on this thread
            box["error"] = e
            ready.set()
            return
        box["loop"], box["server"] = loop, server
        ready.set()
        loop.start()
        loop.close(all_fds=True)

    thread = threading.Thread(target=main, name=f"admit-rs ui :{port}", daemon=True)
    thread.start()
    ready.wait()
    if "error" in box:
        raise box["error"]
    return Running(f"http://{HOST}:{port}/", port, box["loop"], box["server"], thread)


def serve_forever(start_name: str | None, start: Scenario, port: int | None = None,
                  open_browser: bool = True, announce: Any = print) -> None:  # fmt: skip
    """Serves the page in the foreground until Ctrl-C (``admit-rs ui``)."""
    from tornado.ioloop import IOLoop

    port = free_port() if port is None else port
    loop = IOLoop.current()
    server = _server(start_name, start, port, loop)
    server.start()
    url = f"http://{HOST}:{port}/"
    announce(f"admit-rs ui: serving {url} (Ctrl-C stops)")
    if open_browser:
        import webbrowser

        loop.add_callback(partial(webbrowser.open, url))
    try:
        loop.start()
    finally:
        server.stop()
