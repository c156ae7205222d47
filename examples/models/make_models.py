"""Generate the example models (small .glb files) from trimesh primitives.

    python examples/models/make_models.py

- access_panel.glb: access panel P-12, 60 x 45 cm, 3 mm thick, with a 12 cm lightening hole
  and four M6 bolt heads; marker nodes bolt_upper_left ... bolt_lower_right and panel_handle,
  each with its +Y axis (the site's normal, docs/language.md) out of the panel's front, which
  faces -Z. Its origin is the panel's centre on its front face.
- fuel_filter_bay.glb: the cramped bay around the fuel filter (floor, back wall, side walls and
  a shelf over the filter), the filter's bowl as a cylinder; marker nodes filter_bowl (normal
  down: the hand comes from below) and bay_front. Origin on the floor.

The files are checked in; the script is here to regenerate or change them.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "src"))
from mtlc.geometry import solids  # the language's own plate with an opening

HERE = Path(__file__).resolve().parent


def _node(scene: trimesh.Scene, name: str, position: tuple[float, ...], normal: str) -> None:
    """A marker node at ``position`` whose +Y axis points along ``normal`` (-z, +y or -y)."""
    m = np.eye(4)
    angle = {"-z": -math.pi / 2, "+y": 0.0, "-y": math.pi}[normal]
    m[:3, :3] = trimesh.transformations.rotation_matrix(angle, [1, 0, 0])[:3, :3]
    m[:3, 3] = position
    scene.graph.update(frame_to=name, frame_from=scene.graph.base_frame, matrix=m)


def _add(scene: trimesh.Scene, name: str, mesh: trimesh.Trimesh, at: tuple[float, ...]) -> None:
    mesh = mesh.copy()
    mesh.apply_translation(at)
    scene.add_geometry(mesh, node_name=name, geom_name=name)


def access_panel(hole: float = 0.12) -> trimesh.Scene:
    """The panel; ``hole`` (m) the lightening hole's diameter (tests shrink it)."""
    scene = trimesh.Scene()
    vertices, faces = solids.plate((0.60, 0.45, 0.003), ("round", hole))
    _add(scene, "panel", trimesh.Trimesh(vertices, faces, process=False), (0, 0, 0.0015))
    bolts = {
        "bolt_upper_left": (-0.20, 0.15),
        "bolt_upper_right": (0.20, 0.15),
        "bolt_lower_left": (-0.20, -0.15),
        "bolt_lower_right": (0.20, -0.15),
    }
    for i, (name, (x, y)) in enumerate(bolts.items(), start=1):
        head = trimesh.creation.cylinder(radius=0.005, height=0.004, sections=16)
        _add(scene, f"bolt_head_{i}", head, (x, y, -0.002))
        _node(scene, name, (x, y, -0.004), "-z")
    _node(scene, "panel_handle", (0.0, 0.0, -0.02), "-z")
    return scene


def fuel_filter_bay() -> trimesh.Scene:
    scene = trimesh.Scene()
    box = trimesh.creation.box
    _add(scene, "floor_plate", box((0.70, 0.02, 0.50)), (0, 0.01, 1.05))
    _add(scene, "back_wall", box((0.70, 0.60, 0.02)), (0, 0.30, 1.29))
    _add(scene, "left_wall", box((0.02, 0.60, 0.50)), (-0.34, 0.30, 1.05))
    _add(scene, "right_wall", box((0.02, 0.60, 0.50)), (0.34, 0.30, 1.05))
    _add(scene, "shelf", box((0.70, 0.02, 0.30)), (0, 0.45, 1.15))
    bowl = trimesh.creation.cylinder(0.05, 0.15, sections=32)
    bowl.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    _add(scene, "filter_bowl_body", bowl, (0.10, 0.33, 0.95))
    _node(scene, "filter_bowl", (0.10, 0.25, 0.95), "-y")
    _node(scene, "bay_front", (0.0, 0.0, 0.55), "+y")
    return scene


def main() -> None:
    for name, build in (("access_panel", access_panel), ("fuel_filter_bay", fuel_filter_bay)):
        path = HERE / f"{name}.glb"
        path.write_bytes(build().export(file_type="glb"))
        print(f"wrote {path.name} ({path.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
