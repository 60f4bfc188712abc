"""``splatconv view``: serve the player and the scene on 127.0.0.1, nothing else.

The standard library's threading HTTP server is enough: one user, a handful of
requests. The handler answers from a fixed table of paths (the page, and one URL
per scene segment); any other request path, including traversal in any encoding,
is a 404, and a request naming another host (DNS rebinding) is refused.
"""

from __future__ import annotations

import io
import os
import shutil
import signal
import sys
import threading
import time
import webbrowser
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import urlsplit

from .errors import UsageError
from .publish import check_playable, is_plain_playable, page_bytes, page_suffix
from .web.page import SceneRef, build_page, parse_durations

HOST = "127.0.0.1"
#: Seconds a connection may sit idle (no byte of a request received, or none of
#: a reply taken) before the server closes it: a partial request once held a
#: thread for as long as its client liked. A browser reading a scene takes each
#: chunk at once; only a stalled client waits this long.
IDLE_TIMEOUT = 30.0
#: Seconds from a connection's acceptance by which its request line and headers
#: must have arrived whole; then it is closed unanswered. The idle timeout alone
#: let a client sending a byte every few seconds hold a connection and a thread
#: forever. A browser sends a request in one piece, at once.
REQUEST_DEADLINE = 10.0
#: Connections the system may queue before the server accepts them (capped by
#: the system's own limit, somaxconn on Linux). The standard library's 5 dropped
#: the connection attempts of a burst beyond it: they waited for the client to
#: try again, a second and more later, and some never got an answer.
LISTEN_BACKLOG = 1024
_COPY_CHUNK = 1 << 20


@dataclass
class _Resource:
    """What one whitelisted path answers: bytes in memory or a file on disk."""

    content_type: str
    data: bytes | None = None
    path: str | None = None


def scene_resources(paths, durations=None) -> tuple[dict, list, list]:
    """The scene URLs for ``paths``: ``({url: _Resource}, [SceneRef], notes)``.

    A plain file the page plays as it is (``check_playable``: ``.splatv``,
    ``.splatvq``) is served from disk, under its own suffix; a ``.zst`` of one is
    decompressed, and any other input converted to the texture format in memory
    first (its notes returned).
    """
    resources, refs, notes = {}, [], []
    shares = durations or [None] * len(paths)
    for i, path in enumerate(paths):
        path = os.fspath(path)
        url = f"scene/{i}{page_suffix(path)}"
        if is_plain_playable(path):
            check_playable(path)
            resources["/" + url] = _Resource("application/octet-stream", path=os.path.abspath(path))
        else:
            data, lost = page_bytes(path)
            notes.extend(f"{path}: {n}" for n in lost)
            resources["/" + url] = _Resource("application/octet-stream", data=data)
        refs.append(SceneRef(name=os.path.basename(path), url=url, duration=shares[i]))
    return resources, refs, notes


class _DeadlineReader(io.RawIOBase):
    """A connection's bytes, read with no wait past ``deadline`` (a :func:`time.monotonic` time)."""

    def __init__(self, sock, deadline: float, idle_timeout: float):
        self._sock, self._deadline, self._idle = sock, deadline, idle_timeout

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        left = self._deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("request deadline passed")
        self._sock.settimeout(min(self._idle, left))
        return self._sock.recv_into(buffer)


class _Server(ThreadingHTTPServer):
    request_queue_size = LISTEN_BACKLOG
    daemon_threads = True  # a connection still open never holds up the exit


