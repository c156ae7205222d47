"""Fuzz mtlc with hostile input: no traceback, no internal error, no hang, bounded memory.

    python bench/fuzz.py --cases 10000 --seed 1 [--stages check,fmt,lint,compile,serve]
                         [--heavy 200] [--timeout 10] [--memory-mb 1024] [--save DIR]

Cases (deterministic for a seed): half are *generated* from the grammar (grammar/mtask.lark:
its keywords and punctuation) and the standard library's actions, elements and tools (their
parameters and types, read with mtlc's own parser), written with hostile values: huge, tiny,
negative and overflowing numbers, odd and misspelt units, long and Unicode names (bidi
controls, CJK, combining marks), deep nesting of blocks, brackets and calls, `;` joins and
`# mtlc: ignore[...]` comments on long lines, missing tool properties, zero vectors. The other
half are *mutations* of the examples (examples/*.mtask): bytes flipped, inserted, deleted,
duplicated or spliced from another example, numbers replaced by hostile ones, hostile tokens
inserted.

Each case runs through, in a worker process (forked, so a restart is cheap):

* check: the front end (``run_frontend``), as ``mtlc check`` runs it;
* fmt: ``format_source``, and on every case that formats, fmt(fmt(x)) == fmt(x);
* lint and compile: only cases that check clean, the first ``--heavy`` of them (each takes
  seconds): ``lint_paths`` with the default manikins, and the motion passes plus every
  generator (JackScript, BVH, IR JSON) in memory;
* serve: the `mtlc serve` request handler, called in-process on a fake socket with hostile
  requests (400-digit coordinates, 4,000 `[`, NaN, bad lengths and hosts); the hub's
  recompile is stubbed out (the compile stage covers it). If the handler's API changes, the
  stage says "unavailable" instead of failing.

Every stage has a time limit: past ``--timeout`` (10 s) of *CPU time* it counts as over time;
past ``--kill-after`` (60 s) of *wall time* the worker is killed and restarted and it counts as a
time-out (the hang guard). Over-time is judged by the CPU seconds of the stage (user + system, of
the worker process, ``time.process_time``), not by its wall time, because the wall time of a
stage measures the machine as much as mtlc: on a shared machine (2 cores, several other jobs) a
stage that needs 4 s of CPU can take 15 s of wall time, waiting for a core. CPU time is what the
stage costs and stays put when the load changes; both are reported per stage (slowest CPU and
slowest wall), and ``--times FILE`` writes every stage's CPU and wall seconds, to find the slow
cases. The
worker has a memory cap (address space ``--memory-mb`` above its size after the imports). The
peak resident memory of each stage is measured (VmHWM, reset before each stage). The table
counts, per stage: cases, tracebacks (an exception out of mtlc's API), internal errors
(MT0900), over-time, fmt non-idempotent, peak RSS. ``--save DIR`` writes every failing case
and its trace there, for a reproducer.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import multiprocessing as mp
import random
import re
import resource
import shutil
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mtlc.diagnostics import DiagnosticSink  # noqa: E402
from mtlc.syntax import ast, parse_module  # noqa: E402

STAGES = ("check", "fmt", "lint", "compile", "serve")
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))
STDLIB = sorted((ROOT / "stdlib").glob("*.mtask"))

# ------------------------------------------------------------------ the grammar's vocabulary


def grammar_tokens() -> tuple[list[str], list[str]]:
    """Keywords and punctuation: the string terminals of grammar/mtask.lark."""
    text = (ROOT / "grammar" / "mtask.lark").read_text(encoding="utf-8")
    literals = re.findall(r'^[A-Z_]+:\s*"([^"]+)"', text, re.M)
    keywords = [t for t in literals if t.isidentifier()]
    punct = [t for t in literals if not t.isidentifier()]
    return keywords, punct


@dataclass
class Signature:
    name: str
    module: str
    kind: str
    params: list[tuple[str, str, bool]]  # name, type, has a default


def stdlib_signatures() -> tuple[list[Signature], list[str]]:
    """The stdlib's actions and elements with their parameters, and its tools."""
    sigs, tools = [], []
    for path in STDLIB:
        tree = parse_module(path.read_text(encoding="utf-8"), path.name, DiagnosticSink())
        for d in tree.decls:
            if isinstance(d, ast.Definition):
                params = [(p.name, p.type_name, p.default is not None) for p in d.params]
                sigs.append(Signature(d.name, path.stem, d.kind, params))
            elif isinstance(d, ast.ToolDecl):
                tools.append(d.name)
    return sigs, tools


KEYWORDS, PUNCT = grammar_tokens()
SIGNATURES, TOOLS = stdlib_signatures()

