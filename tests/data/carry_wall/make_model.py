"""Generate carry_wall.glb, the model of tests/geometry/test_carried_part.py (made once and
checked in: ``python tests/data/carry_wall/make_model.py``).

A 30 x 40 cm panel, 1 cm thick, standing on edge in front of the manikin to its right, with a
marker node ``panel_handle`` 1 cm over the middle of its top edge (its +Y axis, the site's
normal, up), and a partition 1.00 m high between it and the place it is carried
to: the hand carrying the panel by its handle passes over the partition, the panel hanging
from it does not.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent


def carry_wall() -> trimesh.Scene:
    scene = trimesh.Scene()
    for name, size, at in (
        ("panel", (0.30, 0.40, 0.01), (-0.35, 0.85, 0.45)),
        ("partition", (0.02, 1.00, 0.40), (0.0, 0.50, 0.45)),
    ):
        mesh = trimesh.creation.box(size)
        mesh.apply_translation(at)
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    handle = np.eye(4)  # +Y up: the hand comes down onto the top edge
    handle[:3, 3] = (-0.35, 1.06, 0.45)
    scene.graph.update(frame_to="panel_handle", frame_from=scene.graph.base_frame, matrix=handle)
    return scene


if __name__ == "__main__":
    path = HERE / "carry_wall.glb"
    path.write_bytes(carry_wall().export(file_type="glb"))
    print(f"wrote {path.name} ({path.stat().st_size} bytes)")
