"""The collector pause of the parser, the front end and fmt: off inside, back as it was after."""

from __future__ import annotations

import gc

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
