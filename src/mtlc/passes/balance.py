"""Placeholder while this pass is being written: it must be replaced before the issue closes."""

from __future__ import annotations

from mtlc.ir.model import MotionIR
from mtlc.passes.context import PassContext


def _unfinished(ir: MotionIR, ctx: PassContext) -> MotionIR:
    return ir


solve = generate = run = _unfinished
