"""How long a walk's steps take: the gait's own time, from stature and step length.

MTM-1's W-P (15 TMU a 0.75 m pace) times a walk by its distance alone, so a 0.6 m walk got one
pace (0.54 s) for the two steps the gait must take (a step and a closing step): 222 steps/min.
The schedule gives a walk timed by ``mtm.walk()`` the larger of MTM's time and the time its
steps need at a human cadence (``semantics/turning.py`` adds it; ``passes/locomotion.py`` times
the steps with the same rules):

* step length ``L``: 0.413 × stature for women, 0.415 × stature for men (the pedometer rule,
  inside the 0.41–0.45 × stature range quoted for normal walking; docs/passes.md);
* cadence at that step length, from stature: 113 steps/min at 152 cm down to 90 at 198 cm,
  linear (Rowe, Welk, Heil et al. 2011, "Stride rate recommendations for moderate-intensity
  walking", Med Sci Sports Exerc 43(2):312–318: height explains the cadence of moderate,
  normal-paced walking), held inside [``SLOW_CADENCE``, ``FAST_CADENCE``];
* a shorter step is a slower one: step length and cadence fall together, their ratio (the walk
  ratio) constant across walking speeds (Sekiya & Nagasaki 1998, "Reproducibility of the
  walking patterns of normal young adults: test-retest reliability of the walk ratio
  (step-length/step-rate)", Gait & Posture 7(3):225–227), down to ``SLOW_CADENCE``;
* the first step from standing (gait initiation), the closing step (termination) and each pivot
  step of a turn in place are taken at ``SLOW_CADENCE`` (the first 10 % longer, the closing
  one 5 % shorter, ``SLOW_SHARE``): they accelerate the body from rest, bring it to rest, or
  turn it, and are not steps of steady walking. These are modelling choices, not measured.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

STEP_LENGTH_RATIO = {"female": 0.413, "male": 0.415}  # step length / stature (pedometer rule)
CADENCE_AT = ((1.52, 113.0), (1.98, 90.0))  # (stature m, steps/min): Rowe et al. 2011
SLOW_CADENCE = 95.0  # steps/min: start, closing and pivot steps, and the slowest short step
FAST_CADENCE = 120.0  # steps/min: no stature walks faster (Rowe's line gives 116 at 145 cm)
MAX_TURN_STEP = math.radians(40)  # heading change per pivot step (the gait's rule)

# what a step does, for its time (passes/locomotion.py's Step.kind)
START, WALK, CLOSE, PIVOT = "start", "walk", "close", "pivot"
# the start step takes a tenth longer (its weight shift before toe-off), the closing step a
# twentieth less (it ends in a settle): a walk of one step and a closing step stays at 93
# steps/min, inside the 90-125 a gait lab expects
SLOW_SHARE = {START: 1.1, CLOSE: 0.95}


def step_length(stature: float, sex: str) -> float:
    return STEP_LENGTH_RATIO.get(sex, 0.414) * stature


def free_cadence(stature: float) -> float:
    """Steps per minute at the full step length, for a body of ``stature`` (m)."""
    (h0, c0), (h1, c1) = CADENCE_AT
    c = c0 + (stature - h0) * (c1 - c0) / (h1 - h0)
    return min(max(c, SLOW_CADENCE), FAST_CADENCE)


def step_seconds(kind: str, length: float, full_length: float, stature: float) -> float:
    """Seconds one step takes: ``length`` is the step's (m), ``full_length`` the gait's."""
    if kind != WALK:
        return SLOW_SHARE.get(kind, 1.0) * 60.0 / SLOW_CADENCE
    share = min(1.0, max(0.0, length) / full_length) if full_length > 0 else 1.0
    cadence = max(SLOW_CADENCE, free_cadence(stature) * share)
    return 60.0 / cadence


def pivots(turn: float) -> int:
    """Pivot steps of at most ``MAX_TURN_STEP`` that turn the body by ``turn`` (rad) in place."""
    return math.ceil(abs(turn) / MAX_TURN_STEP - 1e-9)


def pivot_steps(turn: float) -> int:
    """Steps a turn in place takes: its pivots, then a closing step."""
    return pivots(turn) + 1


def walking_steps(distance: float, full_length: float) -> list[tuple[str, float]]:
    """(kind, length) of the steps that walk ``distance``: ``n = ceil(d / L)`` equal steps, the
    first from standing, then the closing step that brings the feet together."""
    n = max(1, math.ceil(distance / full_length - 1e-9))
    each = distance / n
    return [(START, each)] + [(WALK, each)] * (n - 1) + [(CLOSE, each)]


def steps_seconds(steps: Iterable[tuple[str, float]], full_length: float, stature: float) -> float:
    return sum(step_seconds(k, length, full_length, stature) for k, length in steps)


def walk_seconds(
    distance: float, turns: Sequence[float], stature: float, sex: str, min_distance: float
) -> float:
    """Seconds the gait's steps need for a walk of ``distance`` with the stepped ``turns``
    (rad: a start turn before walking, an end turn after; a walk shorter than
    ``min_distance`` only turns)."""
    full = step_length(stature, sex)
    pivots = sum(pivot_steps(t) for t in turns)
    steps: list[tuple[str, float]] = [(PIVOT, 0.0)] * pivots
    if distance >= min_distance and math.isfinite(distance):
        steps += walking_steps(distance, full)
    elif not math.isfinite(distance):
        return math.inf
    if steps:  # whatever it does, the first step starts from standing
        steps[0] = (START, steps[0][1])
    return steps_seconds(steps, full, stature)
