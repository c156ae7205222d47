"""Diagnostics: stable codes, spans, and rustc-style rendering."""

from mtlc.diagnostics.codes import CODES, RETIRED, Code, Severity
from mtlc.diagnostics.diagnostic import Diagnostic, DiagnosticSink, Label, Span

__all__ = ["CODES", "RETIRED", "Code", "Diagnostic", "DiagnosticSink", "Label", "Severity", "Span"]
