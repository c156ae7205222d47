"""Manikins: table dimensions reproduced by forward kinematics, limits, masses, naming."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from mtlc.body import (
    JOINT_TABLE,
    PERCENTILES,
    build_manikin,
    center_of_mass,
    citation,
    dimensions,
    forward,
    site_positions,
)
from mtlc.body.anthropometry import measure
from mtlc.body.skeleton import data_citations

ALL = [(s, p) for s in ("male", "female") for p in PERCENTILES]


def _neutral(sk):  # type: ignore[no-untyped-def]
    return forward(sk, np.zeros(sk.n_dofs))


@pytest.mark.parametrize(("sex", "pct"), ALL)
def test_gb_manikin_matches_stature_shoulder_elbow_within_2_percent(sex: str, pct: int) -> None:
    sk = build_manikin("gb10000_1988", sex, pct)
    pose = _neutral(sk)
    vertex = site_positions(sk, pose, "vertex")[1]
    acromion = site_positions(sk, pose, ["r_acromion", "l_acromion"])[:, 1]
    elbow = pose.p[[sk.joint_index("r_elbow"), sk.joint_index("l_elbow")], 1]
    for got, name in ((vertex, "stature"), (acromion, "shoulder_height"), (elbow, "elbow_height")):
        want = measure("gb10000_1988", sex, pct, name) / 1000
        np.testing.assert_allclose(got, want, rtol=0.02, err_msg=name)
    # Soles on the ground at the neutral root position.
    soles = site_positions(sk, pose, ["r_heel", "r_toe", "l_heel", "l_toe"])[:, 1]
    np.testing.assert_allclose(soles, 0.0, atol=1e-9)


@pytest.mark.parametrize(("sex", "pct"), ALL)
def test_ansur_manikin_is_sensible(sex: str, pct: int) -> None:
    sk = build_manikin("ansur2", sex, pct)
    pose = _neutral(sk)
    h = measure("ansur2", sex, pct, "stature") / 1000
    np.testing.assert_allclose(site_positions(sk, pose, "vertex")[1], h, rtol=0.02)
    acr = measure("ansur2", sex, pct, "acromial_height(shoulder)") / 1000
    np.testing.assert_allclose(site_positions(sk, pose, "r_acromion")[1], acr, rtol=0.02)
    # Elbow and knee heights near the Drillis-Contini stature fractions (0.630, 0.285).
    elbow = pose.p[sk.joint_index("r_elbow"), 1] / h
    knee = pose.p[sk.joint_index("r_knee"), 1] / h
    assert 0.60 < elbow < 0.66
    assert 0.25 < knee < 0.30
    com = center_of_mass(sk, pose)[1] / h
    assert 0.52 < com < 0.59  # standing CoM ~0.55 H
    assert math.isclose(sk.total_mass, measure("ansur2", sex, pct, "weight_kg"), rel_tol=1e-9)


def test_dimensions_grow_with_percentile() -> None:
    for pop in ("gb10000_1988", "ansur2"):
        for sex in ("male", "female"):
            st = [dimensions(pop, sex, p).stature for p in PERCENTILES]
            sh = [dimensions(pop, sex, p).shoulder_height for p in PERCENTILES]
            assert st == sorted(st) and sh == sorted(sh)


def test_dof_count_and_required_joints() -> None:
    sk = build_manikin()
    assert sk.n_dofs >= 34
    per_joint = {j.name: len(j.dofs) for j in sk.joints}
    assert per_joint["lumbar"] + per_joint["thorax"] >= 3
    assert per_joint["neck"] >= 1 and per_joint["head"] >= 1
    for s in ("r", "l"):
        assert per_joint[f"{s}_clavicle"] >= 1
        assert per_joint[f"{s}_shoulder"] == 3
        assert per_joint[f"{s}_elbow"] == 2  # flexion + forearm rotation
        assert per_joint[f"{s}_wrist"] == 2
        assert per_joint[f"{s}_hip"] == 3
        assert per_joint[f"{s}_knee"] == 1
        assert per_joint[f"{s}_ankle"] == 2
    assert [j.name for j in sk.joints] == [n for n, _, _ in JOINT_TABLE]
    assert len(set(sk.dof_names)) == sk.n_dofs


def test_limits_come_from_the_table() -> None:
    sk = build_manikin()
    deg = {
        n: (math.degrees(sk.lower[i]), math.degrees(sk.upper[i]))
        for i, n in enumerate(sk.dof_names)
    }
    assert deg["r_shoulder_flex"] == pytest.approx((-60, 180))
    assert deg["l_shoulder_abd"] == pytest.approx((-45, 180))
    assert deg["r_shoulder_rot"] == pytest.approx((-90, 70))
    assert deg["r_elbow_flex"] == pytest.approx((0, 150))
    assert deg["r_elbow_pro"] == pytest.approx((-80, 80))
    assert deg["r_wrist_flex"] == pytest.approx((-70, 80))
    assert deg["r_wrist_dev"] == pytest.approx((-30, 20))
    assert deg["r_hip_flex"] == pytest.approx((-15, 125))
    assert deg["r_knee_flex"] == pytest.approx((0, 135))
    assert deg["l_ankle_dorsi"] == pytest.approx((-50, 20))
    # Spine and neck splits add up to the whole-range table values.
    assert deg["neck_flex"][1] + deg["head_flex"][1] == pytest.approx(50)
    assert deg["neck_flex"][0] + deg["head_flex"][0] == pytest.approx(-80)
    assert deg["lumbar_rot"][1] + deg["thorax_rot"][1] == pytest.approx(45)
    assert np.all(sk.lower < sk.upper)
    assert np.all(sk.within_limits(sk.q_comfort))


@pytest.mark.parametrize("sex", ["male", "female"])
def test_masses_follow_de_leva_and_sum_to_body_mass(sex: str) -> None:
    sk = build_manikin("gb10000_1988", sex, 50)
    body = measure("gb10000_1988", sex, 50, "weight_kg")
    assert sk.total_mass == pytest.approx(body, rel=1e-3)
    m = {j.name: j.mass for j in sk.joints}
    thigh = {"male": 0.1416, "female": 0.1478}[sex]
    assert m["r_hip"] == pytest.approx(thigh * body, rel=1e-3)
    assert m["l_hip"] == pytest.approx(m["r_hip"])
    assert m["r_clavicle"] == 0 and m["neck"] == 0


def test_left_is_the_mirror_of_the_right() -> None:
    sk = build_manikin("gb10000_1988", "female", 95)
    rng = np.random.default_rng(3)
    q = sk.random_q(rng, 20)
    # Mirror the configuration: swap sides; axial lateral flexion and rotation change sign.
    qm = q.copy()
    for i, n in enumerate(sk.dof_names):
        if n.startswith(("r_", "l_")):
            other = ("l_" if n[0] == "r" else "r_") + n[2:]
            qm[:, i] = q[:, sk.dof_index(other)]
        elif n.endswith(("_lat", "_rot")):
            qm[:, i] = -q[:, i]
    inside = sk.within_limits(qm)
    a, b = forward(sk, q[inside]), forward(sk, qm[inside])
    for side in ("hand", "foot", "heel", "toe"):
        pr = site_positions(sk, a, f"r_{side}")
        pl = site_positions(sk, b, f"l_{side}")
        np.testing.assert_allclose(pl * [-1, 1, 1], pr, atol=1e-12)
    assert inside.sum() >= 5


def test_serialised_manikin_recomputes_the_same_positions() -> None:
    """An independent few-line FK from the JSON (IR.md's rule) agrees with forward()."""
    sk = build_manikin("gb10000_1988", "male", 95)
    data = json.loads(json.dumps(sk.to_dict()))
    rng = np.random.default_rng(7)
    q = sk.random_q(rng, 1)[0]
    root_p = np.array([0.3, 0.9, -0.2])
    quat = np.array([0.9, 0.1, -0.3, 0.2])
    quat /= np.linalg.norm(quat)

    def rot(axis: list[float], ang: float) -> np.ndarray:
        x, y, z = np.asarray(axis) / np.linalg.norm(axis)
        c, s, t = math.cos(ang), math.sin(ang), 1 - math.cos(ang)
        return np.array(
            [
                [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
            ]
        )

    w, x, y, z = quat
    root_R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    qmap = dict(zip(sk.dof_names, q, strict=True))
    world: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for j in data["joints"]:
        if j["parent"] is None:
            R, p = root_R, root_p + root_R @ np.array(j["offset"])
        else:
            PR, pp = world[j["parent"]]
            R, p = PR, pp + PR @ np.array(j["offset"])
        for d in j["dofs"]:
            R = R @ rot(d["axis"], qmap[d["name"]])
        world[j["name"]] = (R, p)
    pose = forward(sk, q, root_p, quat)
    for e in data["effectors"] + data["contact_points"]:
        R, p = world[e["joint"]]
        np.testing.assert_allclose(
            p + R @ np.array(e["offset"]), site_positions(sk, pose, e["name"]), atol=2e-6
        )
    assert data["population"] == "gb10000_1988" and data["percentile"] == 95


def test_citations_are_carried() -> None:
    cites = data_citations()
    assert "GB 10000-88" in cites["gb10000_1988"]
    assert "Gordon" in cites["ansur2"]
    assert "de Leva" in cites["segment_mass"]
    assert "Norkin" in cites["joint_limits"]
    assert "Drillis" in citation("drillis_contini")


def test_unknown_inputs_are_refused_with_a_reason() -> None:
    with pytest.raises(ValueError, match="percentile"):
        build_manikin("gb10000_1988", "male", 42)
    with pytest.raises(ValueError, match="population"):
        build_manikin("nhanes", "male", 50)
    sk = build_manikin()
    with pytest.raises(KeyError, match="known"):
        sk.site("r_elbow_tip")