UNITS = {
    "Length": ["cm", "mm", "m"],
    "Angle": ["deg", "rad"],
    "Duration": ["s", "ms", "min", "tmu"],
    "Mass": ["kg", "g"],
}
ODD_UNITS = ["cms", "MM", "sec", "Kg", "°", "deg2", "tmus", "furlong", "s s", ""]
HOSTILE_NUMBERS = [
    "0", "1", "2", "3", ".5", "2.", "1e-3", "0.0", "1e308", "1e309", "1e-320", "1e300",
    "9" * 30, "9" * 400, "1" + "0" * 20, "1000000000", "4294967296", "9007199254740993",
    "1e15", "1e16", "123456789.123456789", "00001", "1E3", "6.02e23", "1e-9",
]  # fmt: skip
NAMES = ["a", "bolt", "panel", "p5", "_tmp", "x1", "site_a", "螺栓_1", "bolt\u0301", "écrou"]
HOSTILE_TEXT = [
    "\u202e", "\u2028", "\x00", "\x1b[31m", "\ufeff", "\u200b", "ﬁ", "𝔟olt", "\r", "\t",
    "\\u{110000}", '\\"', "\\q", "🔩",
]  # fmt: skip
POPULATIONS = ["gb10000_1988", "ansur2", "ansur3", "GB10000_1988"]
SEXES = ["male", "female", "other"]
PERCENTILES = ["p1", "p5", "p50", "p95", "p99", "p3", "p100", "p"]
ENUM_VALUES = {
    "Hand": ["left", "right", "both", "middle"],
    "ReachCase": ["A", "B", "C", "D", "E", "ReachCase.A", "F"],
    "MoveCase": ["MoveCase.A", "MoveCase.B", "MoveCase.C", "Z"],
    "GraspCase": ["G1A", "G1B", "G1C", "G2", "G4A", "G5", "G9"],
}
TYPES = ["Int", "Number", "Length", "Angle", "Duration", "Mass", "Site", "Tool", "String",
         "Position", "Direction", "Hand", "ReachCase", "MoveCase", "GraspCase", "Lenght"]  # fmt: skip
MTM_CALLS = [
    "mtm.reach(C)", "mtm.move(B, load: {mass})", "mtm.turn({angle})", "mtm.grasp(G4A)",
    "mtm.release()", "mtm.walk()", 'mtm.code("P2SE")', 'mtm.code("XX")', "mtm.fixed({num})",
]  # fmt: skip


