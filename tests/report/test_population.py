"""The population share from measured manikins: hand-computed examples and properties."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mtlc.report.population import (
    Share,
    band,
    combined_share,
    percentile_intervals,
    percentile_weights,
    sex_share,
)

GB = "gb10000_1988"
PCTS = (1, 5, 10, 50, 90, 95, 99)


def test_gb_intervals_are_halfway_to_the_neighbours() -> None:
    assert percentile_intervals(PCTS) == {
        1: (0.0, 3.0),
        5: (3.0, 7.5),
        10: (7.5, 30.0),
        50: (30.0, 70.0),
        90: (70.0, 92.5),
        95: (92.5, 97.0),
        99: (97.0, 100.0),
    }
    assert sum(percentile_weights(GB).values()) == pytest.approx(1.0)


def test_hand_computed_share() -> None:
    # women from p10 up reach: 22.5 + 40 + 22.5 + 4.5 + 3 = 92.5 %; every man reaches
    women = sex_share(GB, {p: p >= 10 for p in PCTS})
    men = sex_share(GB, dict.fromkeys(PCTS, True))
    assert (women.low, women.high) == pytest.approx((0.925, 0.925))
    assert men.exact and men.low == pytest.approx(1.0)
    both = combined_share({"male": men, "female": women}, {"male": 1, "female": 1})
    assert both.low == pytest.approx(0.9625) and both.exact
    mostly_men = combined_share({"male": men, "female": women}, {"male": 3, "female": 1})
    assert mostly_men.low == pytest.approx(0.98125)


def test_unmeasured_percentiles_leave_a_range() -> None:
    # only the 5th-percentile woman measured, and she reaches: at least her 4.5 %, at most all
    assert sex_share(GB, {5: True}) == Share(pytest.approx(0.045), pytest.approx(1.0))
    # she does not reach: at most the 95.5 % she does not stand for
    assert sex_share(GB, {5: False}) == Share(0.0, pytest.approx(0.955))
    # no woman measured at all: the combined share is open on her side
    men = Share(1.0, 1.0)
    assert combined_share({"male": men}, {"male": 1, "female": 1}) == Share(0.5, 1.0)


def test_band_words() -> None:
    assert band({p: p >= 90 for p in PCTS}) == "p90 and up"
    assert band({p: p <= 10 for p in PCTS}) == "up to p10"
    assert band({p: 10 <= p <= 90 for p in PCTS}) == "p10–p90"
    assert band({p: p in (5, 50) for p in PCTS}) == "not one band: p5, p50"
    assert band(dict.fromkeys(PCTS, False)) == "none"
    assert band(dict.fromkeys(PCTS, True)) == "all"


reach_maps = st.fixed_dictionaries({p: st.booleans() for p in PCTS})


@given(reach_maps)
def test_full_measurement_is_exact_and_complementary(reached: dict[int, bool]) -> None:
    yes = sex_share(GB, reached)
    no = sex_share(GB, {p: not ok for p, ok in reached.items()})
    assert yes.exact and 0.0 <= yes.low <= 1.0 + 1e-12
    assert yes.low + no.low == pytest.approx(1.0)


@given(reach_maps, st.sets(st.sampled_from(PCTS)))
def test_a_partial_measurement_brackets_the_full_one(
    reached: dict[int, bool], measured: set[int]
) -> None:
    full = sex_share(GB, reached)
    part = sex_share(GB, {p: reached[p] for p in measured})
    assert part.low <= full.low + 1e-12 and full.high <= part.high + 1e-12


@given(
    st.floats(0, 1),
    st.floats(0, 1),
    st.floats(0, 10, allow_subnormal=False),
    st.floats(0.01, 10),
)
def test_combined_share_lies_between_the_sexes(f: float, m: float, wm: float, wf: float) -> None:
    both = combined_share({"female": Share(f, f), "male": Share(m, m)}, {"male": wm, "female": wf})
    assert min(f, m) - 1e-12 <= both.low <= max(f, m) + 1e-12
