"""A held part's placement per frame (mtlc.geometry.held), on synthetic hand frames: it slides
with the grip point while the hand turns in place, turns with the hand once taken out, goes
with the other hand when the first lets go, and stays where it is let go."""

from __future__ import annotations

import numpy as np

from mtlc.geometry.held import TAKEN_OUT, Hold, _placements


def _frames(positions: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(N, 4, 4) hand frames at ``positions`` turned by ``angles`` about +Y."""
    out = np.zeros((len(positions), 4, 4))
    c, s = np.cos(angles), np.sin(angles)
    out[:, 0, 0], out[:, 0, 2], out[:, 2, 0], out[:, 2, 2] = c, s, -s, c
    out[:, 1, 1] = out[:, 3, 3] = 1.0
    out[:, :3, 3] = positions
    return out


def _hold(side: str, start: float, end: float, at: np.ndarray) -> Hold:
    return Hold(side, start, end, None, at)  # type: ignore[arg-type]


def test_a_turn_in_place_does_not_turn_the_part_and_a_lift_carries_it() -> None:
    t = np.linspace(0.0, 3.0, 31)
    grip = np.zeros((31, 3))
    grip[20:, 1] = np.linspace(0.0, 0.3, 11)  # lifted 30 cm over the last second
    angle = np.where(t < 1.0, 0.0, np.minimum(t - 1.0, 1.0) * np.pi / 2)  # a quarter turn
    hands = {"r": _frames(grip, angle), "l": _frames(grip + 5.0, angle)}
    place, kept = _placements(t, hands, [_hold("r", 0.0, 2.5, np.zeros(3))])
    assert len(kept) == 1
    # turned in place: the part has not turned (its rotation is the identity)
    assert np.allclose(place[19, :3, :3], np.eye(3))
    # lifted: the grasped point stays at the grip point, and once taken out it turns with
    # the hand (the hand's own turn is over by then: no further rotation)
    for i in (22, 25):
        assert np.allclose(place[i, :3, 3] + place[i, :3, :3] @ np.zeros(3), grip[i])
    assert np.allclose(place[25, :3, :3], np.eye(3))
    # let go at 2.5 s: it stays where it was
    assert np.allclose(place[-1], place[25])
    assert TAKEN_OUT < 0.3


def test_two_hands_then_the_second_alone_and_a_far_hand_holds_nothing() -> None:
    t = np.linspace(0.0, 2.0, 21)
    right = np.zeros((21, 3))
    right[:, 0] = np.linspace(0.0, 1.0, 21)  # the right hand walks off along +X
    left = right + np.array([0.0, 0.0, 0.2])
    left[11:] = left[10]  # the left hand stops at 1 s
    hands = {"r": _frames(right, np.zeros(21)), "l": _frames(left, np.zeros(21))}
    holds = [_hold("r", 0.0, 1.0, np.zeros(3)), _hold("l", 0.0, 2.0, np.array([0.0, 0.0, 0.2]))]
    place, kept = _placements(t, hands, holds)
    assert len(kept) == 2
    # with the right hand (first on a tie) until it lets go at 1 s, then with the left
    assert np.allclose(place[8, :3, 3], right[8])
    assert np.allclose(place[15], place[10])  # the left hand stands still: so does the part
    # a hand 30 cm from its grasp point at the grip's start holds nothing
    far = [_hold("r", 0.0, 2.0, np.array([0.0, 0.3, 0.0]))]
    place, kept = _placements(t, hands, far)
    assert kept == [] and np.allclose(place, np.eye(4))
