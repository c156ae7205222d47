"""Hostile and merely large inputs: time and peak memory of one mtlc command on each (issue 17, 2).

    python bench/hostile.py [--only NAME ...] [--scale 1.0] [--timeout 120] [--mem-mb 4096]

Each case builds its input in a temporary folder, runs ``python -m mtlc <command> <file>`` in a
fresh subprocess (the worktree's own ``src`` first on the path) under a wall-clock timeout and an
address-space cap, and prints one row: the case, the input's size, the wall time (interpreter
start-up and imports included: the ``startup`` row is that alone), the command's own time (after
the imports, measured inside the child: what the goals are about) and its CPU time (steadier on
a shared machine, and what the ok column compares with the goal), the peak RSS, the exit code
(``timeout`` or ``killed`` when it did not end by itself), whether the goal is met and the goal.

A case is a name, the command, a builder that writes the input at a given scale, and the goal:
to add one, append a ``Case`` to ``CASES``. ``--scale 0.1`` builds every input ten times smaller
(a quick look; the goals are stated for scale 1).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Case:
    name: str
    command: tuple[str, ...]  # the mtlc subcommand and its options; the input file is appended
    build: Callable[[Path, float], Path]  # (folder, scale) -> the input file
    goal: str
    max_seconds: float | None = None  # for the ok column; None: no time goal
    max_mb: float | None = None


@dataclass(frozen=True)
class Result:
    seconds: float  # wall time of the whole process
    command_seconds: float | None  # the command alone, after start-up (None: it never returned)
    command_cpu: float | None  # its CPU time: steadier than wall time on a shared machine
    peak_mb: float
    exit: str
    size: int

    def ok(self, case: Case) -> str:
        if case.max_seconds is None and case.max_mb is None:
            return ""
        if self.exit not in ("0", "1") or self.command_cpu is None:
            return "NO"
        fast = case.max_seconds is None or self.command_cpu < case.max_seconds
        small = case.max_mb is None or self.peak_mb <= case.max_mb
        return "yes" if fast and small else "NO"


# the child: imports first, then times the command alone (start-up is several seconds on a
# loaded machine, and is the same for every row). mtlc imports a command's modules when it
# runs; building the whole parser imports every command's, as `from mtlc.cli import main` did
_DRIVER = """\
import os, sys, time
from mtlc.cli import build_parser, main
build_parser()
t0, c0 = time.perf_counter(), time.process_time()
try:
    rc = main(sys.argv[1:])
finally:
    with open(os.environ["MTLC_HOSTILE_TIME"], "w") as f:
        f.write(f"{time.perf_counter() - t0!r} {time.process_time() - c0!r}")
