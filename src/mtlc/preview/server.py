"""`mtlc serve`: a local server that streams the motion to a light browser client (seed 004).

The page (the preview page in serve mode) opens a Server-Sent Events stream at ``/events`` and
receives the compiled motion as ``motion`` events; a failed recompile sends a ``diagnostics``
event and the page keeps the last good motion. Dragging a site POSTs ``{"site", "position"}`` to
``/site``; the server recompiles with the site there and streams the result. Saving the
``.mtask`` file recompiles too (the file's modification time is polled).

Standard library only: ``ThreadingHTTPServer``, one thread per client. Requests are refused,
never fatal: bodies over ``MAX_BODY`` bytes, invalid JSON, unknown sites or non-finite numbers
get a 4xx reply with a JSON error and the server carries on.
"""

from __future__ import annotations

import json
import math
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from mtlc.diagnostics import Diagnostic
from mtlc.frontend import FrontendOptions
from mtlc.passes import MotionOptions
from mtlc.preview.compile import Compiled, compile_motions
from mtlc.preview.html import render_page, script_json
from mtlc.preview.sites import Vec3

MAX_BODY = 4096  # bytes: a site move is well under 200
MAX_COORDINATE = 1000.0  # m: a site farther than 1 km from the origin is a mistake
KEEPALIVE_S = 15.0


class BadRequest(ValueError):
    """A client message that is refused (and answered with 400)."""


def parse_site_move(body: bytes, known: set[str]) -> tuple[str, Vec3]:
    """``{"site": NAME, "position": [x, y, z]}`` (metres), checked strictly."""
    try:
        doc = json.loads(body.decode("utf-8"), parse_constant=_reject_constant)
    except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as exc:
        raise BadRequest(f"not JSON: {exc}") from None
    if not isinstance(doc, dict) or set(doc) != {"site", "position"}:
        raise BadRequest('expected an object with exactly "site" and "position"')
    name, position = doc["site"], doc["position"]
    if not isinstance(name, str) or name not in known:
        raise BadRequest(f"unknown site {name!r}")
    if not isinstance(position, list) or len(position) != 3:
        raise BadRequest("position must be a list of three numbers (metres)")
    if not all(isinstance(c, int | float) and not isinstance(c, bool) for c in position):
        raise BadRequest("position must be a list of three numbers (metres)")
    coords = tuple(float(c) for c in position)
    if not all(math.isfinite(c) and abs(c) <= MAX_COORDINATE for c in coords):
        raise BadRequest(f"position must be finite and within {MAX_COORDINATE:g} m")
    return name, (coords[0], coords[1], coords[2])


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number JSON allows")


def diagnostics_payload(items: list[Diagnostic]) -> dict[str, Any]:
    """The diagnostics event: what the page lists (code, place, message)."""
    return {
        "diagnostics": [
            {
                "code": d.code,
                "severity": d.severity.value,
                "message": d.message,
                "file": d.span.file,
                "line": d.span.line,
                "column": d.span.column,
            }
            for d in items
        ]
    }


@dataclass
class MotionHub:
    """The current motion and the clients' queues; recompiles on demand, one at a time."""

    paths: list[Path]
    options: FrontendOptions
    motion: MotionOptions
    task: str | None = None
    moved: dict[str, Vec3] = field(default_factory=dict)
    last_motion: str | None = None  # the last good motion event's data
    last_diagnostics: str | None = None
    generation: int = 0
    sites: set[str] = field(default_factory=set)
    _clients: list[queue.Queue[tuple[str, str]]] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _compile_lock: threading.Lock = field(default_factory=threading.Lock)

    def recompile(self) -> bool:
        """Compile with the current site moves; push the motion or the diagnostics."""
        with self._compile_lock:
            compiled = compile_motions(
                self.paths, self.options, self.motion, task=self.task, moved=self.moved
            )
            return self._publish(compiled)

    def _publish(self, compiled: Compiled) -> bool:
        if not compiled.ok or not compiled.motions:
            items = compiled.program.diagnostics
            payload = json.dumps(diagnostics_payload(items), ensure_ascii=False)
            with self._lock:
                self.last_diagnostics = payload
            self.broadcast("diagnostics", payload)
            return False
        doc = compiled.documents()[0]
        data = script_json(doc)
        with self._lock:
            self.generation += 1
            self.last_motion, self.last_diagnostics = data, None
            self.sites = {s["name"] for s in doc["ir"]["scene"]["sites"]}
        self.broadcast("motion", data)
        return True

    def move_site(self, name: str, position: Vec3) -> bool:
        self.moved[name] = position
        return self.recompile()

    def subscribe(self) -> queue.Queue[tuple[str, str]]:
        q: queue.Queue[tuple[str, str]] = queue.Queue(maxsize=16)
        with self._lock:
            self._clients.append(q)
            if self.last_motion is not None:
                q.put(("motion", self.last_motion))
            if self.last_diagnostics is not None:
                q.put(("diagnostics", self.last_diagnostics))
        return q

    def unsubscribe(self, q: queue.Queue[tuple[str, str]]) -> None:
        with self._lock:
            if q in self._clients:
                self._clients.remove(q)

    def broadcast(self, event: str, data: str) -> None:
        with self._lock:
            clients = list(self._clients)
        for q in clients:
            try:
                q.put_nowait((event, data))
            except queue.Full:  # a stalled client loses old events, never blocks the others
                self.unsubscribe(q)


