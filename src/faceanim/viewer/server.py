"""The viewer's local web server: the page, its assets and the files it was given, nothing else.

Every URL it answers is in a table built before it starts (``/``, ``/config.json``, each asset of the
page under ``/assets/``, each given file under ``/files/``); a request is looked up in that table as a
string and never joined to a filesystem path, so ``..``, encoded dots and absolute paths cannot reach
anything: whatever is not in the table is a 404. It binds to the loopback interface only and answers
only requests addressed to a loopback name (``Host: 127.0.0.1:<port>`` or ``localhost:<port>``), so a web
page that points its own DNS name at 127.0.0.1 (DNS rebinding) reads nothing.

The given files (the model, the video) are opened once, when the server is built, and every answer is
read from those descriptors: renaming or deleting a path afterwards, or swapping a symlink there, changes
nothing that is served. Byte ranges follow RFC 9110 (:func:`parse_range`). Every connection has a
timeout and at most ``workers`` are served at once; one more is told 503 at once, so idle or half-open
connections cannot pile up threads.
"""

from __future__ import annotations

import errno
import json
import math
import mimetypes
import os
import re
import socket
import stat
import sys
import threading
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from typing import Literal
from urllib.parse import urlsplit

from ..errors import FileFormatError, InputError

__all__ = ["ViewerFiles", "ViewerServer", "free_port", "parse_range", "HOST"]

HOST = "127.0.0.1"
_LOOPBACK_NAMES = (HOST, "localhost")  # what a Host header may name; the server does not listen on ::1
_TYPES = {".js": "text/javascript", ".css": "text/css", ".html": "text/html; charset=utf-8",
          ".json": "application/json", ".glb": "model/gltf-binary", ".mp4": "video/mp4", ".webm": "video/webm",
          ".txt": "text/plain; charset=utf-8"}
_CHUNK = 256 * 1024  # bytes per write: a request's memory stays bounded and each write gets its own timeout
_BUSY = b"HTTP/1.0 503 Service Unavailable\r\nRetry-After: 1\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
_RANGE_SPEC = re.compile(r"([0-9]*)-([0-9]*)")  # int-range or suffix-range, ASCII digits only (RFC 9110 14.1.1)


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
    The model and the video are opened here and read only through those descriptors until :meth:`close`.

    Parameters
    ----------
    files : ViewerFiles
        What to show. The model and the video must be regular files (:class:`InputError` otherwise), and
        the model a complete glTF binary (:class:`FileFormatError` otherwise, see :func:`_check_glb`).
    port : int
        The port on 127.0.0.1; 0 picks a free one (see ``self.port``).
    timeout : float
        Seconds any one read or write on a connection may wait before the connection is dropped.
    workers : int
        Connections served at once; one more is answered 503 and closed.
    """

    def __init__(self, files: ViewerFiles, port: int = 0, *, timeout: float = 20.0, workers: int = 16):
        if isinstance(timeout, bool) or not isinstance(timeout, int | float) or not 0 < timeout < math.inf:
            raise ValueError(f"timeout must be a positive number of seconds, got {timeout!r}")
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers must be an int >= 1, got {workers!r}")
        routes = {path: (data, _type(path)) for path, data in _assets().items()}
        routes["/"] = routes.pop("/assets/index.html")
        config = {"title": files.title or files.model.stem, "model": "/files/model.glb", "video": None,
                  "curves": None}
        self._files = []
        try:
            self._files.append(_OpenedFile(files.model))
            _check_glb(self._files[-1], files.model)
            routes["/files/model.glb"] = (self._files[-1], _type(files.model.name))
            if files.video is not None:
                config["video"] = "/files/source" + files.video.suffix.lower()
                self._files.append(_OpenedFile(files.video))
                routes[config["video"]] = (self._files[-1], _type(files.video.name))
            if files.curves is not None:
                config["curves"] = "/files/curves.json"
                routes["/files/curves.json"] = (json.dumps(files.curves).encode(), _TYPES[".json"])
            routes["/config.json"] = (json.dumps(config).encode(), _TYPES[".json"])
            self._server = _bind(port, routes, timeout=timeout, workers=workers)
        except BaseException:
            self._close_files()
            raise
        self.routes = routes
        self.host, self.port = self._server.server_address[:2]
        self.url = f"http://{HOST}:{self.port}/"
        self._thread = None

    def serve_forever(self) -> None:
        self._server.serve_forever()

    def start(self) -> ViewerServer:
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.05},
                                        daemon=True)  # close() waits for one poll: 0.05 s, not the default 0.5
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving, cut the connections still open, wait for their threads, then close the files."""
        if self._thread is not None:
            self._server.shutdown()
            self._thread = None
        self._server.server_close()
        self._close_files()  # only now: no thread can still be reading from them

    def _close_files(self) -> None:
        while self._files:
            self._files.pop().close()

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