class Gen:
    """Random, mostly valid programs with hostile values (deterministic for its rng)."""

    def __init__(self, rng: random.Random, hostility: float = 1.0) -> None:
        self.r = rng
        self.h = hostility  # scales every hostile choice: calm programs mostly check clean
        self.sites: list[str] = []
        self.tools: list[str] = []
        self.scene_name = "bay"
        self.in_definition = False

    def chance(self, p: float) -> bool:
        return self.r.random() < p

    def hostile(self, p: float) -> bool:
        return self.r.random() < p * self.h

    def pick(self, items: list[Any]) -> Any:
        return self.r.choice(items)

    # ------------------------------------------------------------ atoms
    def number(self) -> str:
        if not self.hostile(0.3):
            return self.pick(["0", "1", "2", "3", "5", "10", "20", "45", "60", "90", ".5", "1.5"])
        return self.pick(HOSTILE_NUMBERS)

    def signed(self) -> str:
        n = self.number()
        return f"-{n}" if self.hostile(0.25) else n

    def quantity(self, kind: str) -> str:
        unit = self.pick(ODD_UNITS) if self.hostile(0.07) else self.pick(UNITS[kind])
        text = f"{self.signed()} {unit}".rstrip()
        if self.hostile(0.1):  # arithmetic, perhaps overflowing or dividing by zero
            op = self.pick(["+", "-", "*", "/"])
            other = self.number() if op in "*/" else f"{self.number()} {self.pick(UNITS[kind])}"
            text = f"{text} {op} {other}"
        if self.hostile(0.03):
            text = "(" * 30 + text + ")" * 30
        return text

    def vector(self, unit: str | None) -> str:
        items = [self.signed() for _ in range(self.pick([2, 4]) if self.hostile(0.05) else 3)]
        if self.hostile(0.05):
            items = ["0", "0", "0"]
        text = f"({', '.join(items)})"
        if unit:
            text += f" {unit}"
        if self.hostile(0.05):
            text += f" * {self.pick(['1e308', '2', '0', '-1'])}"
        return text

    def name(self) -> str:
        roll = self.r.random() * self.h
        if roll < 0.75:
            pool = NAMES if self.hostile(1) else NAMES[:6]  # Unicode names when hostile
            return self.pick(pool) + (str(self.r.randrange(100)) if self.chance(0.5) else "")
        if roll < 0.85:
            return self.pick(KEYWORDS)
        if roll < 0.92:
            return "n" * self.pick([64, 255, 256, 1000])
        return self.pick(NAMES) + self.pick(HOSTILE_TEXT)

    def string(self) -> str:
        body = self.pick(["Remove panel", "", 'a \\"b\\"', "x" * 300, "\\u{41}\\n"])
        if self.hostile(0.2):
            body += self.pick(HOSTILE_TEXT)
        return f'"{body}"'

    def value(self, type_name: str) -> str:
        if type_name in UNITS:
            return self.quantity(type_name)
        if type_name == "Int":
            if self.hostile(0.3):
                return self.pick(["-1", "1000000000", "99999999999999999999", "0"])
            return self.pick(["0", "1", "2", "3"])
        if type_name == "Number":
            return self.signed()
        if type_name == "Site":
            if not self.sites or self.hostile(0.1):
                return self.name()
            site = self.pick(self.sites)  # qualified outside a task, where it is not plain
            return f"{self.scene_name}.{site}" if self.in_definition else site
        if type_name == "Tool":
            pool = self.tools + TOOLS
            return self.name() if self.hostile(0.1) else self.pick(pool)
        if type_name == "String":
            return self.string()
        if type_name == "Position":
            return self.vector(self.pick(UNITS["Length"]))
        if type_name == "Direction":
            return self.vector(None)
        if type_name in ENUM_VALUES:
            values = ENUM_VALUES[type_name]
            return self.pick(values) if self.hostile(0.5) else self.pick(values[:2])
        return self.name()

    def timing(self) -> str:
        if self.chance(0.5):
            return self.quantity("Duration")
        return self.pick(MTM_CALLS).format(
            mass=self.quantity("Mass"), angle=self.quantity("Angle"), num=self.signed()
        )

    # ------------------------------------------------------------ declarations
    def scene(self) -> str:
        name = self.pick(["bay", "rack", "bench"])
        lines = []
        if self.chance(0.4):
            lines.append(f"ground {self.quantity('Length')}")
        for _ in range(self.r.randrange(1, 6)):
            site = self.name() if self.hostile(0.2) else f"s{len(self.sites)}"
            self.sites.append(site)
            line = f"site {site} at {self.vector(self.pick(UNITS['Length']))}"
            if self.chance(0.5):
                line += f" normal {self.vector(None)}"
            elif self.chance(0.15) or self.hostile(0.1):
                line += f" frame {self.vector('deg')}"
            lines.append(line)
        self.scene_name = name
        return f"scene {name} {{\n" + "".join(f"    {ln}\n" for ln in lines) + "}\n"

    def tool(self) -> str:
        name = f"t{len(self.tools)}"
        self.tools.append(name)
        props = {
            "kind": self.pick(['"wrench"', '"ratchet"', '"screwdriver"', '"pliers"', '"saw"']),
            "length": self.quantity("Length") if self.hostile(1) else f"{self.number()} cm",
            "mass": self.quantity("Mass") if self.hostile(1) else f"{self.number()} g",
            "grip": self.vector("cm" if self.hostile(1) else "mm"),
            "tip": self.vector("cm" if self.hostile(1) else "mm"),
            "axis": self.vector(None),
            "colour": '"red"',
        }
        chosen = [k for k in props if self.chance(0.7) and (k != "colour" or self.hostile(1))]
        body = "".join(f"    {k} {props[k]}\n" for k in chosen)
        return f"tool {name} {{\n{body}}}\n"

    def call(self, sig: Signature) -> str:
        args = []
        named = False
        for pname, ptype, has_default in sig.params:
            if has_default and self.chance(0.5):
                named = True  # a parameter left out: the ones after it go by name
                continue
            value = self.value(ptype)
            named = named or self.chance(0.3) or self.hostile(0.1)
            args.append(f"{pname}: {value}" if named else value)
        if self.hostile(0.05):
            args.append(self.value(self.pick(TYPES)))  # one too many
        name = sig.name if self.chance(0.9) else f"{sig.module}.{sig.name}"
        return f"{name}({', '.join(args)})"

    def statement(self, level: str, depth: int) -> str:
        pool = [s for s in SIGNATURES if level != "element" or s.kind == "element"]
        roll = self.r.random()
        if depth < 6 and roll < 0.08:
            return f"repeat {self.value('Int') if self.chance(0.3) else self.pick(['1', '2', '3'])} {self.block(level, depth + 1)}"
        if depth < 6 and roll < 0.14 and self.sites:
            items = ", ".join(self.pick(self.sites) for _ in range(self.r.randrange(1, 4)))
            return f"for x in [{items}] {self.block(level, depth + 1)}"
        if depth < 6 and roll < 0.18:
            return f"parallel {self.block(level, depth + 1)}"
        if level == "element" and roll < 0.45:
            return self.primitive()
        if level == "element" and not pool:
            return f"still over {self.timing()}"
        return self.call(self.pick(pool))

    def primitive(self) -> str:
        site = self.value("Site")
        over = f" over {self.timing()}" if self.chance(0.4) else ""
        return self.pick(
            [
                f"goal {self.value('Hand')} at {site} approach {self.quantity('Length')}"
                f" offset {self.vector('cm')}{' orient' if self.chance(0.3) else ''}{over}",
                f"posture twist({self.value('Hand')}, {self.quantity('Angle')}, "
                f"load: {self.quantity('Mass')}){over}",
                f"posture {self.pick(['bend', 'squat', 'kneel', 'sit', 'stand', 'crouch'][: None if self.hostile(0.5) else 5])}{over}",
                f"walk by {self.vector('m')}{over}",
                f"walk to {site}{over}",
                f"grip {self.value('Hand')} {self.pick(['open', 'closed', 'ajar'][: None if self.hostile(0.5) else 2])}{over}",
                f"gaze at {site}{over}",
                f"still over {self.timing()}",
                f"time {self.timing()}",
            ]
        )

    def block(self, level: str, depth: int) -> str:
        stmts = [self.statement(level, depth) for _ in range(self.r.randrange(0, 4))]
        pad = "    " * (depth + 1)
        if stmts and self.chance(0.1):  # several on one line, with an ignore comment
            line = "; ".join(stmts) + "  # mtlc: ignore[MT0201]"
            return "{\n" + pad + line + "\n" + "    " * depth + "}"
        return "{\n" + "".join(f"{pad}{s}\n" for s in stmts) + "    " * depth + "}"

    def definition(self) -> str:
        kind = self.pick(["element", "action"])
        params = []
        defaults = False
        for i in range(self.r.randrange(0, 4)):
            ptype = self.pick(TYPES if self.hostile(0.5) else TYPES[:-1])
            defaults = defaults or self.chance(0.3)
            default = f" = {self.value(ptype)}" if defaults or self.hostile(0.1) else ""
            params.append(f"p{i}: {ptype}{default}")
        self.in_definition = True
        body = self.block(kind, 0)
        self.in_definition = False
        return f"{kind} {self.name()}({', '.join(params)}) {body}\n"

    def task(self) -> str:
        settings = []
        if self.chance(0.4):
            n = None if self.hostile(0.5) else 2
            pop, sex = self.pick(POPULATIONS[:n]), self.pick(SEXES[:n])
            pct = self.pick(PERCENTILES[: None if n is None else 5])
            settings.append(f"manikin {pop} {sex} {pct}")
        if getattr(self, "scene_name", None):
            settings.append(f"scene {self.scene_name}")
        if self.chance(0.4):
            settings.append(f"tool {self.value('Tool')}")
        if self.chance(0.3):
            settings.append(f"budget {self.quantity('Duration')}")
        body = self.block("task", 0)
        head = "".join(f"    {s}\n" for s in settings)
        title = f" {self.string()}" if self.chance(0.5) else ""
        return f"task {self.name()}{title} {{\n{head}{body[2:]}\n"

    def program(self) -> str:
        uses = ("actions", "elements", "tools")
        parts = [f"use stdlib.{m}\n" for m in uses if not self.hostile(0.1)]
        if self.hostile(0.05):
            parts.append(f"use {self.pick(['x' * 256, 'a.' * 200 + 'b', 'missing', 'stdlib'])}\n")
        parts.append(self.scene())
        for _ in range(self.r.randrange(0, 3)):
            parts.append(self.tool())
        for _ in range(self.r.randrange(0, 3)):
            parts.append(self.definition())
        for _ in range(self.r.randrange(1, 3)):
            parts.append(self.task())
        if self.hostile(0.05):  # deep nesting
            depth = self.pick([60, 70, 200, 2000])
            parts.append("task deep {\n" + "{" * depth + "}" * depth + "\n}\n")
        if self.hostile(0.03):
            parts.append(
                "task tokens {\n"
                + " ".join(self.pick(KEYWORDS + PUNCT) for _ in range(40))
                + "\n}\n"
            )
        return "\n".join(parts)


