"""Lint configuration: `[tool.mtlc.lint]` in pyproject.toml or `[lint]` in mtlc.toml.

Looked up from the current folder upwards; the nearest file that has the table wins (mtlc.toml
before pyproject.toml in the same folder). Unknown keys are a usage error, so a typo never
silently disables a check.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mtlc.diagnostics import CODES, Severity
from mtlc.ergonomics import niosh, view
from mtlc.semantics.modules import InputRefused, probe, read_input_bytes

MAX_CONFIG_BYTES = 1024 * 1024

DEFAULT_RULA_THRESHOLD = 5
DEFAULT_PENETRATION_MM = 1.0
DEFAULT_LIMIT_DEG = 0.5
DEFAULT_VIEW_CONE_DEG = view.DEFAULT_HALF_ANGLE_DEG  # docs/visibility.md
DEFAULT_SUSTAINED_RULA = 5  # RULA action level 3 and above (docs/sustained.md)
DEFAULT_SUSTAINED_SECONDS = 60.0  # RULA's "static, held > 1 min" (docs/sustained.md)
DEFAULT_GLOVE_MM = 0.0  # bare hands (docs/collision.md, "Access openings")


class ConfigError(ValueError):
    """A configuration that cannot be used (a usage error, exit code 2)."""


@dataclass(frozen=True)
class LintConfig:
    select: frozenset[str] = field(default_factory=lambda: frozenset(CODES))
    manikins: str | list[str] = "extremes"
    rula_threshold: int = DEFAULT_RULA_THRESHOLD
    penetration_mm: float = DEFAULT_PENETRATION_MM
    limit_deg: float = DEFAULT_LIMIT_DEG
    view_cone_half_angle: float = DEFAULT_VIEW_CONE_DEG  # degrees
    sustained_rula: int = DEFAULT_SUSTAINED_RULA
    sustained_seconds: float = DEFAULT_SUSTAINED_SECONDS
    lift_frequency: float = niosh.DEFAULT_FREQUENCY  # lifts per minute
    lift_duration: str = niosh.DEFAULT_DURATION  # NIOSH work duration: up to 1 h, 2 h or 8 h
    lift_coupling: str = niosh.DEFAULT_COUPLING  # NIOSH hand-to-object coupling
    glove_mm: float = DEFAULT_GLOVE_MM  # a glove's thickness on each side of the hand and arm
    fail_on: Severity = Severity.WARNING
    source: Path | None = None  # the file it came from, None for the defaults

    def enabled(self, code: str) -> bool:
        return code in self.select


_KEYS = (
    "select",
    "ignore",
    "manikins",
    "rula-threshold",
    "penetration-mm",
    "limit-deg",
    "view-cone-half-angle",
    "glove-mm",
    "sustained-rula",
    "sustained-seconds",
    "lift-frequency",
    "lift-duration",
    "lift-coupling",
    "fail-on",
)


def find_config(start: Path) -> tuple[Path, dict[str, Any]] | None:
    """The nearest configuration table at or above ``start``."""
    for folder in [start, *start.parents]:
        for name, keys in (("mtlc.toml", ("lint",)), ("pyproject.toml", ("tool", "mtlc", "lint"))):
            path = folder / name
            if not probe(path, Path.is_file):
                continue
            table = _table(path, keys)
            if table is not None:
                return path, table
    return None


def _table(path: Path, keys: tuple[str, ...]) -> dict[str, Any] | None:
    try:
        doc: Any = tomllib.loads(read_input_bytes(path, MAX_CONFIG_BYTES).decode("utf-8"))
    except (OSError, InputRefused, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"{path}: {exc}") from None
    for key in keys:
        if not isinstance(doc, dict) or key not in doc:
            return None
        doc = doc[key]
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: [{'.'.join(keys)}] must be a table")
    return doc


def load_config(start: Path, explicit: Path | None = None) -> LintConfig:
    if explicit is not None:
        keys = ("lint",) if explicit.name != "pyproject.toml" else ("tool", "mtlc", "lint")
        if not probe(explicit, Path.is_file):
            raise ConfigError(f"{explicit}: no such configuration file")
        table = _table(explicit, keys) or {}
        return parse_config(table, explicit)
    found = find_config(start.resolve())
    if found is None:
        return LintConfig()
    return parse_config(found[1], found[0])


def codes_of(value: Any, key: str, where: Path | None) -> set[str]:
    """Codes or rule names (`MT0603` or `joint-limit`), or prefixes such as `MT06`."""
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f"{where}: `{key}` must be a list of codes or rule names")
    by_name = {c.name: c.code for c in CODES.values()}
    out: set[str] = set()
    for item in value:
        item = item.strip()
        word = by_name.get(item, item.upper())
        matched = {c for c in CODES if c.startswith(word)} if word.startswith("MT") else set()
        if not matched:
            raise ConfigError(f"{where or 'command line'}: `{key}`: no rule or code {item!r}")
        out |= matched
    return out


def parse_config(table: dict[str, Any], where: Path | None = None) -> LintConfig:
    unknown = sorted(set(table) - set(_KEYS))
    if unknown:
        raise ConfigError(
            f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(_KEYS)}"
        )
    select = codes_of(table["select"], "select", where) if "select" in table else set(CODES)
    if "ignore" in table:
        select -= codes_of(table["ignore"], "ignore", where)
    manikins = table.get("manikins", "extremes")
    if not isinstance(manikins, str | list):
        raise ConfigError(f"{where}: `manikins` is 'extremes', 'all' or a list of POP:SEX:PCT")
    return LintConfig(
        select=frozenset(select),
        manikins=manikins,
        rula_threshold=int(_number(table, "rula-threshold", DEFAULT_RULA_THRESHOLD, 1, 7, where)),
        penetration_mm=_number(table, "penetration-mm", DEFAULT_PENETRATION_MM, 0, 1000, where),
        limit_deg=_number(table, "limit-deg", DEFAULT_LIMIT_DEG, 0, 180, where),
        view_cone_half_angle=_number(
            table, "view-cone-half-angle", DEFAULT_VIEW_CONE_DEG, 0, 180, where
        ),
        sustained_rula=int(_number(table, "sustained-rula", DEFAULT_SUSTAINED_RULA, 1, 7, where)),
        sustained_seconds=_number(
            table, "sustained-seconds", DEFAULT_SUSTAINED_SECONDS, 0, 86400, where
        ),
        lift_frequency=_number(table, "lift-frequency", niosh.DEFAULT_FREQUENCY, 0, 15, where),
        lift_duration=_choice(
            table, "lift-duration", niosh.DEFAULT_DURATION, niosh.DURATIONS, where
        ),
        lift_coupling=_choice(
            table, "lift-coupling", niosh.DEFAULT_COUPLING, niosh.COUPLINGS, where
        ),
        glove_mm=_number(table, "glove-mm", DEFAULT_GLOVE_MM, 0, 50, where),
        fail_on=_severity(table.get("fail-on", "warning"), where),
        source=where,
    )


def _number(
    table: dict[str, Any], key: str, default: float, lo: float, hi: float, where: Path | None
) -> float:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
        raise ConfigError(f"{where}: `{key}` must be a number from {lo:g} to {hi:g}")
    return float(value)


def _choice(
    table: dict[str, Any], key: str, default: str, allowed: tuple[str, ...], where: Path | None
) -> str:
    value = table.get(key, default)
    if value not in allowed:
        raise ConfigError(f"{where}: `{key}` is one of {', '.join(allowed)}")
    return str(value)


def _severity(value: Any, where: Path | None) -> Severity:
    try:
        return Severity(value)
    except ValueError:
        raise ConfigError(f"{where}: `fail-on` is error, warning or note") from None
