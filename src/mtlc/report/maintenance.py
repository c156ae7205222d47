"""The predicted time of a task and its MIL-HDBK-472-style split into maintenance activities.

MIL-HDBK-472 (Maintainability Prediction, 24 May 1966), Procedures II and IV, build a corrective
maintenance time from elemental activities: preparation, fault isolation, disassembly (access),
interchange (remove and replace the item), reassembly, alignment and checkout. mtlc predicts
the time itself from MTM-1 (and the durations a task states); this module only says which
activity each moment of the timeline belongs to, by the mapping table below (docs/report.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mtlc.semantics.timeline import Primitive, Timeline
from mtlc.semantics.types import TMU_SECONDS

CATEGORIES = (
    "preparation",
    "fault isolation",
    "disassembly",
    "interchange",
    "reassembly",
    "alignment",
    "checkout",
    "other",
)

# action or element name (or the verb before its first `_`) -> activity
CATEGORY_OF_NAME: dict[str, str] = {
    **dict.fromkeys(
        ("walk_to", "travel", "travel_facing", "step", "kneel", "squat", "stand", "bend"),
        "preparation",
    ),
    **dict.fromkeys(("diagnose", "isolate", "locate", "troubleshoot"), "fault isolation"),
    **dict.fromkeys(
        ("unscrew", "remove", "open", "disconnect", "detach", "loosen", "unlatch", "unlock"),
        "disassembly",
    ),
    **dict.fromkeys(("pick", "place", "lift", "carry", "replace", "exchange"), "interchange"),
    **dict.fromkeys(
        ("screw", "install", "close", "connect", "attach", "tighten", "latch", "lock", "mount"),
        "reassembly",
    ),
    **dict.fromkeys(("align", "adjust", "calibrate"), "alignment"),
    **dict.fromkeys(("inspect", "look", "check", "verify", "test"), "checkout"),
}


def category_of_name(name: str) -> str | None:
    """The activity of one action or element name: the whole name, else its leading verb."""
    return CATEGORY_OF_NAME.get(name) or CATEGORY_OF_NAME.get(name.split("_", 1)[0])


def category_of_path(path: tuple[str, ...]) -> str:
    """The activity of a primitive: that of the step the task line calls (``path[1]``, the
    action or element right below the task), whatever that step calls in turn; 'other' when
    the table does not map it."""
    step = path[1] if len(path) > 1 else ""
    return category_of_name(step) or "other"


@dataclass(frozen=True)
class TimeSplit:
    """A task's predicted time (s) and the seconds of each activity (they add up to it)."""

    total: float
    seconds: dict[str, float]  # every category, in CATEGORIES order

    @property
    def total_tmu(self) -> float:
        return self.total / TMU_SECONDS


def split_time(timeline: Timeline) -> TimeSplit:
    """Attribute each instant of the timeline to the activities running then.

    Parallel steps of different activities share their common time equally, and instants
    where nothing runs go to 'other', so the split adds up to the task's duration."""
    prims = timeline.primitives
    seconds = dict.fromkeys(CATEGORIES, 0.0)
    total = timeline.duration
    if not prims or total <= 0:
        return TimeSplit(total, seconds)
    cuts = np.unique([0.0, total, *(p.start for p in prims), *(p.end for p in prims)])
    mids, widths = (cuts[:-1] + cuts[1:]) / 2, np.diff(cuts)
    active = _activity_matrix(prims, mids)  # (pieces, categories)
    count = active.sum(axis=1)
    idle = count == 0
    active[idle, CATEGORIES.index("other")] = True
    count[idle] = 1
    share = active * (widths / count)[:, None]
    for k, name in enumerate(CATEGORIES):
        seconds[name] = float(share[:, k].sum())
    return TimeSplit(total, seconds)


def _activity_matrix(prims: list[Primitive], mids: np.ndarray) -> np.ndarray:
    """(pieces, categories): which activities have a primitive running at each piece."""
    start = np.array([p.start for p in prims])
    end = np.array([p.end for p in prims])
    cat = np.array([CATEGORIES.index(category_of_path(p.path)) for p in prims])
    running = (start[None, :] <= mids[:, None]) & (mids[:, None] < end[None, :])  # (pieces, P)
    onehot = np.zeros((len(prims), len(CATEGORIES)), dtype=bool)
    onehot[np.arange(len(prims)), cat] = True
    return (running.astype(np.int64) @ onehot.astype(np.int64)) > 0
