"""The motion does not depend on which BLAS kernel numpy runs (issue 17).

Another matmul kernel changes products in the last bit; the passes must not amplify that into a
different motion (the gradient path did, by degrees). OpenBLAS built with DYNAMIC_ARCH picks its
kernel from OPENBLAS_CORETYPE when it loads, so each kernel needs a fresh process: the example is
solved in two subprocesses, Haswell (AVX2/FMA) and Prescott (SSE3), and their frames compared.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
KERNELS = ("Haswell", "Prescott")
# the example whose gradient paths diverged by 0.8° between these two kernels before the fix
EXAMPLE = ROOT / "examples" / "remove_avionics_unit.mtask"

CORENAME = """
import ctypes, numpy
libs = {l.split()[-1] for l in open('/proc/self/maps') if 'openblas' in l.lower() and '.so' in l}
name = '?'
for lib in libs:
    dll = ctypes.CDLL(lib)
    for sym in ('scipy_openblas_get_corename64_', 'openblas_get_corename64_', 'openblas_get_corename'):
        f = getattr(dll, sym, None)
        if f is not None:
            f.restype = ctypes.c_char_p
            name = f().decode()
            break
print(name)
"""

FRAMES = """
import sys
from pathlib import Path
import numpy as np
from mtlc.frontend import run_frontend
from mtlc.passes import MotionOptions, run_motion
prog = run_frontend([Path(sys.argv[2])])
fr = run_motion(prog.timelines[0], prog.sink, MotionOptions(fps=10)).frames
np.savez(sys.argv[1], deg=np.degrees(fr.q), m=fr.root_position, quat=fr.root_rotation)
"""


def _env(kernel: str) -> dict[str, str]:
    path = os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])
    return dict(os.environ, OPENBLAS_CORETYPE=kernel, OPENBLAS_NUM_THREADS="1", PYTHONPATH=path)


def _run(kernel: str, *args: str) -> str:
    proc = subprocess.run(
        [sys.executable, "-c", *args], env=_env(kernel), capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout.strip()


def _kernels_differ() -> str | None:
    """Why the comparison cannot be made here, or None."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return f"needs x86-64 for OpenBLAS's Haswell and Prescott kernels, not {platform.machine()}"
    if not sys.platform.startswith("linux"):
        return "finds the loaded OpenBLAS through /proc/self/maps (Linux only)"
    names = [_run(k, CORENAME) for k in KERNELS]
    if "?" in names or names[0] == names[1]:
        return f"numpy's BLAS is not an OpenBLAS with DYNAMIC_ARCH (kernels: {names})"
    return None


def test_frames_agree_across_blas_kernels(tmp_path: Path) -> None:
    reason = _kernels_differ()
    if reason:
        pytest.skip(reason)
    outs = [tmp_path / f"{k}.npz" for k in KERNELS]
    with ThreadPoolExecutor(2) as pool:
        jobs = [
            pool.submit(_run, k, FRAMES, str(o), str(EXAMPLE))
            for k, o in zip(KERNELS, outs, strict=True)
        ]
        for job in jobs:
            job.result()
    with np.load(outs[0]) as a, np.load(outs[1]) as b:
        for key, tol in (("deg", 1e-6), ("m", 1e-6), ("quat", 1e-8)):
            assert a[key].shape == b[key].shape, key
            worst = float(np.max(np.abs(a[key] - b[key])))
            assert worst < tol, f"{key}: {worst:.3g} apart between {KERNELS}"
