"""The keyframe IR: the contract between lowering, the motion passes and the generators."""

from mtlc.ir.model import (
    IR_FORMAT_VERSION,
    SEGMENT_KINDS,
    TRACKS,
    Frames,
    GoalSpec,
    Keyframes,
    MotionIR,
    Provenance,
    RootPlan,
    Segment,
    Verification,
)

__all__ = [
    "IR_FORMAT_VERSION",
    "SEGMENT_KINDS",
    "TRACKS",
    "Frames",
    "GoalSpec",
    "Keyframes",
    "MotionIR",
    "Provenance",
    "RootPlan",
    "Segment",
    "Verification",
]
