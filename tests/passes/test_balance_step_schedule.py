"""The pelvis step schedule of the balance pass: the retries it skips are the ones that lose.

A toy stands in for the contact solve: a row moving its pelvis by ``s`` loses its contacts by
``k · max(s − slack, 0)`` (a joint ``slack`` from its limit), and a row that keeps them moves
on by the step it took. The schedule with its early stops is run beside the plain halving loop
it replaces (``MAX_STEP`` halved after every loss until under ``MIN_STEP``).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.passes.balance import MAX_STEP, MIN_STEP, POSITION_TOL, ROUNDS, StepSchedule


def contact_error(k: np.ndarray, slack: np.ndarray, size: np.ndarray) -> np.ndarray:
    return k * np.maximum(size - slack, 0.0)


def plain_halving(k, slack, need):  # type: ignore[no-untyped-def]
    """The loop before the schedule: (distance moved, solves) per row."""
    need, moved = need.copy(), np.zeros(len(need))
    cap, solves = np.full(len(need), MAX_STEP), np.zeros(len(need), dtype=int)
    active = np.arange(len(need))
    for _ in range(ROUNDS):
        active = active[need[active] > 1e-9]
        if active.size == 0:
            break
        want = need[active]
        size = want * np.minimum(1.0, cap[active] / np.maximum(want, 1e-12))
        solves[active] += 1
        lost = contact_error(k[active], slack[active], size) > POSITION_TOL
        kept = active[~lost]
        moved[kept] += size[~lost]
        need[kept] -= size[~lost]
        cap[active[lost]] /= 2
        active = active[cap[active] >= MIN_STEP]
    return moved, solves


def scheduled(k, slack, need):  # type: ignore[no-untyped-def]
    """The same toy through ``StepSchedule``: (distance moved, solves) per row."""
    need, moved = need.copy(), np.zeros(len(need))
    schedule, solves = StepSchedule(len(need)), np.zeros(len(need), dtype=int)
    active = np.arange(len(need))
    for _ in range(ROUNDS):
        active = active[need[active] > 1e-9]
        if active.size == 0:
            break
        awake = schedule.awake(active)
        trying = active[awake]
        step = schedule.steps(trying, np.stack([need[trying], np.zeros(trying.size)], axis=1))
        size = step[:, 0]
        solves[trying] += 1
        error = contact_error(k[trying], slack[trying], size)
        lost = error > POSITION_TOL
        kept = trying[~lost]
        moved[kept] += size[~lost]
        need[kept] -= size[~lost]
        retrying = schedule.update(trying, lost, np.zeros(trying.size, dtype=bool), error)
        active = np.sort(np.concatenate([active[~awake], retrying]))
    return moved, solves


def test_a_retry_that_would_repeat_the_lost_step_is_not_solved() -> None:
    # row 0 asked for 3 mm (under every cap) and lost its contacts: each retry is the same
    # solve; row 1 asked for 20 mm and lost at 20 and at 12.5, 7 mm from its limit: the retry
    # at the cap of 25 mm repeats the 20 mm step, the ones at 6.25 mm keep the contacts
    k, slack, need = np.array([0.52, 0.52]), np.array([0.0, 0.007]), np.array([0.003, 0.02])
    moved, solves = scheduled(k, slack, need)
    ref_moved, ref_solves = plain_halving(k, slack, need)
    assert ref_solves.tolist() == [4, 6]
    assert solves.tolist() == [1, 5]
    assert moved.tolist() == ref_moved.tolist()
    assert moved[0] == 0.0 and moved[1] == pytest.approx(0.01875)


def test_a_row_at_its_limit_stops_after_two_losses_and_a_row_with_slack_still_moves() -> None:
    # row 0: at its ankle's limit (#4034: 26 mm of error for a 50 mm step), it loses every
    # retry; row 1: 5 mm from its limit, it keeps its contacts once the step is 6.25 mm
    k, slack, need = np.array([0.52, 0.52]), np.array([0.0, 0.005]), np.array([0.2, 0.2])
    moved, solves = scheduled(k, slack, need)
    ref_moved, ref_solves = plain_halving(k, slack, need)
    assert ref_solves.tolist() == [4, 6]
    assert solves.tolist() == [2, 6]
    assert moved.tolist() == ref_moved.tolist()
    assert moved[0] == 0.0 and moved[1] == pytest.approx(3 * 0.00625)


@settings(max_examples=200, deadline=None)
@given(
    k=st.lists(st.floats(0.0, 2.0), min_size=1, max_size=8),
    slack=st.lists(st.floats(0.0, 0.06), min_size=8, max_size=8),
    need=st.lists(st.floats(0.0, 0.3), min_size=8, max_size=8),
)
def test_the_schedule_moves_every_row_as_the_plain_loop_did(k, slack, need) -> None:  # type: ignore[no-untyped-def]
    """A convex error (a joint's slack, then linear): skipping changes no row's result."""
    n = len(k)
    args = np.array(k), np.array(slack[:n]), np.array(need[:n])
    moved, solves = scheduled(*args)
    ref_moved, ref_solves = plain_halving(*args)
    np.testing.assert_array_equal(moved, ref_moved)
    assert (solves <= ref_solves).all()