raise SystemExit(rc)
"""


# ---------------------------------------------------------------- inputs
def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def empty_file(folder: Path, scale: float) -> Path:
    return _write(folder, "empty.mtask", "# nothing\n")


def nested_parens(folder: Path, scale: float, opener: str = "(", closer: str = ")") -> Path:
    """An argument wrapped in ``n`` brackets: 100 KB of them at scale 1."""
    n = max(1, int(50_000 * scale))
    text = (
        "use stdlib.actions\n\nscene s {\n    site bolt at (0, 100, 40) cm\n}\n\n"
        "task t {\n    scene s\n"
        f"    inspect(bolt, {opener * n}2 s{closer * n})\n}}\n"
    )
    return _write(folder, "parens.mtask", text)


def nested_brackets(folder: Path, scale: float) -> Path:
    return nested_parens(folder, scale, "[", "]")


def unclosed_parens(folder: Path, scale: float) -> Path:
    """100 KB of `(` and nothing else."""
    return _write(folder, "unclosed.mtask", "(" * max(1, int(100_000 * scale)) + "\n")


def mismatched_closers(folder: Path, scale: float) -> Path:
    """50 KB of `(` closed by 50 KB of `]`: every closer looks for an opener that is not there."""
    n = max(1, int(50_000 * scale))
    return _write(folder, "mismatched.mtask", "task t {\n    f(" + "(" * n + "]" * n + ")\n}\n")


def nested_braces(folder: Path, scale: float) -> Path:
    n = max(1, int(50_000 * scale))
    return _write(folder, "braces.mtask", "task t {\n" + "{" * n + "}" * n + "\n}\n")


def deep_unary(folder: Path, scale: float) -> Path:
    """`- - - ... 2 s`: depth without any bracket."""
    n = max(1, int(50_000 * scale))
    text = "use stdlib.actions\n\ntask t {\n    hold(" + "-" * n + "2 s)\n}\n"
    return _write(folder, "unary.mtask", text)


def long_sum(folder: Path, scale: float) -> Path:
    """`1 s + 1 s + ...`: a left-leaning tree as deep as the sum is long."""
    n = max(1, int(20_000 * scale))
    text = "use stdlib.actions\n\ntask t {\n    hold(" + " + ".join(["1 s"] * n) + ")\n}\n"
    return _write(folder, "sum.mtask", text)


def many_sites(count: int) -> Callable[[Path, float], Path]:
    """A scene of ``count`` sites and a task that looks at each by name (and some by
    `scene.site`): every name is resolved against the scene."""

    def build(folder: Path, scale: float) -> Path:
        n = max(1, int(count * scale))
        lines = ["use stdlib.actions", "use stdlib.elements", "", "scene bay {"]
        lines += [
            f"    site s{i} at ({i % 100}, {100 + i % 7}, {40 + i // 100 % 50}) cm"
            for i in range(n)
        ]
        lines += ["}", "", "element glance(target: Site) {", "    gaze at target over 0.1 s", "}"]
        lines += ["", 'task t "many sites" {', "    scene bay"]
        lines += [f"    glance(s{i})" for i in range(n)]
        lines += [f"    glance(bay.s{i})" for i in range(0, n, 10)]
        lines += ["}", ""]
        return _write(folder, f"sites_{count}.mtask", "\n".join(lines))

    return build


def nested_empty_for(folder: Path, scale: float) -> Path:
    """Three `for` loops over 1,000 items each around an empty body: 10^9 rounds of nothing."""
    n = max(2, int(1000 * scale))
    items = "[" + ", ".join(str(i) for i in range(n)) + "]"
    text = (
        "use stdlib.actions\n\nscene s {\n    site bolt at (0, 100, 40) cm\n}\n\n"
        "task t {\n    scene s\n    inspect(bolt)\n"
        f"    for a in {items} {{\n        for b in {items} {{\n"
        f"            for c in {items} {{\n            }}\n        }}\n    }}\n}}\n"
    )
    return _write(folder, "empty_for.mtask", text)


def deep_for(folder: Path, scale: float) -> Path:
    """60 nested `for` loops over two items around an empty body: 2^60 rounds of nothing."""
    depth = 60
    text = "use stdlib.actions\n\nscene s {\n    site bolt at (0, 100, 40) cm\n}\n\n"
    text += "task t {\n    scene s\n    inspect(bolt)\n"
    text += "".join(f"for v{i} in [1, 2] {{\n" for i in range(depth))
    text += "}\n" * depth + "}\n"
    return _write(folder, "deep_for.mtask", text)


# a realistic chunk (a scene, definitions with comments, a task), repeated with new names
_CHUNK = """\
# Bay {i}: loosen and re-torque the access bolts.
scene bay_{i} {{
    ground 0 cm
    site bolt_a at (-20, 105, 110) cm normal (0, 0, -1)  # upper left
    site bolt_b at (20, 105, 110) cm normal (0, 0, -1)
    site tray at (-35, 5, 80) cm normal (0, 1, 0)
    site stand_here at (0, 0, 60) cm
}}

# Turn a bolt a few times, regrasping between the turns.
action service_{i}(hand: Hand, bolt: Site, turns: Int = 2) {{
    look(bolt)
    reach(hand, bolt, case: C)  # a small target
    grasp(hand)
    repeat turns {{
        turn(hand, -90 deg, 0.2 kg)
    }}
    release(hand)
}}

element brace_{i}(hand: Hand, at_site: Site) {{
    goal hand at at_site approach 3 cm over 0.4 s
    time mtm.reach(B)
}}

task service_bay_{i} "Service bay {i}" {{
    manikin gb10000_1988 female p50
    scene bay_{i}
    walk_to(stand_here)
    service_{i}(right, bolt_a)
    parallel {{
        brace_{i}(left, bolt_b)
        inspect(bolt_a, 1 s)
    }}
    service_{i}(right, bolt_b, turns: 3)  # mtlc: ignore[MT0501] the bolt is reached from below
    pick(left, tray)
    place(left, tray)
}}

"""


def steps_file(target_bytes: int, name: str) -> Callable[[Path, float], Path]:
    """Valid steps with comments, about ``target_bytes`` at scale 1 (many tasks, so that no
    task is over the expansion budget)."""

    def build(folder: Path, scale: float) -> Path:
        head = "use stdlib.actions\nuse stdlib.elements\n\n"
        chunks = max(1, int(target_bytes * scale / len(_CHUNK.format(i=0))))
        body = "".join(_CHUNK.format(i=i) for i in range(chunks))
        return _write(folder, name, head + body.rstrip("\n") + "\n")

    return build


def trailing_comments(count: int) -> Callable[[Path, float], Path]:
    """A task of ``count`` steps, each with a trailing `# mtlc: ignore[...]` comment: every
    comment is placed, and every suppression's coverage checked, by fmt."""

    def build(folder: Path, scale: float) -> Path:
        n = max(1, int(count * scale))
        lines = ["use stdlib.actions", "", "scene bay {", "    site bolt at (0, 100, 40) cm", "}"]
        lines += ["", "# many steps", "task t {", "    scene bay"]
        lines += [
            f"    inspect(bolt, {1 + i % 5} s)  # mtlc: ignore[MT0604] step {i}" for i in range(n)
        ]
        lines += ["}", ""]
        return _write(folder, f"comments_{count}.mtask", "\n".join(lines))

    return build


