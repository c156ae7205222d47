"""Pass 1: build the manikin from the task's population, sex and percentile."""

from __future__ import annotations

from mtlc.body import build_manikin
from mtlc.ir.model import MotionIR
from mtlc.passes.context import PassContext


def build(ir: MotionIR, ctx: PassContext) -> MotionIR:
    m = ir.manikin
    ir.skeleton = build_manikin(m["population"], m["sex"], int(m["percentile"]))
    return ir
