"""The keyframe IR as plain dataclasses and numpy arrays, in SI units.

A task lowers to segments on tracks (root, spine, head, each arm, each hand, each leg). A segment
is one primitive's share of the motion: its time window, kind, goal and provenance, and, once a
pass has solved it, its keyframes. Keyframes set some joint angles (named by ``dofs``) and maybe
the root; interpolation merges every segment's keyframes into whole-body frames, which later
passes correct and the sampler turns into the frames a generator writes.

The IR knows numpy and nothing else of mtlc: the skeleton is kept as the body's own object,
typed loosely here, and serialised by mtlc.ir.serialize.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def runs_of(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(start, stop) index ranges where ``mask`` (N,) holds: the runs of frames a pass treats
    as one."""
    edges = np.flatnonzero(np.diff(np.r_[0, np.asarray(mask).astype(np.int8), 0]))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


IR_FORMAT_VERSION = 1
SEGMENT_KINDS = ("TA", "TO", "posture", "locomotion", "grip", "gaze", "hold", "rest")
TRACKS = ("root", "spine", "head", "l_arm", "r_arm", "l_hand", "r_hand", "l_leg", "r_leg")


@dataclass(frozen=True)
class SourceRef:
    """Where a segment came from: a file position (1-based), as in the diagnostics."""

    file: str
    line: int
    column: int
    end_line: int
    end_column: int


@dataclass(frozen=True)
class Provenance:
    path: tuple[str, ...]  # task > action > element
    span: SourceRef  # the primitive statement
    origin: SourceRef  # the line in the task that led here


@dataclass
class GoalSpec:
    """What a segment asks for. Positions in world metres; orientation as a 3x3 matrix."""

    effector: str  # a body site (r_hand, l_hand, gaze) or "root" or "body"
    site: str | None = None
    position: FloatArray | None = None
    orientation: FloatArray | None = None
    approach: float | None = None  # TA stops this far short of the site, along its normal
    params: dict[str, Any] = field(default_factory=dict)  # posture kind and arguments, grip...


@dataclass
class Keyframes:
    """Poses at given times for some joint angles (``dofs``) and, when set, for the root."""

    time: FloatArray  # (K,)
    dofs: tuple[str, ...] = ()
    q: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))  # (K, len(dofs))
    root_position: FloatArray | None = None  # (K, 3)
    root_rotation: FloatArray | None = None  # (K, 4) quaternion, w first


@dataclass
class Segment:
    track: str
    kind: str  # one of SEGMENT_KINDS
    start: float
    end: float
    goal: GoalSpec
    provenance: Provenance
    keyframes: Keyframes | None = None
    # what the solver reached: remaining distance, success, iterations...
    result: dict[str, Any] = field(default_factory=dict)


@dataclass
class RootPlan:
    """Where the root stands and which way it faces, over time, before the gait is made.

    Piecewise linear in position and heading between the knots; the TA and TO passes read it to
    know where the body is when a hand must reach.
    """

    time: FloatArray  # (K,)
    position: FloatArray  # (K, 3), the root on the standing pose's height
    heading: FloatArray  # (K,) yaw about +Y, radians; 0 faces +Z

    def at(self, t: float | FloatArray) -> tuple[FloatArray, FloatArray]:
        tt = np.asarray(t, dtype=float)
        pos = np.stack([np.interp(tt, self.time, self.position[:, i]) for i in range(3)], axis=-1)
        heading = np.interp(tt, self.time, np.unwrap(self.heading))
        return pos, heading


@dataclass
class Frames:
    """Whole-body motion sampled at a fixed rate: what generators write and metrics read."""

    fps: float
    time: FloatArray  # (N,)
    root_position: FloatArray  # (N, 3)
    root_rotation: FloatArray  # (N, 4) quaternion, w first
    q: FloatArray  # (N, n_dofs), in the skeleton's dof order


