"""A loopback HTTP server standing in for the internet in the ``appeal data`` tests.

It serves a folder (``shared/data``, or a copy the test altered) on 127.0.0.1 only, answers
``Range: bytes=N-`` requests with 206 (Python's own server ignores them), and records every
request's path and Range header so a test can see what was downloaded.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path


class _Handler(SimpleHTTPRequestHandler):
    requests: list[tuple[str, str | None]]

    def log_message(self, *args) -> None:  # quiet
        pass

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        self.requests.append((self.path, self.headers.get("Range")))
        rng = self.headers.get("Range")
        path = Path(self.translate_path(self.path))
        if not rng or not path.is_file():
            return super().do_GET()
        start = int(rng.split("=", 1)[1].split("-", 1)[0])
        size = path.stat().st_size
        if start >= size:
            self.send_response(416)
            self.send_header("Content-Range", f"bytes */{size}")
            self.end_headers()
            return
        self.send_response(206)
        self.send_header("Content-Type", "application/octet-stream")
        self.send_header("Content-Range", f"bytes {start}-{size - 1}/{size}")
        self.send_header("Content-Length", str(size - start))
        self.end_headers()
        with open(path, "rb") as f:
            f.seek(start)
            self.wfile.write(f.read())


class _Server(ThreadingHTTPServer):
    """A server that stays silent when the client hangs up mid-answer (a download refused after
    its first bytes): Python's default prints the traceback to stderr, which a test that checks
    the command's one-line error then reads as the command's output."""

    def handle_error(self, request, client_address) -> None:
        import sys

        if not isinstance(sys.exc_info()[1], ConnectionError):
            super().handle_error(request, client_address)


@contextlib.contextmanager
def serve(folder: Path) -> Iterator[tuple[str, list]]:
    """Serve ``folder`` on 127.0.0.1; yields (base URL, the list of (path, Range) requests)."""
    requests: list = []
    handler = type("Handler", (_Handler,), {"requests": requests})
    server = _Server(("127.0.0.1", 0), lambda *a: handler(*a, directory=os.fspath(folder)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}", requests
    finally:
        server.shutdown()
        server.server_close()


def closed_port_url() -> str:
    """A loopback URL where nothing listens (the offline case)."""
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return f"http://127.0.0.1:{port}"
