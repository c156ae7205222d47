"""The body out of the equipment, checked on the compiled IR JSON with our own kinematics and
trimesh's proximity and ray queries (issue 20): neither mtlc's capsules nor its collision
library. Each limb is a capsule built here from the IR's joint and site positions
(bench/motion.py's forward kinematics) with docs/collision.md's radii from the manikin's
GB 10000-88 row; wherever one goes deeper than verify's tolerance into a model, the compile
must have printed MT0515 naming that part at a task line live then (MT0515's rule)."""

from __future__ import annotations

import contextlib
import io
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("coal")

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "tests"))

import motion  # noqa: E402  (bench/motion.py: forward kinematics from the IR JSON alone)
from conftest import shared  # noqa: E402

from mtlc.cli import main as mtlc_main  # noqa: E402

TOLERANCE = 0.005  # m: MT0515's (docs/diagnostics/MT0515.md)
SLACK = 0.002  # m: the capsule's ends here are the documented ones, rebuilt on their own
AXIS_POINTS = 11

SHELF = """use stdlib.actions

scene cupboard {
    ground 0 cm
    box crate size (60, 30, 30) cm at (0, 15, 85) cm
    box shelf size (60, 2, 30) cm at (0, 100, 95) cm
    site front at (0, 0, 60) cm
    site latch at (0, 88, 90) cm normal (0, -1, 0)
}

task reach_under_shelf {
    manikin gb10000_1988 female p5
    scene cupboard
    walk_to(front)
    press(right, latch)
}
"""
BAR = "    box bar size (60, 4, 4) cm at (0, 95, 72) cm\n"


def compile_ir(path: Path, manikin: str, out: Path) -> tuple[dict, list[dict]]:
    """The IR JSON and the diagnostics ``mtlc compile --target ir`` prints; an example's
    compile for a manikin is made once for the whole run (``conftest.shared``: this module and
    test_penetration ask for the same ones)."""
    if path.parent == ROOT / "examples":
        return shared(f"cli ir {path.name} {manikin}", path.parent,
                      lambda: _compile_ir(path, manikin, out))  # fmt: skip
    return _compile_ir(path, manikin, out)


def _compile_ir(path: Path, manikin: str, out: Path) -> tuple[dict, list[dict]]:
    buf = io.StringIO()
    argv = ["compile", str(path), "--manikin", manikin, "--target", "ir", "-o", str(out),
            "--format", "json"]  # fmt: skip
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        assert mtlc_main(argv) == 0
    (ir_file,) = out.glob("*.ir.json")
    printed = json.loads(buf.getvalue())
    diagnostics = printed["diagnostics"] if isinstance(printed, dict) else printed
    return json.loads(ir_file.read_text(encoding="utf-8")), diagnostics


def scene_meshes(doc: dict, folder: Path) -> dict[str, trimesh.Trimesh]:
    """The IR's models rebuilt with trimesh: a file read and placed by its transform, a box
    made from its size. A part a hand holds (``verification.equipment.held``) is a mesh of its
    own, ``model/node``, and its model the rest of the file."""
    held = {
        (h["model"], h["node"]) for h in doc["verification"].get("equipment", {}).get("held", [])
    }
    out = {}
    for m in doc["scene"]["models"]:
        place = np.asarray(m["transform"], float)
        if m["kind"] == "model":
            taken = {node for model, node in held if model == m["name"]}
            scene = trimesh.load(folder / m["path"])
            pieces: dict[str, list[trimesh.Trimesh]] = {}
            for node in scene.graph.nodes_geometry:
                matrix, geometry = scene.graph[node]
                mesh = scene.geometry[geometry].copy()
                mesh.apply_transform(matrix)
                key = f"{m['name']}/{node}" if node in taken else m["name"]
                pieces.setdefault(key, []).append(mesh)
            for key, meshes in pieces.items():
                mesh = trimesh.util.concatenate(meshes)
                mesh.apply_transform(place)
                out[key] = mesh
            continue
        if m["kind"] == "box":
            mesh = trimesh.creation.box(extents=m["size"])
        else:
            pytest.skip(f"no trimesh twin for a {m['kind']} here")
        mesh.apply_transform(place)
        out[m["name"]] = mesh
    return out


