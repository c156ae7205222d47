"""Every diagnostic code mtlc can emit.

Codes are grouped by the stage that finds them (MT00xx input, MT01xx syntax, MT02xx modules and
names, MT03xx types, units and calls, MT04xx expansion, MT05xx motion passes, MT06xx `mtlc lint` rules) and are never
renumbered: CI scripts and suppressions depend on them. Each code has a page in docs/diagnostics/ that ``mtlc explain`` shows.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class Severity(StrEnum):
    ERROR = "error"
    WARNING = "warning"
    NOTE = "note"


@dataclass(frozen=True, slots=True)
class Code:
    code: str
    name: str
    severity: Severity
    summary: str
    # a code no stage raises any more, with the code(s) that report its fault now: kept in the
    # table so old ignore comments and lint.toml lists still name a code (docs/diagnostics.md)
    retired_for: str = ""


_ALL = [
    # input
    Code("MT0001", "unreadable-file", Severity.ERROR, "a file cannot be read"),
    Code("MT0002", "invalid-utf8", Severity.ERROR, "a file is not valid UTF-8"),
    Code("MT0003", "file-too-large", Severity.ERROR, "a file is larger than the input limit"),
    Code(
        "MT0004", "not-a-regular-file", Severity.ERROR, "an input is a pipe, a device or a socket"
    ),
    Code("MT0005", "model-not-found", Severity.ERROR, "a model's file cannot be found or read"),
    Code(
        "MT0006",
        "unreadable-model",
        Severity.ERROR,
        "a model file that is not a mesh mtlc reads, or has no triangles",
    ),
    Code("MT0007", "model-too-large", Severity.ERROR, "a model with more triangles than the limit"),
    Code(
        "MT0008",
        "model-outside-folder",
        Severity.ERROR,
        "a model's path leads outside the folder of the file that names it",
    ),
    # syntax
    Code("MT0101", "unexpected-token", Severity.ERROR, "the parser found a token it cannot use"),
    Code("MT0102", "unexpected-character", Severity.ERROR, "a character that no token starts with"),
    Code("MT0103", "unterminated-string", Severity.ERROR, "a string has no closing quote"),
    Code("MT0104", "nesting-too-deep", Severity.ERROR, "blocks or expressions nest too deeply"),
    Code("MT0105", "unexpected-end", Severity.ERROR, "the file ends inside a definition"),
    Code(
        "MT0106", "too-many-errors", Severity.ERROR, "so many syntax errors that checking stopped"
    ),
    Code("MT0107", "invalid-escape", Severity.ERROR, "an unknown escape sequence in a string"),
    Code("MT0108", "invalid-name", Severity.ERROR, "a word that is not a valid name"),
    Code(
        "MT0109",
        "unkeepable-suppression",
        Severity.ERROR,
        "fmt cannot lay out an ignore comment so it covers the same statements",
    ),
    # modules and names
    Code("MT0201", "unknown-name", Severity.ERROR, "a name that is not defined"),
    Code("MT0202", "duplicate-definition", Severity.ERROR, "a name defined twice"),
    Code("MT0203", "module-not-found", Severity.ERROR, "a `use` names a module that is not found"),
    Code("MT0204", "import-cycle", Severity.ERROR, "modules that use each other in a cycle"),
    Code("MT0205", "module-outside-roots", Severity.ERROR, "a `use` leads outside the search path"),
    Code("MT0206", "ambiguous-name", Severity.ERROR, "a name imported from two modules"),
    Code(
        "MT0207",
        "recursive-definition",
        Severity.ERROR,
        "actions or elements that call each other in a cycle",
    ),
    Code(
        "MT0208",
        "wrong-level-call",
        Severity.ERROR,
        "a call that breaks the task > action > element hierarchy",
    ),
    Code(
        "MT0209",
        "misplaced-statement",
        Severity.ERROR,
        "a statement that is not allowed where it stands",
    ),
    Code("MT0210", "duplicate-setting", Severity.ERROR, "a setting given twice in one place"),
    Code("MT0211", "unknown-model-node", Severity.ERROR, "a site names a node its model lacks"),
    Code(
        "MT0212",
        "invalid-shape-clause",
        Severity.ERROR,
        "a model or solid with a clause it does not take, or without one it needs",
    ),
    # types, units, calls
    Code("MT0301", "type-mismatch", Severity.ERROR, "a value of the wrong type"),
    Code("MT0302", "unit-mismatch", Severity.ERROR, "quantities of different dimensions mixed"),
    Code("MT0303", "unknown-unit", Severity.ERROR, "a unit that mtlc does not know"),
    Code("MT0304", "unknown-type", Severity.ERROR, "a parameter type that does not exist"),
    Code(
        "MT0305", "too-many-arguments", Severity.ERROR, "more positional arguments than parameters"
    ),
    Code("MT0306", "unknown-argument", Severity.ERROR, "a named argument that is not a parameter"),
    Code("MT0307", "missing-argument", Severity.ERROR, "a parameter without a value"),
    Code("MT0308", "argument-repeated", Severity.ERROR, "a parameter given a value twice"),
    Code("MT0309", "invalid-value", Severity.ERROR, "a value out of its allowed range"),
    Code("MT0310", "duplicate-parameter", Severity.ERROR, "two parameters with the same name"),
    Code(
        "MT0311",
        "positional-after-named",
        Severity.ERROR,
        "a positional argument after a named one",
    ),
    Code(
        "MT0312", "ambiguous-member", Severity.ERROR, "a bare member name that belongs to two enums"
    ),
    Code(
        "MT0313",
        "required-after-default",
        Severity.ERROR,
        "a parameter without a default after one with a default",
    ),
    # expansion
    Code("MT0401", "expansion-budget", Severity.ERROR, "a task expands into too many primitives"),
    Code("MT0402", "empty-task", Severity.WARNING, "a task that produces no motion"),
    Code("MT0403", "division-by-zero", Severity.ERROR, "a division by zero while expanding"),
    Code("MT0404", "over-budget", Severity.WARNING, "a task takes longer than its declared budget"),
    Code(
        "MT0405",
        "expansion-too-deep",
        Severity.ERROR,
        "calls and blocks nest too deeply while expanding",
    ),
    Code(
        "MT0406",
        "parallel-conflict",
        Severity.ERROR,
        "two parallel branches move the same body part",
    ),
    Code("MT0407", "motion-budget", Severity.ERROR, "a task's motion is longer than the budget"),
    Code(
        "MT0408",
        "model-far-away",
        Severity.ERROR,
        "a model or solid more than 1 km from the origin",
    ),
    # motion passes
    Code("MT0501", "unreachable-site", Severity.WARNING, "a manikin cannot reach a site"),
    Code(
        "MT0502",
        "balance-lost",
        Severity.WARNING,
        "the centre of mass leaves the support and cannot be brought back",
    ),
    Code("MT0503", "walking-clip", Severity.ERROR, "a walking clip that cannot be read or used"),
    # the verify pass: claims checked on the output frames (docs/metrics.md)
    Code("MT0510", "contact-missed", Severity.WARNING, "a hand is off a site it was said to reach"),
    Code("MT0511", "grip-slipped", Severity.WARNING, "a hand holding a part moves off it"),
    Code("MT0512", "below-floor", Severity.WARNING, "a body point goes below the floor"),
    Code("MT0513", "past-joint-limit", Severity.WARNING, "a joint goes past its limit"),
    Code("MT0514", "hand-in-body", Severity.WARNING, "a hand or forearm goes into the body"),
    Code(
        "MT0515",
        "into-equipment",
        Severity.WARNING,
        "a body part or held tool goes into the equipment",
    ),
    # retired: verify reports these faults on the output frames, once (issue 18)
    Code(
        "MT0520",
        "hold-lost",
        Severity.WARNING,
        "retired: see MT0511 (a hand pulled off the site it holds)",
        retired_for="MT0511",
    ),
    Code(
        "MT0525",
        "fingertips-under-floor",
        Severity.WARNING,
        "retired: see MT0512 (a fingertip under the floor)",
        retired_for="MT0512",
    ),
    # lint rules (mtlc lint)
    Code("MT0601", "unused-definition", Severity.WARNING, "a definition nothing uses"),
    Code("MT0602", "unused-parameter", Severity.WARNING, "a parameter its body never reads"),
    Code("MT0603", "joint-limit", Severity.WARNING, "a joint moves past its limit"),
    Code("MT0604", "ground-penetration", Severity.WARNING, "the body sinks below the ground"),
    Code("MT0605", "rula-score", Severity.WARNING, "a posture at or above the RULA threshold"),
    Code("MT0606", "unused-suppression", Severity.WARNING, "an ignore comment that hides nothing"),
    Code(
        "MT0607",
        "site-out-of-view",
        Severity.WARNING,
        "a site worked on lies outside the view cone",
    ),
    Code("MT0608", "lifting-index", Severity.WARNING, "a lift above the NIOSH recommended limit"),
    Code(
        "MT0609",
        "sustained-posture",
        Severity.WARNING,
        "a posture at or above a RULA score held too long",
    ),
    Code(
        "MT0610",
        "access-opening",
        Severity.WARNING,
        "a hand, forearm or tool does not fit through the way to a site",
    ),
    Code("MT0611", "site-occluded", Severity.WARNING, "the equipment hides a site from the eyes"),
    Code("MT0612", "arms-crossed", Severity.WARNING, "each hand works on the other's side"),
    # internal
    Code("MT0900", "internal-error", Severity.ERROR, "a bug in mtlc: please report it"),
]

CODES: dict[str, Code] = {c.code: c for c in _ALL}
RETIRED: frozenset[str] = frozenset(c.code for c in _ALL if c.retired_for)
