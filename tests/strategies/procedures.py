"""Random valid `.mtask` procedures in random scenes, for property tests and bench/motion.py.

The four examples exercise a few paths of the motion passes; a new user's procedures leave them
at once (issue 18). This module writes procedures the way the docs allow one to (docs/language.md,
docs/stdlib.md): a scene with a few work stations on a floor at a random height, each with sites
spread inside and beyond the reach envelope of a small and a large manikin (in front, far, near
the floor, overhead, to the side, behind), and a task of walks (`walk_to`, `travel_facing`,
`walk by`), postures (squat, kneel, bend, stand), reaches, grasps and releases, picks and places,
moves and carries with loads, fasteners turned with wrenches, ratchets and screwdrivers, and
`parallel` blocks whose branches work with one hand each.

Every procedure is valid: `mtlc check` accepts it (tests/test_generated_procedures.py asserts it
over many examples). Whether the *motion* is feasible is another matter: a site beyond reach
should give a diagnostic (MT0501...), never a silent miss.

Two ways in, one generator:

* ``generate(seed)``: a plain function for benches (``random.Random(seed)``, no hypothesis);
* ``procedures()``: a hypothesis strategy (the same choices drawn from hypothesis, so failures
  shrink to fewer steps, fewer sites and smaller numbers).
"""

from __future__ import annotations

import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, TypeVar

T = TypeVar("T")

HANDS = ("left", "right")
TOOLS = (
    "wrench_10mm",
    "wrench_13mm",
    "ring_wrench_10mm",
    "ratchet_3_8",
    "screwdriver_flat",
    "screwdriver_cross",
    "pliers",
)
TASK_TOOLS = (None, None, "wrench_10mm", "ratchet_3_8", "screwdriver_flat")
NORMALS = (None, None, "(0, 0, -1)", "(0, 1, 0)", "(0, -1, 0)", "(1, 0, 0)", "(-1, 0, 0)")
MANIKINS = tuple(
    f"gb10000_1988 {sex} p{pct}" for sex in ("female", "male") for pct in (1, 5, 10, 50, 90, 95, 99)
)

# Where a work site lies from its station, in cm: (dx, height above the floor, dz) ranges.
# The station faces +Z. "front" is within reach of a 5th-percentile woman standing, "far" beyond
# it for most manikins, "low" calls for a squat or a kneel, "overhead" is at or beyond a small
# manikin's reach, "side" and "behind" make the trunk turn.
CATEGORIES: dict[str, tuple[tuple[int, int], tuple[int, int], tuple[int, int]]] = {
    "front": ((-35, 35), (80, 150), (25, 60)),
    "far": ((-60, 60), (60, 170), (65, 115)),
    "low": ((-40, 40), (3, 35), (20, 70)),
    "overhead": ((-40, 40), (165, 215), (0, 50)),
    "side": ((45, 90), (60, 150), (-10, 40)),
    "behind": ((-40, 40), (70, 140), (-60, -25)),
}


class Chooser(Protocol):
    """The random choices a generator makes: a seeded ``random.Random`` or hypothesis' draw."""

    def choice(self, items: Sequence[T]) -> T: ...

    def randint(self, lo: int, hi: int) -> int: ...


class RandomChooser:
    """Choices from a seeded ``random.Random`` (reproducible by seed, no hypothesis)."""

    def __init__(self, seed: int) -> None:
        self.rng = random.Random(seed)

    def choice(self, items: Sequence[T]) -> T:
        return self.rng.choice(list(items))

    def randint(self, lo: int, hi: int) -> int:
        return self.rng.randint(lo, hi)


class DrawChooser:
    """Choices drawn from hypothesis, so a failing procedure shrinks."""

    def __init__(self, draw: Callable[[Any], Any]) -> None:
        from hypothesis import strategies as st

        self.draw, self.st = draw, st

    def choice(self, items: Sequence[T]) -> T:
        return self.draw(self.st.sampled_from(list(items)))

    def randint(self, lo: int, hi: int) -> int:
        return self.draw(self.st.integers(lo, hi))


