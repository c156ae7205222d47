"""jackscript's key search answers the short spans for every frame at once (``_LineFit``) and
formats numbers without numpy scalars: the keys and the text must be those of the plain,
one-question-at-a-time search and of the plain formatting it replaced."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from mtlc.codegen.jackscript import _LineFit, key_indices, number, vector


def _fits_one_by_one(time: np.ndarray, values: np.ndarray, i: int, j: int) -> bool:
    if j - i < 2:
        return True
    weight = (time[i + 1 : j] - time[i]) / (time[j] - time[i])
    line = values[i] + weight[:, None] * (values[j] - values[i])
    return bool(np.max(np.abs(values[i + 1 : j] - line)) <= 1.0)


def _key_indices_one_by_one(time: np.ndarray, values: np.ndarray, marks: list[int]) -> list[int]:
    n = len(time)
    stops = sorted({0, n - 1, *(b for b in marks if 0 <= b < n)})
    keys = [0]
    for a, b in itertools.pairwise(stops):
        i = a
        while i < b:
            good, step, bad = i + 1, 1, b + 1
            while good < b:
                candidate = min(good + step, b)
                if not _fits_one_by_one(time, values, i, candidate):
                    bad = candidate
                    break
                good, step = candidate, step * 2
            while bad - good > 1:
                middle = (good + bad) // 2
                if _fits_one_by_one(time, values, i, middle):
                    good = middle
                else:
                    bad = middle
            i = good
            keys.append(i)
    return keys


def _curves(seed: int) -> list[tuple[np.ndarray, np.ndarray, list[int]]]:
    rng = np.random.default_rng(seed)
    cases = []
    for case in range(300):
        n = int(rng.integers(1, 300))
        m = int(rng.integers(1, 7))
        time = np.cumsum(rng.uniform(0.001, 0.1, n)) if case % 3 else np.arange(n) / 30.0
        values = np.cumsum(rng.normal(0, float(rng.choice([0.05, 0.4, 2.0, 20.0])), (n, m)), 0)
        if case % 5 == 0:
            values[rng.integers(0, n, 3)] += 10.0  # spikes
        if case % 7 == 0:
            values = np.round(values)  # lines that miss by exactly the tolerance
        marks = rng.integers(-2, n + 2, int(rng.integers(0, 6))).tolist()
        cases.append((time, values, marks))
    return cases


@pytest.mark.parametrize("seed", [0, 1])
def test_the_keys_are_those_of_the_one_by_one_search(seed: int) -> None:
    differing = 0
    for time, values, marks in _curves(seed):
        keys = key_indices(time, values, marks).tolist()
        assert keys == _key_indices_one_by_one(time, values, marks)
        differing += len(keys) not in (1, 2, len(time))  # the cases are not all trivial
    assert differing > 100


def test_every_precomputed_answer_is_the_one_by_one_answer() -> None:
    time, values, _ = _curves(3)[10]
    fit = _LineFit(time, values)
    for span in _LineFit.PRECOMPUTED:
        answers = [fit.fits(i, i + span) for i in range(len(time) - span)]
        assert answers == [_fits_one_by_one(time, values, i, i + span) for i in range(len(answers))]
        assert True in answers and False in answers


def _number_plainly(value: float, decimals: int) -> str:
    if not math.isfinite(value):
        raise ValueError(value)
    text = f"{value:.{decimals}f}"
    if float(text) == 0.0:
        text = f"{0.0:.{decimals}f}"
    if "." not in text:
        return f"{text}.0"
    text = text.rstrip("0")
    return f"{text}0" if text.endswith(".") else text


def test_numbers_and_vectors_are_written_as_plainly() -> None:
    rng = np.random.default_rng(5)
    values = [0.0, -0.0, -0.0004, -0.0005, 0.0005, 2.5, -9.9995, 1e300, 5e-324, 7, -3]
    values += (rng.standard_normal(3000) * 10.0 ** rng.integers(-8, 6, 3000)).tolist()
    for decimals in (0, 1, 3, 6):
        for value in values:
            assert number(value, decimals) == _number_plainly(value, decimals), (value, decimals)
        for row in zip(values, values[1:], values[2:], strict=False):
            plain = "(" + ", ".join(_number_plainly(v, decimals) for v in row) + ")"
            assert vector(row, decimals) == plain
            assert vector(np.array(row), decimals) == plain
    assert vector([4.5], 3) == "(4.5,)"
    for bad in ([1.0, float("nan")], np.array([float("inf")])):
        with pytest.raises(ValueError):
            vector(bad, 3)
