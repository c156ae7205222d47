"""`mtlc serve` under crashes, foreign pages, slow clients and odd requests (review fixes).

A small task keeps each server start (one compile) short.
"""

from __future__ import annotations

import http.client
import json
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mtlc.frontend import FrontendOptions
from mtlc.passes import MotionOptions
from mtlc.preview import server as server_module
from mtlc.preview.server import (
    SCENE_REACH,
    BadRequest,
    Mailbox,
    MotionHub,
    PreviewServer,
    host_is_allowed,
    is_json_content,
    parse_site_move,
    scene_centre,
)

from .test_preview_server import Events

SMALL_TASK = """use stdlib.actions

scene s {
    ground 0 cm
    site button at (0, 100, 60) cm normal (0, 0, -1)
}

task t "press a button" {
    manikin gb10000_1988 female p50
    scene s
    press(right, button)
}
"""
JSON = {"Content-Type": "application/json"}
MOVE = json.dumps({"site": "button", "position": [0.02, 1.0, 0.6]}).encode()


def _start(task: Path, host: str = "127.0.0.1") -> PreviewServer:
    hub = MotionHub([task], FrontendOptions(), MotionOptions(fps=10))
    server = PreviewServer(hub, host=host, port=0, poll=0.05)
    server.start()
    return server


@pytest.fixture
def small(tmp_path: Path) -> Iterator[tuple[PreviewServer, Path]]:
    task = tmp_path / "small.mtask"
    task.write_text(SMALL_TASK, encoding="utf-8")
    server = _start(task)
    try:
        yield server, task
    finally:
        server.stop()


def _request(server: PreviewServer, method: str, path: str, body: bytes | None = None,
             headers: dict[str, str] | None = None) -> tuple[int, Any]:  # fmt: skip
    """A request with whatever headers are given (``Host`` too, which http.client would set)."""
    host, port = server.httpd.server_address[:2]
    conn = http.client.HTTPConnection(host, port, timeout=60)
    headers = dict(headers or {})
    conn.putrequest(method, path, skip_host="Host" in headers, skip_accept_encoding=True)
    for name, value in headers.items():
        conn.putheader(name, value)
    if body is not None:
        conn.putheader("Content-Length", str(len(body)))
    conn.endheaders(body)
    reply = conn.getresponse()
    data = reply.read()
    conn.close()
    return reply.status, json.loads(data) if data[:1] in (b"{", b"[", b"n") else data


def _raw(server: PreviewServer, request: bytes) -> bytes:
    """Send bytes, read the reply until the server closes the connection."""
    host, port = server.httpd.server_address[:2]
    with socket.create_connection((host, port), timeout=20) as sock:
        sock.sendall(request)
        out = b""
        while chunk := sock.recv(65536):
            out += chunk
    return out


def _touch(task: Path) -> None:
    """A save: the watcher compares modification time and size, so change the size."""
    task.write_text(task.read_text(encoding="utf-8") + "\n", encoding="utf-8")


# --------------------------------------------------------------------------- crashes


def _crash(*args: Any, **kwargs: Any) -> Any:
    raise RuntimeError("simulated bug")


