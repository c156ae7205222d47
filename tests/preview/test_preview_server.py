"""`mtlc serve`: frames streamed over SSE, site moves recompiled, garbage refused, saves picked up."""

from __future__ import annotations

import http.client
import json
import re
import socket
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.preview.server import (
    MAX_BODY,
    BadRequest,
    PreviewServer,
    parse_site_move,
)

SITE = "bolt_upper_left"
MOVE = (-0.17, 1.33, 1.10)  # 3 cm right, 2 cm down, 2 cm nearer: still within reach
JSON = {"Content-Type": "application/json"}


class Events:
    """A minimal Server-Sent Events reader over a raw socket (no client library needed)."""

    def __init__(self, host: str, port: int, timeout: float = 60) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout)
        request = (
            f"GET /events HTTP/1.1\r\nHost: {host}:{port}\r\nAccept: text/event-stream\r\n\r\n"
        )
        self.sock.sendall(request.encode())
        self.buf = b""
        head = self._until(b"\r\n\r\n")
        assert head.startswith(b"HTTP/1.1 200"), head

    def _until(self, sep: bytes) -> bytes:
        while sep not in self.buf:
            chunk = self.sock.recv(1 << 16)
            if not chunk:
                raise ConnectionError("stream closed")
            self.buf += chunk
        out, self.buf = self.buf.split(sep, 1)
        return out

    def next(self) -> tuple[str, Any]:
        """The next event (name, decoded data), skipping keep-alive comments."""
        while True:
            block = self._until(b"\n\n").decode("utf-8")
            if block.startswith(":"):
                continue
            fields = dict(line.split(": ", 1) for line in block.splitlines())
            return fields["event"], json.loads(fields["data"])

    def close(self) -> None:
        self.sock.close()


def _request(server: PreviewServer, method: str, path: str, body: bytes | None = None,
             headers: dict[str, str] | None = None) -> tuple[int, Any]:  # fmt: skip
    host, port = server.httpd.server_address[:2]
    conn = http.client.HTTPConnection(host, port, timeout=60)
    conn.request(method, path, body=body, headers=headers or {})
    reply = conn.getresponse()
    data = reply.read()
    conn.close()
    return reply.status, json.loads(data) if data[:1] in (b"{", b"[", b"n") else data


def test_parse_site_move_accepts_a_well_formed_move() -> None:
    assert parse_site_move(b'{"site": "a", "position": [1, 2.5, -3]}', {"a"}) == (
        "a",
        (1.0, 2.5, -3.0),
    )


@pytest.mark.parametrize(
    "body",
    [
        b"", b"\xff\xfe", b"[]", b'"a"', b"{}", b'{"site": "a"}', b'{"site": "b", "position": [0, 0, 0]}',
        b'{"site": "a", "position": [0, 0]}', b'{"site": "a", "position": [0, 0, "1"]}',
        b'{"site": "a", "position": [0, 0, true]}', b'{"site": "a", "position": [0, 0, NaN]}',
        b'{"site": "a", "position": [0, 0, 1e400]}', b'{"site": "a", "position": [0, 0, 5000]}',
        b'{"site": "a", "position": [0, 0, 0], "x": 1}',
    ],
)  # fmt: skip
def test_parse_site_move_refuses_malformed_messages(body: bytes) -> None:
    with pytest.raises(BadRequest):
        parse_site_move(body, {"a"})


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300) | st.text(max_size=200).map(str.encode))
def test_parse_site_move_never_fails_otherwise(body: bytes) -> None:
    """Any bytes: a move or BadRequest, nothing else (the server must not crash on garbage)."""
    try:
        name, position = parse_site_move(body, {"a"})
    except BadRequest:
        return
    assert name == "a" and len(position) == 3


def _contact_error(doc: dict[str, Any], site: str, position: tuple[float, ...]) -> float:
    """Distance from the right hand to ``position`` at the end of the TO onto ``site``, by the
    numpy forward kinematics of docs/ir.md, on the streamed JSON."""
    ir = doc["ir"]
    goal = next(g for g in ir["goals"] if g["site"] == site and g["phase"] == "TO")
    assert np.allclose(goal["position"], position, atol=1e-6)
    frames = ir["frames"]
    i = int(np.searchsorted(frames["time"], goal["t_end"] - 1e-9))
    return _fk_hand_error(ir, i, goal)


def _fk_hand_error(ir: dict[str, Any], i: int, goal: dict[str, Any]) -> float:
    def axis_angle(axis: list[float], angle: float) -> np.ndarray:
        x, y, z = axis
        k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
        return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k

    w, x, y, z = ir["frames"]["root_rotation"][i]
    R0 = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip
    angle = dict(zip(ir["frames"]["dof_names"], ir["frames"]["q"][i], strict=True))
    world: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for joint in ir["manikin"]["joints"]:
        if joint["parent"] is None:
            R, p = R0, np.array(ir["frames"]["root_position"][i]) + R0 @ np.array(joint["offset"])
        else:
            Rp, pp = world[joint["parent"]]
            R, p = Rp, pp + Rp @ np.array(joint["offset"])
        for dof in joint["dofs"]:
            R = R @ axis_angle(dof["axis"], angle[dof["name"]])
        world[joint["name"]] = (R, p)
    spec = next(e for e in ir["manikin"]["effectors"] if e["name"] == goal["effector"])
    R, p = world[spec["joint"]]
    return float(np.linalg.norm(p + R @ np.array(spec["offset"]) - np.array(goal["position"])))


