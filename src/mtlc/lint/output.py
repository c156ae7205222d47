"""The four output formats of `mtlc lint`: text, json, github, sarif.

Every path is shown relative to the root (the current folder) when the file lies under it, with
forward slashes, so outputs are the same on every machine and SARIF locations are repo-relative.
"""

from __future__ import annotations

import json
import os
import re
from functools import cache
from pathlib import Path
from typing import Any
from urllib.parse import quote

from mtlc import __version__
from mtlc.diagnostics import CODES, Severity, Span
from mtlc.diagnostics.render import render_one, terminal_safe
from mtlc.lint.engine import LintResult
from mtlc.lint.findings import Finding
from mtlc.lint.manikins import label
from mtlc.resources import resource_dir

LINT_FORMAT_VERSION = 1
SARIF_SCHEMA = "https://json.schemastore.org/sarif-2.1.0.json"
FORMATS = ("text", "json", "github", "sarif")


def display_path(file: str, root: Path) -> str:
    path = Path(file)
    if path.is_absolute():
        try:
            return path.resolve().relative_to(root.resolve()).as_posix()
        except ValueError:
            return path.as_posix()
    return path.as_posix()


def artifact_location(file: str, root: Path) -> dict[str, str]:
    """A SARIF artifactLocation with a valid URI: percent-encoded (a space, `%`, `#`, `:` and
    non-UTF-8 bytes are escaped) and relative to %SRCROOT% inside the root; a file outside it is
    a `file://` URI of its own, with no base."""
    path = Path(file)
    if not path.is_absolute() and ".." not in path.parts:
        return {"uri": quote(os.fsencode(path.as_posix()), safe="/"), "uriBaseId": "%SRCROOT%"}
    absolute = (path if path.is_absolute() else root / path).resolve()
    try:
        inside = absolute.relative_to(root.resolve())
    except ValueError:
        return {"uri": absolute.as_uri()}
    return {"uri": quote(os.fsencode(inside.as_posix()), safe="/"), "uriBaseId": "%SRCROOT%"}


def _relocated(span: Span, root: Path) -> Span:
    return span._replace(file=display_path(span.file, root))


# -- text --------------------------------------------------------------------------------------


def render_text(result: LintResult, root: Path, *, color: bool = False) -> str:
    sources = {display_path(k, root): v for k, v in result.sources.items()}
    parts = []
    for f in result.findings:
        d = f.as_diagnostic()
        d = type(d)(
            d.code,
            d.message,
            _relocated(d.span, root),
            d.help,
            tuple(type(lb)(_relocated(lb.span, root), lb.message) for lb in d.labels),
            d.notes,
        )
        parts.append(render_one(d, sources, color=color))
    parts.append(_summary(result))
    return "\n".join(parts)


def _summary(result: LintResult) -> str:
    counts = _counts(result.findings)
    found = ", ".join(f"{n} {k}{'s' if n != 1 else ''}" for k, n in counts.items() if n)
    line = (
        f"{len(result.files)} file{'s' if len(result.files) != 1 else ''} linted for "
        f"{', '.join(label(m) for m in result.full)}"
    )
    return f"{line}: {found or 'no findings'}\n"


def _counts(findings: list[Finding]) -> dict[str, int]:
    return {
        "error": sum(f.severity is Severity.ERROR for f in findings),
        "warning": sum(f.severity is Severity.WARNING for f in findings),
        "note": sum(f.severity is Severity.NOTE for f in findings),
    }


# -- json --------------------------------------------------------------------------------------


def render_json(result: LintResult, root: Path) -> str:
    items = []
    for f in result.findings:
        item: dict[str, Any] = {
            "code": f.code,
            "name": f.name,
            "severity": f.severity.value,
            "message": f.message,
            "span": _relocated(f.span, root).as_dict(),
            "manikins": [
                {"manikin": m, "message": d} for m, d in zip(f.manikins, f.details, strict=True)
            ],
            "doc": f"docs/diagnostics/{f.code}.md",
        }
        if f.help:
            item["help"] = f.help
        if f.notes:
            item["notes"] = list(f.notes)
        items.append(item)
    doc = {
        "format": "mtlc-lint",
        "version": LINT_FORMAT_VERSION,
        "files": [display_path(str(p), root) for p in result.files],
        "manikins": [label(m) for m in result.manikins],
        "compiled_in_full": [label(m) for m in result.full],
        "findings": items,
        "summary": {k + "s": n for k, n in _counts(result.findings).items()},
    }
    return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