def parse_range(header: str | None, size: int) -> tuple[int, int] | Literal["unsatisfiable"] | None:
    """The byte range a ``Range`` header asks of a body of ``size`` bytes, read as RFC 9110 (14.1, 14.2) says.

    Parameters
    ----------
    header : str or None
        The ``Range`` field's value as received; None where the request has none.
    size : int
        The length of the body in bytes.

    Returns
    -------
    tuple of int, or "unsatisfiable", or None
        ``(first, last)``, inclusive byte offsets with ``0 <= first <= last < size``: answer 206 with
        ``Content-Range: bytes first-last/size``. A last byte past the end means the end; a suffix longer
        than the body means all of it.

        ``"unsatisfiable"``: answer 416 with ``Content-Range: bytes */size``. The range starts at or past
        the end, is an empty suffix (``bytes=-0``), or ends before it starts (``bytes=100-50``: RFC 9110
        calls that range invalid and lets a server reject it; a 416 tells the client its mistake, where
        ignoring it would send a whole video it did not ask for).

        None: ignore the header and answer 200 with the whole body. No header; a unit other than bytes;
        anything outside the grammar (``bytes=abc``, ``bytes=1-2-3``, ``bytes=+5-``); several ranges
        (``bytes=0-1,5-6``: a server may ignore any Range, and one whole body is simpler than a
        ``multipart/byteranges`` answer that no client of the viewer asks for: the video element asks
        for one range at a time); a suffix of an empty body (the whole, empty body: no range to name).

    Examples
    --------
    >>> parse_range("bytes=100-199", 1000), parse_range("bytes=900-", 1000), parse_range("bytes=-300", 1000)
    ((100, 199), (900, 999), (700, 999))
    >>> parse_range("bytes=0-99999", 1000), parse_range("bytes=-99999", 1000)
    ((0, 999), (0, 999))
    >>> parse_range("bytes=1000-", 1000), parse_range("bytes=100-50", 1000), parse_range("bytes=-0", 1000)
    ('unsatisfiable', 'unsatisfiable', 'unsatisfiable')
    >>> [parse_range(h, 1000) for h in ("bytes=abc", "bytes=0-1,5-6", "items=0-1", None)]
    [None, None, None, None]
    """
    if isinstance(size, bool) or not isinstance(size, int) or size < 0:
        raise ValueError(f"size must be a byte count (an int >= 0), got {size!r}")
    if header is None:
        return None
    unit, equals, ranges = header.strip(" \t").partition("=")
    if not equals or not unit.isascii() or unit.lower() != "bytes":  # a unit compares case-insensitively
        return None
    specs = [spec.strip(" \t") for spec in ranges.split(",")]
    specs = [spec for spec in specs if spec]  # a list may hold empty elements ("bytes=0-1,"), RFC 9110 5.6.1
    match = _RANGE_SPEC.fullmatch(specs[0]) if len(specs) == 1 else None
    if match is None or match[0] == "-":
        return None
    first, last = match.groups()
    if not first:  # a suffix-range: the last N bytes
        if not last.strip("0"):
            return "unsatisfiable"
        return (size - _at_most(last, size), size - 1) if size else None
    first = _at_most(first, size)
    end = _at_most(last, size) if last else size  # size stands for "at or past the end"
    if first >= size or end < first:
        return "unsatisfiable"
    return first, min(end, size - 1)


def _at_most(digits: str, cap: int) -> int:
    """``min(int(digits), cap)`` without converting thousands of digits: Python refuses strings over
    4,300 digits, and a header line may hold 65,536."""
    digits = digits.lstrip("0") or "0"
    return cap if len(digits) > len(str(cap)) else min(int(digits), cap)


