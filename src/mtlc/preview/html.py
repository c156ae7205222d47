"""The self-contained preview page: one HTML file with three.js, the page script and the data.

Nothing is fetched when the file opens, so it works offline and can be mailed or archived. The
page template, its style and script live beside this module; three.js is the vendored bundle in
``vendor/`` (MIT, see ``vendor/three.LICENSE``; how it was built: ``vendor/README.md``).
"""

from __future__ import annotations

import html
import json
import re
from functools import cache
from importlib.resources import files
from typing import Any

from mtlc.diagnostics.render import terminal_safe
from mtlc.jsontext import escape_surrogates

THREE_BUNDLE = "three.preview.min.js"
_PLACEHOLDER = re.compile(r"__(TITLE|CSS|THREE|DATA|SERVE|PAGE_JS)__")


@cache
def asset(name: str) -> str:
    """A file shipped with the preview package (template, style, script, vendored three.js)."""
    return (files("mtlc.preview") / name).read_text(encoding="utf-8")


def script_json(value: Any) -> str:
    """JSON that is safe inside a <script> element: no '<', '>' or '&' can end it early."""
    text = escape_surrogates(
        json.dumps(value, ensure_ascii=False, separators=(",", ":"), allow_nan=False)
    )
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def render_page(document: dict[str, Any] | None, *, serve: bool = False, title: str = "") -> str:
    """The whole page; ``document`` embedded (None when a server streams it), deterministic."""
    if document is not None and not title:
        source = document["ir"]["source"]
        title = source.get("title") or source["task"]
    values = {
        "TITLE": html.escape(terminal_safe(title or "mtlc preview")),  # no raw ESC, NUL, U+202E
        "CSS": asset("page.css"),
        "THREE": asset(f"vendor/{THREE_BUNDLE}"),
        "DATA": script_json(document),
        "SERVE": "true" if serve else "false",
        "PAGE_JS": asset("page.js"),
    }
    # one pass, so that text inserted for one placeholder is never scanned for another
    return _PLACEHOLDER.sub(lambda m: values[m.group(1)], asset("page.html"))
