"""'Did you mean' suggestions."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

CUTOFF = 0.6


def close_matches(name: str, candidates: Iterable[str]) -> list[str]:
    """The candidates closest to ``name`` (all of those tied for best), in a stable order."""
    scored = []
    for candidate in sorted(set(candidates)):
        matcher = difflib.SequenceMatcher(None, name, candidate)
        if matcher.real_quick_ratio() >= CUTOFF and matcher.quick_ratio() >= CUTOFF:
            score = matcher.ratio()
            if score >= CUTOFF:
                scored.append((score, candidate))
    if not scored:
        return []
    best = max(score for score, _ in scored)
    return [c for score, c in scored if score == best]


def did_you_mean(name: str, candidates: Iterable[str], preferred: Iterable[str] = ()) -> str | None:
    """'did you mean' the closest candidate; close ``preferred`` ones (the kind the context
    wants, such as units of the expected dimension) win over closer others."""
    matches = close_matches(name, preferred) or close_matches(name, candidates)
    if not matches:
        return None
    return "did you mean " + " or ".join(f"`{m}`" for m in matches[:3]) + "?"


def suggest(name: str, candidates: Iterable[str], label: str, preferred: Iterable[str] = ()) -> str:
    """'did you mean' when something is close, else the list of what exists."""
    candidates = list(candidates)
    return did_you_mean(name, candidates, preferred) or f"{label}: {', '.join(candidates)}"