def placements(doc: dict, body: motion.Body) -> dict[str, tuple[np.ndarray, list]]:
    """Each held part's placement per frame, by docs/collision.md's rule ("Held parts") from
    the IR's record of who holds it when, with bench/motion.py's joint frames: with the first
    hand on it, it slides with the grip point until that is 5 cm from where it closed, then
    turns with the hand (its joint's rotation at its grip point); it stays where it is let go.
    With its holds."""
    hands = {e["name"]: e for e in doc["manikin"]["effectors"]}
    frame = {}
    for side in ("r", "l"):
        R, _ = body.world[hands[f"{side}_hand"]["joint"]]
        m = np.zeros((len(body.time), 4, 4))
        m[:, :3, :3], m[:, :3, 3], m[:, 3, 3] = R, body.points[f"{side}_hand"], 1.0
        frame[side] = m
    out = {}
    for rec in doc["verification"].get("equipment", {}).get("held", []):
        holds = sorted(rec["holds"], key=lambda h: (h[1], h[0] == "l"))
        place = np.tile(np.eye(4), (len(body.time), 1, 1))
        carrier, anchor, closed_at, mounted = None, None, None, None
        for i, t in enumerate(body.time):
            if i:
                place[i] = place[i - 1]
            live = [h for h in holds if h[1] - 1e-6 <= t <= h[2] + 1e-6]
            now = live[0] if live else None
            if now != carrier:
                carrier, anchor = now, None
                if now is not None:
                    closed_at, mounted = frame[now[0]][i, :3, 3].copy(), place[i].copy()
            if carrier is None:
                continue
            f = frame[carrier[0]][i]
            if anchor is None:
                place[i] = mounted
                place[i, :3, 3] += f[:3, 3] - closed_at
                if np.linalg.norm(f[:3, 3] - closed_at) > 0.05:
                    anchor = np.linalg.inv(f) @ place[i]
            else:
                place[i] = f @ anchor
        out[f"{rec['model']}/{rec['node']}"] = (place, holds)
    return out


def limbs(body: motion.Body) -> dict[str, tuple[np.ndarray, np.ndarray, float, bool]]:
    """Name -> (start (T, 3), end (T, 3), radius, is_hand_or_tool), docs/collision.md's sizes."""
    P, m = body.points, body.doc["manikin"]
    row = motion.gb10000()

    def mm(name: str) -> float:
        return row[(m["sex"], int(m["percentile"]), name)] / 1000.0

    hand_r, foot_r = 0.25 * mm("hand_breadth"), 0.3 * mm("foot_breadth")
    out = {}
    for side, word in (("r", "right"), ("l", "left")):
        wrist, tip = P[f"{side}_wrist"], P[f"{side}_fingertip"]
        along = (tip - wrist) / np.linalg.norm(tip - wrist, axis=-1, keepdims=True)
        out[f"{word} hand"] = (wrist, tip - hand_r * along, hand_r, True)
        out[f"{word} forearm"] = (P[f"{side}_elbow"], wrist, 0.36 * mm("hand_breadth"), False)
        out[f"{word} shank"] = (P[f"{side}_knee"], P[f"{side}_ankle"], 0.5 * mm("foot_breadth"),
                                False)  # fmt: skip
        heel, toe = P[f"{side}_heel"], P[f"{side}_toe"]
        fwd = (toe - heel) / np.linalg.norm(toe - heel, axis=-1, keepdims=True)
        up = np.array([0.0, foot_r, 0.0])
        out[f"{word} foot"] = (heel + up + foot_r * fwd, toe + up - foot_r * fwd, foot_r, False)
    for name, (tool, _, _) in body.tools.items():
        out[f"tool {tool['name']}"] = (P[f"{name[0]}_hand"], P[name], 0.01, True)
    return out


