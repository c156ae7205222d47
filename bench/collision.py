"""Capsule-to-mesh distance: coal against python-fcl against a brute-force numpy baseline.

Run:  PYTHONPATH=src python bench/collision.py [--sizes 10000 100000 1000000] [--queries 2000]
      [--frames 300] [--seed 0]

Meshes: a UV sphere of radius 0.5 m about the origin with (about) each size's triangles.
Queries: capsule axes (segments) of 5-30 cm, centres uniform in a 1.6 m cube about the sphere (a
share cross its surface, a share are inside it, most are outside). Measured per library (CPU time,
``time.process_time``: the machine is shared):

* build: the hierarchy of one mesh (best of 3; 1 for 1 M triangles);
* query: one segment-mesh distance, mean over ``--queries`` segments;
* batch: ``--frames`` frames x 16 capsules (the manikin's collision model: a frame's queries);
* max err: the largest difference to the brute force on the segments it checks (all of them for
  10 k triangles, fewer for bigger meshes: the baseline is O(segments x triangles)).

The brute force's own time per query is the last row per size. A library that does not import is
listed with the reason and skipped.

``--pairs`` instead times what a user waits for with geometry: each geometry example compiled
(``mtlc compile``, a fresh process, CPU seconds of the child, best of ``--repeat``) beside the
same procedure with typed sites and no models, and the ratio against the issue's goal (2x). The
difference is the front end reading the model (trimesh's import, the glTF) and the lint/verify
work on the geometry.

``--example FILE`` adds the metric on a compiled procedure (female P5): the compile's CPU time,
then ``frame_clearance`` (16 body capsules and the held tools, every output frame) against one
UV sphere of each size, of radius 0.15 m, centred 0.2 m behind the first reach's site (so the
hand comes near it), with and without the 0.25 m horizon.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mtlc.geometry.distance import MeshIndex, brute_force_distance
from mtlc.semantics import schedule

CAPSULES_PER_FRAME = 16
LIBRARIES = ("coal", "fcl")


def uv_sphere(n_triangles: int, radius: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """A closed UV sphere with about ``n_triangles`` triangles (rows x 2·rows quads, caps
    included), vertices (V, 3) and faces (F, 3)."""
    rows = max(3, round((n_triangles / 4) ** 0.5))
    cols = 2 * rows
    theta = np.linspace(0.0, np.pi, rows + 1)[1:-1]
    phi = np.linspace(0.0, 2 * np.pi, cols, endpoint=False)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)], -1)
    vertices = np.vstack([[0, 1, 0], ring.reshape(-1, 3), [0, -1, 0]]) * radius
    idx = 1 + np.arange((rows - 1) * cols).reshape(rows - 1, cols)
    nxt = np.roll(idx, -1, axis=1)
    faces = [np.stack([np.zeros(cols, int), nxt[0], idx[0]], -1)]
    faces.append(np.stack([idx[:-1], nxt[:-1], nxt[1:]], -1).reshape(-1, 3))
    faces.append(np.stack([idx[:-1], nxt[1:], idx[1:]], -1).reshape(-1, 3))
    last = len(vertices) - 1
    faces.append(np.stack([np.full(cols, last), idx[-1], nxt[-1]], -1))
    return vertices, np.vstack(faces).astype(np.int64)


def random_segments(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` segments of 5-30 cm, centres uniform in a 1.6 m cube about the origin."""
    centre = rng.uniform(-0.8, 0.8, size=(n, 3))
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    half = 0.5 * rng.uniform(0.05, 0.3, size=(n, 1)) * direction
    return centre - half, centre + half


