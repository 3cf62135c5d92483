"""The viewer's local web server: the page, its assets and the files it was given, nothing else.

Every URL it answers is in a table built before it starts (``/``, ``/config.json``, each asset of the
page under ``/assets/``, each given file under ``/files/``); a request is looked up in that table as a
string and never joined to a filesystem path, so ``..``, encoded dots and absolute paths cannot reach
anything: whatever is not in the table is a 404. It binds to the loopback interface only.
"""

from __future__ import annotations

import errno
import json
import mimetypes
import socket
import threading
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from urllib.parse import urlsplit

from ..errors import InputError

__all__ = ["ViewerFiles", "ViewerServer", "free_port", "HOST"]

HOST = "127.0.0.1"
_TYPES = {".js": "text/javascript", ".css": "text/css", ".html": "text/html; charset=utf-8",
          ".json": "application/json", ".glb": "model/gltf-binary", ".mp4": "video/mp4", ".webm": "video/webm",
          ".txt": "text/plain; charset=utf-8"}


@dataclass(frozen=True)
class ViewerFiles:
    """What one viewer page shows: a model, and optionally its source video and FAP curves (as JSON)."""

    model: Path
    video: Path | None = None
    curves: dict | None = None
    title: str = ""


def _assets() -> dict[str, bytes]:
    """The page's own files, by URL: everything under the package's ``assets`` folder."""
    table = {}

    def walk(node, prefix):
        for child in node.iterdir():
            if child.is_dir():
                walk(child, f"{prefix}{child.name}/")
            elif not child.name.startswith("."):
                table[f"/assets/{prefix}{child.name}"] = child.read_bytes()

    walk(resources.files(__package__).joinpath("assets"), "")
    return table


class ViewerServer:
    """Serves one :class:`ViewerFiles` on ``http://127.0.0.1:<port>/``; a context manager.

    ``serve_forever()`` blocks (the command); ``start()`` serves from a background thread (tests).
    """

    def __init__(self, files: ViewerFiles, port: int = 0):
        routes = {path: (data, _type(path)) for path, data in _assets().items()}
        routes["/"] = routes.pop("/assets/index.html")
        config = {"title": files.title or files.model.stem, "model": "/files/model.glb", "video": None,
                  "curves": None}
        routes["/files/model.glb"] = _file_route(files.model)
        if files.video is not None:
            config["video"] = "/files/source" + files.video.suffix.lower()
            routes[config["video"]] = _file_route(files.video)
        if files.curves is not None:
            config["curves"] = "/files/curves.json"
            routes["/files/curves.json"] = (json.dumps(files.curves).encode(), _TYPES[".json"])
        routes["/config.json"] = (json.dumps(config).encode(), _TYPES[".json"])
        self.routes = routes
        try:
            self._server = ThreadingHTTPServer((HOST, port), _handler(routes))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise InputError(f"port {port} is in use; try --port {free_port(port + 1)}") from None
            raise
        self._server.daemon_threads = True
        self.host, self.port = self._server.server_address[:2]
        self.url = f"http://{HOST}:{self.port}/"
        self._thread = None

    def serve_forever(self) -> None:
        self._server.serve_forever()

    def start(self) -> ViewerServer:
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        if self._thread is not None:
            self._server.shutdown()
        self._server.server_close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def free_port(start: int) -> int:
    """The first port from ``start`` on that nothing listens on at 127.0.0.1."""
    for port in range(max(1024, start), 65536):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            if probe.connect_ex((HOST, port)) != 0:
                return port
    raise InputError(f"no free port found from {start} on")


def _type(path: str) -> str:
    suffix = Path(path).suffix.lower()
    return _TYPES.get(suffix) or mimetypes.guess_type(path)[0] or "application/octet-stream"


def _file_route(path: Path):
    """A given file, read when asked for, with its content type."""
    return (path, _type(path.name))


def _handler(routes: dict):
    class Handler(BaseHTTPRequestHandler):
        server_version = "faceanim-viewer"

        def do_GET(self):  # noqa: N802 (the name http.server calls)
            self._answer(body=True)

        def do_HEAD(self):  # noqa: N802
            self._answer(body=False)

        def _answer(self, *, body: bool):
            route = routes.get(urlsplit(self.path).path)
            if route is None:
                self.send_error(404, "Not Found")
                return
            content, kind = route
            size = content.stat().st_size if isinstance(content, Path) else len(content)
            start, end, status = 0, size, 200
            ranged = self.headers.get("Range", "")
            if ranged.startswith("bytes=") and isinstance(content, Path):  # video seeking asks for ranges
                first, _, last = ranged[6:].split(",")[0].partition("-")
                try:
                    start = int(first) if first else max(0, size - int(last))
                    end = min(size, int(last) + 1) if first and last else size
                except ValueError:
                    start, end = 0, size
                if start >= size:
                    self.send_error(416, "Range Not Satisfiable")
                    return
                status = 206
            self.send_response(status)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(end - start))
            self.send_header("Accept-Ranges", "bytes")
            self.send_header("Cache-Control", "no-store")
            if status == 206:
                self.send_header("Content-Range", f"bytes {start}-{end - 1}/{size}")
            self.end_headers()
            if not body:
                return
            if isinstance(content, Path):  # read only the part asked for: a video can be large
                with open(content, "rb") as handle:
                    handle.seek(start)
                    self.wfile.write(handle.read(end - start))
            else:
                self.wfile.write(content[start:end])

        def log_message(self, *args):  # the terminal is the person's, not a request log
            pass

    return Handler