class _OpenedFile:
    """A given file, opened once when the server is built and read only through that descriptor.

    Renaming or deleting the path afterwards, or swapping a symlink there, changes nothing that is
    served: the path is never looked at again. Anything but a regular file (a folder, a FIFO, a device)
    is refused; it is opened without blocking, so that refusing a FIFO cannot hang.
    """

    def __init__(self, path: Path):
        try:
            fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        except OSError as exc:
            raise InputError(f"{path}: cannot be opened ({exc.strerror})") from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise InputError(f"{path}: is not a regular file")
        self._fd = fd

    def __len__(self) -> int:  # asked per request: a file rewritten in place is served as it now is
        return os.fstat(self._fd).st_size

    def read(self, offset: int, count: int) -> bytes:
        return os.pread(self._fd, count, offset)  # no shared file position: threads do not disturb each other

    def close(self) -> None:
        os.close(self._fd)


_GLB_MAGIC, _GLB_JSON = b"glTF", b"JSON"


def _check_glb(opened: _OpenedFile, path: Path) -> None:
    """Refuse, naming ``path``, a model that is not a complete glTF binary as the descriptor reads it:
    the ``glTF`` magic, version 2, a declared length equal to the file's, then chunks (the first one
    JSON) that each lie inside the file and together fill it. A file cut short (a copy in progress, a
    full disk) would otherwise be served, and fail in the browser with no word said."""
    size = len(opened)
    header = opened.read(0, 12)

    def refuse(why: str):
        return FileFormatError(path, f"is not a complete glTF binary ({why})")

    if len(header) < 12 or header[:4] != _GLB_MAGIC:
        raise refuse("no glTF header")
    version, length = int.from_bytes(header[4:8], "little"), int.from_bytes(header[8:12], "little")
    if version != 2:
        raise refuse(f"version {version}; the viewer shows glTF 2")
    if length != size:
        raise refuse(f"its header declares {length} bytes, the file holds {size}")
    offset, first = 12, True
    while offset < length:
        chunk = opened.read(offset, 8)
        if len(chunk) < 8:
            raise refuse(f"a chunk header at byte {offset} is cut short")
        chunk_length, kind = int.from_bytes(chunk[:4], "little"), chunk[4:8]
        if offset + 8 + chunk_length > length:
            raise refuse(f"the chunk at byte {offset} declares {chunk_length} bytes; {length - offset - 8} follow")
        if first and kind != _GLB_JSON:
            raise refuse("its first chunk is not JSON")
        offset, first = offset + 8 + chunk_length, False
    if first:
        raise refuse("it holds no chunk")


def _bind(port: int, routes: dict, *, timeout: float, workers: int) -> _Server:
    try:
        return _Server((HOST, port), routes, timeout=timeout, workers=workers)
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise InputError(f"port {port} is in use; try --port {free_port(port + 1)}") from None
        raise


class _Server(ThreadingHTTPServer):
    """A thread per connection, at most ``workers`` at once: a connection beyond them is answered 503
    and closed at once (the accept loop never waits), so a pile of idle or half-open connections holds
    ``workers`` threads, not one each, and each of those is dropped after ``timeout`` seconds of silence.
    """

    daemon_threads = True
    request_queue_size = 64  # connections the kernel holds until accepted: a page asks for a dozen at once

    def __init__(self, address, routes: dict, *, timeout: float, workers: int):
        self.routes = routes
        self.connection_timeout = timeout
        self._slots = threading.BoundedSemaphore(workers)
        self._open = set()  # the connections being served, so that closing can cut them
        self._open_lock = threading.Lock()
        super().__init__(address, _Handler)
        port = self.server_address[1]
        self.hosts = frozenset(name + suffix for name in _LOOPBACK_NAMES for suffix in ("", f":{port}"))

    def process_request(self, request, client_address):
        if not self._slots.acquire(blocking=False):
            try:
                request.setblocking(False)
                request.send(_BUSY)
            except OSError:
                pass
            self.shutdown_request(request)
            return
        with self._open_lock:
            self._open.add(request)
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._release(request)
            raise

    def process_request_thread(self, request, client_address):
        try:
            self.finish_request(request, client_address)
        except Exception:
            self.handle_error(request, client_address)
        finally:
            self._release(request)  # before the close: a client that sees it end can connect again at once
            self.shutdown_request(request)

    def _release(self, request) -> None:
        with self._open_lock:
            self._open.discard(request)
        self._slots.release()

    def handle_error(self, request, client_address):
        if isinstance(sys.exc_info()[1], ConnectionError | TimeoutError):
            return  # the client went away (a seeking video drops its request) or stalled past the timeout
        super().handle_error(request, client_address)  # a bug: its traceback

    def server_close(self):
        """Stop listening, cut the connections still open (a paused video's) and wait for their threads."""
        with self._open_lock:
            for request in self._open:
                try:
                    request.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
        super().server_close()


