"""CPU time to check a scene with a big model, against the same scene without it (issue 20).

Writes binary STL files of N random triangles into a temporary folder, then for each runs the
front end (parse, check: the file read with trimesh, expansion: the model placed) on a small
task whose scene names it, in a fresh process (so trimesh's import, about 0.7 s, is counted
once, as a user's `mtlc check` pays it), and prints the CPU seconds (user + system).

    python bench/models.py                      # 10 k, 100 k and 1 M triangles
    python bench/models.py --triangles 2000000
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

TASK = """use stdlib.actions
scene s {{
{model}    site front at (0, 0, 1) m
}}
task t {{
    scene s
    walk_to(front)
}}
"""
RUN = (
    "import sys; from pathlib import Path; from mtlc.frontend import run_frontend; "
    "p = run_frontend([Path(sys.argv[1])]); assert not p.diagnostics, p.diagnostics"
)


def write_stl(path: Path, n: int) -> None:
    rng = np.random.default_rng(0)
    record = np.zeros(n, dtype=[("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    record["v"] = rng.uniform(-0.5, 0.5, (n, 3, 3))
    path.write_bytes(bytes(80) + np.uint32(n).tobytes() + record.tobytes())


def cpu_seconds(mtask: Path) -> float:
    """User + system CPU of a fresh process running the front end on ``mtask``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", RUN, str(mtask)], check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=int, nargs="*", default=[10_000, 100_000, 1_000_000])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        plain = folder / "plain.mtask"
        plain.write_text(TASK.format(model=""), encoding="utf-8")
        base = cpu_seconds(plain)
        print(f"{'triangles':>10}  {'CPU s':>6}  {'over no model':>13}")
        print(f"{0:>10,}  {base:6.2f}  {0.0:13.2f}")
        for n in args.triangles:
            write_stl(folder / f"m{n}.stl", n)
            mtask = folder / f"m{n}.mtask"
            model = f'    model m "m{n}.stl" units m\n'
            mtask.write_text(TASK.format(model=model), encoding="utf-8")
            cpu = cpu_seconds(mtask)
            print(f"{n:>10,}  {cpu:6.2f}  {cpu - base:13.2f}")


if __name__ == "__main__":
    main()