def unreported(doc: dict, diagnostics: list[dict], meshes: dict) -> list[str]:
    """Every (part, model, run of frames) deeper than the tolerance with no MT0515 naming the
    part at a line live in the run; the hands and tools count only where their axis passes
    through the model (a hand at its site may touch what it works on: MT0515's rule). A held
    part is measured where it is on each frame (``placements``), and a hand holding it is not
    measured against it from its reach's start to its arm's next goal after the release."""
    body = motion.Body.of(doc)
    named = [(d["span"]["line"], d["message"]) for d in diagnostics if d["code"] == "MT0515"]
    held = {f"tool {t['name']}": (a, b) for t, a, b in body.tools.values()}
    moved = placements(doc, body)
    s = np.linspace(0.0, 1.0, AXIS_POINTS)
    missing = []
    for part, (a0, b0, radius, touching_allowed) in limbs(body).items():
        for model, mesh in meshes.items():
            a, b = a0, b0
            if model in moved:  # the capsule in the part's own frame: its placement undone
                place = moved[model][0]
                a = np.einsum("nji,nj->ni", place[:, :3, :3], a0 - place[:, :3, 3])
                b = np.einsum("nji,nj->ni", place[:, :3, :3], b0 - place[:, :3, 3])
            # frames whose capsule's box meets the mesh's box: the others are clear
            lo, hi = np.minimum(a, b) - radius, np.maximum(a, b) + radius
            near = np.all((lo <= mesh.bounds[1]) & (hi >= mesh.bounds[0]), axis=1)
            depth = np.full(len(a), -np.inf)
            if near.any():
                pts = a[near, None, :] + s[None, :, None] * (b - a)[near, None, :]
                _, dist, _ = trimesh.proximity.closest_point(mesh, pts.reshape(-1, 3))
                depth[near] = radius - dist.reshape(-1, AXIS_POINTS).min(axis=1)
            length = np.linalg.norm(b - a, axis=-1)
            hits = mesh.ray.intersects_location(a, (b - a) / length[:, None], multiple_hits=False)
            through = np.zeros(len(a), bool)
            for loc, ray in zip(hits[0], hits[1], strict=True):
                through[ray] |= np.linalg.norm(loc - a[ray]) <= length[ray]
            through &= near
            if touching_allowed:  # through the surface, its nearer end out beyond it
                bad = through.copy()
                if through.any():
                    ends = np.concatenate([a[through], b[through]])
                    _, gap, _ = trimesh.proximity.closest_point(mesh, ends)
                    k = int(through.sum())
                    bad[through] = np.minimum(gap[:k], gap[k:]) > TOLERANCE + SLACK
            else:
                bad = (depth > TOLERANCE + SLACK) | through
            if part in held:
                start, end = held[part]
                bad &= (body.time >= start) & (body.time <= end)
            if model in moved and part.endswith(" hand"):
                for side, start, end in moved[model][1]:
                    if part.startswith({"r": "right", "l": "left"}[side]):
                        bad &= ~holding_window(doc, body, side, start, end)
            for first, last in runs(bad):
                lines = set().union(
                    *(motion.report_lines(doc, t) for t in body.time[first : last + 1])
                )
                said = any(line in lines and f"the {part.removeprefix('tool ')} " in msg
                           for line, msg in named)  # fmt: skip
                if not said:
                    missing.append(
                        f"{part} in {model} {body.time[first]:.2f}-{body.time[last]:.2f} s"
                    )
    return missing


def holding_window(doc: dict, body: motion.Body, side: str, start: float, end: float) -> np.ndarray:
    """(T,) from the start of the arm's last reach (TA) before the grasp to the start of its
    next goal after the release (the end of the motion when none follows)."""
    arm = [s for s in doc["segments"] if s["track"] == f"{side}_arm" and s["kind"] in ("TA", "TO")]
    came = max((s["t_start"] for s in arm if s["kind"] == "TA" and s["t_start"] <= start),
               default=start)  # fmt: skip
    until = min((s["t_start"] for s in arm if s["t_start"] >= end - 1e-6), default=np.inf)
    return (body.time >= came - 1e-6) & (body.time < until - 1e-6)


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    idx = np.flatnonzero(mask)
    if not idx.size:
        return []
    cuts = np.flatnonzero(np.diff(idx) > 1)
    return list(zip(np.r_[idx[0], idx[cuts + 1]], np.r_[idx[cuts], idx[-1]], strict=True))


