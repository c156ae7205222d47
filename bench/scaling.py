"""How `compile` and `lint` grow with motion length (issue 17: none over 10 s, linear in length).

    python bench/scaling.py [--kinds walk,hold,steps] [--scale 1,4] [--stages compile,lint]

Three generated procedures, each at sizes ``base × scale``: (a) ``walk``: a ``walk_to`` a site
``22 m × scale`` away; (b) ``hold``: ``inspect`` a site for ``2.5 min × scale``; (c) ``steps``:
``75 × scale`` short reach/look/inspect steps. Every run is a fresh process (``python -m mtlc``
in-process inside it, so imports are not timed; the child also reports its wall time with
imports). Prints seconds (the run's wall and CPU time), peak RSS and, per kind and stage, the
growth exponent ``log(t2 / t1) / log(n2 / n1)`` of the CPU time between the smallest and the
largest size (1 = linear).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASE = {"walk": 22, "hold": 2.5, "steps": 75}  # metres, minutes, steps
UNIT = {"walk": "m", "hold": "min", "steps": "steps"}

HEAD = """use stdlib.actions
use stdlib.elements

scene s {{
    ground 0 cm
    site a at (0, 0, 0) cm
    site far at ({far}, 0, 0) cm
    site v at (10, 120, 60) cm normal (0, 0, -1)
    site w at (-10, 110, 60) cm normal (0, 0, -1)
}}

task t "scaling" {{
    manikin gb10000_1988 male p50
    scene s
    budget 600 min
{body}}}
"""

CHILD = """
import json, resource, sys, time
t0 = time.perf_counter()
from mtlc.cli import main
def cpu():  # this process and its (reaped) workers: lint compiles in worker processes
    return sum(r.ru_utime + r.ru_stime for r in map(resource.getrusage, (resource.RUSAGE_SELF,
               resource.RUSAGE_CHILDREN)))
t1, c1 = time.perf_counter(), cpu()
try:
    code = main(sys.argv[1:])
except SystemExit as e:
    code = e.code
t2, c2 = time.perf_counter(), cpu()
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps({"code": code, "run": t2 - t1, "cpu": c2 - c1, "wall": t2 - t0, "rss_mb": rss}),
      file=sys.stderr)
"""


def procedure(kind: str, size: float) -> str:
    """The ``.mtask`` text of one generated case."""
    if kind == "walk":
        return HEAD.format(far=round(size * 100), body="    walk_to(far)\n")
    if kind == "hold":
        return HEAD.format(far=100, body=f"    look(v)\n    inspect(v, {size:g} min)\n")
    sites = (["v", "w"] * int(size))[: int(size)]
    body = "".join(f"    reach(right, {s})\n    look({s})\n    inspect({s}, 1 s)\n" for s in sites)
    return HEAD.format(far=100, body=body)


def run(
    stage: str, path: Path, out: Path, timeout: float, src: Path = ROOT / "src"
) -> dict[str, float]:
    """One fresh process: ``mtlc <stage>`` of ``path``; its times and peak RSS."""
    args = [stage, "--motion-budget", "600min", str(path)]
    if stage == "compile":
        args += ["--target", "all", "-o", str(out)]
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**__import__("os").environ, "PYTHONPATH": str(src)},
    )
    last = proc.stderr.strip().splitlines()[-1]
    return json.loads(last)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", default="walk,hold,steps")
    ap.add_argument("--scale", default="1,4", help="size multipliers, e.g. 1,2,4")
    ap.add_argument("--stages", default="compile,lint")
    ap.add_argument("--timeout", type=float, default=580.0, help="seconds per run")
    ap.add_argument("--src", type=Path, default=ROOT / "src",
                    help="the mtlc sources to run (another checkout's src: before and after)")  # fmt: skip
    a = ap.parse_args()
    scales = [float(s) for s in a.scale.split(",")]
    print(
        f"{'case':<18} {'stage':<8} {'run s':>8} {'CPU s':>8} {'wall s':>8} {'RSS MB':>8} {'exit':>5}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for kind in a.kinds.split(","):
            for stage in a.stages.split(","):
                seen: list[tuple[float, float]] = []
                for k in scales:
                    size = BASE[kind] * k
                    path = Path(tmp) / f"{kind}_{k:g}.mtask"
                    path.write_text(procedure(kind, size), encoding="utf-8")
                    r = run(stage, path, Path(tmp) / "out", a.timeout, a.src)
                    name = f"{kind} {size:g} {UNIT[kind]}"
                    print(
                        f"{name:<18} {stage:<8} {r['run']:8.2f} {r['cpu']:8.2f} {r['wall']:8.2f} "
                        f"{r['rss_mb']:8.0f} {r['code']!s:>5}",
                        flush=True,
                    )
                    seen.append((size, r["cpu"]))  # CPU: the machine's load moves wall time
                (n1, t1), (n2, t2) = seen[0], seen[-1]
                if n2 > n1 and t1 > 0:
                    growth = math.log(t2 / t1) / math.log(n2 / n1)
                    print(f"{'':<18} {stage:<8} growth exponent {growth:.2f}", flush=True)


if __name__ == "__main__":
    main()