@dataclass(frozen=True)
class Procedure:
    """One generated `.mtask` file with a single task."""

    name: str
    text: str
    seed: int | None = None

    def write(self, folder: Path) -> Path:
        """Write the file as ``folder/NAME.mtask`` and return its path."""
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{self.name}.mtask"
        path.write_text(self.text, encoding="utf-8")
        return path


@dataclass
class _Site:
    name: str
    category: str
    station: int
    normal: bool


@dataclass
class _State:
    posture: str = "stand"
    station: int = 0
    # per hand: None (free), "fixed" (closed on a part that stays put), "part" (holds a loose
    # part it may move); "both" when the two hands hold one part together
    held: dict[str, str | None] = field(default_factory=lambda: {"left": None, "right": None})


class _Writer:
    """Builds one procedure from a chooser: the scene first, then the task step by step."""

    def __init__(self, ch: Chooser, name: str, min_steps: int, max_steps: int) -> None:
        self.ch, self.name = ch, name
        self.min_steps, self.max_steps = min_steps, max_steps
        self.sites: list[_Site] = []
        self.stations: list[str] = []
        self.elements: list[str] = []
        self.state = _State()

    # -------------------------------------------------------------- scene
    def scene(self) -> list[str]:
        ch = self.ch
        ground = ch.choice((0, 0, 0, 0, 15, -30))
        lines = [f"scene {self.name}_bay {{", f"    ground {ground} cm"]
        for k in range(ch.randint(1, 3)):
            sx, sz = (
                (0, 0)
                if k == 0 and ch.randint(0, 1)
                else (ch.randint(-150, 150), ch.randint(0, 250))
            )
            name = f"station_{k}"
            self.stations.append(name)
            lines.append(f"    site {name} at ({sx}, {ground}, {sz}) cm")
            for _ in range(ch.randint(2, 5)):
                cat = ch.choice(tuple(CATEGORIES))
                (x0, x1), (y0, y1), (z0, z1) = CATEGORIES[cat]
                dx = ch.randint(x0, x1) * (ch.choice((-1, 1)) if cat == "side" else 1)
                pos = (sx + dx, ground + ch.randint(y0, y1), sz + ch.randint(z0, z1))
                normal = ch.choice(NORMALS)
                site = _Site(f"{cat}_{len(self.sites)}", cat, k, normal is not None)
                self.sites.append(site)
                extra = f" normal {normal}" if normal else ""
                lines.append(f"    site {site.name} at ({pos[0]}, {pos[1]}, {pos[2]}) cm{extra}")
        lines.append("}")
        return lines

    # -------------------------------------------------------------- helpers
    def site(self) -> str:
        """A work site, mostly at the station the manikin stands at (sometimes another: a miss)."""
        return self._pick(self.sites)

    def fastener(self) -> str | None:
        """A site with a normal (a wrench swings about it), None when the scene has none."""
        sites = [s for s in self.sites if s.normal]
        return self._pick(sites) if sites else None

    def _pick(self, sites: list[_Site]) -> str:
        here = [s for s in sites if s.station == self.state.station]
        pool = here if here and self.ch.randint(0, 9) else sites
        return self.ch.choice(pool).name

    def kg(self) -> str:
        return f"{self.ch.choice((0.5, 2, 5, 9, 15, 25, 40))} kg"

    # -------------------------------------------------------------- hand actions
    def free_hand(self, hand: str) -> list[str]:
        """One action of a free hand; updates what it holds."""
        ch, s = self.ch, self.site()
        kind = ch.choice(("reach", "reach_grasp", "pick", "press", "unscrew", "unscrew", "look"))
        if kind == "reach":
            case = ch.choice(("", ", A", ", C"))
            return [f"reach({hand}, {s}{case})"]
        if kind == "reach_grasp":
            self.state.held[hand] = "fixed"
            return [f"reach({hand}, {s})", f"grasp({hand})"]
        if kind == "pick":
            self.state.held[hand] = "part"
            return [f"pick({hand}, {s}{ch.choice(('', ', G4A', ', G1C'))})"]
        if kind == "press":
            return [f"press({hand}, {s})"]
        if kind == "look":
            return [f"look({s})", f"reach({hand}, {s}, approach: {ch.randint(0, 10)} cm)"]
        fastener = self.fastener()
        if fastener is None:
            return [f"press({hand}, {s})"]
        verb = ch.choice(("unscrew", "screw"))
        args = [hand, fastener, f"turns: {ch.randint(1, 2)}"]
        if ch.randint(0, 1):
            args.append(f"tool: {ch.choice(TOOLS)}")
        if ch.randint(0, 2) == 0:
            args.append(f"swing: {ch.choice((30, 45, 90))} deg")
        if ch.randint(0, 3) == 0:
            args.append(f"load: {ch.choice((0.4, 2))} kg")
        return [f"{verb}({', '.join(args)})"]

    def holding_hand(self, hand: str) -> list[str]:
        """One action of a hand that holds something; updates what it holds."""
        ch = self.ch
        held = self.state.held[hand]
        kinds = (
            ("release", "turn", "move", "move", "place") if held == "part" else ("release", "turn")
        )
        kind = ch.choice(kinds)
        if kind == "release":
            self.state.held[hand] = None
            return [f"release({hand})"]
        if kind == "turn":
            return [
                f"turn({hand}, {ch.choice((-180, -90, 45, 90))} deg, {ch.choice((0, 0.4, 3))} kg)"
            ]
        s = self.site()
        if kind == "move":
            case = ch.choice(("", ", A", ", C"))
            return [f"move({hand}, {s}{case}, load: {self.kg()})"]
        self.state.held[hand] = None
        return [f"place({hand}, {s})"]

    def hand_action(self, hand: str) -> list[str]:
        if self.state.held[hand] in ("fixed", "part"):
            return self.holding_hand(hand)
        return self.free_hand(hand)

    def both_hands(self) -> list[str]:
        """A two-handed action: pick or lift a part together, move or place it, let go."""
        ch, held = self.ch, self.state.held
        if held["left"] == held["right"] == "both":
            kind = ch.choice(("move", "place", "release"))
            if kind == "move":
                return [f"move(both, {self.site()}, C, {self.kg()})"]
            held["left"] = held["right"] = None
            if kind == "place":
                return [f"place(both, {self.site()})"]
            return ["release(both)"]
        lines = self.release_all()
        held["left"] = held["right"] = "both"
        if ch.randint(0, 1):
            return [*lines, f"pick(both, {self.site()})"]
        return [*lines, f"lift({self.site()}, {self.site()}, load: {self.kg()})"]

    def release_all(self) -> list[str]:
        held = self.state.held
        if held["left"] and held["right"]:
            held["left"] = held["right"] = None
            return ["release(both)"]
        out = [f"release({h})" for h in HANDS if held[h]]
        held["left"] = held["right"] = None
        return out

    def parallel(self) -> list[str]:
        """A `parallel` block: one branch per hand (each a block when it has several steps)."""
        held = self.state.held
        if "both" in (held["left"], held["right"]):
            return self.both_hands()
        lines = ["parallel {"]
        for hand in HANDS:
            branch = self.hand_action(hand)
            if self.ch.randint(0, 2) == 0:
                branch += self.hand_action(hand)
            if len(branch) == 1:
                lines.append(f"    {branch[0]}")
            else:
                lines += ["    {", *(f"        {b}" for b in branch), "    }"]
        lines.append("}")
        return lines

    # -------------------------------------------------------------- body
    def posture(self) -> list[str]:
        ch = self.ch
        kind = ch.choice(("squat", "squat", "kneel", "kneel", "bend", "stand"))
        self.state.posture = kind
        if kind == "squat":
            return [f"squat({ch.choice((0, 10, 20, 35, 50, 70))} cm)"]
        if kind == "kneel":
            return [f"kneel({ch.choice((1, 2))})"]
        if kind == "bend":
            return [f"bend({ch.randint(1, 8) * 10} deg)"]
        return ["stand()"]

    def walk(self) -> list[str]:
        """Walk to another station (or step aside): stand up and let go of fixed parts first."""
        ch, state = self.ch, self.state
        lines: list[str] = []
        for h in HANDS:
            if state.held[h] == "fixed":
                state.held[h] = None
                lines.append(f"release({h})")
        if state.posture != "stand":
            state.posture = "stand"
            lines.append("stand()")
        kind = ch.choice(("walk_to", "walk_to", "facing", "by", "carry"))
        if kind == "by":
            name = f"shift_{len(self.elements)}"
            dx, dz = ch.randint(-80, 80), ch.randint(-80, 80)
            self.elements += [f"element {name}() {{", f"    walk by ({dx}, 0, {dz}) cm", "}", ""]
            return [*lines, f"{name}()"]
        k = ch.randint(0, len(self.stations) - 1)
        state.station = k
        target = self.stations[k]
        holder = next((h for h in HANDS if state.held[h] == "part"), None)
        if kind == "carry" and holder:
            return [*lines, f"carry({holder}, {self.site()}, {self.kg()})"]
        if kind == "facing":
            return [*lines, f"travel_facing({target}, {self.site()})"]
        return [*lines, f"walk_to({target})"]

    def step(self) -> list[str]:
        ch = self.ch
        kind = ch.choice(
            (
                "hand",
                "hand",
                "hand",
                "parallel",
                "parallel",
                "both",
                "posture",
                "posture",
                "walk",
                "inspect",
            )
        )
        if kind == "hand":
            return self.hand_action(ch.choice(HANDS))
        if kind == "parallel":
            return self.parallel()
        if kind == "both":
            return self.both_hands()
        if kind == "posture":
            return self.posture()
        if kind == "walk":
            return self.walk()
        if ch.randint(0, 1):
            return [f"inspect({self.site()}, {ch.randint(1, 3)} s)"]
        return [f"hold({ch.randint(1, 2)} s)"]

    # -------------------------------------------------------------- file
    def file(self) -> str:
        ch = self.ch
        scene = self.scene()
        body = self.hand_action(ch.choice(HANDS))  # every procedure has a goal
        for _ in range(ch.randint(self.min_steps, self.max_steps) - 1):
            body += self.step()
        body += self.release_all()
        if self.state.posture != "stand" and ch.randint(0, 1):
            body.append("stand()")
        settings = [f"manikin {ch.choice(MANIKINS)}", f"scene {self.name}_bay"]
        tool = ch.choice(TASK_TOOLS)
        if tool:
            settings.append(f"tool {tool}")
        out = [
            f"# generated procedure {self.name} (tests/strategies/procedures.py)",
            "use stdlib.actions",
            "use stdlib.elements",
            "use stdlib.tools",
            "",
            *scene,
            "",
            *self.elements,
            f'task {self.name} "generated {self.name}" {{',
            *(f"    {s}" for s in settings),
            "",
            *(f"    {b}" for b in body),
            "}",
        ]
        return "\n".join(out) + "\n"


def build(ch: Chooser, name: str = "gen", min_steps: int = 3, max_steps: int = 8) -> Procedure:
    """One procedure from any chooser (``min_steps``..``max_steps`` task-level steps)."""
    return Procedure(name, _Writer(ch, name, min_steps, max_steps).file())


def generate(seed: int, min_steps: int = 3, max_steps: int = 8) -> Procedure:
    """The procedure of a seed: the same text for the same seed and arguments, on any machine."""
    name = f"gen_{seed}"
    return Procedure(name, _Writer(RandomChooser(seed), name, min_steps, max_steps).file(), seed)


def procedures(min_steps: int = 2, max_steps: int = 5) -> Any:
    """A hypothesis strategy of procedures (shrinks toward fewer steps and sites)."""
    from hypothesis import strategies as st

    @st.composite
    def _procedures(draw: Callable[[Any], Any]) -> Procedure:
        return build(DrawChooser(draw), "gen", min_steps, max_steps)

    return _procedures()
