"""`mtlc serve` against hostile numbers, floods of idle connections, clients that leave and bad
options (issue 17, section 5). Loopback only; every wait is bounded."""

from __future__ import annotations

import json
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from mtlc.cli import main
from mtlc.preview import server as server_module
from mtlc.preview.server import BadRequest, PreviewServer, parse_site_move

from .test_preview_serve_hardening import JSON, SMALL_TASK, _raw, _request, _start


@pytest.fixture
def small(tmp_path: Path) -> Iterator[PreviewServer]:
    task = tmp_path / "small.mtask"
    task.write_text(SMALL_TASK, encoding="utf-8")
    server = _start(task)
    try:
        yield server
    finally:
        server.stop()


def _move(position: str) -> bytes:
    return ('{"site": "button", "position": ' + position + "}").encode()


@pytest.mark.parametrize(
    ("body", "says"),
    [
        (_move("[" + "9" * 400 + ", 1, 0.6]"), "finite"),  # OverflowError in float()
        (_move("[-" + "9" * 400 + ".5e999, 1, 0.6]"), "finite"),  # a float literal: inf
        (b"[" * 4000, "nested too deeply"),  # RecursionError in json.loads
        (b'{"site": "button", "position": ' + b"[" * 3000 + b"]" * 3000 + b"}", "nested"),
    ],
)
def test_hostile_numbers_and_nesting_are_bad_requests(body: bytes, says: str) -> None:
    with pytest.raises(BadRequest, match=says):
        parse_site_move(body, {"button"})


def test_the_server_answers_them_400_and_carries_on(small: PreviewServer) -> None:
    for body in (_move("[" + "9" * 400 + ", 1, 0.6]"), b"[" * 4000):
        status, reply = _request(small, "POST", "/site", body, JSON)
        assert status == 400 and "error" in reply
    status, reply = _request(small, "GET", "/motion")
    assert status == 200 and reply["format"] == "mtlc-preview"


def _idle(server: PreviewServer) -> socket.socket:
    host, port = server.httpd.server_address[:2]
    return socket.create_connection((host, port), timeout=20)


def test_idle_connections_cannot_take_more_than_the_bound(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """20 silent connections against a bound of 3: 3 threads, the rest a 503 at once; a slot
    comes back when its client leaves."""
    monkeypatch.setattr(server_module.BoundedServer, "max_workers", 3)
    task = tmp_path / "small.mtask"
    task.write_text(SMALL_TASK, encoding="utf-8")
    before = threading.active_count()
    server = _start(task)
    base = threading.active_count() - before  # the accept loop and the watcher
    idle = [_idle(server) for _ in range(3)]
    refused = [_idle(server) for _ in range(17)]
    try:
        for sock in refused:  # each answered and closed by the accepting thread
            reply = b""
            while chunk := sock.recv(4096):
                reply += chunk
            assert reply.startswith(b"HTTP/1.1 503 ")
            assert json.loads(reply.split(b"\r\n\r\n", 1)[1])["error"].startswith("too many")
        assert threading.active_count() - before <= base + 3
        idle.pop().close()  # its thread sees the end of the stream and gives its slot back
        for _ in range(200):  # bounded: the freed slot is taken by the first retry that fits
            host, port = server.httpd.server_address[:2]
            reply = _raw(server, f"GET /motion HTTP/1.1\r\nHost: {host}:{port}\r\n"
                         "Connection: close\r\n\r\n".encode())  # fmt: skip
            if not reply.startswith(b"HTTP/1.1 503"):
                break
            threading.Event().wait(0.05)
        assert reply.startswith(b"HTTP/1.1 200 ")
    finally:
        for sock in idle + refused:
            sock.close()
        server.stop()


def test_a_client_that_goes_away_is_one_line(
    small: PreviewServer, capsys: pytest.CaptureFixture[str]
) -> None:
    for exc in (BrokenPipeError(32, "Broken pipe"), ConnectionResetError(104, "reset")):
        try:
            raise exc
        except OSError:
            small.httpd.handle_error(None, ("127.0.0.1", 5555))
    err = capsys.readouterr().err
    assert err.splitlines() == [
        "mtlc serve: 127.0.0.1:5555 went away (BrokenPipeError)",
        "mtlc serve: 127.0.0.1:5555 went away (ConnectionResetError)",
    ]
    assert "Traceback" not in err


def test_a_real_reset_mid_reply_prints_no_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A page too large for the socket buffers, and a client that resets after asking for it."""
    monkeypatch.setattr(server_module, "render_page", lambda *a, **k: "x" * 8_000_000)
    task = tmp_path / "small.mtask"
    task.write_text(SMALL_TASK, encoding="utf-8")
    server = _start(task)
    try:
        host, port = server.httpd.server_address[:2]
        sock = _idle(server)
        sock.sendall(f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\n\r\n".encode())
        sock.recv(1024)  # the reply has started
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        sock.close()  # RST
        err = ""
        for _ in range(200):
            err += capsys.readouterr().err
            if "went away" in err:
                break
            threading.Event().wait(0.05)
    finally:
        server.stop()
    err += capsys.readouterr().err
    assert "went away" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("value", ["inf", "nan", "-1", "0", "1e400", "soon"])
def test_a_bad_poll_is_a_usage_error(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["serve", "examples/remove_access_panel.mtask", f"--poll={value}"])
    assert exit_.value.code == 2
    assert "argument --poll:" in capsys.readouterr().err


@pytest.mark.parametrize("value", ["65536", "-1", "http"])
def test_a_bad_port_is_a_usage_error(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["serve", "examples/remove_access_panel.mtask", f"--port={value}"])
    assert exit_.value.code == 2
    assert "argument --port:" in capsys.readouterr().err