def test_stream_move_a_site_and_get_the_recompiled_motion(
    served: tuple[PreviewServer, Path],
) -> None:
    server, _ = served
    host, port = server.httpd.server_address[:2]
    assert host == "127.0.0.1"
    events = Events(host, port)
    try:
        kind, first = events.next()
        assert kind == "motion" and first["format"] == "mtlc-preview"
        old = next(s for s in first["ir"]["scene"]["sites"] if s["name"] == SITE)["position"]
        status, reply = _request(server, "POST", "/site",
                                 json.dumps({"site": SITE, "position": list(MOVE)}).encode(),
                                 {"Content-Type": "application/json"})  # fmt: skip
        assert status == 200 and reply["ok"] is True
        kind, moved = events.next()
        assert kind == "motion"
        new = next(s for s in moved["ir"]["scene"]["sites"] if s["name"] == SITE)["position"]
        assert new == pytest.approx(list(MOVE)) and new != old
        assert _contact_error(moved, SITE, MOVE) < 1e-3
    finally:
        events.close()


def test_garbage_is_refused_and_the_server_still_answers(
    served: tuple[PreviewServer, Path],
) -> None:
    server, _ = served
    assert (
        _request(server, "POST", "/site", b"{not json", {"Content-Type": "application/json"})[0]
        == 400
    )
    nowhere = b'{"site": "nowhere", "position": [0, 0, 0]}'
    assert _request(server, "POST", "/site", nowhere, JSON)[0] == 400
    assert _request(server, "POST", "/site", b"x" * (MAX_BODY + 1), JSON)[0] == 413
    assert _request(server, "POST", "/nothing-here", b"{}", JSON)[0] == 404
    host, port = server.httpd.server_address[:2]
    with socket.create_connection((host, port), timeout=10) as raw:  # not even HTTP
        raw.sendall(b"\x00\x01garbage\r\n\r\n")
        raw.recv(1024)
    status, motion = _request(server, "GET", "/motion")
    assert status == 200 and motion["format"] == "mtlc-preview"
    status, page = _request(server, "GET", "/")
    assert status == 200 and b"window.MTLC_SERVE = true" in page


def test_saving_recompiles_and_a_broken_save_keeps_the_last_good_motion(
    served: tuple[PreviewServer, Path],
) -> None:
    server, task = served
    events = Events(*server.httpd.server_address[:2])
    try:
        assert events.next()[0] == "motion"
        good = server.hub.last_motion
        text = task.read_text(encoding="utf-8")
        task.write_text(
            text.replace("budget 3 min", "budget 3 min\n    walk_to(("), encoding="utf-8"
        )
        kind, data = events.next()
        assert kind == "diagnostics" and data["diagnostics"]
        assert data["diagnostics"][0]["file"].endswith("remove_access_panel.mtask")
        assert server.hub.last_motion == good
        time.sleep(0.05)  # a distinct modification time on coarse clocks
        moved = re.sub(r"bolt_upper_right at \(\s*20,", "bolt_upper_right at (22,", text)
        assert moved != text
        task.write_text(moved, encoding="utf-8")
        kind, data = events.next()
        assert kind == "motion"
        site = next(s for s in data["ir"]["scene"]["sites"] if s["name"] == "bolt_upper_right")
        assert site["position"] == pytest.approx([0.22, 1.35, 1.12])
    finally:
        events.close()


def test_serve_command_listens_on_loopback_and_serves_the_page() -> None:
    """`python -m mtlc.preview serve FILE --port 0` prints its URL and answers on 127.0.0.1."""
    import subprocess
    import sys
    import urllib.request

    proc = subprocess.Popen(
        [sys.executable, "-m", "mtlc.preview", "serve", "examples/drain_hydraulic_reservoir.mtask",
         "--port", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        line = proc.stdout.readline() if proc.stdout else ""
        match = re.search(r"at (http://127\.0\.0\.1:\d+/)", line)
        assert match, (line, proc.stderr.read() if proc.poll() is not None and proc.stderr else "")
        with urllib.request.urlopen(match.group(1) + "motion", timeout=30) as reply:
            doc = json.loads(reply.read())
        assert doc["ir"]["source"]["task"] == "drain_reservoir"
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_a_new_watched_file_is_no_change_and_its_edit_is(tmp_path: Path) -> None:
    """The watch list grows when a compile names a model: that alone does not recompile; a
    later edit of the model does."""
    from mtlc.preview.server import FileWatcher

    task, model = tmp_path / "t.mtask", tmp_path / "m.glb"
    task.write_text("x", encoding="utf-8")
    model.write_bytes(b"one")
    files = [task]
    calls: list[int] = []
    watcher = FileWatcher(lambda: list(files), lambda: calls.append(1), 0.01)
    before = watcher._stamp()
    files.append(model)  # a compile named the model
    assert not watcher._changed(before, watcher._stamp())
    seen = watcher._stamp()
    time.sleep(0.05)
    model.write_bytes(b"two, longer")
    assert watcher._changed(seen, watcher._stamp())


def test_the_hub_watches_the_models_its_scenes_name(tmp_path: Path) -> None:
    from mtlc.frontend import FrontendOptions
    from mtlc.passes import MotionOptions
    from mtlc.preview.server import MotionHub

    (tmp_path / "models").mkdir()
    glb = tmp_path / "models" / "panel.glb"
    source = Path(__file__).resolve().parents[2] / "examples" / "models" / "access_panel.glb"
    glb.write_bytes(source.read_bytes())
    task = tmp_path / "t.mtask"
    task.write_text(
        "use stdlib.actions\n\nscene s {\n    ground 0 cm\n"
        '    model panel "models/panel.glb" at (0, 120, 60) cm\n'
        "    site front at (0, 0, 10) cm\n}\n\n"
        'task t "t" {\n    scene s\n    walk_to(front)\n}\n',
        encoding="utf-8",
    )
    hub = MotionHub([task], FrontendOptions(), MotionOptions())
    assert hub.recompile()
    assert hub.watched() == [task, glb]