CASES: list[Case] = [
    Case("startup (empty file)", ("check",), empty_file, "reference: start-up and imports"),
    Case("100 KB nested ( )", ("check",), nested_parens, "< 1 s, MT0104", 1.0),
    Case("100 KB nested [ ]", ("check",), nested_brackets, "< 1 s, MT0104", 1.0),
    Case("100 KB of (", ("check",), unclosed_parens, "< 1 s, MT0104", 1.0),
    Case("50 KB ( then 50 KB ]", ("check",), mismatched_closers, "< 1 s, a diagnostic", 1.0),
    Case("100 KB nested { }", ("check",), nested_braces, "< 1 s, MT0104", 1.0),
    Case("50 KB unary minus", ("check",), deep_unary, "< 1 s, MT0104", 1.0),
    Case("20,000-term sum", ("check",), long_sum, "< 1 s, MT0104", 1.0),
    Case("100 KB nested ( ), fmt", ("fmt", "--check"), nested_parens, "< 1 s, MT0104", 1.0),
    Case("1k sites by name", ("check",), many_sites(1_000), "linear"),
    Case("10k sites by name", ("check",), many_sites(10_000), "linear"),
    Case("50k sites by name", ("check",), many_sites(50_000), "linear"),
    Case("nested empty for 1000^3", ("check",), nested_empty_for, "diagnostic or instant", 2.0),
    Case("60 nested for over 2", ("check",), deep_for, "diagnostic or instant", 2.0),
    Case("fmt 1.8 MB", ("fmt", "--check"), steps_file(1_800_000, "big.mtask"), "< 2 s", 2.0),
    Case("fmt 20k trailing comments", ("fmt", "--check"), trailing_comments(20_000), "linear"),
    Case("check 1 MB valid steps", ("check",), steps_file(1_000_000, "steps.mtask"), "linear"),
]


# ---------------------------------------------------------------- running
def run(
    argv: list[str], timeout: float, mem_mb: int, env: dict[str, str]
) -> tuple[float, float, str]:
    """Wall seconds, peak RSS (MB) and exit status of ``argv`` under the limits."""
    cap = mem_mb * 1024 * 1024

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    t0 = time.perf_counter()
    proc = subprocess.Popen(
        argv,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
        preexec_fn=limit,
    )
    status = "?"
    while True:
        pid, wait_status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            proc.returncode = os.waitstatus_to_exitcode(wait_status)
            status = str(proc.returncode) if proc.returncode >= 0 else "killed"
            break
        if time.perf_counter() - t0 > timeout:
            proc.kill()
            _, _, usage = os.wait4(proc.pid, 0)
            proc.returncode = -9
            status = "timeout"
            break
        time.sleep(0.01)
    seconds = time.perf_counter() - t0
    return seconds, usage.ru_maxrss / 1024, status


def measure(case: Case, folder: Path, scale: float, timeout: float, mem_mb: int) -> Result:
    path = case.build(folder, scale)
    timing = folder / "command-seconds"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "MTLC_HOSTILE_TIME": str(timing)}
    argv = [sys.executable, "-c", _DRIVER, *case.command, str(path)]
    seconds, peak, status = run(argv, timeout, mem_mb, env)
    command = cpu = None
    if timing.exists():
        command, cpu = (float(x) for x in timing.read_text().split())
    return Result(seconds, command, cpu, peak, status, path.stat().st_size)


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--only", nargs="*", default=None, help="cases whose name contains any of these"
    )
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--mem-mb", type=int, default=4096)
    ap.add_argument("--list", action="store_true", help="list the cases and stop")
    args = ap.parse_args()
    cases = [c for c in CASES if args.only is None or any(word in c.name for word in args.only)]
    if args.list:
        for c in cases:
            print(f"{c.name}: mtlc {' '.join(c.command)} <file>  (goal: {c.goal})")
        return 0
    header = (
        f"{'input':<28} {'size':>9} {'wall':>8} {'command':>8} {'cmd CPU':>8} {'peak RSS':>9}"
        f" {'exit':>7}"
        f" {'ok':>3}  goal"
    )
    print(header)
    print("-" * len(header))
    with tempfile.TemporaryDirectory(prefix="mtlc-hostile-") as tmp:
        for case in cases:
            folder = Path(tmp) / str(CASES.index(case))
            folder.mkdir()
            r = measure(case, folder, args.scale, args.timeout, args.mem_mb)
            size = f"{r.size / 1024:,.0f} KB" if r.size >= 1024 else f"{r.size} B"
            command = "-" if r.command_seconds is None else f"{r.command_seconds:.2f}s"
            cpu = "-" if r.command_cpu is None else f"{r.command_cpu:.2f}s"
            print(
                f"{case.name:<28} {size:>9} {r.seconds:>7.2f}s {command:>8} {cpu:>8}"
                f" {r.peak_mb:>6.0f} MB"
                f" {r.exit:>7} {r.ok(case):>3}  {case.goal}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