class _Handler(BaseHTTPRequestHandler):
    server_version = "faceanim-viewer"

    def setup(self):
        self.timeout = self.server.connection_timeout  # applies to every read and every write
        super().setup()

    def do_GET(self):  # noqa: N802 (the name http.server calls)
        self._answer(body=True)

    def do_HEAD(self):  # noqa: N802
        self._answer(body=False)

    def _answer(self, *, body: bool):
        if not self._addressed_here():
            return
        route = self.server.routes.get(urlsplit(self.path).path)
        if route is None:
            self.send_error(404, "Not Found")
            return
        content, kind = route
        size = len(content)
        wanted = parse_range(self._range_header(), size)
        if wanted == "unsatisfiable":
            self.send_response(416)
            self.send_header("Content-Range", f"bytes */{size}")
            self.send_header("Content-Length", "0")
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            return
        first, last = wanted or (0, size - 1)
        self.send_response(206 if wanted else 200)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(last + 1 - first))
        self.send_header("Accept-Ranges", "bytes")
        self.send_header("Cache-Control", "no-store")
        if wanted:
            self.send_header("Content-Range", f"bytes {first}-{last}/{size}")
        self.end_headers()
        if body:
            self._send(content, first, last + 1)

    def _addressed_here(self) -> bool:
        """Whether the request names this server: exactly one Host header (400 otherwise, RFC 9112 3.2),
        holding a loopback name and, where given, this port; else 421 Misdirected Request.

        421 rather than 403: what happened is that a request for another origin (a rebinding page's own
        name) reached a server that does not answer for it, which is what 421 means; 403 would say the
        resource is here but forbidden to this client. Browsers send the port unless it is 80, and the
        bare loopback names are safe either way: a rebinding page cannot make a browser send them.
        """
        hosts = self.headers.get_all("Host") or []
        if len(hosts) != 1:
            self.send_error(400, "Bad Request", "a request needs exactly one Host header")
            return False
        named = {hosts[0].strip(" \t").lower()}
        target = urlsplit(self.path)
        if target.scheme:  # a request target in absolute form names the host too
            named.add(target.netloc.lower())
        if not named <= self.server.hosts:
            self.send_error(421, "Misdirected Request", "this server answers only for 127.0.0.1 and localhost")
            return False
        return True

    def _range_header(self) -> str | None:
        """The Range header to honour, or None to send the whole body.

        Ranges are defined for GET only (RFC 9110 14.2). The server sends no validator (no ETag, no
        Last-Modified), so no If-Range can match one, and a Range under an If-Range is then ignored
        (RFC 9110 13.1.5). Two Range headers are no single range: ignored too.
        """
        values = self.headers.get_all("Range") or []
        if self.command != "GET" or "If-Range" in self.headers or len(values) != 1:
            return None
        return values[0]

    def _send(self, content, start: int, end: int) -> None:
        """Bytes ``start`` to ``end`` of ``content``, read and written a chunk at a time."""
        while start < end:
            chunk = content.read(start, min(_CHUNK, end - start)) if isinstance(content, _OpenedFile) \
                else content[start:min(start + _CHUNK, end)]
            if not chunk:  # the file was cut short after its length was sent: end the connection here
                self.close_connection = True
                return
            self.wfile.write(chunk)
            start += len(chunk)

    def log_message(self, *args):  # the terminal is the person's, not a request log
        pass
