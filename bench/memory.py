"""Peak memory and time of long inputs (issue 17, section 2): each run in a fresh process.

    python bench/memory.py [--only NAME ...] [--cap-mb 6000] [--timeout 600] [--src DIR]

Builds each input in a temporary folder, runs ``python -m mtlc ...`` on it in a subprocess
under a memory cap (RLIMIT_AS) and a timeout, and prints a table: input, seconds (wall),
peak resident MB (the child's ru_maxrss), exit code and the goal. Exit code 1 with MT0407 is
the motion budget answering; 124 is the timeout; a MemoryError shows as exit 2 (MT0900).
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

STEPS = ("reach(right, bolt_a)", "grasp(right)", "move(right, tray)", "release(right)")


def steps_file(size: int) -> str:
    """One task of ``size`` bytes of reach/grasp/move/release steps (1 MB: ~7 h of motion)."""
    head = (
        "use stdlib.actions\nuse stdlib.elements\n\nscene bay {\n    ground 0 cm\n"
        "    site bolt_a at (-20, 135, 112) cm normal (0, 0, -1)\n"
        "    site tray at (30, 90, 60) cm normal (0, 1, 0)\n}\n\n"
        'task big "many steps" {\n    scene bay\n'
    )
    out, n, i = [head], len(head), 0
    while n < size - 2:
        line = f"    {STEPS[i % len(STEPS)]}\n"
        out.append(line)
        n, i = n + len(line), i + 1
    return "".join(out) + "}\n"


def walk_file(km: float) -> str:
    return (
        "use stdlib.actions\n\nscene field {\n"
        f"    site far at ({km * 1000:g}, 0, 0) m\n}}\n\ntask walk {{\n    scene field\n"
        "    walk_to(far)\n}\n"
    )


def inspect_file(minutes: float) -> str:
    return (
        "use stdlib.actions\n\nscene bay {\n    site gauge at (0, 150, 60) cm normal (0, 0, -1)\n"
        f"}}\n\ntask watch {{\n    scene bay\n    inspect(gauge, {minutes:g} min)\n}}\n"
    )


@dataclass(frozen=True)
class Case:
    name: str
    make: Callable[[], str]
    args: tuple[str, ...]  # after the command; the file goes last
    command: str
    goal: str


CASES = [
    Case("lint 1 MB of steps", lambda: steps_file(1_000_000), (), "lint", "<= 1 GB"),
    Case("compile 1 MB of steps", lambda: steps_file(1_000_000), (), "compile", "<= 1 GB"),
    Case("lint 20 KB of steps (8.4 min)", lambda: steps_file(20_000), (), "lint", "<= 1 GB"),
    Case("compile 20 KB of steps (8.4 min)", lambda: steps_file(20_000), (), "compile", "<= 1 GB"),
    Case("compile walk_to 1 km (12 min)", lambda: walk_file(1), (), "compile", "linear, <= 1 GB"),
    Case("compile walk_to 10 km (2 h)", lambda: walk_file(10), (), "compile", "MT0407, fast"),
    Case("compile inspect 60 min", lambda: inspect_file(60), (), "compile", "MT0407, fast"),
    Case(
        "compile inspect 60 min, budget 2h, all",
        lambda: inspect_file(60),
        ("--motion-budget", "2h", "--target", "all"),
        "compile",
        "linear, <= 1 GB",
    ),
    Case(
        "lint inspect 60 min, budget 2h",
        lambda: inspect_file(60),
        ("--motion-budget", "2h"),
        "lint",
        "linear, <= 1 GB",
    ),
]


def run(
    case: Case, folder: Path, cap_mb: int, timeout: float, src: Path = ROOT / "src"
) -> tuple[float, float, float, int]:
    """(wall seconds, CPU seconds of the child, peak MB, exit code) of the case in a fresh process."""
    path = folder / f"{case.name.split()[1]}.mtask"
    path.write_text(case.make(), encoding="utf-8")
    argv = [sys.executable, "-m", "mtlc", case.command, *case.args]
    if case.command == "compile":
        argv += ["-o", str(folder / "out")]
    argv.append(str(path))
    env = {**os.environ, "PYTHONPATH": str(src)}

    def limit() -> None:
        cap = cap_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    t0 = time.perf_counter()
    proc = subprocess.Popen(
        argv,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        preexec_fn=limit,
    )
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            code = os.waitstatus_to_exitcode(status)
            break
        if time.perf_counter() - t0 > timeout:
            proc.kill()
            _, _, usage = os.wait4(proc.pid, 0)
            code = 124
            break
        time.sleep(0.05)
    cpu = usage.ru_utime + usage.ru_stime  # what the run cost, whatever the machine's load
    return time.perf_counter() - t0, cpu, usage.ru_maxrss / 1024, code


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", default=None, help="cases whose name has this")
    parser.add_argument("--cap-mb", type=int, default=6000, help="memory cap (RLIMIT_AS), MB")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per case")
    parser.add_argument("--src", type=Path, default=ROOT / "src",
                        help="the mtlc sources to run (another checkout's src: before and after)")  # fmt: skip
    args = parser.parse_args()
    cases = [c for c in CASES if not args.only or any(o in c.name for o in args.only)]
    print(
        "| input | seconds | CPU s | peak MB | exit | goal |\n|---|---|---|---|---|---|", flush=True
    )
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            seconds, cpu, peak, code = run(case, Path(tmp), args.cap_mb, args.timeout, args.src)
            print(
                f"| {case.name} | {seconds:.1f} | {cpu:.1f} | {peak:.0f} | {code} | {case.goal} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
