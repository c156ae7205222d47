"""Which manikins lint checks: `--manikins extremes|all|POP:SEX:PCT,...`."""

from __future__ import annotations

from mtlc.semantics import builtins as B
from mtlc.semantics.timeline import ManikinSpec

SWEEP_POPULATION = "gb10000_1988"
# the range's extremes: the smallest woman and the largest man a design usually must fit
EXTREMES = (ManikinSpec(SWEEP_POPULATION, "female", 5), ManikinSpec(SWEEP_POPULATION, "male", 95))


class ManikinError(ValueError):
    """A selection that names no known manikin (a usage error)."""


def label(spec: ManikinSpec) -> str:
    return f"{spec.population}:{spec.sex}:{spec.percentile}"


def all_manikins(population: str = SWEEP_POPULATION) -> tuple[ManikinSpec, ...]:
    """Every tabulated manikin of a population: both sexes, every percentile (14 for GB)."""
    return tuple(ManikinSpec(population, s, p) for s in B.SEXES for p in B.POPULATIONS[population])


def parse_one(text: str) -> ManikinSpec:
    parts = text.strip().split(":")
    if len(parts) != 3:
        raise ManikinError(
            f"{text!r}: expected POPULATION:SEX:PERCENTILE, e.g. gb10000_1988:female:5"
        )
    pop, sex, pct = parts
    if pop not in B.POPULATIONS:
        raise ManikinError(f"{text!r}: unknown population; one of {', '.join(B.POPULATIONS)}")
    if sex not in B.SEXES:
        raise ManikinError(f"{text!r}: sex is male or female")
    pct = pct.removeprefix("p")
    if not pct.isdigit() or int(pct) not in B.POPULATIONS[pop]:
        allowed = ", ".join(str(p) for p in B.POPULATIONS[pop])
        raise ManikinError(f"{text!r}: percentile must be one of {allowed}")
    return ManikinSpec(pop, sex, int(pct))


def parse_selection(text: str | list[str]) -> tuple[ManikinSpec, ...]:
    """'extremes', 'all', or a comma-separated list (or a list from the configuration)."""
    items = text if isinstance(text, list) else text.split(",")
    out: list[ManikinSpec] = []
    for item in items:
        word = item.strip()
        if word == "all":
            found: tuple[ManikinSpec, ...] = all_manikins()
        elif word == "extremes":
            found = EXTREMES
        elif word:
            found = (parse_one(word),)
        else:
            continue
        out.extend(m for m in found if m not in out)
    if not out:
        raise ManikinError("no manikin selected")
    return tuple(out)
