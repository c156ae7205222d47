"""The MTM-1 time of a task and its MIL-HDBK-472 split, against hand-computed values."""

from __future__ import annotations

from pathlib import Path

import pytest

from mtlc.frontend import run_frontend
from mtlc.report.maintenance import (
    CATEGORIES,
    category_of_name,
    category_of_path,
    split_time,
)

# walk_to(front): 1.5 m from the start is 2 paces of MTM-1 W-P (15 TMU each): 30 TMU = 1.08 s,
# shorter than its steps take (semantics.gait): the male P50's step is 0.696 m, so 3 steps of
# 0.5 m and a closing step; steps of 72 % of the full length are at the slowest cadence, 95 per
# minute, the first 10 % longer and the closing one 5 % shorter: (1.1 + 2 + 0.95) × 60/95 s.
# remove_cover 3 s (disassembly). parallel { install_cover 2 s, wipe 1 s }: the first second is
# shared by reassembly and other (0.5 s each), the second is reassembly's: 1.5 s and 0.5 s.
# check_gauge 1 s (checkout). release(right): RL1, 2 TMU = 0.072 s, an element the table does
# not map (other). Total with MTM's walk 1.08 + 3 + 2 + 1 + 0.072 = 7.152 s.
SMALL = """\
use stdlib.actions
use stdlib.elements

scene s {
    ground 0 cm
    site front at (0, 0, 150) cm
}

element pause(d: Duration) {
    still over d
}

element squeeze(hand: Hand, d: Duration) {
    grip hand closed
    time d
}

action remove_cover() {
    pause(3 s)
}

action install_cover() {
    squeeze(right, 2 s)
}

action wipe() {
    squeeze(left, 1 s)
}

action check_gauge() {
    pause(1 s)
}

task small {
    scene s

    walk_to(front)
    remove_cover()
    parallel {
        install_cover()
        wipe()
    }
    check_gauge()
    release(right)
}
"""

WALK = (1.1 + 2 + 0.95) * 60 / 95  # 2.558 s, not MTM's 1.08 s

EXPECTED = {
    "preparation": WALK,
    "disassembly": 3.0,
    "reassembly": 1.5,
    "checkout": 1.0,
    "other": 0.5 + 0.072,
}


@pytest.fixture(scope="module")
def small_split(tmp_path_factory: pytest.TempPathFactory):
    path = tmp_path_factory.mktemp("split") / "small.mtask"
    path.write_text(SMALL, encoding="utf-8")
    program = run_frontend([Path(path)])
    assert not program.sink.has_errors, program.diagnostics
    (timeline,) = program.timelines
    return split_time(timeline)


def test_total_is_the_hand_computed_mtm_time(small_split) -> None:
    total = 7.152 - 1.08 + WALK
    assert small_split.total == pytest.approx(total, abs=1e-9)
    assert small_split.total_tmu == pytest.approx(total / 0.036, abs=1e-6)


def test_split_matches_hand_computed_values(small_split) -> None:
    for name in CATEGORIES:
        assert small_split.seconds[name] == pytest.approx(EXPECTED.get(name, 0.0), abs=1e-9), name


def test_split_adds_up_to_the_total(small_split) -> None:
    assert sum(small_split.seconds.values()) == pytest.approx(small_split.total, abs=1e-9)


@pytest.mark.parametrize(
    ("name", "category"),
    [
        ("walk_to", "preparation"),
        ("unscrew", "disassembly"),
        ("remove_panel", "disassembly"),  # by its leading verb
        ("screw", "reassembly"),
        ("install", "reassembly"),
        ("pick", "interchange"),
        ("align_shaft", "alignment"),
        ("inspect", "checkout"),
        ("diagnose_fault", "fault isolation"),
        ("spin_off", None),
    ],
)
def test_mapping_table(name: str, category: str | None) -> None:
    assert category_of_name(name) == category


def test_the_step_the_task_line_calls_decides() -> None:
    # pick calls look: the whole step is interchange, not checkout
    assert category_of_path(("t", "pick", "look")) == "interchange"
    assert category_of_path(("t", "press", "look")) == "other"
    assert category_of_path(("t",)) == "other"


def test_examples_split_adds_up() -> None:
    for path in sorted(Path("examples").glob("*.mtask")):
        for timeline in run_frontend([path]).timelines:
            split = split_time(timeline)
            assert sum(split.seconds.values()) == pytest.approx(timeline.duration, abs=1e-9)
            assert all(v >= 0 for v in split.seconds.values())