def _handler(routes: dict, port_holder: list, idle_timeout: float, request_deadline: float):
    class Handler(BaseHTTPRequestHandler):
        server_version = "splatconv"
        sys_version = ""
        timeout = idle_timeout  # StreamRequestHandler sets it on each connection's socket

        def setup(self):
            super().setup()
            # The request is read through a reader that stops at the deadline
            # (http.server answers its TimeoutError by closing the connection).
            self.rfile.close()
            deadline = time.monotonic() + request_deadline
            self.rfile = io.BufferedReader(_DeadlineReader(self.connection, deadline, idle_timeout))

        def parse_request(self):
            ok = super().parse_request()
            # The request is read: the reply's writes wait the idle timeout, not what
            # was left of the deadline.
            self.connection.settimeout(idle_timeout)
            return ok

        def _resource(self):
            host = (self.headers.get("Host") or "").lower()
            allowed = {f"{HOST}:{port_holder[0]}", f"localhost:{port_holder[0]}"}
            if host not in allowed:
                self.send_error(403, "Forbidden")
                return None
            # The raw path, compared exactly (no decoding, no normalising): only
            # the listed URLs exist; a query string is ignored.
            path = urlsplit(self.path).path if self.path.startswith("/") else ""
            resource = routes.get(path)
            if resource is None:
                self.send_error(404, "Not Found")
            return resource

        def _headers(self, resource, length):
            self.send_response(200)
            self.send_header("Content-Type", resource.content_type)
            self.send_header("Content-Length", str(length))
            self.send_header("Cache-Control", "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            self.end_headers()

        def _open(self, resource):
            """The scene file served from disk, open; None (a 404 sent) once it cannot be read."""
            try:
                return open(resource.path, "rb")
            except OSError:
                # Moved or deleted while `view` runs: the page says the server answered this.
                self.send_error(404, "The scene file can no longer be read")
                return None

        def do_GET(self):  # noqa: N802 (the http.server protocol)
            resource = self._resource()
            if resource is None:
                return
            try:
                if resource.data is not None:
                    self._headers(resource, len(resource.data))
                    view = memoryview(resource.data)
                    for start in range(0, len(view), _COPY_CHUNK):  # each piece within the idle timeout
                        self.wfile.write(view[start:start + _COPY_CHUNK])
                    return
                f = self._open(resource)
                if f is None:
                    return
                with f:
                    self._headers(resource, os.fstat(f.fileno()).st_size)
                    shutil.copyfileobj(f, self.wfile, _COPY_CHUNK)
            except (BrokenPipeError, ConnectionResetError):
                pass  # the browser went away mid-file (a reload): nothing to tell anyone

        def do_HEAD(self):  # noqa: N802
            resource = self._resource()
            if resource is None:
                return
            if resource.data is not None:
                self._headers(resource, len(resource.data))
                return
            f = self._open(resource)
            if f is not None:
                with f:
                    self._headers(resource, os.fstat(f.fileno()).st_size)

        def log_message(self, format, *args):  # noqa: A002
            pass  # quiet: the terminal shows the one line `view` prints

    return Handler


def can_open_browser() -> bool:
    """Whether a graphical browser can be opened here.

    On Linux without a display, :mod:`webbrowser` falls back to text browsers in
    the terminal (lynx, w3m), which would take it over and cannot run the page.
    """
    if sys.platform.startswith("linux"):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


class ViewServer:
    """The player and its scenes on ``http://127.0.0.1:PORT/``.

    Parameters
    ----------
    paths : list of path
        The scene, or the segments of one clip in playing order.
    port : int
        0 picks a free port.
    durations : str, optional
        ``"D0,D1,..."``: each segment's share of the timeline (default equal shares).
    idle_timeout : float
        Seconds before an idle connection is closed (:data:`IDLE_TIMEOUT`).
    request_deadline : float
        Seconds a connection has to send its request whole (:data:`REQUEST_DEADLINE`).

    Raises
    ------
    UsageError
        When the port is taken or cannot be bound.
    """

    def __init__(self, paths, port: int = 0, durations: str | None = None, idle_timeout: float = IDLE_TIMEOUT,
                 request_deadline: float = REQUEST_DEADLINE):
        paths = [os.fspath(p) for p in paths]
        if not paths:
            raise UsageError("give a scene file to view")
        self.paths = paths
        scenes, refs, self.notes = scene_resources(paths, parse_durations(durations, len(paths)))
        title = os.path.basename(paths[0]) + (f" + {len(paths) - 1} segments" if len(paths) > 1 else "")
        page = _Resource("text/html; charset=utf-8", data=build_page(refs, title=title))
        self.routes = {"/": page, "/index.html": page, **scenes}
        port_holder = [port]
        try:
            self.httpd = _Server((HOST, port), _handler(self.routes, port_holder, idle_timeout, request_deadline))
        except OSError as e:
            raise UsageError(f"--port {port}: cannot listen on {HOST}:{port} ({e.strerror or e})") from None
        self.port = port_holder[0] = self.httpd.server_address[1]
        self.url = f"http://{HOST}:{self.port}/"
        self._stop = threading.Event()

    def serve(self, open_browser: bool = True) -> None:
        """Serve until SIGINT or SIGTERM (or :meth:`stop`), then close the socket."""
        stop = self._stop

        def on_signal(signum, frame):
            stop.set()

        previous = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                previous[sig] = signal.signal(sig, on_signal)
        thread = threading.Thread(target=self.httpd.serve_forever, kwargs={"poll_interval": 0.2}, daemon=True)
        thread.start()
        try:
            if open_browser:
                webbrowser.open(self.url)
            # wait() with a timeout so the main thread returns to Python often
            # enough for the signal handler to run.
            while not stop.wait(0.2):
                pass
        finally:
            self.httpd.shutdown()
            self.httpd.server_close()
            thread.join()
            for sig, handler in previous.items():
                signal.signal(sig, handler)

    def close(self) -> None:
        """Close the listening socket (:meth:`serve` does so when it returns)."""
        self.httpd.server_close()

    def stop(self) -> None:
        """Ask a running :meth:`serve` to return."""
        self._stop.set()