# ------------------------------------------------------------------ mutation of the examples
HOSTILE_TOKENS = ["{", "}", "(", ")", "[", "]", ",", ":", ";", "\n", '"', "#", "-", "deg",
                  "use x", "repeat 99999999", "\x00", "\xff", "\u202e", "1e309",
                  "# mtlc: ignore[MT0201]", "parallel {"]  # fmt: skip


def mutate(rng: random.Random, sources: list[bytes]) -> bytes:
    data = bytearray(rng.choice(sources))
    for _ in range(rng.randrange(1, 6)):
        if not data:
            break
        op = rng.randrange(7)
        i = rng.randrange(len(data))
        if op == 0:  # flip a byte
            data[i] = rng.randrange(256)
        elif op == 1:  # insert random bytes
            data[i:i] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 8)))
        elif op == 2:  # delete a range
            del data[i : i + rng.randrange(1, 40)]
        elif op == 3:  # duplicate a range
            j = min(len(data), i + rng.randrange(1, 200))
            data[j:j] = data[i:j] * rng.randrange(1, 4)
        elif op == 4:  # splice from another example
            other = rng.choice(sources)
            k = rng.randrange(len(other))
            data[i:i] = other[k : k + rng.randrange(1, 300)]
        elif op == 5:  # a hostile number in place of one
            numbers = [m.span() for m in re.finditer(rb"\d+(\.\d*)?", bytes(data))]
            if numbers:
                a, b = rng.choice(numbers)
                data[a:b] = rng.choice(HOSTILE_NUMBERS).encode()
        else:  # a hostile token
            data[i:i] = rng.choice(HOSTILE_TOKENS).encode("utf-8", "surrogatepass")
    return bytes(data)


