"""What `mtlc report` measures for a task and a set of manikins.

The sweep is lint's (docs/lint.md): every manikin's timeline is timed for it as `mtlc compile
--manikin` times it (``frontend.time_task``: a walk's steps take that body's time) and compiled
in full (every motion pass), through mtlc.executor (worker processes; the same numbers whatever
their count). For each manikin: how far the hand stays from each contact goal's site, and the
worst RULA grand score with its time and task line. The predicted time is the task's timeline
as given (timed for the task's own manikin): MTM-1 distances come from the scene, and only a
walk's steps depend on the body.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mtlc import executor
from mtlc.diagnostics import DiagnosticSink
from mtlc.ergonomics import rula as R
from mtlc.frontend import DEFAULT_MOTION_BUDGET, time_task
from mtlc.ir.model import MotionIR, Segment
from mtlc.lint.config import LintConfig
from mtlc.lint.manikins import label
from mtlc.lint.rules.access import goal_openings
from mtlc.lint.rules.reach import contact_goals, stature
from mtlc.lint.rules.view import MotionView, make_view
from mtlc.lint.rules.visibility import goal_sights
from mtlc.metrics import foot_stance
from mtlc.passes import MotionOptions, run_motion
from mtlc.passes.approach import HAND_NAMES, TOLERANCE
from mtlc.passes.tool import is_stroke
from mtlc.report.maintenance import TimeSplit, split_time
from mtlc.semantics.timeline import ManikinSpec, Timeline

FULL, FAILED = "full", "failed"


@dataclass(frozen=True)
class GoalRef:
    """One contact goal: a hand on a site, asked for by one task line."""

    site: str
    hand: str  # "right hand" / "left hand"
    file: str
    line: int
    column: int


@dataclass(frozen=True)
class RulaWorst:
    """The worst RULA grand score over a manikin's frames, and where it first happens."""

    score: int
    action_level: int
    time: float  # s
    side: str  # "right" / "left"
    line: int
    column: int
    where: str  # task > action > element


@dataclass
class ManikinResult:
    spec: ManikinSpec
    stature: float  # m
    method: str  # FULL or FAILED
    distance: dict[GoalRef, float] = field(default_factory=dict)  # m, hand to site
    rula: RulaWorst | None = None
    # with equipment geometry only: the share of each goal's site the eyes see at its least
    # visible frame (MT0611's measure), and its tightest opening (MT0610's: what passes, what
    # the part needs, in m, and the part)
    seen: dict[GoalRef, float] = field(default_factory=dict)
    opening: dict[GoalRef, tuple[float, float, str]] = field(default_factory=dict)
    error: str | None = None
    # s, the task's predicted time for this manikin (its walks' steps take its body's time);
    # None when it is past the motion budget
    time: float | None = None

    @property
    def label(self) -> str:
        return label(self.spec)

    def reached(self, goal: GoalRef) -> bool | None:
        """Within the passes' 1 mm tolerance; None when not measured."""
        d = self.distance.get(goal)
        return None if d is None else d <= TOLERANCE


@dataclass
class TaskResult:
    task: str
    title: str | None
    file: str
    line: int
    time: TimeSplit
    goals: list[GoalRef]
    manikins: list[ManikinResult]


def goal_ref(seg: Segment) -> GoalRef:
    o = seg.provenance.origin
    hand = HAND_NAMES.get(seg.goal.effector, seg.goal.effector)
    return GoalRef(seg.goal.site or "", hand, o.file, o.line, o.column)


def analyse_task(
    timeline: Timeline,
    selection: tuple[ManikinSpec, ...],
    *,
    options: MotionOptions | None = None,
    jobs: int | None = None,
) -> TaskResult:
    """Compile ``timeline`` for each manikin of ``selection`` (in its order)."""
    return analyse_tasks([timeline], selection, options=options, jobs=jobs)[0]


def analyse_tasks(
    timelines: list[Timeline],
    selection: tuple[ManikinSpec, ...],
    *,
    options: MotionOptions | None = None,
    jobs: int | None = None,
    motion_budget: float = DEFAULT_MOTION_BUDGET,
) -> list[TaskResult]:
    """Every (task, manikin) timed for that manikin and compiled in full, ``jobs`` at a time
    (None: one per CPU); one over ``motion_budget`` (MT0407) is a failed row, not compiled."""
    timed: list[Timeline] = []
    over: dict[tuple[int, int], str] = {}  # (task, manikin) index -> MT0407's message
    for i, timeline in enumerate(timelines):
        for k, spec in enumerate(selection):
            sink = DiagnosticSink()
            one = time_task(timeline, spec, motion_budget, sink)
            if one is None:
                over[i, k] = "; ".join(d.message for d in sink.sorted() if d.code == "MT0407")
            else:
                timed.append(one)
    shared = (tuple(timed), options or MotionOptions())
    outcomes = iter(executor.run(measure_one, shared, list(range(len(timed))), jobs))
    durations = iter(t.duration for t in timed)
    out = []
    for i, timeline in enumerate(timelines):
        ordered = []
        for k, spec in enumerate(selection):
            outcome = executor.Failed(over[i, k]) if (i, k) in over else next(outcomes)
            if isinstance(outcome, executor.Done):
                ordered.append(outcome.value)
            else:
                failed = ManikinResult(spec, stature(spec) / 1000.0, FAILED)
                failed.error = outcome.message
                ordered.append(failed)
            if (i, k) not in over:
                ordered[-1].time = next(durations)
        # in the order of the motion (the first compile's segments)
        goals = list(dict.fromkeys(g for r in ordered for g in r.distance))
        out.append(
            TaskResult(
                timeline.task,
                timeline.title,
                timeline.file,
                timeline.span.line,
                split_time(timeline),
                goals,
                ordered,
            )
        )
    return out