@pytest.mark.parametrize("manikin", ["gb10000_1988:female:5", "gb10000_1988:male:95"])
def test_access_panel_cad_collisions_are_reported(manikin: str, tmp_path: Path) -> None:
    example = ROOT / "examples" / "remove_access_panel_cad.mtask"
    doc, diagnostics = compile_ir(example, manikin, tmp_path)
    meshes = scene_meshes(doc, example.parent)
    assert unreported(doc, diagnostics, meshes) == []
    # the stance at the bench is moved out of it: no foot or shank in the bench any more
    assert not [d for d in diagnostics if d["code"] == "MT0515" and "bench" in d["message"]
                and ("foot" in d["message"] or "shank" in d["message"])]  # fmt: skip


def test_a_reach_under_a_shelf_from_behind_a_crate(tmp_path: Path) -> None:
    path = tmp_path / "shelf.mtask"
    path.write_text(SHELF, encoding="utf-8")
    doc, diagnostics = compile_ir(path, "gb10000_1988:female:5", tmp_path / "out")
    meshes = scene_meshes(doc, tmp_path)
    assert unreported(doc, diagnostics, meshes) == []
    assert [d for d in diagnostics if d["code"] == "MT0515"] == []
    walk = next(s for s in doc["segments"] if s["kind"] == "locomotion")
    moved = walk["result"]["stance_moved"]  # the toes at the site were in the crate
    assert moved[2] <= -0.05 and moved[0] == 0.0
    body = motion.Body.of(doc)
    legs = limbs(body)
    crate = meshes["crate"]
    for part in ("right foot", "left foot", "right shank", "left shank"):
        a, b, radius, _ = legs[part]
        s = np.linspace(0.0, 1.0, AXIS_POINTS)
        pts = (a[:, None, :] + s[None, :, None] * (b - a)[:, None, :]).reshape(-1, 3)
        _, dist, _ = trimesh.proximity.closest_point(crate, pts)
        assert dist.min() - radius > -TOLERANCE, part


def test_a_limb_through_a_model_is_reported_at_its_line(tmp_path: Path) -> None:
    """A bar across the arm's way to the latch: the forearm goes through it, and the finding is
    at the press's line, worded as a site not reachable without collision."""
    text = SHELF.replace("    site front", BAR + "    site front")
    path = tmp_path / "shelf.mtask"
    path.write_text(text, encoding="utf-8")
    doc, diagnostics = compile_ir(path, "gb10000_1988:female:5", tmp_path / "out")
    press = 1 + text.splitlines().index("    press(right, latch)")
    found = [d for d in diagnostics if d["code"] == "MT0515"]
    assert any("right forearm" in d["message"] and "`bar`" in d["message"] for d in found)
    assert all(d["span"]["line"] == press for d in found), found
    assert all("site `latch` is not reachable without collision" in d["message"] for d in found)
    assert unreported(doc, diagnostics, scene_meshes(doc, tmp_path)) == []


def test_every_finding_names_a_depth_past_the_tolerance(tmp_path: Path) -> None:
    """The fuel filter's bay, kneeling (female P5): runs of frames a few frames apart merge,
    and a piece of one cut off at a segment's start may hold only excused frames; it printed
    "goes -inf mm into model `bay`" before it was skipped."""
    example = ROOT / "examples" / "replace_fuel_filter_cad.mtask"
    _, diagnostics = compile_ir(example, "gb10000_1988:female:5", tmp_path)
    found = [d["message"] for d in diagnostics if d["code"] == "MT0515"]
    assert found
    for message in found:
        match = re.search(r"goes (\S+) mm into", message)
        assert match is not None, message
        assert float(match.group(1)) >= TOLERANCE * 1000, message


KIT = """use stdlib.actions

scene bench {
    ground 0 cm
    model kit "kit.glb"
    sites from kit
    site front at (0, 0, 10) cm
    site away at (60, 0, -40) cm
    site drop at (60, 90, 0) cm normal (0, 1, 0)
}

task lift_out {
    manikin gb10000_1988 female p5
    scene bench
    walk_to(front)
    press(right, bolt)
    pick(right, part)
    walk_to(away)
    place(right, drop)
}
"""


