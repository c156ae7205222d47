"""THE table of every Jack-side name and convention the JackScript generator and replay use.

Jack's scripting API is not publicly documented: seed 000 shows only ``from js import *``,
``CreateHuman()`` and ``human.Walk((200, 0, 200), duration=5)`` (centimetres, Y up, floor in
XZ). Everything else here is our documented assumption, kept in this one module so that someone
with a licensed Jack install can correct a name, an axis or a sign in one place. The generator
(mtlc.codegen.jackscript), the replay (mtlc.codegen.replay) and docs/jackscript.md (checked by a
test) all read it from here.
"""

from __future__ import annotations

from dataclasses import dataclass

# A row of the joint table: (our dof, Jack joint, index of the dof in that joint, sign).
# Jack's value = sign * our angle, converted to degrees.
DofMapping = tuple[str, str, int, int]


@dataclass(frozen=True)
class JackApi:
    """Names and conventions of the ``js`` module as the generated scripts call it."""

    module: str = "js"
    create_human: str = "CreateHuman"
    # load a scene's model file: LoadModel(path, name=..., transform=4x4 rows), the matrix
    # taking the file's own coordinates to Jack's world in its length unit (our assumption)
    load_model: str = "LoadModel"
    human_variable: str = "human"
    # methods of the object CreateHuman returns
    set_anthropometry: str = "SetAnthropometry"
    walk: str = "Walk"
    key_root: str = "KeyRoot"
    key_joints: str = "KeyJoints"
    reach: str = "Reach"
    grasp: str = "Grasp"
    look_at: str = "LookAt"
    # keyword arguments
    duration_keyword: str = "duration"
    start_keyword: str = "start"
    # units and axes (ours are SI, Y up, heading 0 facing +Z)
    length_unit: str = "cm"
    length_per_metre: float = 100.0
    angle_unit: str = "deg"
    # Jack's world axes in ours: row i is Jack's axis i written in our (x, y, z) frame
    world_axes: tuple[tuple[float, float, float], ...] = (
        (1.0, 0.0, 0.0),
        (0.0, 1.0, 0.0),
        (0.0, 0.0, 1.0),
    )
    up_axis: str = "Y"
    floor_plane: str = "XZ"
    # the root's orientation as intrinsic Euler angles about Jack's axes, in this order
    root_euler_order: str = "YXZ"
    root_joint: str = "pelvis"
    # how Jack fills the motion between two keys of one joint (our documented assumption)
    interpolation: str = "linear"

    @property
    def methods(self) -> tuple[str, ...]:
        """Every method name a script may call on the human."""
        return (
            self.set_anthropometry,
            self.walk,
            self.key_root,
            self.key_joints,
            self.reach,
            self.grasp,
            self.look_at,
        )

    @property
    def functions(self) -> tuple[str, ...]:
        """Every module-level name ``from js import *`` brings in."""
        return (self.create_human, self.load_model)


JACK_API = JackApi()

# Our effectors (body sites) as Jack names them in Reach, Grasp and LookAt.
EFFECTORS: dict[str, str] = {
    "r_hand": "right_hand",
    "l_hand": "left_hand",
    "gaze": "eyes",
}

# Grip states (IR segment params) as Jack's Grasp takes them.
GRASP_STATES: dict[str, str] = {
    "closed": "close",
    "open": "open",
}

