"""`mtlc serve`: a local server that streams the motion to a light browser client (seed 004).

The page (the preview page in serve mode) opens a Server-Sent Events stream at ``/events`` and
receives the compiled motion as ``motion`` events; a failed recompile sends a ``diagnostics``
event and the page keeps the last good motion. Dragging a site POSTs ``{"site", "position"}`` to
``/site``; the server recompiles with the site there and streams the result. Saving the
``.mtask`` file recompiles too (the file's modification time is polled).

Standard library only: ``ThreadingHTTPServer``, one thread per client, at most ``MAX_WORKERS``
at a time (one more gets a 503 at once), each dropped after ``REQUEST_TIMEOUT_S`` of silence.
Requests are refused, never fatal: bodies over ``MAX_BODY`` bytes, invalid or deeply nested
JSON, numbers too large for a float, unknown sites, non-finite numbers or sites moved far from
the scene get a 4xx reply with a JSON error and the server carries on; a compile that crashes
is an MT0900 diagnostics event (and a 500 to the move that caused it). A client that goes away
mid-reply is one line on stderr, never a traceback.

Only this machine's pages may talk to it: the ``Host`` header must name the server (a DNS
rebinding page has its own name there), a POST must be ``application/json`` (a cross-site form
or ``text/plain`` fetch cannot send that without a CORS preflight, which is never granted) and
an ``Origin``, when sent, must be the server's own.
"""

from __future__ import annotations

import ipaddress
import json
import math
import os
import socket
import sys
import threading
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from enum import Enum
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from mtlc.diagnostics import Diagnostic, DiagnosticSink, Span
from mtlc.frontend import FrontendOptions
from mtlc.passes import MotionOptions
from mtlc.preview.compile import Compiled, compile_motions
from mtlc.preview.html import render_page, script_json
from mtlc.preview.sites import Vec3

MAX_BODY = 4096  # bytes: a site move is well under 200
MAX_COORDINATE = 1000.0  # m: a site farther than 1 km from the origin is a mistake
SCENE_REACH = 50.0  # m: a site moves at most this far (per axis) from the scene's centre
KEEPALIVE_S = 15.0
REQUEST_TIMEOUT_S = 30.0  # a client silent this long (request line, body, or reading) is dropped
MAX_WORKERS = 32  # connections served at once: each open page holds one for its event stream
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")


class BadRequest(ValueError):
    """A client message that is refused (and answered with 400)."""


def parse_site_move(
    body: bytes, known: set[str], centre: Vec3 = (0.0, 0.0, 0.0)
) -> tuple[str, Vec3]:
    """``{"site": NAME, "position": [x, y, z]}`` (metres), checked strictly; the position must
    lie within ``SCENE_REACH`` of the scene's ``centre`` on every axis (a site dragged 1 km away
    made one recompile walk for 5 min 38 s, holding the compile lock)."""
    try:
        doc = json.loads(body.decode("utf-8"), parse_constant=_reject_constant)
    except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as exc:
        raise BadRequest(f"not JSON: {exc}") from None
    except RecursionError:  # 4,000 `[` fit in MAX_BODY
        raise BadRequest("not JSON a site move can be: nested too deeply") from None
    if not isinstance(doc, dict) or set(doc) != {"site", "position"}:
        raise BadRequest('expected an object with exactly "site" and "position"')
    name, position = doc["site"], doc["position"]
    if not isinstance(name, str) or name not in known:
        raise BadRequest(f"unknown site {name!r}")
    if not isinstance(position, list) or len(position) != 3:
        raise BadRequest("position must be a list of three numbers (metres)")
    if not all(isinstance(c, int | float) and not isinstance(c, bool) for c in position):
        raise BadRequest("position must be a list of three numbers (metres)")
    try:
        coords = tuple(float(c) for c in position)
    except OverflowError:  # an integer of 400 digits
        raise BadRequest(f"position must be finite and within {MAX_COORDINATE:g} m") from None
    if not all(math.isfinite(c) and abs(c) <= MAX_COORDINATE for c in coords):
        raise BadRequest(f"position must be finite and within {MAX_COORDINATE:g} m")
    if any(abs(c - m) > SCENE_REACH for c, m in zip(coords, centre, strict=True)):
        raise BadRequest(f"position must be within {SCENE_REACH:g} m of the scene's centre")
    return name, (coords[0], coords[1], coords[2])


