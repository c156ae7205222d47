"""The expanded element timeline: what the front end hands to lowering.

Plain data in SI units. Every primitive keeps the task › action › element path that produced it,
the span of the primitive statement and the span of the line in the task that asked for it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from mtlc.diagnostics import Span

TIMELINE_FORMAT_VERSION = 1
PRIMITIVE_KINDS = ("goal", "posture", "locomotion", "grip", "gaze", "hold")


@dataclass(frozen=True)
class Site:
    name: str
    position: tuple[float, float, float]
    normal: tuple[float, float, float] | None
    frame: tuple[float, float, float] | None  # X, Y, Z rotations (rad), applied in that order
    span: Span


@dataclass(frozen=True)
class Tool:
    name: str
    properties: dict[str, Any]


@dataclass(frozen=True)
class ManikinSpec:
    population: str
    sex: str
    percentile: int


@dataclass
class Primitive:
    kind: str
    effector: str  # left_hand, right_hand, head, root, body
    start: float
    end: float
    params: dict[str, Any]
    path: tuple[str, ...]
    span: Span
    origin: Span

    @property
    def duration(self) -> float:
        return self.end - self.start


@dataclass
class Timeline:
    task: str
    title: str | None
    file: str
    span: Span
    manikin: ManikinSpec
    scene: str | None
    ground: float
    sites: list[Site]
    tool: Tool | None
    budget: float | None
    primitives: list[Primitive] = field(default_factory=list)
    # the scene's models and solids, placed (mtlc.geometry.model.SceneModel)
    models: list[Any] = field(default_factory=list)
    # where the `budget` statement is (MT0404 is reported there)
    budget_span: Span | None = None
    # the indices in ``primitives`` of the walks timed by MTM-1 paces: the ones that get turn
    # time and the time their steps need (``semantics.schedule``)
    mtm_walks: tuple[int, ...] = ()
    # the manikin whose body timed those walks: None in the expander's timeline (the same for
    # every manikin); ``schedule.for_manikin`` returns a copy timed for one manikin's body, and
    # the motion passes refuse a timeline whose ``manikin`` is not the one it is timed for
    timed_for: ManikinSpec | None = None
    # a timed timeline's untimed source, which times it again for another manikin
    expanded: Timeline | None = field(default=None, compare=False, repr=False)

    @property
    def duration(self) -> float:
        return max((p.end for p in self.primitives), default=0.0)

    def as_dict(self) -> dict[str, Any]:
        return {
            "format": "mtlc-timeline",
            "version": TIMELINE_FORMAT_VERSION,
            "units": {"length": "m", "angle": "rad", "time": "s", "mass": "kg"},
            "task": self.task,
            "title": self.title,
            "source": _span(self.span),
            "manikin": {
                "population": self.manikin.population,
                "sex": self.manikin.sex,
                "percentile": self.manikin.percentile,
            },
            "scene": {
                "name": self.scene,
                "ground": _num(self.ground),
                "sites": [
                    {
                        "name": s.name,
                        "position": _num(s.position),
                        "normal": _num(s.normal),
                        "frame": _num(s.frame),
                        "source": _span(s.span),
                    }
                    for s in self.sites
                ],
            }
            # only with geometry: timelines of scenes without it keep their bytes
            | ({"models": [_num(m.record()) for m in self.models]} if self.models else {}),
            "tool": None
            if self.tool is None
            else {"name": self.tool.name, **{k: _num(v) for k, v in self.tool.properties.items()}},
            "budget": _num(self.budget),
            "duration": _num(self.duration),
            "primitives": [
                {
                    "kind": p.kind,
                    "effector": p.effector,
                    "start": _num(p.start),
                    "end": _num(p.end),
                    "params": {k: _num(v) for k, v in p.params.items()},
                    "path": " > ".join(p.path),
                    "source": _span(p.span),
                    "origin": _span(p.origin),
                }
                for p in self.primitives
            ],
        }

    def to_json(self) -> str:
        return json.dumps(self.as_dict(), indent=1, ensure_ascii=False) + "\n"


def _span(s: Span) -> dict[str, Any]:
    return {"file": s.file, "line": s.line, "column": s.column}


def _num(v: Any) -> Any:
    """Round floats so that output is byte-identical across platforms' last-bit noise."""
    if isinstance(v, float):
        r = round(v, 6)
        return 0.0 if r == 0 else r
    if isinstance(v, tuple | list):
        return [_num(x) for x in v]
    if isinstance(v, dict):
        return {k: _num(x) for k, x in v.items()}
    return v