@dataclass
class Verification:
    """What the verify pass measured on the output frames (docs/metrics.md): each figure once.

    Metrics, lint, report and preview read these instead of measuring again. Per-frame arrays
    have one value per output frame; the lists hold one entry per goal, grip or finding.
    """

    # one per goal (TO segment with a position): effector, site, time (s, the contact frame),
    # error (m, at that frame), reached (the compiler's claim), shortfall (m, closest approach
    # over the goal's frames), closest_time, and the task line's file, line and column
    contacts: list[dict[str, Any]] = field(default_factory=list)
    # one per held window: hand, t_start, t_end (s), drift (m), time of the worst frame, line
    grips: list[dict[str, Any]] = field(default_factory=list)
    # deepest point of each class below the floor: class -> {"depth": m, "time": s}
    penetration: dict[str, dict[str, float]] = field(default_factory=dict)
    # worst joint-limit excess: count (frame x dof values), excess (rad), dof, time
    limits: dict[str, Any] = field(default_factory=dict)
    # deepest hand or forearm axis inside the trunk or a thigh: depth (m), time, limb, part
    self_intersection: dict[str, Any] = field(default_factory=dict)
    static_margin: float = float("nan")  # m, minimum over static frames (NaN: none)
    static_margin_time: float = float("nan")
    # per output frame
    penetration_frames: FloatArray = field(default_factory=lambda: np.zeros(0))  # m, all points
    support_margin: FloatArray = field(default_factory=lambda: np.zeros(0))  # m, NaN airborne
    static: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    contact_error: FloatArray = field(default_factory=lambda: np.zeros(0))  # m, NaN: no rest
    intersection_frames: FloatArray = field(default_factory=lambda: np.zeros(0))  # m, >0 inside
    # (N, D) rad past each dof's limit: positive past the upper, negative past the lower, else 0
    limit_excess: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    # what verify reported: code, message, line, column
    findings: list[dict[str, Any]] = field(default_factory=list)
    seconds: float = 0.0  # time verify took (not serialised: output stays deterministic)
    # with scene models only: the deepest capsule into a model, not at its goal's site (MT0515):
    # depth (m, 0 when clear), part, model, time
    equipment: dict[str, Any] = field(default_factory=dict)
    # ...and every capsule's clearance to every model on every frame (a FrameClearance, for the
    # preview; not serialised), with which contacts are not findings (``excused``) and how deep
    # each held part goes into the rest of the equipment
    equipment_clearance: Any = None
    # the parts the hands hold, with their faces and placement on every frame
    # (mtlc.geometry.held.HeldPart; the JSON has ``equipment.held``): for the preview
    held_parts: list[Any] = field(default_factory=list)


@dataclass
class MotionIR:
    task: str
    title: str | None
    file: str
    manikin: dict[str, Any]  # population, sex, percentile
    ground: float
    sites: list[dict[str, Any]]  # name, position, normal, frame
    segments: list[Segment] = field(default_factory=list)
    skeleton: Any = None  # mtlc.body.Skeleton, set by the manikin pass
    root_plan: RootPlan | None = None
    frames: Frames | None = None  # dense frames, set by interpolation, refined by later passes
    verification: Verification | None = None  # set by the verify pass, on the output frames
    # (last: the fields before keep their positions)
    # the scene's models and solids as the IR JSON gives them (SceneModel.record); present in
    # the JSON only when there are some, so scenes without geometry keep their bytes
    models: list[dict[str, Any]] = field(default_factory=list)
    # the same, placed, with their meshes (mtlc.geometry.model.SceneModel): for passes, not JSON
    geometry: list[Any] = field(default_factory=list)

    def on_track(self, track: str) -> list[Segment]:
        return [s for s in self.segments if s.track == track]

    @property
    def duration(self) -> float:
        return max((s.end for s in self.segments), default=0.0)


def yaw_quaternion(heading: FloatArray) -> FloatArray:
    """Quaternions (w, x, y, z) for rotations by ``heading`` about +Y."""
    h = np.asarray(heading, dtype=float) / 2.0
    zeros = np.zeros_like(h)
    return np.stack([np.cos(h), zeros, np.sin(h), zeros], axis=-1)