def test_a_crashing_recompile_is_mt0900_and_later_saves_still_recompile(
    small: tuple[PreviewServer, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A crash in the watcher's recompile killed the watcher thread: no recompile ever after."""
    server, task = small
    events = Events(*server.httpd.server_address[:2], timeout=20)
    try:
        assert events.next()[0] == "motion"
        good = server.hub.last_motion
        monkeypatch.setattr(server_module, "compile_motions", _crash)
        _touch(task)
        kind, data = events.next()
        assert kind == "diagnostics"
        (item,) = data["diagnostics"]
        assert item["code"] == "MT0900" and "simulated bug" in item["message"]
        assert item["file"].endswith("small.mtask")
        assert server.hub.last_motion == good  # the last good motion stays
        monkeypatch.undo()
        _touch(task)
        assert events.next()[0] == "motion"
    finally:
        events.close()


def test_a_crashing_site_move_gets_500_and_is_undone(
    small: tuple[PreviewServer, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    server, _ = small
    monkeypatch.setattr(server_module, "compile_motions", _crash)
    status, reply = _request(server, "POST", "/site", MOVE, JSON)
    assert status == 500 and "MT0900" in reply["error"]
    assert server.hub.moved == {}
    monkeypatch.undo()
    status, reply = _request(server, "POST", "/site", MOVE, JSON)
    assert status == 200 and reply["ok"] is True
    assert server.hub.moved == {"button": (0.02, 1.0, 0.6)}


def test_an_undone_move_restores_the_previous_move(monkeypatch: pytest.MonkeyPatch) -> None:
    hub = MotionHub([Path("nowhere.mtask")], FrontendOptions(), MotionOptions())
    hub.moved["button"] = (0.0, 1.0, 0.5)
    monkeypatch.setattr(server_module, "compile_motions", _crash)
    assert hub.move_site("button", (0.1, 1.0, 0.5)).value == "crashed"
    assert hub.moved == {"button": (0.0, 1.0, 0.5)}
    assert json.loads(hub.last_diagnostics or "{}")["diagnostics"][0]["code"] == "MT0900"


# --------------------------------------------------------------------------- foreign pages


def test_a_rebound_host_name_cannot_read_the_motion(small: tuple[PreviewServer, Path]) -> None:
    server, _ = small
    port = server.httpd.server_address[1]
    for host in (f"attacker.example:{port}", "127.0.0.1:1", f"localhost.attacker.example:{port}"):
        status, reply = _request(server, "GET", "/motion", headers={"Host": host})
        assert status == 403 and "Host" in reply["error"], host
    for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"[::1]:{port}"):
        status, reply = _request(server, "GET", "/motion", headers={"Host": host})
        assert status == 200 and reply["format"] == "mtlc-preview", host
    assert _raw(server, b"GET /motion HTTP/1.0\r\n\r\n").split(b" ")[1] == b"403"  # no Host


def test_a_cross_site_post_is_refused(small: tuple[PreviewServer, Path]) -> None:
    server, _ = small
    port = server.httpd.server_address[1]
    plain = {"Content-Type": "text/plain"}  # what a cross-site fetch may send without preflight
    assert _request(server, "POST", "/site", MOVE, plain)[0] == 415
    assert _request(server, "POST", "/site", MOVE, {})[0] == 415
    foreign = {**JSON, "Origin": "http://attacker.example"}
    assert _request(server, "POST", "/site", MOVE, foreign)[0] == 403
    assert _request(server, "POST", "/site", MOVE, {**JSON, "Origin": "null"})[0] == 403
    assert server.hub.moved == {}
    own = {"Content-Type": "application/json; charset=utf-8", "Origin": f"http://127.0.0.1:{port}"}
    assert _request(server, "POST", "/site", MOVE, own)[0] == 200


@pytest.mark.parametrize(
    ("host", "bound", "ok"),
    [
        ("127.0.0.1:8765", "127.0.0.1", True),
        ("localhost:8765", "127.0.0.1", True),
        ("[::1]:8765", "::1", True),
        ("localhost:8766", "127.0.0.1", False),
        ("evil.example:8765", "127.0.0.1", False),
        ("192.168.1.5:8765", "127.0.0.1", False),
        ("192.168.1.5:8765", "192.168.1.5", True),
        ("192.168.1.5:8765", "0.0.0.0", True),  # an IP literal cannot be DNS-rebound
        ("[fe80::1]:8765", "::", True),
        ("evil.example:8765", "0.0.0.0", False),
        ("", "127.0.0.1", False),
    ],
)
def test_host_is_allowed(host: str, bound: str, ok: bool) -> None:
    assert host_is_allowed(host, bound, 8765) is ok


def test_json_content_types() -> None:
    assert is_json_content("application/json") and is_json_content("Application/JSON; charset=x")
    assert not is_json_content("text/plain") and not is_json_content("")
    assert not is_json_content("application/jsonp")


# --------------------------------------------------------------------------- far sites


def test_a_site_cannot_be_moved_far_from_the_scene() -> None:
    centre = (10.0, 1.0, -3.0)
    ok = json.dumps({"site": "a", "position": [10 + SCENE_REACH - 1, 1.0, -3.0]}).encode()
    assert parse_site_move(ok, {"a"}, centre)[1][0] == pytest.approx(10 + SCENE_REACH - 1)
    for far in ([10 + SCENE_REACH + 1, 1, -3], [10, 1 - SCENE_REACH - 1, -3], [0, 0, 1000]):
        with pytest.raises(BadRequest, match="scene"):
            parse_site_move(json.dumps({"site": "a", "position": far}).encode(), {"a"}, centre)


def test_the_scene_centre_leaves_out_moved_sites_and_keeps_the_origin() -> None:
    sites = [{"name": "a", "position": [2.0, 1.0, 4.0]}, {"name": "b", "position": [900, 0, 0]}]
    assert scene_centre(sites, {"b"}) == pytest.approx((1.0, 0.5, 2.0))
    assert scene_centre([], []) == (0.0, 0.0, 0.0)


def test_a_site_move_far_away_is_refused_by_the_server(small: tuple[PreviewServer, Path]) -> None:
    server, _ = small
    far = json.dumps({"site": "button", "position": [999.0, 1.0, 0.6]}).encode()
    status, reply = _request(server, "POST", "/site", far, JSON)
    assert status == 400 and "scene" in reply["error"]


# --------------------------------------------------------------------------- slow clients


def test_a_mailbox_keeps_the_latest_event_of_each_kind() -> None:
    box = Mailbox()
    for i in range(100):
        box.put("motion", str(i))
    box.put("diagnostics", "d")
    box.put("motion", "last")
    assert box.pending() == [("diagnostics", "d"), ("motion", "last")]
    assert box.get(0.0) == ("diagnostics", "d")
    assert box.get(0.0) == ("motion", "last")
    assert box.get(0.0) is None


def test_a_slow_client_stays_subscribed_and_catches_up(small: tuple[PreviewServer, Path]) -> None:
    """A client that stopped reading was unsubscribed when 16 events had piled up, and then
    only got keep-alives: it now gets the latest motion once it reads again."""
    server, _ = small
    events = Events(*server.httpd.server_address[:2], timeout=20)
    try:
        hub = server.hub
        pad = "x" * 1_000_000  # 60 MB in all: more than the socket buffers hold unread
        for i in range(60):
            hub.broadcast("motion", json.dumps({"n": i, "pad": pad}))
        assert len(hub._clients) == 1
        seen = []
        while not seen or seen[-1] != 59:
            kind, data = events.next()
            if kind == "motion" and "n" in data:
                seen.append(data["n"])
        assert seen == sorted(seen) and len(seen) < 60  # the backlog was coalesced
    finally:
        events.close()


# --------------------------------------------------------------------------- odd requests


def test_a_non_ascii_content_length_is_refused(small: tuple[PreviewServer, Path]) -> None:
    server, _ = small
    host, port = server.httpd.server_address[:2]
    request = (
        f"POST /site HTTP/1.1\r\nHost: {host}:{port}\r\nContent-Type: application/json\r\n"
        "Content-Length: \u00b2\r\n\r\n"
    ).encode()
    assert _raw(server, request).split(b" ")[1] == b"411"
    assert _request(server, "GET", "/motion")[0] == 200


def test_a_silent_client_is_dropped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A client that never sends its request line held a server thread forever."""
    monkeypatch.setattr(server_module, "REQUEST_TIMEOUT_S", 0.3)
    task = tmp_path / "small.mtask"
    task.write_text(SMALL_TASK, encoding="utf-8")
    server = _start(task)
    try:
        host, port = server.httpd.server_address[:2]
        with socket.create_connection((host, port), timeout=20) as sock:
            sock.sendall(b"POST /site HTTP/1.1\r\n")  # and then nothing
            assert sock.recv(1024) == b""  # closed by the server, long before our 20 s
    finally:
        server.stop()


def _ipv6_loopback() -> bool:
    try:
        with socket.socket(socket.AF_INET6, socket.SOCK_STREAM) as sock:
            sock.bind(("::1", 0))
    except OSError:
        return False
    return True


@pytest.mark.skipif(not _ipv6_loopback(), reason="no IPv6 loopback here")
def test_serve_listens_on_ipv6(tmp_path: Path) -> None:
    task = tmp_path / "small.mtask"
    task.write_text(SMALL_TASK, encoding="utf-8")
    server = _start(task, host="::1")
    try:
        assert server.url.startswith("http://[::1]:")
        status, reply = _request(server, "GET", "/motion")
        assert status == 200 and reply["format"] == "mtlc-preview"
    finally:
        server.stop()
