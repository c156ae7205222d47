"""JSON text that a UTF-8 file can hold, whatever the names in it.

A bottom layer of its own (no mtlc import): the IR's serializer, the code generators, the
preview and the output transaction all write JSON that may carry file names.
"""

from __future__ import annotations

import re

_SURROGATE = re.compile("[\ud800-\udfff]")


def escape_surrogates(json_text: str) -> str:
    """JSON with each lone surrogate (a byte of a file name that is not UTF-8, as Python decodes
    it) written as a `\\uXXXX` escape: the file is valid UTF-8 and reads back as the same name."""
    return _SURROGATE.sub(lambda m: f"\\u{ord(m.group()):04x}", json_text)