def make_case(seed: int, index: int, sources: list[bytes]) -> tuple[str, bytes]:
    """Case ``index`` of a run: the same bytes for the same seed, whatever ran before."""
    rng = random.Random(f"{seed}:{index}")
    if index % 2 == 0:
        hostility = 1.0 if index % 4 == 0 else 0.05  # wild, or calm enough to compile
        return "generated", Gen(rng, hostility).program().encode("utf-8", "surrogatepass")
    return "mutated", mutate(rng, sources)


def example_sources() -> list[bytes]:
    return [p.read_bytes() for p in EXAMPLES]


# ------------------------------------------------------------------ the stages
@dataclass
class Outcome:
    status: (
        str  # ok | diagnostics | internal | traceback | nonidempotent | timeout | memory | skipped
    )
    detail: str = ""
    seconds: float = 0.0  # wall time
    cpu: float = 0.0  # CPU time of the worker (user + system): what over-time is judged by
    peak_kb: int = 0
    clean: bool = False  # check: no error, so lint and compile may run


def _has_internal(diagnostics: list[Any]) -> Any:
    return next((d for d in diagnostics if d.code == "MT0900"), None)


def stage_check(path: Path) -> Outcome:
    from mtlc.frontend import run_frontend

    program = run_frontend([path])
    bad = _has_internal(program.diagnostics)
    if bad is not None:
        return Outcome("internal", bad.message)
    return Outcome("ok", clean=not program.sink.has_errors)


def stage_fmt(path: Path) -> Outcome:
    from mtlc.fmt import format_source
    from mtlc.semantics.modules import read_source

    text = read_source(path, "case.mtask", DiagnosticSink())
    if text is None:
        return Outcome("skipped", "not readable as UTF-8 text")
    once = format_source(text, "case.mtask")
    bad = _has_internal(once.diagnostics)
    if once.text is None:
        kept = next((d for d in once.diagnostics if d.code == "MT0109"), None)
        if bad is None and kept is not None:
            return Outcome("refused", kept.message)  # a layout fmt cannot keep: left as it was
        return Outcome("internal", bad.message) if bad is not None else Outcome("diagnostics")
    twice = format_source(once.text, "case.mtask")
    if twice.text != once.text:
        why = twice.diagnostics[0].message if twice.diagnostics else "the output changed"
        return Outcome("nonidempotent", why)
    return Outcome("ok")


def stage_lint(path: Path) -> Outcome:
    from mtlc.lint import LintConfig, lint_paths

    # jobs=1: the compiles run in this (daemonic) worker, which may not start processes, and
    # its CPU time is then the whole lint's
    result = lint_paths([path], LintConfig(), jobs=1)
    bad = next((f for f in result.findings if f.code == "MT0900"), None)
    return Outcome("internal", bad.message) if bad is not None else Outcome("ok")


def stage_compile(path: Path) -> Outcome:
    from mtlc.codegen import GenerateOptions, expand_target, generate_file, stem_of
    from mtlc.frontend import run_frontend
    from mtlc.passes import run_motion

    program = run_frontend([path])
    if program.sink.has_errors:
        return Outcome("skipped", "does not check clean")
    irs = [run_motion(t, program.sink) for t in program.timelines]
    if irs:
        files = generate_file(stem_of(str(path)), irs, GenerateOptions(expand_target("all")))
        for name, data in files.items():
            if name.endswith(".json"):  # valid JSON: no NaN, no Infinity
                json.loads(data, parse_constant=_no_constant)
    bad = _has_internal(program.diagnostics)
    return Outcome("internal", bad.message) if bad is not None else Outcome("ok")


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} in the IR JSON")


class _FakeSocket:
    """Enough of a socket for BaseHTTPRequestHandler: the request in, the response out."""

    def __init__(self, request: bytes) -> None:
        self._in = io.BytesIO(request)
        self.out = bytearray()

    def makefile(self, mode: str, *args: Any, **kwargs: Any) -> Any:
        return self._in if "r" in mode else io.BytesIO()

    def sendall(self, data: bytes) -> None:
        self.out += data

    def settimeout(self, value: float | None) -> None:
        pass

    def setsockopt(self, *args: Any) -> None:
        pass

    def close(self) -> None:
        pass


