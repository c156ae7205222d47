"""The collector pause of the parser, the front end and fmt: off inside, back as it was after."""

from __future__ import annotations

import gc
import weakref

import pytest

from mtlc.syntax.gcpause import no_collections


def test_collection_is_paused_inside_and_restored_after() -> None:
    assert gc.isenabled()
    with no_collections():
        assert not gc.isenabled()
        with no_collections():  # nested: only the outermost turns it back on
            assert not gc.isenabled()
        assert not gc.isenabled()
    assert gc.isenabled()


def test_restored_after_an_error_and_left_off_if_it_was_off() -> None:
    with pytest.raises(RuntimeError), no_collections():
        raise RuntimeError("boom")
    assert gc.isenabled()
    gc.disable()
    try:
        with no_collections():
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()


class _Node:
    pass


def test_the_pauses_objects_leave_it_aged_and_its_cycles_are_still_collected() -> None:
    """Issue 21: the objects made during the pause go to the oldest generation when it ends,
    instead of all waiting for one young collection to walk them (0.1 s after a 20,000-line
    check); a cycle made during the pause is still garbage to the next full collection."""
    with no_collections():
        kept = [_Node() for _ in range(5_000)]
        looped = _Node()
        looped.me = looped  # type: ignore[attr-defined]
        probe = weakref.ref(looped)
        del looped
    assert gc.get_count()[0] < 700, gc.get_count()  # no young collection pending
    assert probe() is not None  # nothing collected it on the way out
    gc.collect()
    assert probe() is None
    assert len(kept) == 5_000


def test_objects_frozen_by_someone_else_stay_frozen() -> None:
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        assert frozen > 0
        with no_collections():
            made = [_Node() for _ in range(100)]
        assert gc.get_freeze_count() == frozen
        assert len(made) == 100
    finally:
        gc.unfreeze()
