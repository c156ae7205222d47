"""What every motion pass receives besides the IR: options, the diagnostic sink, a cache."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.ir.model import SourceRef

DEFAULT_FPS = 30.0
INTERNAL_FPS = 60.0  # dense frames between interpolation and sampling


@dataclass(frozen=True)
class MotionOptions:
    fps: float = DEFAULT_FPS
    walk_clip: Path | None = None  # a BVH walking clip to take the gait from


@dataclass
class PassContext:
    sink: DiagnosticSink
    options: MotionOptions = field(default_factory=MotionOptions)
    cache: dict[str, Any] = field(default_factory=dict)  # solver models and the like, per compile

    def report(self, code: str, message: str, ref: SourceRef, **kw: Any) -> None:
        """Report at a segment's source position (passes know SourceRefs, not AST spans)."""
        span = Span(ref.file, ref.line, ref.column, ref.end_line, ref.end_column)
        self.sink.report(code, message, span, **kw)
