"""Check that Blender imports our BVH files as we meant them; run by scripts/check_blender.sh.

Two halves in one file, so the expectations and the check cannot drift apart:

* with any Python 3 and numpy: ``python scripts/blender_check_bvh.py expect OUT/<stem>.<task>.ir.json``
  reads the IR that ``mtlc compile --target all`` wrote beside the BVH (the compile's own output,
  not a second compile) and writes ``OUT/<stem>.<task>.expected.json``: the frame count and rate,
  the ground, every foot contact point and hand site (joint and offset), the frames where the
  body stands (no walk, no posture change), every hand's goal site at the end of each of its TO
  segments, and every joint's position at the first of them (forward kinematics from the IR's
  JSON alone, as docs/ir.md shows);
* inside Blender: ``blender --background --factory-startup --python-exit-code 1 --python
  scripts/blender_check_bvh.py -- A.bvh A.expected.json [B.bvh B.expected.json ...]`` imports
  each BVH into an empty scene with ``bpy.ops.import_anim.bvh`` (scale 0.01: the file is in
  centimetres; axes forward −Z, up Y: our Y-up world to Blender's Z-up one) and checks, in
  Blender's own coordinates (metres, Z up):

  - the frame count, and the scene's frame rate against the BVH's ``Frame Time`` and the IR's fps;
  - feet on the ground: on every frame no sole point (heel, toe, balls) below the floor, and on
    every standing frame each foot's lowest sole point on it;
  - every hand at its goal site on the first frame at or after each TO end (where it holds);
    where the IR says the reach fell short, at the distance the IR reports;
  - every bone's head at the first TO end against our forward kinematics.

  Everything within TOLERANCE_M (1 mm). One Blender process checks every file given.

Exit status 0 when everything matches, 1 otherwise.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

TOLERANCE_M = 1e-3  # Blender keeps float32 matrices: about 1e-7 m here, far inside a millimetre
FPS_TOLERANCE = 1e-4  # the BVH writes 1/fps with 8 decimals: 30 fps reads back as 30.0000003
BVH_UNITS_PER_METRE = 100.0
HANDS = ("r_hand", "l_hand")
# Segments during which the feet may leave the floor: walking, and kneeling or squatting down.
MOVING_KINDS = ("locomotion", "posture")


# -- our side: expectations from the IR's JSON -----------------------------------------------
def _axis_angle(axis: Any, angle: float) -> Any:
    import numpy as np

    x, y, z = axis
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _quat_matrix(w: float, x: float, y: float, z: float) -> Any:
    import numpy as np

    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def joint_positions(doc: dict[str, Any], frame: int) -> dict[str, list[float]]:
    """Every joint's world position (m, Y up) at one frame: docs/ir.md's forward kinematics."""
    import numpy as np

    f = doc["frames"]
    angle = dict(zip(f["dof_names"], f["q"][frame], strict=True))
    world: dict[str, tuple[Any, Any]] = {}
    for joint in doc["manikin"]["joints"]:
        if joint["parent"] is None:
            R = _quat_matrix(*f["root_rotation"][frame])
            p = np.array(f["root_position"][frame]) + R @ np.array(joint["offset"])
        else:
            Rp, pp = world[joint["parent"]]
            R, p = Rp, pp + Rp @ np.array(joint["offset"])
        for dof in joint["dofs"]:
            R = R @ _axis_angle(dof["axis"], angle[dof["name"]])
        world[joint["name"]] = (R, p)
    return {name: [round(float(v), 9) for v in p] for name, (_, p) in world.items()}


def expectations(doc: dict[str, Any]) -> dict[str, Any]:
    """What Blender must show for one task, in our world (metres, Y up), from its IR."""
    f = doc["frames"]
    times = f["time"]
    n = len(times)
    manikin = doc["manikin"]
    sites = {s["name"]: s for s in manikin["effectors"] + manikin["contact_points"]}

    def first_frame_at_or_after(t: float) -> int:
        return next((k for k, tk in enumerate(times) if tk >= t - 1e-6), n - 1)

    moving = [(s["t_start"], s["t_end"]) for s in doc["segments"] if s["kind"] in MOVING_KINDS]
    standing = [k for k, t in enumerate(times) if not any(a <= t <= b for a, b in moving)]
    to_ends = []
    for s in doc["segments"]:
        goal = s["goal"]
        if s["kind"] != "TO" or goal["effector"] not in HANDS or goal["position"] is None:
            continue
        result = s.get("result") or {}
        reached = bool(result.get("success", True))
        to_ends.append(
            {
                "frame": first_frame_at_or_after(s["t_end"]),
                "hand": goal["effector"],
                "site": goal["site"],
                "goal": goal["position"],
                # where the IR says the reach fell short, the hand stays that far from the site
                "distance": 0.0 if reached else float(result.get("distance", 0.0)),
                "path": s["path"],
            }
        )
    if not to_ends:
        raise SystemExit(f"task {doc['source']['task']} has no TO segment of a hand")
    feet = {
        side: [
            {"name": p["name"], "joint": p["joint"], "offset": p["offset"]}
            for p in manikin["contact_points"]
            if p["name"].startswith(f"{side}_")
        ]
        for side in ("r", "l")
    }
    contact_frame = to_ends[0]["frame"]
    return {
        "task": doc["source"]["task"],
        "frames": n,
        "fps": f["fps"],
        "ground": doc["scene"]["ground"],
        "feet": feet,
        "hands": {h: {"joint": sites[h]["joint"], "offset": sites[h]["offset"]} for h in HANDS},
        "standing_frames": standing,
        "to_ends": to_ends,
        "contact_frame": contact_frame,
        "joints": joint_positions(doc, contact_frame),
    }


def write_expectations(ir_json: Path) -> Path:
    doc = json.loads(ir_json.read_text(encoding="utf-8"))
    out = ir_json.with_name(ir_json.name.removesuffix(".ir.json") + ".expected.json")
    out.write_text(json.dumps(expectations(doc), indent=1, sort_keys=True) + "\n", "utf-8")
    return out


# -- Blender's side: the check -------------------------------------------------------------
def blender_check(bvh: Path, expected_path: Path) -> list[str]:
    """Import ``bvh`` into an empty scene and list every mismatch with the expectations."""
    import bpy
    from bpy_extras.io_utils import axis_conversion
    from mathutils import Vector

    expected = json.loads(expected_path.read_text(encoding="utf-8"))
    tolerate_removed_open_mode()
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
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
    scene = bpy.context.scene
    problems = check_frame_count(arm, expected["frames"])
    problems += check_fps(scene, bvh, expected["fps"])
    to_blender = axis_conversion(from_forward="-Z", from_up="Y").to_3x3()
    world = arm.matrix_world
    to_armature = world.to_3x3().inverted()
    rest_inverse = {b.name: b.bone.matrix_local.to_3x3().inverted() for b in arm.pose.bones}

    def point(joint: str, offset: list[float]) -> Vector:
        """A point fixed in our joint's frame, in Blender's world: at rest our joint frames are
        the world's axes, so the bone's rotation from its rest pose carries the offset."""
        bone = arm.pose.bones[joint]
        turn = bone.matrix.to_3x3() @ rest_inverse[joint]
        return world @ (bone.head + turn @ (to_armature @ (to_blender @ Vector(offset))))

    ground = expected["ground"]  # our Y is Blender's Z
    standing = set(expected["standing_frames"])
    to_ends: dict[int, list[dict[str, Any]]] = {}
    for end in expected["to_ends"]:
        to_ends.setdefault(end["frame"], []).append(end)
    lowest, highest_standing, worst_hand = float("inf"), 0.0, 0.0
    feet_problems: list[str] = []
    for frame in range(expected["frames"]):
        scene.frame_set(1 + frame)
        for side, points in expected["feet"].items():
            heights = [point(p["joint"], p["offset"]).z - ground for p in points]
            low = min(heights)
            lowest = min(lowest, low)
            if low < -TOLERANCE_M:
                feet_problems.append(
                    f"frame {frame}: {side} sole {low * 1000:.3f} mm below the floor"
                )
            if frame in standing:
                highest_standing = max(highest_standing, low)
                if low > TOLERANCE_M:
                    feet_problems.append(
                        f"frame {frame}: standing {side} foot {low * 1000:.3f} mm above the floor"
                    )
        for end in to_ends.get(frame, []):
            hand = expected["hands"][end["hand"]]
            got = point(hand["joint"], hand["offset"])
            off = (got - to_blender @ Vector(end["goal"])).length
            error = abs(off - end["distance"])
            worst_hand = max(worst_hand, error)
            if error > TOLERANCE_M:
                problems.append(
                    f"frame {frame}: {end['hand']} {off * 1000:.3f} mm from {end['site']} "
                    f"({end['path']}), expected {end['distance'] * 1000:.3f} mm "
                    f"({error * 1000:.3f} mm off)"
                )
        if frame == expected["contact_frame"]:
            for name, ours in expected["joints"].items():
                got = world @ arm.pose.bones[name].head
                problems += compare(f"joint {name}", got, to_blender @ Vector(ours))
    problems += feet_problems[:10] + (
        [f"... and {len(feet_problems) - 10} more foot problems"] if len(feet_problems) > 10 else []
    )
    print(
        f"{bvh.name}: {expected['frames']} frames at {scene.render.fps / scene.render.fps_base:.4f}"
        f" fps; feet: lowest sole {lowest * 1000:+.3f} mm, standing feet within"
        f" {highest_standing * 1000:.3f} mm of the floor on {len(standing)} frames;"
        f" {len(expected['to_ends'])} TO ends: hands within {worst_hand * 1000:.3f} mm"
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


def check_fps(scene: Any, bvh: Path, fps: float) -> list[str]:
    """The scene's rate is the BVH's ``Frame Time`` (what the importer read) and the IR's fps."""
    frame_time = None
    with bvh.open(encoding="utf-8") as text:
        for line in text:
            if line.startswith("Frame Time:"):
                frame_time = float(line.split(":", 1)[1])
                break
    if frame_time is None:
        return ["no Frame Time line"]
    scene_fps = scene.render.fps / scene.render.fps_base
    problems = []
    if abs(scene_fps - 1.0 / frame_time) > FPS_TOLERANCE:
        problems.append(
            f"scene at {scene_fps} fps, the BVH's Frame Time {frame_time} says {1 / frame_time}"
        )
    if abs(scene_fps - fps) > FPS_TOLERANCE:
        problems.append(f"scene at {scene_fps} fps, the IR at {fps} fps")
    return problems


def compare(what: str, got: Any, want: Any) -> list[str]:
    error = (got - want).length
    if error <= TOLERANCE_M:
        return []
    return [f"{what}: Blender {tuple(got)}, expected {tuple(want)} ({error * 1000:.3f} mm)"]


def main(argv: list[str]) -> int:
    if "--" in argv:  # inside Blender: pairs of files after "--"
        args = argv[argv.index("--") + 1 :]
        if not args or len(args) % 2:
            print("usage: blender ... -- A.bvh A.expected.json [B.bvh ...]", file=sys.stderr)
            return 2
        failed = 0
        for bvh, expected in zip(args[::2], args[1::2], strict=True):
            problems = blender_check(Path(bvh), Path(expected))
            for p in problems:
                print(f"FAIL {Path(bvh).name} ({Path(expected).name}): {p}", file=sys.stderr)
            print(f"{'FAIL' if problems else 'ok  '} {Path(bvh).name} ({Path(expected).name})")
            failed += bool(problems)
        sys.stdout.flush()
        return 1 if failed else 0
    if len(argv) >= 3 and argv[1] == "expect":
        for ir_json in argv[2:]:
            write_expectations(Path(ir_json))
        return 0
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