def make_handler(hub: MotionHub, page: str) -> type[BaseHTTPRequestHandler]:
    """The request handler bound to one hub and its page."""

    class Handler(BaseHTTPRequestHandler):
        server_version = "mtlc-serve"
        protocol_version = "HTTP/1.1"

        def log_message(self, format: str, *args: Any) -> None:  # quiet: the CLI owns stderr
            pass

        def do_GET(self) -> None:
            if self.path in ("/", "/index.html"):
                self._send(HTTPStatus.OK, page.encode("utf-8"), "text/html; charset=utf-8")
            elif self.path == "/events":
                self._stream()
            elif self.path == "/motion":
                body = (hub.last_motion or "null").encode("utf-8")
                self._send(HTTPStatus.OK, body, "application/json")
            else:
                self._error(HTTPStatus.NOT_FOUND, "no such page")

        def do_POST(self) -> None:
            if self.path != "/site":
                self._error(HTTPStatus.NOT_FOUND, "no such endpoint")
                return
            length = self.headers.get("Content-Length", "")
            if not length.isdigit():
                self._error(HTTPStatus.LENGTH_REQUIRED, "Content-Length required")
                return
            if int(length) > MAX_BODY:
                self.close_connection = True  # do not read an oversized body
                self._error(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, f"over {MAX_BODY} bytes")
                return
            body = self.rfile.read(int(length))
            try:
                name, position = parse_site_move(body, hub.sites)
            except BadRequest as exc:
                self._error(HTTPStatus.BAD_REQUEST, str(exc))
                return
            ok = hub.move_site(name, position)
            reply = {"ok": ok, "generation": hub.generation}
            self._send(HTTPStatus.OK, json.dumps(reply).encode(), "application/json")

        def _stream(self) -> None:
            self.send_response(HTTPStatus.OK)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-cache")
            self.send_header("Connection", "close")
            self.end_headers()
            self.close_connection = True
            q = hub.subscribe()
            try:
                while not getattr(self.server, "stopping", False):
                    try:
                        event, data = q.get(timeout=KEEPALIVE_S)
                        self.wfile.write(f"event: {event}\ndata: {data}\n\n".encode())
                    except queue.Empty:
                        self.wfile.write(b": keep-alive\n\n")
                    self.wfile.flush()
            except (BrokenPipeError, ConnectionResetError, OSError):
                pass  # the client left
            finally:
                hub.unsubscribe(q)

        def _send(self, status: HTTPStatus, body: bytes, kind: str) -> None:
            self.send_response(status)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(body)

        def _error(self, status: HTTPStatus, message: str) -> None:
            body = json.dumps({"error": message}).encode()
            self._send(status, body, "application/json")

    return Handler


class FileWatcher(threading.Thread):
    """Recompile when a watched file's modification time or size changes (polling)."""

    def __init__(self, paths: list[Path], on_change: Callable[[], object], interval: float) -> None:
        super().__init__(daemon=True, name="mtlc-watch")
        self.paths, self.on_change, self.interval = paths, on_change, interval
        self.stop_event = threading.Event()
        self._seen = self._stamp()

    def _stamp(self) -> tuple[tuple[int, int], ...]:
        out = []
        for p in self.paths:
            try:
                st = p.stat()
                out.append((st.st_mtime_ns, st.st_size))
            except OSError:
                out.append((0, 0))
        return tuple(out)

    def run(self) -> None:
        while not self.stop_event.wait(self.interval):
            stamp = self._stamp()
            if stamp != self._seen:
                self._seen = stamp
                self.on_change()


@dataclass
class PreviewServer:
    """The HTTP server, its hub and its file watcher; ``start`` runs them in threads."""

    hub: MotionHub
    host: str = "127.0.0.1"
    port: int = 0
    poll: float = 0.5
    httpd: ThreadingHTTPServer | None = None
    watcher: FileWatcher | None = None

    @property
    def url(self) -> str:
        assert self.httpd is not None
        host, port = self.httpd.server_address[:2]
        return f"http://{host}:{port}/"

    def start(self) -> None:
        self.hub.recompile()
        page = render_page(None, serve=True, title="mtlc serve")
        self.httpd = ThreadingHTTPServer((self.host, self.port), make_handler(self.hub, page))
        self.httpd.daemon_threads = True
        threading.Thread(target=self.httpd.serve_forever, daemon=True, name="mtlc-http").start()
        self.watcher = FileWatcher(self.hub.paths, self.hub.recompile, self.poll)
        self.watcher.start()

    def stop(self) -> None:
        if self.watcher is not None:
            self.watcher.stop_event.set()
        if self.httpd is not None:
            self.httpd.stopping = True  # type: ignore[attr-defined]
            self.httpd.shutdown()
            self.httpd.server_close()
