"""Capsule-to-mesh distance (mtlc.geometry.distance): the collision library against the numpy
brute force on random capsules and meshes, and cases whose answer is known by hand."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.geometry.distance import (
    MeshIndex,
    brute_force_distance,
    capsule_clearance,
    point_triangle_distance,
    segment_triangle_distance,
)

# python-fcl is the comparison's (bench extras): tested when installed
LIBRARIES = ("coal", "fcl") if importlib.util.find_spec("fcl") else ("coal",)


def plate_with_hole(
    outer: float = 0.3, hole: float = 0.05, z: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """A flat square plate (half side ``outer``) in the plane z with a square hole (half side
    ``hole``) through its centre: 8 vertices, 8 triangles (one side of it: a sheet)."""
    o, h = outer, hole
    v = np.array(
        [[-o, -o], [o, -o], [o, o], [-o, o], [-h, -h], [h, -h], [h, h], [-h, h]], dtype=float
    )
    v = np.column_stack([v, np.full(8, z)])
    f = []
    for i in range(4):
        j = (i + 1) % 4
        f += [[i, j, 4 + j], [i, 4 + j, 4 + i]]
    return v, np.array(f, dtype=np.int64)


def random_mesh(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    centres = rng.uniform(-0.5, 0.5, size=(n, 1, 3))
    v = (centres + rng.normal(scale=0.15, size=(n, 3, 3))).reshape(-1, 3)
    return v, np.arange(3 * n, dtype=np.int64).reshape(n, 3)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_tri=st.integers(1, 60), n_seg=st.integers(1, 30))
def test_library_matches_brute_force_on_random_meshes(seed: int, n_tri: int, n_seg: int) -> None:
    rng = np.random.default_rng(seed)
    mesh = random_mesh(rng, n_tri)
    a = rng.uniform(-0.8, 0.8, size=(n_seg, 3))
    b = a + rng.normal(scale=0.2, size=(n_seg, 3))
    truth = brute_force_distance(a, b, mesh)
    for lib in LIBRARIES:
        got = MeshIndex(*mesh, library=lib).segment_distance(a, b)
        np.testing.assert_allclose(got, truth, atol=1e-6, err_msg=lib)


def test_point_triangle_regions() -> None:
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    points = np.array([[0.2, 0.2, 0.5], [2.0, 0, 0], [0.5, -1, 0], [-1, -1, 1]])
    expected = [0.5, 1.0, 1.0, np.sqrt(3.0)]  # over the face, past a vertex, an edge, a vertex
    np.testing.assert_allclose(point_triangle_distance(points, tri[None]), expected)


def test_segment_through_a_triangle_touches_it() -> None:
    tri = np.array([[[-1.0, -1, 0], [1, -1, 0], [0, 1, 0]]])
    assert segment_triangle_distance(np.array([0, 0, -1.0]), np.array([0, 0, 1.0]), tri) == 0.0
    # the same segment stopped 3 cm short of the face
    d = segment_triangle_distance(np.array([0, 0, -1.0]), np.array([0, 0, -0.03]), tri)
    assert d == pytest.approx(0.03)


@pytest.mark.parametrize("lib", LIBRARIES)
def test_capsule_through_the_hole_clears_the_plate(lib: str) -> None:
    plate = plate_with_hole(hole=0.05)
    # a 2 cm capsule straight through the middle of a 10 cm hole: 5 cm from the hole's edges
    c, names = capsule_clearance(
        np.array([[0.0, 0, -0.2]]), np.array([[0.0, 0, 0.2]]), 0.02, {"plate": plate}, lib
    )
    assert names == ("plate",)
    assert c[0, 0] == pytest.approx(0.05 - 0.02, abs=1e-9)
    # off centre by 4 cm: 1 cm from the edge, the 2 cm radius 1 cm into the plate's rim
    c, _ = capsule_clearance(
        np.array([[0.04, 0, -0.2]]), np.array([[0.04, 0, 0.2]]), 0.02, {"plate": plate}, lib
    )
    assert c[0, 0] == pytest.approx(-0.01, abs=1e-9)


@pytest.mark.parametrize("lib", LIBRARIES)
def test_capsule_into_the_plate_penetrates_by_its_depth(lib: str) -> None:
    plate = plate_with_hole(hole=0.05)
    # a capsule lying over the solid part of the plate, its axis 1.5 cm above: 3 cm radius is
    # 1.5 cm into it; 5 cm above it is 2 cm clear
    for height, expected in ((0.015, -0.015), (0.05, 0.02)):
        a, b = np.array([[0.1, -0.2, height]]), np.array([[0.1, 0.2, height]])
        c, _ = capsule_clearance(a, b, 0.03, {"plate": plate}, lib)
        assert c[0, 0] == pytest.approx(expected, abs=1e-9)
    # the axis through the solid plate: the whole radius is in
    c, _ = capsule_clearance(
        np.array([[0.2, 0, -0.1]]), np.array([[0.2, 0, 0.1]]), 0.03, {"plate": plate}, lib
    )
    assert c[0, 0] == pytest.approx(-0.03, abs=1e-9)


def test_horizon_gives_a_lower_bound_and_keeps_near_answers_exact() -> None:
    rng = np.random.default_rng(3)
    mesh = random_mesh(rng, 40)
    a = rng.uniform(-2.0, 2.0, size=(200, 3))
    b = a + rng.normal(scale=0.1, size=(200, 3))
    index = MeshIndex(*mesh)
    exact = index.segment_distance(a, b)
    bounded = index.segment_distance(a, b, horizon=0.2)
    near = exact <= 0.2
    assert near.any() and (~near).any()
    np.testing.assert_allclose(bounded[near], exact[near], atol=1e-12)
    assert np.all(bounded[~near] <= exact[~near] + 1e-12)
    assert np.all(bounded[~near] > 0.2)


def test_capsule_clearance_batches_frames_and_capsules() -> None:
    plate = plate_with_hole()
    a = np.zeros((5, 4, 3))
    a[..., 2] = np.linspace(0.1, 0.5, 20).reshape(5, 4)  # axes standing over the plate's rim
    a[..., 0] = 0.2
    b = a + np.array([0.0, 0.0, 0.1])
    c, _ = capsule_clearance(a, b, np.full(4, 0.01), {"plate": plate, "other": plate})
    assert c.shape == (5, 4, 2)
    np.testing.assert_allclose(c[..., 0], a[..., 2] - 0.01, atol=1e-9)
    np.testing.assert_allclose(c[..., 0], c[..., 1])


def test_empty_mesh_is_infinitely_far() -> None:
    empty = (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
    assert np.isinf(MeshIndex(*empty).segment_distance(np.zeros(3), np.ones(3))).all()
    assert np.isinf(brute_force_distance(np.zeros(3), np.ones(3), empty)).all()