def cpu(fn, repeat: int = 1) -> tuple[float, object]:
    """Best CPU time (s) of ``repeat`` calls, and the last result."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t0)
    return best, out


def example_rows(path: str, sizes: list[int]) -> None:
    """The compile's CPU time and the clearance metric's on its frames (see the docstring)."""
    from pathlib import Path

    from mtlc.diagnostics import DiagnosticSink
    from mtlc.frontend import run_frontend
    from mtlc.geometry.clearance import frame_clearance
    from mtlc.passes import run_motion
    from mtlc.semantics.timeline import ManikinSpec

    t0 = time.process_time()
    program = run_frontend([Path(path)])
    (timeline,) = program.timelines
    timeline = schedule.for_manikin(timeline, ManikinSpec("gb10000_1988", "female", 5))
    ir = run_motion(timeline, DiagnosticSink())
    t_compile = time.process_time() - t0
    reach = next(s for s in ir.segments if s.kind == "TA" and s.goal.site)
    site = next(s for s in ir.sites if s["name"] == reach.goal.site)
    normal = np.asarray(site.get("normal") or (0.0, 0.0, -1.0), float)
    centre = np.asarray(site["position"], float) - 0.2 * normal / np.linalg.norm(normal)
    n_frames = len(ir.frames.time)
    print(f"\n{path} (female P5): compile {t_compile:.2f} s CPU, {n_frames} frames")
    print(
        f"{'triangles':>10} {'horizon':>8} {'build+clearance s':>18} {'per frame ms':>13} "
        f"{'min clearance mm':>17}"
    )
    for size in sizes:
        v, f = uv_sphere(size, radius=0.15)
        for horizon in (0.25, None):
            t, fc = cpu(
                lambda h=horizon, m=(v + centre, f): frame_clearance(ir, {"s": m}, horizon=h)
            )
            low = float(np.nanmin(fc.clearance)) * 1e3
            print(
                f"{len(f):>10} {horizon!s:>8} {t:>18.2f} {t / n_frames * 1e3:>13.2f} {low:>17.1f}"
            )


PAIRS = (  # a geometry example and the same procedure without models
    ("examples/remove_access_panel_cad.mtask", "examples/remove_access_panel.mtask"),
    ("examples/replace_fuel_filter_cad.mtask", "examples/replace_fuel_filter.mtask"),
)


def compile_cpu(path: str, repeat: int) -> float:
    """CPU seconds (user + system) of ``mtlc compile PATH`` in a fresh process, best of
    ``repeat``."""
    import resource
    import subprocess
    import sys
    import tempfile

    best = float("inf")
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as out:
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run([sys.executable, "-m", "mtlc", "compile", path, "-o", out],
                           check=True, capture_output=True)  # fmt: skip
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
        used = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        best = min(best, used)
    return best


def pair_rows(repeat: int) -> None:
    print(f"{'geometry example':<42} {'with models s':>13} {'without s':>10} {'ratio':>6} goal")
    for with_models, without in PAIRS:
        a, b = compile_cpu(with_models, repeat), compile_cpu(without, repeat)
        print(f"{with_models:<42} {a:>13.2f} {b:>10.2f} {a / b:>6.2f} <= 2")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", action="store_true", help="geometry examples against their twins")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--queries", type=int, default=2000)
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--example", help="also time the clearance metric on this procedure")
    args = ap.parse_args()
    if args.pairs:
        pair_rows(args.repeat)
        return
    rng = np.random.default_rng(args.seed)
    a, b = random_segments(rng, args.queries)
    batch = args.frames * CAPSULES_PER_FRAME
    ba, bb = random_segments(rng, batch)

    print(
        f"{'triangles':>10} {'method':<12} {'build ms':>9} {'query us':>9} "
        f"{f'batch {args.frames}x16 ms':>17} {'max err m':>10} {'checked':>8}"
    )
    for size in args.sizes:
        mesh = uv_sphere(size)
        n_tri = len(mesh[1])
        checked = min(args.queries, max(4, 20_000_000 // n_tri))
        t_brute, truth = cpu(lambda n=checked, m=mesh: brute_force_distance(a[:n], b[:n], m))
        for lib in LIBRARIES:
            try:
                t_build, index = cpu(
                    lambda lib=lib, m=mesh: MeshIndex(*m, library=lib),
                    repeat=1 if n_tri > 500_000 else 3,
                )
            except ImportError as exc:
                print(f"{n_tri:>10} {lib:<12} not installed ({exc})")
                continue
            t_query, got = cpu(lambda index=index: index.segment_distance(a, b))
            t_batch, _ = cpu(lambda index=index: index.segment_distance(ba, bb))
            err = float(np.max(np.abs(np.asarray(got)[:checked] - truth)))
            print(
                f"{n_tri:>10} {lib:<12} {t_build * 1e3:>9.1f} {t_query / args.queries * 1e6:>9.1f} "
                f"{t_batch * 1e3:>17.1f} {err:>10.1e} {checked:>8}"
            )
        per = t_brute / checked
        print(
            f"{n_tri:>10} {'numpy brute':<12} {'-':>9} {per * 1e6:>9.0f} "
            f"{per * batch * 1e3:>17.0f} {0.0:>10.1e} {checked:>8}"
        )
    if args.example:
        example_rows(args.example, args.sizes)


if __name__ == "__main__":
    main()