# -- github ------------------------------------------------------------------------------------

_GITHUB_LEVEL = {Severity.ERROR: "error", Severity.WARNING: "warning", Severity.NOTE: "notice"}


def escape_data(text: str) -> str:
    """Workflow-command message escapes (actions/toolkit, command.ts escapeData)."""
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def escape_property(text: str) -> str:
    """Property escapes: the data escapes, and ':' and ',' which separate properties."""
    return escape_data(text).replace(":", "%3A").replace(",", "%2C")


def _full_message(f: Finding) -> str:
    if not f.manikins:
        return f.message
    return f"{f.message}\nfor " + "\n    ".join(f.manikin_lines())


def render_github(result: LintResult, root: Path) -> str:
    lines = []
    for f in result.findings:
        s = _relocated(f.span, root)
        props = [
            ("file", s.file),
            ("line", str(s.line)),
            ("endLine", str(s.end_line)),
            ("col", str(s.column)),
            ("endColumn", str(s.end_column)),
            ("title", f"{f.code} {f.name}"),
        ]
        head = ",".join(f"{k}={escape_property(v)}" for k, v in props)
        message = escape_data(terminal_safe(_full_message(f), newlines=True))  # no raw ESC in logs
        lines.append(f"::{_GITHUB_LEVEL[f.severity]} {head}::{message}\n")
    return "".join(lines)


# -- sarif -------------------------------------------------------------------------------------

_SARIF_LEVEL = {Severity.ERROR: "error", Severity.WARNING: "warning", Severity.NOTE: "note"}


@cache
def _page(code: str) -> str:
    path = resource_dir("diagnostics") / f"{code}.md"
    return path.read_text(encoding="utf-8") if path.is_file() else f"# {code}\n"


def _first_paragraph(page: str) -> str:
    paragraphs = [p.strip() for p in page.split("\n\n") if p.strip()]
    body = [p for p in paragraphs if not p.startswith("#")]
    text = " ".join(body[0].split()) if body else ""
    return re.sub(r"^Severity: \w+\. ", "", text)


def sarif_rules(codes: list[str]) -> list[dict[str, Any]]:
    """The rules the results refer to (in CODES order), each with its page as the help."""
    rules = []
    for code in codes:
        c = CODES[code]
        page = _page(c.code)
        rules.append(
            {
                "id": c.code,
                "name": c.name,
                "shortDescription": {"text": c.summary},
                "fullDescription": {"text": _first_paragraph(page) or c.summary},
                "help": {"text": f"{c.summary}. Run `mtlc explain {c.code}`.", "markdown": page},
                "defaultConfiguration": {"level": _SARIF_LEVEL[c.severity]},
                "properties": {"tags": ["maintainability"]},
            }
        )
    return rules


def render_sarif(result: LintResult, root: Path) -> str:
    used = {f.code for f in result.findings}
    codes = [c for c in CODES if c in used]
    index = {code: i for i, code in enumerate(codes)}
    results = []
    for f in result.findings:
        s = _relocated(f.span, root)
        region = {
            "startLine": max(1, s.line),
            "startColumn": max(1, s.column),
            "endLine": max(1, s.end_line),
            "endColumn": max(1, s.end_column),
        }
        results.append(
            {
                "ruleId": f.code,
                "ruleIndex": index[f.code],
                "level": _SARIF_LEVEL[f.severity],
                "message": {"text": _full_message(f)},
                "locations": [
                    {
                        "physicalLocation": {
                            "artifactLocation": artifact_location(f.span.file, root),
                            "region": region,
                        }
                    }
                ],
                "properties": {"manikins": list(f.manikins)},
            }
        )
    doc = {
        "$schema": SARIF_SCHEMA,
        "version": "2.1.0",
        "runs": [
            {
                "tool": {
                    "driver": {
                        "name": "mtlc",
                        "version": __version__,
                        "rules": sarif_rules(codes),
                    }
                },
                "columnKind": "unicodeCodePoints",
                "results": results,
            }
        ],
    }
    return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


RENDERERS = {"json": render_json, "github": render_github, "sarif": render_sarif}
