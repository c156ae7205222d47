"""How much do the outputs move when OpenBLAS picks another kernel? (issue 17)

Compiles .mtask files in fresh subprocesses, one per (OPENBLAS_CORETYPE, manikin), with every
target, and prints per file and manikin the largest difference of any kernel from the first:
BVH rotation channels (degrees), BVH positions (metres), every number of the IR JSON and every
number of the JackScript module. OPENBLAS_CORETYPE is read when numpy loads OpenBLAS, so it
only takes effect in a fresh process; the kernel each process really got is printed too.

    python bench/blas_stability.py                       # examples + bench/blas_tasks, 4 manikins
    python bench/blas_stability.py examples/remove_avionics_unit.mtask --kernels Haswell,Prescott

A structural difference (another number of frames or of numbers) is printed as ``STRUCT``. The
``raw_*`` columns compare the frames before printing (a second process per job runs the passes
and saves them), so they show differences below the printed precision too.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_FILES = sorted((ROOT / "examples").glob("*.mtask")) + sorted(
    (ROOT / "bench" / "blas_tasks").glob("*.mtask")
)
DEFAULT_KERNELS = ("Haswell", "Prescott", "Sandybridge", "Zen")
DEFAULT_MANIKINS = (
    "gb10000_1988:female:5",
    "gb10000_1988:female:50",
    "gb10000_1988:male:50",
    "gb10000_1988:male:95",
)
NUMBER = re.compile(r"-?\d+\.\d+(?:[eE][-+]?\d+)?|-?\d+[eE][-+]?\d+")
CORENAME = (
    "import ctypes, glob, os, numpy\n"
    "libs = glob.glob(os.path.join(os.path.dirname(numpy.__file__), '..', 'numpy.libs', '*openblas*'))\n"
    "f = getattr(ctypes.CDLL(libs[0]), 'scipy_openblas_get_corename64_', None) if libs else None\n"
    "if f is not None:\n"
    "    f.restype = ctypes.c_char_p\n"
    "print(f().decode() if f is not None else '?')\n"
)


RAW = """
import sys
from pathlib import Path
import numpy as np
from mtlc.cli import _manikin
from mtlc.frontend import FrontendOptions, run_frontend
from mtlc.passes import MotionOptions, run_motion
out, fps, man, files = sys.argv[1], float(sys.argv[2]), _manikin(sys.argv[3]), sys.argv[4:]
prog = run_frontend([Path(f) for f in files], FrontendOptions(manikin=man))
arrays = {}
for tl in prog.timelines:
    fr = run_motion(tl, prog.sink, MotionOptions(fps=fps)).frames
    stem = Path(tl.file).stem
    arrays[stem + "|deg"] = np.degrees(fr.q)
    arrays[stem + "|m"] = fr.root_position
    arrays[stem + "|quat"] = fr.root_rotation
