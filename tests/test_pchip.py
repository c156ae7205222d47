"""mtlc.ir.pchip and the pace pass's Gaussian against scipy's PchipInterpolator,
CubicHermiteSpline and gaussian_filter1d (issue 21): compiles load no scipy, same numbers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator

from mtlc.ir.pchip import hermite, pchip, pchip_slopes

values = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@st.composite
def knots(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Increasing times (some gaps tiny, some repeated values: flat runs, turns), values of one
    or three columns, and times to evaluate at, knots and outside included."""
    n = draw(st.integers(2, 12))
    gaps = draw(st.lists(st.floats(1e-6, 5.0), min_size=n - 1, max_size=n - 1))
    x = np.concatenate([[draw(st.floats(-10, 10))], np.cumsum(gaps)])
    x = x[0] + np.concatenate([[0.0], np.cumsum(gaps)])
    cols = draw(st.sampled_from([None, 1, 3]))
    shape = (n,) if cols is None else (n, cols)
    pool = draw(st.lists(values, min_size=1, max_size=4))  # few distinct values: flat runs
    y = np.array(draw(st.lists(st.sampled_from(pool) | values, min_size=int(np.prod(shape)),
                                max_size=int(np.prod(shape))))).reshape(shape)  # fmt: skip
    inside = draw(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20))
    t = np.concatenate([x, x[0] + (x[-1] - x[0]) * np.asarray(inside), [x[0] - 1.0, x[-1] + 1.0]])
    return x, y, t


def close(a: np.ndarray, b: np.ndarray) -> bool:
    scale = max(1.0, float(np.nanmax(np.abs(b))) if np.isfinite(b).any() else 1.0)
    return bool(np.allclose(a, b, rtol=0.0, atol=1e-12 * scale, equal_nan=True))


@settings(max_examples=300, deadline=None)
@given(knots())
def test_pchip_is_scipys(case: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    x, y, t = case
    for extrapolate in (True, False):
        ours = pchip(x, y, extrapolate=extrapolate)(t)
        theirs = PchipInterpolator(x, y, axis=0, extrapolate=extrapolate)(t)
        assert ours.shape == theirs.shape
        assert close(ours, theirs)
    theirs_slopes = PchipInterpolator(x, y, axis=0).derivative()(x[:-1])
    assert close(pchip_slopes(x, y)[:-1], theirs_slopes)


@settings(max_examples=200, deadline=None)
@given(knots(), st.data())
def test_hermite_is_scipys(case: tuple[np.ndarray, np.ndarray, np.ndarray], data) -> None:
    x, y, t = case
    dydx = np.array(data.draw(st.lists(values, min_size=y.size, max_size=y.size))).reshape(y.shape)
    assert close(hermite(x, y, dydx)(t), CubicHermiteSpline(x, y, dydx, axis=0)(t))


def test_knots_are_hit_exactly_and_the_curve_does_not_overshoot() -> None:
    x = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    y = np.array([0.0, 1.0, 1.0, 3.0, 2.0])
    curve = pchip(x, y)
    assert np.array_equal(curve(x), y)
    dense = curve(np.linspace(0, 4, 401))
    assert dense.min() >= 0.0 and dense.max() <= 3.0
    assert np.all(np.diff(dense[100:201]) == 0.0)  # flat between the two equal keys


def test_bad_knots_are_refused() -> None:
    with pytest.raises(ValueError):
        pchip([0.0, 0.0, 1.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError):
        pchip([0.0], [1.0])


@settings(max_examples=150, deadline=None)
@given(
    n=st.integers(3, 120),
    cols=st.integers(1, 6),
    sigma=st.floats(0.05, 40.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_pace_pass_gaussian_is_scipys(n: int, cols: int, sigma: float, seed: int) -> None:
    """passes.pace.gaussian_rows sums in scipy's order: the same numbers, to the bit."""
    from scipy.ndimage import gaussian_filter1d

    from mtlc.passes.pace import gaussian_rows

    x = np.random.default_rng(seed).normal(size=(n, cols)) * 10.0
    ours = gaussian_rows(x, sigma)
    assert np.array_equal(ours, gaussian_filter1d(x, sigma, axis=0, mode="nearest"))