def scene_centre(sites: Iterable[dict[str, Any]], moved: Iterable[str]) -> Vec3:
    """The centre of the box around the scene's sites where the file puts them (sites moved in
    this session are left out, so moves cannot creep the box away) and the origin, where the
    manikin starts."""
    skip = set(moved)
    points = [s["position"] for s in sites if s["name"] not in skip] + [[0.0, 0.0, 0.0]]
    lo = [min(p[i] for p in points) for i in range(3)]
    hi = [max(p[i] for p in points) for i in range(3)]
    return ((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2)


def allowed_hosts(bound: str, port: int) -> set[str]:
    """``Host`` values that name this server: the loopback names and the host it was bound to
    (bracketed when IPv6), with the port."""
    names = set(LOOPBACK_NAMES)
    names.add(f"[{bound}]" if ":" in bound else bound)
    return {f"{n}:{port}" for n in names}


def host_is_allowed(host: str, bound: str, port: int) -> bool:
    """Whether a request's ``Host`` names this server. Bound to every interface (0.0.0.0,
    ::), any IP literal with the port is also accepted: DNS rebinding needs a host name."""
    if host in allowed_hosts(bound, port):
        return True
    if bound not in ("0.0.0.0", "::", ""):
        return False
    name, _, got_port = host.rpartition(":")
    if got_port != str(port):
        return False
    try:
        ipaddress.ip_address(name[1:-1] if name.startswith("[") else name)
    except ValueError:
        return False
    return True


def is_json_content(content_type: str) -> bool:
    """``application/json``, with parameters (``; charset=utf-8``) or not."""
    return content_type.split(";", 1)[0].strip().lower() == "application/json"


class Outcome(Enum):
    """How a compile ended: a motion, diagnostics for the input, or a crash (MT0900)."""

    MOTION = "motion"
    DIAGNOSTICS = "diagnostics"
    CRASHED = "crashed"


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
    centre: Vec3 = (0.0, 0.0, 0.0)  # of the scene, for bounding site moves
    models: list[Path] = field(default_factory=list)  # the scenes' model files, watched too
    _clients: list[Mailbox] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _compile_lock: threading.Lock = field(default_factory=threading.Lock)  # also guards `moved`

    def recompile(self) -> bool:
        """Compile with the current site moves; push the motion or the diagnostics. Never
        raises: a crash is published as MT0900 and the last good motion stays."""
        with self._compile_lock:
            return self._compile() is Outcome.MOTION

    def move_site(self, name: str, position: Vec3) -> Outcome:
        """Move a site and recompile; a move whose compile crashed is taken back."""
        with self._compile_lock:
            before = self.moved.get(name)
            self.moved[name] = position
            outcome = self._compile()
            if outcome is Outcome.CRASHED:
                if before is None:
                    del self.moved[name]
                else:
                    self.moved[name] = before
            return outcome

    def _compile(self) -> Outcome:
        """One compile and its publication; the caller holds ``_compile_lock``."""
        try:
            compiled = compile_motions(
                self.paths, self.options, self.motion, task=self.task, moved=dict(self.moved)
            )
            if compiled.program.checker is not None:  # a broken model stays watched: its fix
                self.models = compiled.program.model_files  # recompiles
            return self._publish(compiled)
        except Exception as exc:  # a bug in mtlc: say so, and keep serving
            self._publish_crash(exc)
            return Outcome.CRASHED

    def watched(self) -> list[Path]:
        """The files whose change recompiles: the task files and their scenes' models."""
        return [*self.paths, *self.models]

    def _publish(self, compiled: Compiled) -> Outcome:
        if not compiled.ok or not compiled.motions:
            self._publish_diagnostics(compiled.program.diagnostics)
            return Outcome.DIAGNOSTICS
        doc = compiled.documents()[0]
        data = script_json(doc)
        sites = doc["ir"]["scene"]["sites"]
        with self._lock:
            self.generation += 1
            self.last_motion, self.last_diagnostics = data, None
            self.sites = {s["name"] for s in sites}
            self.centre = scene_centre(sites, self.moved)
        self.broadcast("motion", data)
        return Outcome.MOTION

    def _publish_diagnostics(self, items: list[Diagnostic]) -> None:
        payload = json.dumps(diagnostics_payload(items), ensure_ascii=False)
        with self._lock:
            self.last_diagnostics = payload
        self.broadcast("diagnostics", payload)

    def _publish_crash(self, exc: Exception) -> None:
        if os.environ.get("MTLC_DEBUG"):
            traceback.print_exception(exc, file=sys.stderr)
        sink = DiagnosticSink()
        sink.report(
            "MT0900",
            f"internal error: {type(exc).__name__}: {exc}",
            Span.whole_file(str(self.paths[0]) if self.paths else "<serve>"),
            help="this is a bug in mtlc; rerun with MTLC_DEBUG=1 for the trace and report it",
        )
        self._publish_diagnostics(sink.items)

    def subscribe(self) -> Mailbox:
        box = Mailbox()
        with self._lock:
            self._clients.append(box)
            if self.last_motion is not None:
                box.put("motion", self.last_motion)
            if self.last_diagnostics is not None:
                box.put("diagnostics", self.last_diagnostics)
        return box

    def unsubscribe(self, box: Mailbox) -> None:
        with self._lock:
            if box in self._clients:
                self._clients.remove(box)

    def broadcast(self, event: str, data: str) -> None:
        with self._lock:
            clients = list(self._clients)
        for box in clients:
            box.put(event, data)  # never blocks: a slow client gets the latest when it reads


class Mailbox:
    """A client's pending events, at most one of each kind: a newer ``motion`` replaces one the
    client has not read yet (it only ever needs the latest), so a slow client neither blocks
    the others nor falls silently out of the stream; it catches up with the current state."""

    def __init__(self) -> None:
        self._pending: list[tuple[str, str]] = []
        self._ready = threading.Condition()

    def put(self, event: str, data: str) -> None:
        with self._ready:
            self._pending = [p for p in self._pending if p[0] != event]
            self._pending.append((event, data))
            self._ready.notify()

    def get(self, timeout: float) -> tuple[str, str] | None:
        """The oldest pending event, or None after ``timeout`` seconds without one."""
        with self._ready:
            if not self._ready.wait_for(lambda: bool(self._pending), timeout):
                return None
            return self._pending.pop(0)

    def pending(self) -> list[tuple[str, str]]:
        with self._ready:
            return list(self._pending)


def make_handler(hub: MotionHub, page: str) -> type[BaseHTTPRequestHandler]:
    """The request handler bound to one hub and its page."""

    class Handler(BaseHTTPRequestHandler):
        server_version = "mtlc-serve"
        protocol_version = "HTTP/1.1"
        timeout = REQUEST_TIMEOUT_S  # socket timeout: a silent client frees its thread

        def log_message(self, format: str, *args: Any) -> None:  # quiet: the CLI owns stderr
            pass

        def _from_this_machine(self) -> bool:
            """Refuse (403) a request whose Host or Origin is not this server."""
            bound, port = self.server.server_address[:2]
            host = self.headers.get("Host", "")
            if not host_is_allowed(host, str(bound), int(port)):
                self._error(HTTPStatus.FORBIDDEN, f"Host {host!r} is not this server")
                return False
            origin = self.headers.get("Origin")
            if origin is not None and origin != f"http://{host}":
                self._error(HTTPStatus.FORBIDDEN, f"Origin {origin!r} is not this server")
                return False
            return True

        def do_GET(self) -> None:
            if not self._from_this_machine():
                return
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
            if not self._from_this_machine():
                self.close_connection = True  # its body is not read
                return
            if self.path != "/site":
                self._error(HTTPStatus.NOT_FOUND, "no such endpoint")
                return
            if not is_json_content(self.headers.get("Content-Type", "")):
                self.close_connection = True
                self._error(
                    HTTPStatus.UNSUPPORTED_MEDIA_TYPE, "Content-Type must be application/json"
                )
                return
            length = self.headers.get("Content-Length", "")
            if not (length.isascii() and length.isdigit()):  # "²".isdigit() is True
                self.close_connection = True
                self._error(HTTPStatus.LENGTH_REQUIRED, "Content-Length required")
                return
            if int(length) > MAX_BODY:
                self.close_connection = True  # do not read an oversized body
                self._error(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, f"over {MAX_BODY} bytes")
                return
            body = self.rfile.read(int(length))
            try:
                name, position = parse_site_move(body, hub.sites, hub.centre)
            except BadRequest as exc:
                self._error(HTTPStatus.BAD_REQUEST, str(exc))
                return
            outcome = hub.move_site(name, position)
            if outcome is Outcome.CRASHED:
                self._error(HTTPStatus.INTERNAL_SERVER_ERROR,
                            "MT0900: the recompile crashed (a bug in mtlc); the move was undone")  # fmt: skip
                return
            reply = {"ok": outcome is Outcome.MOTION, "generation": hub.generation}
            self._send(HTTPStatus.OK, json.dumps(reply).encode(), "application/json")

        def _stream(self) -> None:
            self.send_response(HTTPStatus.OK)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-cache")
            self.send_header("Connection", "close")
            self.end_headers()
            self.close_connection = True
            box = hub.subscribe()
            try:
                while not getattr(self.server, "stopping", False):
                    item = box.get(timeout=KEEPALIVE_S)
                    if item is None:
                        self.wfile.write(b": keep-alive\n\n")
                    else:
                        self.wfile.write(f"event: {item[0]}\ndata: {item[1]}\n\n".encode())
                    self.wfile.flush()
            except OSError:
                pass  # the client left, or stopped reading for REQUEST_TIMEOUT_S
            finally:
                hub.unsubscribe(box)

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


CLIENT_GONE = (BrokenPipeError, ConnectionResetError, ConnectionAbortedError, TimeoutError)
BUSY_REPLY = (
    b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
    b"Content-Length: 52\r\nRetry-After: 1\r\nConnection: close\r\n\r\n"
    b'{"error": "too many connections; try again shortly"}'
)


class BoundedServer(ThreadingHTTPServer):
    """A thread per connection, at most ``max_workers`` at once: 200 idle sockets held 198
    threads. A connection over the bound is answered 503 by the accepting thread and closed;
    an error while answering is one line on stderr (a browser that went away is no bug)."""

    max_workers = MAX_WORKERS
    daemon_threads = True

    def server_activate(self) -> None:
        self._slots = threading.BoundedSemaphore(self.max_workers)
        super().server_activate()

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self._slots.acquire(blocking=False):
            self._refuse(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def _refuse(self, request: socket.socket) -> None:
        try:
            request.settimeout(1.0)
            request.sendall(BUSY_REPLY)
        except OSError:
            pass
        self.shutdown_request(request)

    def handle_error(self, request: Any, client_address: Any) -> None:
        exc = sys.exc_info()[1]
        who = f"{client_address[0]}:{client_address[1]}" if client_address else "a client"
        if isinstance(exc, CLIENT_GONE):
            sys.stderr.write(f"mtlc serve: {who} went away ({type(exc).__name__})\n")
            return
        sys.stderr.write(f"mtlc serve: error answering {who}: {type(exc).__name__}: {exc}\n")
        if os.environ.get("MTLC_DEBUG"):
            traceback.print_exc()


class IPv6Server(BoundedServer):
    """``--host ::1``: the standard server is IPv4 only ("Address family not supported")."""

    address_family = socket.AF_INET6


SETTLE_SECONDS = 0.05  # a changed file is recompiled once its stamp held still this long


class FileWatcher(threading.Thread):
    """Recompile when a watched file's modification time or size changes (polling). The list
    is asked anew at each poll: a compile can add files (a scene's model)."""

    def __init__(
        self, watched: Callable[[], list[Path]], on_change: Callable[[], object], interval: float
    ) -> None:
        super().__init__(daemon=True, name="mtlc-watch")
        self.watched, self.on_change, self.interval = watched, on_change, interval
        self.stop_event = threading.Event()
        self._seen = self._stamp()

    def _stamp(self) -> dict[str, tuple[int, int]]:
        out = {}
        for p in self.watched():
            try:
                st = p.stat()
                out[str(p)] = (st.st_mtime_ns, st.st_size)
            except OSError:
                out[str(p)] = (0, 0)
        return out

    @staticmethod
    def _changed(before: dict[str, tuple[int, int]], now: dict[str, tuple[int, int]]) -> bool:
        """A file seen before with another stamp; a file just added to the list (the compile
        that named it has read it) or dropped from it is not a change."""
        return any(before.get(path, stamp) != stamp for path, stamp in now.items())

    def run(self) -> None:
        while not self.stop_event.wait(self.interval):
            stamp = self._stamp()
            if self._changed(self._seen, stamp):
                # a save in progress (truncated, then written) changes the stamp twice: wait
                # until it holds still, and recompile once, on the saved text (a poll between
                # the two sent the half-written file's diagnostics and then the file's own)
                while not self.stop_event.wait(SETTLE_SECONDS) and self._changed(
                    stamp, again := self._stamp()
                ):
                    stamp = again
                try:
                    self.on_change()
                except Exception:  # one bad recompile must not end the watching
                    if os.environ.get("MTLC_DEBUG"):
                        traceback.print_exc()
            self._seen = {**self._stamp(), **stamp}  # what was compiled, and the files it added


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
        return f"http://[{host}]:{port}/" if ":" in str(host) else f"http://{host}:{port}/"

    def start(self) -> None:
        self.hub.recompile()
        page = render_page(None, serve=True, title="mtlc serve")
        server_class = IPv6Server if ":" in self.host else BoundedServer
        self.httpd = server_class((self.host, self.port), make_handler(self.hub, page))
        threading.Thread(target=self.httpd.serve_forever, daemon=True, name="mtlc-http").start()
        self.watcher = FileWatcher(self.hub.watched, self.hub.recompile, self.poll)
        self.watcher.start()

    def stop(self) -> None:
        if self.watcher is not None:
            self.watcher.stop_event.set()
        if self.httpd is not None:
            self.httpd.stopping = True  # type: ignore[attr-defined]
            self.httpd.shutdown()
            self.httpd.server_close()
