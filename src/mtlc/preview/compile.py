"""Front end and motion passes for the preview: task files in, preview documents out."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mtlc.frontend import FrontendOptions, Program, run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import MotionOptions, run_motion
from mtlc.preview.document import preview_document
from mtlc.preview.sites import Vec3, run_frontend_with_sites


@dataclass
class Compiled:
    """A compile's program (diagnostics, sources) and one motion per task, if it succeeded."""

    program: Program
    motions: list[MotionIR] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.program.sink.has_errors

    def documents(self) -> list[dict[str, Any]]:
        """One preview document per task."""
        return [
            preview_document(ir, self.program.sources, site_sources(ir, self))
            for ir in self.motions
        ]


def site_sources(ir: MotionIR, compiled: Compiled) -> dict[str, dict[str, Any]]:
    """Where each of the task's sites is declared (file, line), for the page."""
    for timeline in compiled.program.timelines:
        if timeline.task == ir.task and timeline.file == ir.file:
            return {
                s.name: {"file": s.span.file, "line": s.span.line, "column": s.span.column}
                for s in timeline.sites
            }
    return {}


def compile_motions(
    paths: list[Path],
    options: FrontendOptions | None = None,
    motion: MotionOptions | None = None,
    *,
    task: str | None = None,
    moved: Mapping[str, Vec3] | None = None,
) -> Compiled:
    """Compile every task (or the one named), with scene sites optionally moved."""
    program = (
        run_frontend_with_sites(paths, options, moved) if moved else run_frontend(paths, options)
    )
    compiled = Compiled(program)
    if program.sink.has_errors:
        return compiled
    for timeline in program.timelines:
        if task is None or timeline.task == task:
            compiled.motions.append(run_motion(timeline, program.sink, motion))
    if program.sink.has_errors:
        compiled.motions = []
    return compiled
