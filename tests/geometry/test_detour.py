"""A reach bent around the equipment (issue 20, the detour pass): a hand reaching past a plate's
edge to a bolt behind it goes around the plate, not through it. Checked on the compiled IR
JSON with our own kinematics (bench/motion.py) and trimesh's proximity and ray queries, not
mtlc's capsules or its collision library."""

from __future__ import annotations

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

import mtlc.passes as passes  # noqa: E402
from geometry.test_equipment import AXIS_POINTS, compile_ir, limbs, scene_meshes  # noqa: E402

DEPTH = 0.001  # m: no capsule deeper than this into the plate (issue 20's done-when)

PLATE = """use stdlib.actions

scene stand {
    ground 0 cm
    model kit "plate.glb"
    sites from kit
    site front at (0, 0, 0) cm
}

task reach_past_plate {
    manikin gb10000_1988 female p5
    scene stand
    walk_to(front)
    press(right, bolt)
}
"""


def plate_model(path: Path) -> None:
    """A 40 x 30 cm plate, 1 cm thick, standing across the body's way 36 cm in front, its top
    edge at 0.93 m; the bolt (a marker, normal towards the body) 22 cm behind it and 17 cm
    above its edge: the straight way to it goes through the plate (69 mm female P5, 90 mm
    male P95 before the detour pass), the way over its edge does not."""
    scene = trimesh.Scene()
    plate = trimesh.creation.box((0.40, 0.30, 0.01))
    plate.apply_translation((-0.10, 0.78, 0.36))
    scene.add_geometry(plate, node_name="plate", geom_name="plate")
    marker = np.eye(4)
    marker[:3, :3] = trimesh.geometry.align_vectors([0, 1, 0], [0, 0, -1])[:3, :3]
    marker[:3, 3] = (-0.10, 1.10, 0.58)
    scene.graph.update(frame_to="bolt", frame_from=scene.graph.base_frame, matrix=marker)
    path.write_bytes(scene.export(file_type="glb"))


def deepest(doc: dict, mesh: trimesh.Trimesh, since: float = 0.0) -> tuple[float, str]:
    """The deepest any limb capsule (hands, forearms, shanks, feet, held tools) goes into
    ``mesh`` on any frame (m; a capsule whose axis crosses the surface counts as its radius
    and its nearer end's distance beyond), and which; only the frames from ``since`` (s)."""
    body = motion.Body.of(doc)
    s = np.linspace(0.0, 1.0, AXIS_POINTS)
    worst, who = -np.inf, ""
    for part, (a, b, radius, _) in limbs(body).items():
        pts = (a[:, None, :] + s[None, :, None] * (b - a)[:, None, :]).reshape(-1, 3)
        _, dist, _ = trimesh.proximity.closest_point(mesh, pts)
        depth = radius - dist.reshape(len(a), AXIS_POINTS).min(axis=1)
        length = np.linalg.norm(b - a, axis=-1)
        hits, rays, _ = mesh.ray.intersects_location(a, (b - a) / length[:, None])
        for loc, ray in zip(hits, rays, strict=True):
            if np.linalg.norm(loc - a[ray]) <= length[ray]:  # the axis crosses the surface
                _, gap, _ = trimesh.proximity.closest_point(mesh, np.stack([a[ray], b[ray]]))
                depth[ray] = max(depth[ray], radius + float(gap.min()))
        depth[body.time < since - 1e-9] = -np.inf
        k = int(np.argmax(depth))
        if depth[k] > worst:
            worst, who = float(depth[k]), f"{part} at {body.time[k]:.2f} s"
    return worst, who


@pytest.mark.parametrize(
    "manikin",
    [
        "gb10000_1988:female:5",
        pytest.param(
            "gb10000_1988:male:95",
            marks=pytest.mark.xfail(
                strict=True,
                reason="the detour's smoothness gate (detour.LDLJ_FLOOR) stops the bow over the "
                "edge short: 87 -> 7.3 mm through the plate (docs/passes.md, detour)",
            ),
        ),
    ],
)
def test_a_reach_goes_over_a_plate_edge_not_through_it(manikin: str, tmp_path: Path) -> None:
    plate_model(tmp_path / "plate.glb")
    path = tmp_path / "plate.mtask"
    path.write_text(PLATE, encoding="utf-8")
    doc, diagnostics = compile_ir(path, manikin, tmp_path / "out")
    assert [d["message"] for d in diagnostics if d["code"] == "MT0515"] == []
    # from the reach's start: male P95's arm swing in the walk before it brushes the plate
    # (3.4 mm at 0.30 s; no pass keeps a walk's arms out of the models), not this test's
    reach = min(s["t_start"] for s in doc["segments"] if s["track"] == "r_arm")
    depth, who = deepest(doc, scene_meshes(doc, tmp_path)["kit"], since=reach)
    assert depth <= DEPTH, f"{depth * 1000:.1f} mm: {who}"
    # the hand got to the bolt: the detour is a way there, not a reach given up
    press = [s for s in doc["segments"] if s["track"] == "r_arm" and s["kind"] == "TO"]
    assert press and press[-1]["result"]["distance"] <= 1e-3


def test_without_the_detour_the_hand_goes_through_the_plate(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same reach with the detour pass left out: the straight way is through the plate
    (what the test above would catch)."""
    plate_model(tmp_path / "plate.glb")
    path = tmp_path / "plate.mtask"
    path.write_text(PLATE, encoding="utf-8")
    without = [(name, step) for name, step in passes.MOTION_PASSES if name != "detour"]
    monkeypatch.setattr(passes, "MOTION_PASSES", without)
    doc, diagnostics = compile_ir(path, "gb10000_1988:female:5", tmp_path / "out")
    assert any(
        d["code"] == "MT0515" and "`kit`" in d["message"] and "press > reach" in d["message"]
        for d in diagnostics
    )
    depth, _ = deepest(doc, scene_meshes(doc, tmp_path)["kit"])
    assert depth > 0.02
