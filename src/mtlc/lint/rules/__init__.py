"""The lint rules, in the order they run: code, name, default severity and page come from
mtlc.diagnostics.codes (one table for every code); this table adds what each rule reads.

Program rules read the checked front end; motion rules read one manikin's compiled frames.
The front end's own diagnostics (MT00xx–MT04xx, e.g. MT0404 over-budget, the MTM-1 time
against the task's `budget`) and the motion passes' (MT0501 unreachable site, MT0502 balance
lost) are lint findings too, under their own codes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from mtlc.diagnostics import CODES, Code
from mtlc.frontend import Program
from mtlc.lint.findings import Finding
from mtlc.lint.rules import access, crossing, lifting, motion, sustained, unused, visibility
from mtlc.lint.rules.view import MotionView

ProgramRule = Callable[[Program], list[Finding]]
MotionRule = Callable[[MotionView], list[Finding]]


@dataclass(frozen=True)
class Rule:
    code: str
    check: ProgramRule | MotionRule
    on: str  # "program" or "motion"

    @property
    def info(self) -> Code:
        return CODES[self.code]

    @property
    def page(self) -> str:
        return f"docs/diagnostics/{self.code}.md"


RULES: tuple[Rule, ...] = (
    Rule("MT0601", unused.unused_definitions, "program"),
    Rule("MT0602", unused.unused_parameters, "program"),
    Rule("MT0603", motion.joint_limits, "motion"),
    Rule("MT0604", motion.ground_penetration, "motion"),
    Rule("MT0605", motion.rula, "motion"),
    Rule("MT0607", visibility.site_out_of_view, "motion"),
    Rule("MT0608", lifting.lifting_index, "motion"),
    Rule("MT0609", sustained.sustained_posture, "motion"),
    Rule("MT0610", access.access_openings, "motion"),
    Rule("MT0611", visibility.site_hidden, "motion"),
    Rule("MT0612", crossing.crossed_arms, "motion"),
)
# MT0606 (unused suppression) is reported by mtlc.lint.suppress after every rule has run.

__all__ = ["RULES", "MotionRule", "ProgramRule", "Rule"]