np.savez(out, **arrays)
"""


def env_for(kernel: str) -> dict[str, str]:
    env = dict(os.environ, OPENBLAS_CORETYPE=kernel, PYTHONPATH=str(ROOT / "src"))
    env["OPENBLAS_NUM_THREADS"] = env.get("OPENBLAS_NUM_THREADS", "1")
    return env


def corename(kernel: str) -> str:
    """The OpenBLAS kernel a fresh process gets with this OPENBLAS_CORETYPE."""
    out = subprocess.run(
        [sys.executable, "-c", CORENAME], env=env_for(kernel), capture_output=True, text=True
    )
    return out.stdout.strip() or "?"


def compile_all(files: list[Path], kernel: str, manikin: str, out: Path, fps: float) -> None:
    cmd = [sys.executable, "-m", "mtlc", "compile", *map(str, files), "--target", "all"]
    cmd += ["--fps", str(fps), "--manikin", manikin, "-o", str(out)]
    proc = subprocess.run(cmd, env=env_for(kernel), capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{kernel} {manikin}: compile failed\n{proc.stderr[-2000:]}")
    raw = [sys.executable, "-c", RAW, str(out / "raw.npz"), str(fps), manikin, *map(str, files)]
    proc = subprocess.run(raw, env=env_for(kernel), capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{kernel} {manikin}: raw frames failed\n{proc.stderr[-2000:]}")


def raw_diffs(a: Path, b: Path) -> dict[str, float]:
    """The unprinted frames: joint angles in degrees, root position in metres, root quaternion."""
    with np.load(a) as fa, np.load(b) as fb:
        return {
            k: float(np.max(np.abs(fa[k] - fb[k]), initial=0.0))
            if fa[k].shape == fb[k].shape
            else float("inf")
            for k in fa.files
        }


def bvh_numbers(text: str) -> tuple[list[bool], list[list[float]]]:
    """(is_position per channel, frames of channel values) of a BVH file."""
    head, motion = text.split("MOTION", 1)
    is_pos: list[bool] = []
    for line in head.splitlines():
        parts = line.split()
        if parts and parts[0] == "CHANNELS":
            is_pos += [p.endswith("position") for p in parts[2:]]
    rows = [ln for ln in motion.splitlines()[1:] if ln and not ln.startswith(("Frames", "Frame"))]
    return is_pos, [[float(x) for x in r.split()] for r in rows]


def json_numbers(doc: object, out: list[float]) -> list[float]:
    if isinstance(doc, bool):
        return out
    if isinstance(doc, (int, float)):
        out.append(float(doc))
    elif isinstance(doc, dict):
        for v in doc.values():
            json_numbers(v, out)
    elif isinstance(doc, list):
        for v in doc:
            json_numbers(v, out)
    return out


def max_diff(a: list[float], b: list[float]) -> float:
    if len(a) != len(b):
        return float("inf")
    return max((abs(x - y) for x, y in zip(a, b, strict=True)), default=0.0)


def compare(a: Path, b: Path) -> dict[str, float]:
    """Largest differences between two output folders, by kind, per output stem."""
    diffs: dict[str, float] = {}
    for fa in sorted(a.iterdir()):
        fb = b / fa.name
        name = fa.name
        stem = name.split(".")[0]
        if name.endswith(".bvh"):
            pa, ra = bvh_numbers(fa.read_text())
            pb, rb = bvh_numbers(fb.read_text())
            rot, pos = 0.0, 0.0
            if (
                pa != pb
                or len(ra) != len(rb)
                or any(len(x) != len(y) for x, y in zip(ra, rb, strict=False))
            ):
                rot = pos = float("inf")
            else:
                for x, y in zip(ra, rb, strict=True):
                    for p, u, v in zip(pa, x, y, strict=True):
                        if p:
                            pos = max(pos, abs(u - v) / 100.0)  # cm -> m
                        else:
                            rot = max(rot, abs(u - v))
            diffs[f"{stem}|bvh_deg"] = max(rot, diffs.get(f"{stem}|bvh_deg", 0.0))
            diffs[f"{stem}|bvh_m"] = max(pos, diffs.get(f"{stem}|bvh_m", 0.0))
        elif name.endswith(".ir.json"):
            na = json_numbers(json.loads(fa.read_text()), [])
            nb = json_numbers(json.loads(fb.read_text()), [])
            diffs[f"{stem}|ir"] = max(max_diff(na, nb), diffs.get(f"{stem}|ir", 0.0))
        elif name.endswith(".py"):
            na = [float(x) for x in NUMBER.findall(fa.read_text())]
            nb = [float(x) for x in NUMBER.findall(fb.read_text())]
            diffs[f"{stem}|jack"] = max_diff(na, nb)
        elif name == "raw.npz":
            for key, d in raw_diffs(fa, fb).items():
                k = f"{key.split('|')[0]}|raw_{key.split('|')[1]}"
                diffs[k] = max(d, diffs.get(k, 0.0))
    return diffs


def fmt(x: float) -> str:
    return "STRUCT" if x == float("inf") else f"{x:.1e}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path, default=DEFAULT_FILES)
    ap.add_argument("--kernels", default=",".join(DEFAULT_KERNELS))
    ap.add_argument("--manikins", default=",".join(DEFAULT_MANIKINS))
    ap.add_argument("--fps", type=float, default=10.0)
    ap.add_argument("-j", "--jobs", type=int, default=2)
    ap.add_argument("--keep", type=Path, help="write the outputs here instead of a temp folder")
    args = ap.parse_args(argv)
    kernels = args.kernels.split(",")
    manikins = args.manikins.split(",")
    files = [f.resolve() for f in args.files]
    for k in kernels:
        print(f"OPENBLAS_CORETYPE={k}: kernel {corename(k)}")
    with tempfile.TemporaryDirectory() as tmp:
        base = args.keep or Path(tmp)
        jobs = [(k, m) for m in manikins for k in kernels]
        with ThreadPoolExecutor(args.jobs) as pool:
            list(
                pool.map(
                    lambda km: compile_all(
                        files, km[0], km[1], base / km[0] / km[1].replace(":", "_"), args.fps
                    ),
                    jobs,
                )
            )
        rows: dict[tuple[str, str], dict[str, float]] = {}
        for m in manikins:
            ref = base / kernels[0] / m.replace(":", "_")
            for k in kernels[1:]:
                for key, d in compare(ref, base / k / m.replace(":", "_")).items():
                    stem, kind = key.split("|")
                    cell = rows.setdefault((stem, m), {})
                    cell[kind] = max(cell.get(kind, 0.0), d)
    kinds = ("bvh_deg", "bvh_m", "ir", "jack", "raw_deg", "raw_m", "raw_quat")
    print(f"\nmax |diff| against {kernels[0]} over {', '.join(kernels[1:])} (fps {args.fps:g})")
    print("printed outputs: bvh_deg, bvh_m (BVH rotations, positions), ir and jack (every number);")
    print("raw_*: the frames before printing (joint angles deg, root position m, root quaternion)")
    print(f"{'file':28s} {'manikin':24s} " + " ".join(f"{k:>8s}" for k in kinds))
    worst = dict.fromkeys(kinds, 0.0)
    for (stem, m), cell in sorted(rows.items()):
        print(f"{stem:28s} {m:24s} " + " ".join(f"{fmt(cell.get(k, 0.0)):>8s}" for k in kinds))
        for k in kinds:
            worst[k] = max(worst[k], cell.get(k, 0.0))
    print(f"{'ALL':28s} {'':24s} " + " ".join(f"{fmt(worst[k]):>8s}" for k in kinds))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