def serve_requests(rng: random.Random) -> list[bytes]:
    """Hostile requests for the serve endpoints."""
    coords = [
        "1" * 400, "1e400", "NaN", "Infinity", "-0", "1e-400", '"1"', "true", "null", "[1]",
        "0.1", "999", "-1000.5", "[" * 4000, "{}", "1" + "0" * 30,
    ]  # fmt: skip
    bodies = []
    for _ in range(4):
        xyz = ", ".join(rng.choice(coords) if rng.random() < 0.5 else "0.5" for _ in range(3))
        site = rng.choice(['"a"', '"s0"', '"x" ', "1", '"\\u202e"', '"' + "n" * 5000 + '"'])
        bodies.append(f'{{"site": {site}, "position": [{xyz}]}}'.encode())
    bodies.append(b"[" * 4000)
    bodies.append(b'{"site": "a", "position": [0, 0, ' + b"9" * 400 + b"]}")
    bodies.append(bytes(rng.randrange(256) for _ in range(64)))
    requests = []
    for body in bodies:
        length = str(len(body)) if rng.random() < 0.85 else rng.choice(["-1", "²", "99999", "x"])
        kind = "application/json" if rng.random() < 0.9 else "text/plain"
        requests.append(
            b"POST /site HTTP/1.1\r\nHost: 127.0.0.1:8000\r\nContent-Type: "
            + kind.encode()
            + b"\r\nContent-Length: "
            + length.encode()
            + b"\r\n\r\n"
            + body
        )
    for target in ["/", "/motion", "/nope", "/" + "a" * 70000, "/..%2f", "/site"]:
        host = rng.choice(["127.0.0.1:8000", "evil.example:8000", "", "[::1]:8000"])
        requests.append(f"GET {target} HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
    requests.append(b"\x00\xff garbage\r\n\r\n")
    return requests


def stage_serve(seed: int, index: int) -> Outcome:
    try:
        from mtlc.frontend import FrontendOptions
        from mtlc.passes import MotionOptions
        from mtlc.preview import server
    except ImportError as exc:
        return Outcome("skipped", f"unavailable: {exc}")
    try:
        hub = server.MotionHub([], FrontendOptions(), MotionOptions())
        hub.sites = {"a", "s0"}
        hub.move_site = lambda name, position: server.Outcome.DIAGNOSTICS  # type: ignore[method-assign]
        handler = server.make_handler(hub, "<html></html>")
    except (AttributeError, TypeError) as exc:  # the server's API changed: a hook to update
        return Outcome("skipped", f"unavailable: {exc}")

    class _Server:
        server_address = ("127.0.0.1", 8000)
        stopping = True

    rng = random.Random(f"{seed}:{index}:serve")
    for request in serve_requests(rng):
        sock = _FakeSocket(request)
        with contextlib.redirect_stderr(io.StringIO()):
            handler(sock, ("127.0.0.1", 50000), _Server())  # an exception here is a traceback
        status = bytes(sock.out[:12])
        if sock.out and not status.startswith((b"HTTP/1.", b"<!DOCTYPE")):  # 0.9: no status
            return Outcome("internal", f"not an HTTP response: {status!r}")
        if b" 500 " in sock.out[:16]:
            return Outcome("internal", f"500 for {request[:80]!r}")
    return Outcome("ok")


# ------------------------------------------------------------------ the worker
def _peak_kb() -> int:
    with open("/proc/self/status", encoding="ascii") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def _reset_peak() -> None:
    with contextlib.suppress(OSError), open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # resets VmHWM (Linux 4.0+)


def run_stage(stage: str, path: Path, seed: int, index: int) -> Outcome:
    """One stage, in this process: its outcome, its time and its peak resident memory."""
    _reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        if stage == "serve":
            out = stage_serve(seed, index)
        else:
            out = {"check": stage_check, "fmt": stage_fmt, "lint": stage_lint,
                   "compile": stage_compile}[stage](path)  # fmt: skip
    except MemoryError:
        out = Outcome("memory", "MemoryError")
    except RecursionError as exc:
        out = Outcome("traceback", f"RecursionError: {exc}")
    except Exception as exc:
        frames = traceback.extract_tb(exc.__traceback__)[-3:]
        where = " <- ".join(
            f"{Path(f.filename).name}:{f.lineno} {f.name}" for f in reversed(frames)
        )
        out = Outcome("traceback", f"{type(exc).__name__}: {str(exc)[:200]} at {where}")
    out.seconds = time.perf_counter() - t0
    out.cpu = time.process_time() - c0
    out.peak_kb = _peak_kb()
    return out


def _worker(conn: Any, memory_bytes: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    with contextlib.suppress(ValueError, OSError):
        resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, hard))
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 1000))
    while True:
        job = conn.recv()
        if job is None:
            return
        stage, path, seed, index = job
        conn.send(run_stage(stage, Path(path), seed, index))


def _vm_size() -> int:
    with open("/proc/self/status", encoding="ascii") as f:
        for line in f:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


