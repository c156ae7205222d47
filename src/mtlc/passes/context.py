"""What every motion pass receives besides the IR: options, the diagnostic sink, a cache."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.ir.model import SourceRef

DEFAULT_FPS = 30.0
# Claims a pass makes about the output frames that the verify pass confirms with a measurement
# on those frames (docs/metrics.md): a pass's own estimate (the distance to its approach point,
# its balance on the dense frames) is not what the user sees.
VERIFIED_CODES = frozenset({"MT0501", "MT0502"})
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
    # a pass's reports of VERIFIED_CODES, held for the verify pass: (code, message, ref, kw)
    claims: list[tuple[str, str, SourceRef, dict[str, Any]]] = field(default_factory=list)

    def report(self, code: str, message: str, ref: SourceRef, **kw: Any) -> None:
        """Report at a segment's source position (passes know SourceRefs, not AST spans).

        A code in ``VERIFIED_CODES`` is held as a claim: the verify pass reports it with the
        figure measured on the output frames (``flush_claims`` reports what verify did not)."""
        if code in VERIFIED_CODES:
            self.claims.append((code, message, ref, kw))
            return
        self.emit(code, message, ref, **kw)

    def emit(self, code: str, message: str, ref: SourceRef, **kw: Any) -> None:
        """Report now, whatever the code (the verify pass's own findings)."""
        span = Span(ref.file, ref.line, ref.column, ref.end_line, ref.end_column)
        self.sink.report(code, message, span, **kw)

    def flush_claims(self) -> None:
        """Report the held claims as the passes worded them (the run stopped before verify)."""
        for code, message, ref, kw in self.claims:
            self.emit(code, message, ref, **kw)
        self.claims.clear()
