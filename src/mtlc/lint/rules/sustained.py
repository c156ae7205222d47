"""MT0609: a posture at or above a RULA score held longer than a time limit (static load).

RULA adds a muscle-use point for a posture "mainly static, e.g. held for longer than 1 minute"
(McAtamney & Corlett 1993; the muscle_use row of mtlc/ergonomics/data/rula_bands.csv): a run of
frames whose grand score stays at or above ``sustained-rula`` for more than ``sustained-seconds``
is reported with its duration, at the task line active when it starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mtlc.ir.model import runs_of
from mtlc.lint.findings import Finding
from mtlc.lint.rules.view import MotionView
from mtlc.metrics import foot_stance


@dataclass(frozen=True)
class Run:
    """Frames ``start`` to ``stop`` (exclusive) at or above the score."""

    start: int
    stop: int
    seconds: float  # (stop − start) frames, each standing for 1/fps
    worst: int  # the highest grand score in the run


def runs_at_or_above(
    grand: NDArray[np.integer], threshold: int, fps: float, min_seconds: float
) -> list[Run]:
    """The runs of frames scoring ``threshold`` or more that last longer than ``min_seconds``."""
    out = []
    for start, stop in runs_of(np.asarray(grand) >= threshold):
        seconds = (stop - start) / fps
        if seconds > min_seconds + 1e-9:
            out.append(Run(int(start), int(stop), seconds, int(np.max(grand[start:stop]))))
    return out


def sustained_posture(view: MotionView) -> list[Finding]:
    from mtlc.ergonomics import rula as R

    assert view.ir.frames is not None
    both_feet = foot_stance(view.ir, view.time).all(axis=1)
    grand = R.worst_grand(R.task_scores(view.ir, view.pose, view.q, view.time, both_feet))
    cfg = view.config
    runs = runs_at_or_above(grand, cfg.sustained_rula, view.ir.frames.fps, cfg.sustained_seconds)
    return [_finding(view, run) for run in runs]


def _finding(view: MotionView, run: Run) -> Finding:
    cfg = view.config
    end = view.time[run.stop - 1]
    msg = (
        f"a posture scoring RULA {cfg.sustained_rula} or more is held longer than "
        f"{cfg.sustained_seconds:g} s: {run.seconds:.1f} s, from {view.time[run.start]:.2f} to "
        f"{end:.2f} s from `{view.where(run.start)}` on, RULA up to {run.worst}"
    )
    return Finding(
        "MT0609",
        msg,
        view.span(run.start),
        help="break the hold into shorter ones with rests, or support the body (a stand, a "
        "seat, a fixture that holds the part)",
        manikins=(view.manikin,),
        details=(msg,),
    )