def kit_model(path: Path) -> None:
    """An open bin on a stand with a 8 cm block in it (node `part_body`, grasped at the marker
    `part` on its top), and a plate standing on edge to the right with a bolt on its face
    towards the body's side (marker `bolt`, normal +x): a reach from the side, a part lifted
    out of a box and carried."""

    def marker(scene: trimesh.Scene, name: str, at: tuple, normal: tuple) -> None:
        m = np.eye(4)
        m[:3, :3] = trimesh.geometry.align_vectors([0, 1, 0], normal)[:3, :3]
        m[:3, 3] = at
        scene.graph.update(frame_to=name, frame_from=scene.graph.base_frame, matrix=m)

    def add(scene: trimesh.Scene, name: str, mesh: trimesh.Trimesh, at: tuple) -> None:
        mesh = mesh.copy()
        mesh.apply_translation(at)
        scene.add_geometry(mesh, node_name=name, geom_name=name)

    box, s = trimesh.creation.box, trimesh.Scene()
    add(s, "bin_floor", box((0.32, 0.02, 0.32)), (0.0, 0.79, 0.45))
    add(s, "bin_left", box((0.01, 0.25, 0.32)), (0.155, 0.925, 0.45))
    add(s, "bin_right", box((0.01, 0.25, 0.32)), (-0.155, 0.925, 0.45))
    add(s, "bin_back", box((0.32, 0.25, 0.01)), (0.0, 0.925, 0.605))
    add(s, "bin_front", box((0.32, 0.25, 0.01)), (0.0, 0.925, 0.295))
    add(s, "part_body", box((0.08, 0.08, 0.08)), (0.0, 0.84, 0.45))
    marker(s, "part", (0.0, 0.88, 0.45), (0, 1, 0))
    add(s, "side_plate", box((0.004, 0.40, 0.40)), (-0.45, 1.10, 0.40))
    head = trimesh.creation.cylinder(0.006, 0.005, sections=16)
    head.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1]))
    add(s, "bolt_head", head, (-0.4455, 1.10, 0.40))
    marker(s, "bolt", (-0.443, 1.10, 0.40), (1, 0, 0))
    path.write_bytes(s.export(file_type="glb"))


def test_a_part_lifted_out_of_a_bin_goes_with_the_hand(tmp_path: Path) -> None:
    """The block picked out of the bin is carried with the hand to the drop site (the IR says
    who holds it when); measured where it is, with trimesh, every limb deeper than the
    tolerance into the bin, the plate or the carried block has MT0515 at a line live then;
    the hand carrying it is not reported in it on the walk."""
    kit_model(tmp_path / "kit.glb")
    path = tmp_path / "kit.mtask"
    path.write_text(KIT, encoding="utf-8")
    doc, diagnostics = compile_ir(path, "gb10000_1988:female:5", tmp_path / "out")
    (held,) = doc["verification"]["equipment"]["held"]
    assert (held["model"], held["node"], held["at"]) == ("kit", "part_body", "part")
    (hold,) = held["holds"]
    lines = KIT.splitlines()
    walk = 1 + lines.index("    walk_to(away)")
    assert hold[0] == "r"
    meshes = scene_meshes(doc, tmp_path)
    assert set(meshes) == {"kit", "kit/part_body"}
    assert unreported(doc, diagnostics, meshes) == []
    # at the end the block's grasp point is at the drop site, where the hand let it go
    body = motion.Body.of(doc)
    place = placements(doc, body)["kit/part_body"][0][-1]
    grasped = place[:3, :3] @ np.array([0.0, 0.88, 0.45]) + place[:3, 3]
    assert np.linalg.norm(grasped - np.array([0.60, 0.90, 0.0])) < 0.01
    carried = [d for d in diagnostics if d["code"] == "MT0515" and d["span"]["line"] == walk]
    assert not [d for d in carried if "right hand" in d["message"] and "part_body" in d["message"]]