class Worker:
    """A forked worker that runs stages under a time limit and a memory cap."""

    def __init__(self, memory_mb: int) -> None:
        self.memory_bytes = _vm_size() + memory_mb * 1024 * 1024
        self.ctx = mp.get_context("fork")
        self.proc: Any = None
        self.restarts = 0

    def _start(self) -> None:
        self.conn, child = self.ctx.Pipe()
        self.proc = self.ctx.Process(target=_worker, args=(child, self.memory_bytes), daemon=True)
        self.proc.start()

    def run(self, stage: str, path: Path, seed: int, index: int, timeout: float) -> Outcome:
        if self.proc is None or not self.proc.is_alive():
            self._start()
        t0 = time.perf_counter()
        self.conn.send((stage, str(path), seed, index))
        if self.conn.poll(timeout):
            try:
                return self.conn.recv()
            except EOFError:
                pass
            self.stop()
            return Outcome("memory", "the worker died (killed: out of memory?)")
        self.stop()
        self.restarts += 1
        return Outcome("timeout", f"over {timeout:g} s", seconds=time.perf_counter() - t0)

    def stop(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.join()
            self.proc = None


# ------------------------------------------------------------------ the run
@dataclass
class Tally:
    cases: int = 0
    tracebacks: int = 0
    internal: int = 0
    timeouts: int = 0
    over_time: int = 0  # finished, but took more CPU seconds than the limit
    memory: int = 0
    nonidempotent: int = 0
    refused: int = 0
    skipped: int = 0
    clean: int = 0
    peak_kb: int = 0
    slowest: float = 0.0  # wall seconds
    slowest_cpu: float = 0.0
    examples: list[str] = field(default_factory=list)


def warm_up() -> None:
    """Import and touch everything once before the worker forks: a restarted worker (after a
    time-out) then starts at once, and no case pays for the imports."""
    import mtlc.codegen
    import mtlc.lint
    import mtlc.passes

    with contextlib.suppress(ImportError):
        import mtlc.preview.server  # noqa: F401
    for stage in ("check", "fmt"):
        run_stage(stage, EXAMPLES[0], 0, 0)


def run(args: argparse.Namespace) -> dict[str, Tally]:
    stages = [s for s in args.stages.split(",") if s]
    sources = example_sources()
    warm_up()
    tallies = {s: Tally() for s in stages}
    worker = Worker(args.memory_mb)
    workdir = Path(tempfile.mkdtemp(prefix="mtlc-fuzz-"))
    origins: Counter[str] = Counter()
    heavy_left = args.heavy
    save = Path(args.save) if args.save else None
    if save:
        save.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    times = open(args.times, "w", encoding="utf-8") if args.times else None  # noqa: SIM115
    if times is not None:
        times.write("stage\tcase\torigin\tstatus\tcpu_s\twall_s\tpeak_mb\n")
    try:
        for index in range(args.first, args.cases):
            if args.max_seconds and time.perf_counter() - t_start > args.max_seconds:
                print(f"stopped after {index} cases: --max-seconds", file=sys.stderr)
                break
            origin, data = make_case(args.seed, index, sources)
            origins[origin] += 1
            case_dir = workdir / f"c{index}"
            case_dir.mkdir()
            path = case_dir / "case.mtask"
            path.write_bytes(data)
            clean = False
            heavy = False
            for stage in stages:
                if stage in ("lint", "compile") and not (clean and (heavy or heavy_left > 0)):
                    continue
                if stage in ("lint", "compile") and not heavy:
                    heavy, heavy_left = True, heavy_left - 1
                if stage == "serve" and index % args.serve_every:
                    continue
                out = worker.run(stage, path, args.seed, index, args.kill_after)
                _count(tallies[stage], out, args.timeout)
                if stage == "check":
                    clean = out.clean
                failed = out.status in (
                    "traceback",
                    "internal",
                    "nonidempotent",
                    "timeout",
                    "memory",
                )
                if failed or out.cpu > args.timeout or out.peak_kb > args.memory_mb * 1024:
                    _record(tallies[stage], stage, index, origin, out, data, save)
                if times is not None:
                    times.write(f"{stage}\t{index}\t{origin}\t{out.status}\t{out.cpu:.2f}\t"
                                f"{out.seconds:.2f}\t{out.peak_kb // 1024}\n")  # fmt: skip
                    times.flush()
                if save and stage in ("lint", "compile") and out.cpu > args.save_slower:
                    (save / f"case{index}.mtask").write_bytes(data)
            shutil.rmtree(case_dir, ignore_errors=True)
            if args.progress and (index + 1) % args.progress == 0:
                elapsed = time.perf_counter() - t_start
                print(f"... {index + 1} cases, {elapsed:.0f} s", file=sys.stderr, flush=True)
    finally:
        worker.stop()
        shutil.rmtree(workdir, ignore_errors=True)
        if times is not None:
            times.close()
    clean = tallies["check"].clean if "check" in tallies else 0
    print(f"cases: {dict(origins)}; checked clean: {clean}; heavy (lint/compile) cases: {args.heavy - heavy_left}; "
          f"worker restarts: {worker.restarts}; {time.perf_counter() - t_start:.0f} s")  # fmt: skip
    return tallies


def _count(t: Tally, out: Outcome, limit: float) -> None:
    t.cases += 1
    t.tracebacks += out.status == "traceback"
    t.internal += out.status == "internal"
    t.timeouts += out.status == "timeout"
    t.memory += out.status == "memory"
    t.nonidempotent += out.status == "nonidempotent"
    t.refused += out.status == "refused"
    t.skipped += out.status == "skipped"
    t.clean += out.clean
    t.over_time += out.status != "timeout" and out.cpu > limit
    t.peak_kb = max(t.peak_kb, out.peak_kb)
    t.slowest = max(t.slowest, out.seconds)
    t.slowest_cpu = max(t.slowest_cpu, out.cpu)


def _record(
    t: Tally, stage: str, index: int, origin: str, out: Outcome, data: bytes, save: Path | None
) -> None:
    line = f"{stage} case {index} ({origin}): {out.status} {out.cpu:.1f} s CPU, {out.seconds:.1f} s wall, " \
        f"{out.peak_kb // 1024} MB: {out.detail[:300]}"  # fmt: skip
    t.examples.append(line)
    if save:
        (save / f"case{index}.mtask").write_bytes(data)
        with open(save / "failures.txt", "a", encoding="utf-8") as f:
            f.write(line + "\n")


def table(tallies: dict[str, Tally], limit: float, cpu_limit: float) -> str:
    head = ("stage", "cases", "tracebacks", "MT0900", f"timeout {limit:g}s wall",
            f"over {cpu_limit:g}s CPU", "memory", "fmt non-idempotent", "fmt refused", "skipped",
            "slowest CPU s", "slowest wall s", "peak RSS MB")  # fmt: skip
    rows = [head]
    for stage, t in tallies.items():
        rows.append((stage, t.cases, t.tracebacks, t.internal, t.timeouts, t.over_time, t.memory,
                     t.nonidempotent if stage == "fmt" else "-",
                     t.refused if stage == "fmt" else "-", t.skipped,
                     f"{t.slowest_cpu:.2f}", f"{t.slowest:.2f}", t.peak_kb // 1024))  # fmt: skip
    widths = [max(len(str(r[i])) for r in rows) for i in range(len(head))]
    lines = ["| " + " | ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)) + " |"
             for r in rows]  # fmt: skip
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines)


def tallies_from_times(path: Path, limit: float) -> dict[str, Tally]:
    """The table's counts from a ``--times`` file: a run stopped before its end still gives
    its table."""
    tallies: dict[str, Tally] = {}
    lines = path.read_text(encoding="utf-8").splitlines()[1:]
    for line in lines:
        stage, _index, _origin, status, cpu, wall, peak_mb = line.split("\t")
        out = Outcome(status, seconds=float(wall), cpu=float(cpu), peak_kb=int(peak_mb) * 1024)
        _count(tallies.setdefault(stage, Tally()), out, limit)
    return tallies


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--first",
        type=int,
        default=0,
        help="start at this case (each case is made from the seed and its index alone, so a "
        "run can be split across processes: --first K --cases N runs K..N-1)",
    )
    parser.add_argument("--stages", default=",".join(STAGES))
    parser.add_argument("--heavy", type=int, default=100, help="lint/compile this many clean cases")
    parser.add_argument("--serve-every", type=int, default=10, help="serve stage on every Nth case")
    parser.add_argument(
        "--timeout",
        type=float,
        default=10.0,
        help="a stage using more CPU seconds than this is 'over time'",
    )
    parser.add_argument(
        "--kill-after", type=float, default=60.0, help="a stage is killed after this (wall s: hang)"
    )
    parser.add_argument("--memory-mb", type=int, default=1024, help="the worker's memory cap")
    parser.add_argument(
        "--max-seconds", type=float, default=0, help="stop starting cases after this long"
    )
    parser.add_argument("--save", help="write failing cases and failures.txt into this folder")
    parser.add_argument(
        "--times", help="write every stage's CPU and wall seconds and peak RSS here (TSV)"
    )
    parser.add_argument(
        "--save-slower",
        type=float,
        default=1e9,
        help="with --save, also save lint/compile cases using more CPU seconds than this",
    )
    parser.add_argument("--progress", type=int, default=0, help="print progress every N cases")
    parser.add_argument(
        "--table-from", help="print the table of an earlier run's --times file and stop"
    )
    args = parser.parse_args(argv)
    if args.table_from:
        print(table(tallies_from_times(Path(args.table_from), args.timeout), args.kill_after,
                    args.timeout))  # fmt: skip
        return 0
    tallies = run(args)
    print(table(tallies, args.kill_after, args.timeout))
    failures = [line for t in tallies.values() for line in t.examples]
    for line in failures[:40]:
        print(line)
    bad = sum(t.tracebacks + t.internal + t.timeouts + t.memory + t.nonidempotent
              for t in tallies.values())  # fmt: skip
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
