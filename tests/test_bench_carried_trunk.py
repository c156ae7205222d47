"""bench/human.py's carried-walk trunk figure (issue 19: "a carried load is held near the body
while walking"), on a made-up IR: the lean in the middle of a walk that starts with a hand
closed on a part, and no figure for a walk with both hands open."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("mtlc_bench_human", ROOT / "bench" / "human.py")
assert _spec is not None and _spec.loader is not None
human = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(human)


def _doc(state: str, lean_deg: float) -> tuple[dict[str, Any], np.ndarray]:
    time = np.arange(0.0, 6.0, 1 / 30)
    q = np.zeros((len(time), 3))
    walking = (time >= 2.0) & (time <= 5.0)
    q[walking, 0] = math.radians(lean_deg) * 0.75  # lumbar
    q[walking, 1] = math.radians(lean_deg) * 0.25  # thorax
    segments = [
        {"track": "r_hand", "kind": "grip", "t_start": 1.0, "t_end": 1.1,
         "goal": {"params": {"state": state}}},
        {"track": "root", "kind": "locomotion", "t_start": 2.0, "t_end": 5.0},
    ]  # fmt: skip
    frames = {"dof_names": ["lumbar_flex", "thorax_flex", "r_knee_flex"], "q": q.tolist()}
    return {"segments": segments, "frames": frames}, time


def test_the_lean_of_a_carried_walk_is_its_middles() -> None:
    doc, time = _doc("closed", 40.0)
    got = human.carried_trunk(doc, time)
    assert got["carried_walks"] == 1
    assert abs(got["carried_trunk_deg"] - 40.0) < 1e-6
    assert got["carried_trunk_at"] == "walk @2.00-5.00s"


def test_a_walk_with_open_hands_is_not_a_carry() -> None:
    doc, time = _doc("open", 40.0)
    assert human.carried_trunk(doc, time) == {
        "carried_walks": 0, "carried_trunk_deg": None, "carried_trunk_at": None,
    }  # fmt: skip
