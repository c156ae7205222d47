"""The share of a population that reaches a site, from the manikins measured.

A manikin at percentile p stands for the people of its sex between the midpoints to its
tabulated neighbours (GB 10000-88: p1 for 0–3 %, p5 for 3–7.5 %, p10 for 7.5–30 %, p50 for
30–70 %, p90 for 70–92.5 %, p95 for 92.5–97 %, p99 for 97–100 %). A sex's share is the sum of
the intervals of the manikins that reach; nothing is interpolated between manikins and reach
is not assumed to grow with stature. When some percentiles were not measured the share is a
range: at least the intervals that reach, at most everything but the intervals that do not.
The sexes combine with a stated ratio (default 1:1). See docs/accessibility.md.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from mtlc.semantics import builtins as B


@dataclass(frozen=True)
class Share:
    """A fraction of people (0–1): exact when ``low == high``, else the range measurement
    leaves open (untested percentiles could go either way)."""

    low: float
    high: float

    @property
    def exact(self) -> bool:
        return abs(self.high - self.low) < 1e-12


def percentile_intervals(percentiles: tuple[int, ...]) -> dict[int, tuple[float, float]]:
    """Each tabulated percentile's interval (in %), halfway to its neighbours, 0 and 100 at
    the ends: the people a manikin at that percentile stands for."""
    ps = sorted(percentiles)
    cuts = [0.0, *((a + b) / 2 for a, b in itertools.pairwise(ps)), 100.0]
    return {p: (cuts[i], cuts[i + 1]) for i, p in enumerate(ps)}


def percentile_weights(population: str) -> dict[int, float]:
    """Each tabulated percentile's share of its sex (0–1); they add up to 1."""
    intervals = percentile_intervals(B.POPULATIONS[population])
    return {p: (hi - lo) / 100.0 for p, (lo, hi) in intervals.items()}


def sex_share(population: str, reached: dict[int, bool]) -> Share:
    """The share of one sex that reaches, from the percentiles measured (``reached``)."""
    weights = percentile_weights(population)
    yes = sum(weights[p] for p, ok in reached.items() if ok)
    no = sum(weights[p] for p, ok in reached.items() if not ok)
    return Share(yes, 1.0 - no)


def combined_share(shares: dict[str, Share], ratio: dict[str, float]) -> Share:
    """The sexes' shares weighted by ``ratio`` (e.g. {'male': 1, 'female': 1}); a sex with no
    manikin measured counts as unknown (0 to 1)."""
    total = sum(ratio.values())
    unknown = Share(0.0, 1.0)
    low = sum(w * shares.get(sex, unknown).low for sex, w in ratio.items()) / total
    high = sum(w * shares.get(sex, unknown).high for sex, w in ratio.items()) / total
    return Share(low, high)


def band(reached: dict[int, bool]) -> str:
    """Which measured percentiles reach, in words: a band when they are contiguous in
    percentile (so in stature), else the list; 'none' or 'all' at the ends."""
    ps = sorted(reached)
    yes = [p for p in ps if reached[p]]
    if not yes:
        return "none"
    if len(yes) == len(ps):
        return "all"
    first, last = ps.index(yes[0]), ps.index(yes[-1])
    if last - first + 1 != len(yes):
        return "not one band: " + ", ".join(f"p{p}" for p in yes)
    if first == 0:
        return f"up to p{yes[-1]}"
    if last == len(ps) - 1:
        return f"p{yes[0]} and up"
    return f"p{yes[0]}–p{yes[-1]}"
