"""Check that Blender imports our BVH files as we wrote them; run by scripts/check_blender.sh.

Two halves in one file, so the expectations and the check cannot drift apart:

* with our Python (mtlc importable): ``python scripts/blender_check_bvh.py expect FILE.mtask OUT
  [--emit]`` compiles every task of FILE, computes with our forward kinematics what Blender
  must show, and writes ``OUT/<stem>.<task>.expected.json`` (and, with ``--emit``, the BVH
  itself, for when the CLI has no ``--target bvh``);
* inside Blender: ``blender --background --factory-startup --python-exit-code 1 --python
  scripts/blender_check_bvh.py -- FILE.bvh FILE.expected.json`` imports the BVH with
  ``bpy.ops.import_anim.bvh`` (scale 0.01: the file is in centimetres; axes forward −Z, up Y:
  our Y-up world to Blender's Z-up one) and checks the frame count, every joint at a contact
  frame and the hand (the wrist bone's tail, the BVH End Site at the grip point) there.

Exit status 0 when everything matches within the tolerance, 1 otherwise.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

TOLERANCE_M = 1e-3  # Blender keeps float32 matrices: about 1e-7 m here, far inside a millimetre
BVH_UNITS_PER_METRE = 100.0


# -- our side: expectations ----------------------------------------------------------------
def contact(ir: Any) -> tuple[int, str, str]:
    """(frame, wrist joint, hand site) where the right hand's first TO segment ends.

    The left hand's when the right one never reaches.
    """
    import numpy as np

    reaches = [s for s in ir.segments if s.kind == "TO" and s.goal.effector in ("r_hand", "l_hand")]
    for seg in sorted(reaches, key=lambda s: s.goal.effector != "r_hand"):  # right hand first
        frame = int(np.argmin(np.abs(ir.frames.time - seg.end)))
        side = seg.goal.effector[0]
        return frame, f"{side}_wrist", seg.goal.effector
    raise SystemExit(f"{ir.file}: task {ir.task} has no TO segment of a hand")


def expectations(ir: Any) -> dict[str, Any]:
    """What Blender must show for one task, in our world (metres, Y up)."""
    from mtlc.body.kinematics import forward, site_positions

    f = ir.frames
    frame, wrist, hand = contact(ir)
    pose = forward(ir.skeleton, f.q[frame], f.root_position[frame], f.root_rotation[frame])
    return {
        "task": ir.task,
        "frames": len(f.time),
        "fps": f.fps,
        "contact_frame": frame,
        "hand_bone": wrist,
        "hand_site": hand,
        "hand": [round(float(v), 9) for v in site_positions(ir.skeleton, pose, hand)],
        "joints": {
            name: [round(float(v), 9) for v in pose.p[i]]
            for i, name in enumerate(ir.skeleton.joint_names)
        },
    }


def write_expectations(mtask: Path, out: Path, emit: bool) -> None:
    from mtlc.codegen.bvh import emit_bvh
    from mtlc.frontend import run_frontend
    from mtlc.passes import run_motion

    program = run_frontend([mtask])
    if program.sink.has_errors:
        raise SystemExit(f"{mtask}: does not compile")
    out.mkdir(parents=True, exist_ok=True)
    for timeline in program.timelines:
        ir = run_motion(timeline, program.sink)
        base = out / f"{mtask.stem}.{ir.task}"
        if emit:
            Path(f"{base}.bvh").write_text(emit_bvh(ir), encoding="utf-8")
        text = json.dumps(expectations(ir), indent=1, sort_keys=True) + "\n"
        Path(f"{base}.expected.json").write_text(text, encoding="utf-8")


# -- Blender's side: the check -------------------------------------------------------------
def blender_check(bvh: Path, expected_path: Path) -> list[str]:
    """Import ``bvh`` into an empty scene and list every mismatch with the expectations."""
    import bpy
    from bpy_extras.io_utils import axis_conversion
    from mathutils import Vector

    expected = json.loads(expected_path.read_text(encoding="utf-8"))
    tolerate_removed_open_mode()
    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.object.delete()
    result = bpy.ops.import_anim.bvh(
        filepath=str(bvh),
        target="ARMATURE",
        global_scale=1.0 / BVH_UNITS_PER_METRE,
        axis_forward="-Z",
        axis_up="Y",
        frame_start=1,
        use_fps_scale=False,
        update_scene_fps=True,
        update_scene_duration=True,
        rotate_mode="NATIVE",
    )
    if result != {"FINISHED"}:
        return [f"import_anim.bvh returned {result}"]
    arm = bpy.context.view_layer.objects.active
    problems = check_frame_count(arm, expected["frames"])
    to_blender = axis_conversion(from_forward="-Z", from_up="Y").to_4x4()
    scene = bpy.context.scene
    scene.frame_set(1 + expected["contact_frame"])
    bpy.context.view_layer.update()
    for name, ours in expected["joints"].items():
        got = arm.matrix_world @ arm.pose.bones[name].head
        problems += compare(f"joint {name}", got, to_blender @ Vector(ours))
    hand = arm.matrix_world @ arm.pose.bones[expected["hand_bone"]].tail
    problems += compare(
        f"hand {expected['hand_site']}", hand, to_blender @ Vector(expected["hand"])
    )
    distance = (hand - to_blender @ Vector(expected["hand"])).length
    print(
        f"{bvh.name}: {expected['frames']} frames expected; contact frame {expected['contact_frame']}: "
        f"{expected['hand_site']} at {tuple(round(v, 4) for v in hand)} (Blender, m), "
        f"{distance * 1000:.4f} mm from our FK"
    )
    return problems


def tolerate_removed_open_mode() -> None:
    """Debian's Blender 3.4 importer opens the file in mode 'rU', which Python 3.11 removed.

    The importer module looks ``open`` up in its own globals first: give it one without 'U'.
    """
    import builtins

    from io_anim_bvh import import_bvh

    def open_without_u(file: Any, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        return builtins.open(file, mode.replace("U", ""), *args, **kwargs)

    import_bvh.open = open_without_u


def check_frame_count(arm: Any, frames: int) -> list[str]:
    action = arm.animation_data.action if arm.animation_data else None
    if action is None:
        return ["no action imported"]
    start, end = action.frame_range
    counts = {len(c.keyframe_points) for c in action.fcurves}
    problems = []
    if round(end - start) + 1 != frames:
        problems.append(f"action spans {start}..{end}, expected {frames} frames")
    if counts != {frames}:
        problems.append(f"f-curves hold {sorted(counts)} keyframes, expected {frames}")
    return problems


def compare(what: str, got: Any, want: Any) -> list[str]:
    error = (got - want).length
    if error <= TOLERANCE_M:
        return []
    return [f"{what}: Blender {tuple(got)}, expected {tuple(want)} ({error * 1000:.3f} mm)"]


def main(argv: list[str]) -> int:
    if "--" in argv:  # inside Blender: arguments after "--"
        bvh, expected = argv[argv.index("--") + 1 :][:2]
        problems = blender_check(Path(bvh), Path(expected))
        for p in problems:
            print(f"FAIL {Path(bvh).name}: {p}", file=sys.stderr)
        return 1 if problems else 0
    if len(argv) >= 4 and argv[1] == "expect":
        write_expectations(Path(argv[2]), Path(argv[3]), emit="--emit" in argv[4:])
        return 0
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