# Every dof of the skeleton, in the skeleton's dof order. Jack's joints keep our anatomical
# sign convention (positive = flexion, abduction, internal rotation, pronation...): sign +1.
DOF_MAP: tuple[DofMapping, ...] = (
    ("lumbar_flex", "spine_lumbar", 0, 1),
    ("lumbar_lat", "spine_lumbar", 1, 1),
    ("lumbar_rot", "spine_lumbar", 2, 1),
    ("thorax_flex", "spine_thoracic", 0, 1),
    ("thorax_lat", "spine_thoracic", 1, 1),
    ("thorax_rot", "spine_thoracic", 2, 1),
    ("neck_flex", "neck", 0, 1),
    ("neck_lat", "neck", 1, 1),
    ("neck_rot", "neck", 2, 1),
    ("head_flex", "head", 0, 1),
    ("head_lat", "head", 1, 1),
    ("r_clavicle_elev", "right_clavicle", 0, 1),
    ("r_clavicle_prot", "right_clavicle", 1, 1),
    ("r_shoulder_flex", "right_shoulder", 0, 1),
    ("r_shoulder_abd", "right_shoulder", 1, 1),
    ("r_shoulder_rot", "right_shoulder", 2, 1),
    ("r_elbow_flex", "right_elbow", 0, 1),
    ("r_elbow_pro", "right_elbow", 1, 1),
    ("r_wrist_flex", "right_wrist", 0, 1),
    ("r_wrist_dev", "right_wrist", 1, 1),
    ("l_clavicle_elev", "left_clavicle", 0, 1),
    ("l_clavicle_prot", "left_clavicle", 1, 1),
    ("l_shoulder_flex", "left_shoulder", 0, 1),
    ("l_shoulder_abd", "left_shoulder", 1, 1),
    ("l_shoulder_rot", "left_shoulder", 2, 1),
    ("l_elbow_flex", "left_elbow", 0, 1),
    ("l_elbow_pro", "left_elbow", 1, 1),
    ("l_wrist_flex", "left_wrist", 0, 1),
    ("l_wrist_dev", "left_wrist", 1, 1),
    ("r_hip_flex", "right_hip", 0, 1),
    ("r_hip_abd", "right_hip", 1, 1),
    ("r_hip_rot", "right_hip", 2, 1),
    ("r_knee_flex", "right_knee", 0, 1),
    ("r_ankle_dorsi", "right_ankle", 0, 1),
    ("r_ankle_inv", "right_ankle", 1, 1),
    ("l_hip_flex", "left_hip", 0, 1),
    ("l_hip_abd", "left_hip", 1, 1),
    ("l_hip_rot", "left_hip", 2, 1),
    ("l_knee_flex", "left_knee", 0, 1),
    ("l_ankle_dorsi", "left_ankle", 0, 1),
    ("l_ankle_inv", "left_ankle", 1, 1),
    ("r_toes_dorsi", "right_toes", 0, 1),
    ("l_toes_dorsi", "left_toes", 0, 1),
)


def jack_joints() -> tuple[str, ...]:
    """Jack joint names in first-use order (the order a KeyJoints call lists them)."""
    return tuple(dict.fromkeys(row[1] for row in DOF_MAP))


def joint_dof_count(joint: str) -> int:
    return sum(1 for row in DOF_MAP if row[1] == joint)


def markdown_tables() -> str:
    """The tables docs/jackscript.md embeds; a test checks the doc holds exactly this text."""
    api = JACK_API
    lines = [
        "| what | Jack name or value |",
        "|---|---|",
        f"| module | `{api.module}` |",
        f"| create the manikin | `{api.create_human}()` |",
        f"| variable holding it | `{api.human_variable}` |",
        f"| load a model file | `{api.load_model}(path, name=, transform=)` |",
        f"| anthropometry | `{api.human_variable}.{api.set_anthropometry}` |",
        f"| walk | `{api.human_variable}.{api.walk}` |",
        f"| root keyframe | `{api.human_variable}.{api.key_root}` |",
        f"| joint keyframe | `{api.human_variable}.{api.key_joints}` |",
        f"| reach (Jack's IK) | `{api.human_variable}.{api.reach}` |",
        f"| grasp | `{api.human_variable}.{api.grasp}` |",
        f"| look at | `{api.human_variable}.{api.look_at}` |",
        f"| keywords | `{api.start_keyword}=`, `{api.duration_keyword}=` (seconds) |",
        f"| length unit | {api.length_unit} ({api.length_per_metre:g} per metre) |",
        f"| angle unit | {api.angle_unit} |",
        f"| world axes (rows: Jack's x, y, z in ours) | `{api.world_axes}` |",
        f"| up axis, floor plane | {api.up_axis}, {api.floor_plane} |",
        f"| root orientation | intrinsic Euler angles, order {api.root_euler_order} |",
        f"| root joint | `{api.root_joint}` |",
        f"| interpolation between keys | {api.interpolation} |",
        "",
        "| our effector | Jack effector |",
        "|---|---|",
        *(f"| `{ours}` | `{jack}` |" for ours, jack in EFFECTORS.items()),
        "",
        "| our grip state | Jack grasp state |",
        "|---|---|",
        *(f"| `{ours}` | `{jack}` |" for ours, jack in GRASP_STATES.items()),
        "",
        "| our dof | Jack joint | Jack dof index | sign |",
        "|---|---|---|---|",
        *(f"| `{dof}` | `{joint}` | {index} | {sign:+d} |" for dof, joint, index, sign in DOF_MAP),
    ]
    return "\n".join(lines) + "\n"