def measure_one(shared: tuple[tuple[Timeline, ...], MotionOptions], index: int) -> ManikinResult:
    """One task compiled for the manikin it is timed for: its distances and worst RULA (runs in
    a worker; a bug in a pass is the executor's Failed, a FAILED row, and the others go on)."""
    timelines, options = shared
    timeline = timelines[index]
    spec = timeline.manikin
    result = ManikinResult(spec, stature(spec) / 1000.0, FULL)
    ir = run_motion(timeline, DiagnosticSink(), options)
    result.distance = contact_distances(ir)
    view = make_view(ir, "", LintConfig())  # the output frames posed once, for both below
    result.rula = worst_rula(ir, view)
    if ir.geometry and view is not None:
        result.seen, result.opening = prototype_measures(view)
    return result


def prototype_measures(
    view: MotionView,
) -> tuple[dict[GoalRef, float], dict[GoalRef, tuple[float, float, str]]]:
    """Per goal, what lint's MT0611 and MT0610 measure: the least share of the site seen, and
    the tightest opening on the way (only where there is one around a part)."""
    seen: dict[GoalRef, float] = {}
    for sight in goal_sights(view):
        ref = goal_ref(sight.goal)
        seen[ref] = min(seen.get(ref, 1.0), sight.share)
    opening: dict[GoalRef, tuple[float, float, str]] = {}
    for tight in goal_openings(view):
        ref = goal_ref(tight.goal)
        if not np.isfinite(tight.scale):
            continue
        free, need = tight.scale * tight.size[0], tight.size[0]
        if ref not in opening or free / need < opening[ref][0] / opening[ref][1]:
            opening[ref] = (free, need, tight.part)
    return seen, opening


def contact_distances(ir: MotionIR) -> dict[GoalRef, float]:
    """Hand-to-site distance (m) of each contact goal of a full compile, as the verify pass
    measured it on the output frames (docs/metrics.md): where the solver claimed the site
    reached, the distance at the first frame at or after the goal's end; where it did not, the
    shortfall (the closest the hand comes over the goal's frames), the number MT0501 gives."""
    v = ir.verification
    if v is None:
        raise ValueError("the motion is not verified: run the verify pass last")
    measured: dict[tuple[object, ...], list[dict]] = {}
    for c in v.contacts:
        key = (c["file"], c["line"], c["column"], c["site"], c["effector"])
        measured.setdefault(key, []).append(c)
    out: dict[GoalRef, float] = {}
    strokes = _stroke_ends(ir)
    for reach in contact_goals(ir):
        seg, o = reach.segment, reach.segment.provenance.origin
        key = (o.file, o.line, o.column, seg.goal.site or "", seg.goal.effector)
        # the goal's own contacts: a wrench's strokes after it (same line, site and tool) are
        # judged each where it ends, and MT0501 names them apart ("through its strokes")
        found = [c for c in measured.get(key, ()) if (*key, round(c["time"], 6)) not in strokes]
        if not found:
            continue
        short = [c["shortfall"] for c in found if not c["reached"]]
        out.setdefault(goal_ref(seg), min(short) if short else float(found[0]["error"]))
    return out


def _stroke_ends(ir: MotionIR) -> set[tuple[object, ...]]:
    """(file, line, column, site, effector, time) of the output frame where each wrench stroke
    ends: the key of its entry in ``Verification.contacts``."""
    t = ir.frames.time if ir.frames is not None else np.zeros(0)
    out: set[tuple[object, ...]] = set()
    for seg in ir.segments:
        if not is_stroke(seg) or not len(t):
            continue
        o = seg.provenance.origin
        i = min(int(np.searchsorted(t, seg.end - 1e-9)), len(t) - 1)
        out.add(
            (
                o.file,
                o.line,
                o.column,
                seg.goal.site or "",
                seg.goal.effector,
                round(float(t[i]), 6),
            )
        )
    return out


def worst_rula(ir: MotionIR, view: MotionView | None) -> RulaWorst | None:
    """The highest RULA grand score of any frame (the first such frame), as lint's MT0605
    scores it: both sides, legs supported when both feet stand (``view``: ``make_view(ir)``)."""
    if view is None:
        return None
    both_feet = foot_stance(ir, view.time).all(axis=1)
    scores = R.task_scores(ir, view.pose, view.q, view.time, both_feet)
    grand = R.worst_grand(scores)
    i = int(np.argmax(grand))
    side = "right" if scores["r"].grand[i] >= scores["l"].grand[i] else "left"
    span = view.span(i)
    return RulaWorst(
        int(grand[i]),
        int(R.action_level(grand[i : i + 1])[0]),
        float(view.time[i]),
        side,
        span.line,
        span.column,
        view.where(i),
    )


@dataclass
class Report:
    """Everything one `mtlc report` run shows, in every format."""

    tasks: list[TaskResult]
    selection: tuple[ManikinSpec, ...]
    ratio: dict[str, float]  # sex -> weight in the combined share
