"""The contact sheet: key poses from the front and the side, and the main joint angles over time.

The scene's models are drawn behind the poses (grey), and a part the hands hold where they
have taken it on each pose (in colour), so a sheet shows the panel going to the bench.

For reports and for review without a browser. Needs matplotlib (the ``preview`` extra); the
figure is drawn with the Agg backend, without fonts or timestamps that vary between runs, so the
same motion gives the same PNG bytes on one machine.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mtlc.body import forward
from mtlc.ir.model import MotionIR
from mtlc.preview.document import blocks

FloatArray = NDArray[np.float64]
MAX_POSES = 8
# (label, dofs summed): the angles a reviewer reads first, in degrees
MAIN_ANGLES: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("trunk flexion", ("lumbar_flex", "thorax_flex")),
    ("neck flexion", ("neck_flex", "head_flex")),
    ("r shoulder flexion", ("r_shoulder_flex",)),
    ("l shoulder flexion", ("l_shoulder_flex",)),
    ("r elbow flexion", ("r_elbow_flex",)),
    ("l elbow flexion", ("l_elbow_flex",)),
    ("r hip flexion", ("r_hip_flex",)),
    ("r knee flexion", ("r_knee_flex",)),
)


class MissingMatplotlib(RuntimeError):
    """matplotlib is not installed: the PNG needs the ``preview`` extra."""


def key_times(ir: MotionIR, limit: int = MAX_POSES) -> FloatArray:
    """The start, the end of every action, evenly thinned to at most ``limit`` times."""
    assert ir.frames is not None
    ends = sorted({0.0, *(b.end for b in blocks(ir, {}) if b.level == 1)})
    times = np.asarray(ends, dtype=float)
    if len(times) > limit:
        times = times[np.round(np.linspace(0, len(times) - 1, limit)).astype(int)]
    return np.clip(times, ir.frames.time[0], ir.frames.time[-1])


def _frame_indices(ir: MotionIR, times: FloatArray) -> NDArray[np.intp]:
    assert ir.frames is not None
    t = ir.frames.time
    return np.clip(np.searchsorted(t, times - 1e-9), 0, len(t) - 1)


def _bones(ir: MotionIR) -> list[tuple[int, int]]:
    skel = ir.skeleton
    assert skel is not None
    return [
        (skel.joint_index(j.parent), skel.joint_index(j.name))
        for j in skel.joints
        if j.parent is not None
    ]


def _draw_pose(ax: Any, p: FloatArray, bones: list[tuple[int, int]], axes: tuple[int, int]) -> None:
    for a, b in bones:
        ax.plot(p[[a, b], axes[0]], p[[a, b], axes[1]], color="#5f7fae", lw=2.2,
                solid_capstyle="round")  # fmt: skip
    ax.plot(p[:, axes[0]], p[:, axes[1]], "o", color="#2c3e5c", ms=2.5)


MAX_SHEET_TRIANGLES = 20_000  # a model with more is drawn as its bounding box's outline
MODEL_GREY, HELD_COLOUR = "#9aa3ad", "#2a9d8f"


def _model_pieces(ir: MotionIR) -> list[tuple[FloatArray, FloatArray | None]]:
    """The scene's models as (T, 3, 3) triangles to draw at every key pose, with None, and each
    part a hand holds as its triangles in the model's place with its (N, 4, 4) placement
    (``Verification.held_parts``): drawn where the hand has taken it on each pose."""
    held = ir.verification.held_parts if ir.verification is not None else []
    out: list[tuple[FloatArray, FloatArray | None]] = []
    for model in ir.geometry:
        taken = np.zeros(len(model.faces), dtype=bool)
        for part in (p for p in held if p.model == model.name):
            taken[part.faces] = True
            out.append((model.vertices[model.faces[part.faces]], part.placement))
        faces = model.faces[~taken]
        if len(faces) > MAX_SHEET_TRIANGLES:
            lo, hi = model.vertices.min(axis=0), model.vertices.max(axis=0)
            faces = np.array([[0, 1, 2], [0, 2, 3]])
            box = np.array([lo, [hi[0], lo[1], lo[2]], hi, [lo[0], hi[1], hi[2]]])
            out.append((box[faces], None))
        elif len(faces):
            out.append((model.vertices[faces], None))
    return out


def _draw_models(
    ax: Any, pieces: list[tuple[FloatArray, FloatArray | None]], frame: int, axes: tuple[int, int]
) -> None:
    """The models projected on the view's plane, light grey; a held part where it is on
    ``frame``, in colour."""
    from matplotlib.collections import PolyCollection

    for tri, placement in pieces:
        colour = MODEL_GREY
        if placement is not None:
            m = placement[min(frame, len(placement) - 1)]
            tri = tri @ m[:3, :3].T + m[:3, 3]
            colour = HELD_COLOUR
        polys = tri[:, :, list(axes)]
        ax.add_collection(PolyCollection(polys, facecolors=colour, edgecolors="none",
                                         alpha=0.25 if placement is None else 0.6))  # fmt: skip


def render_sheet(ir: MotionIR) -> bytes:
    """The contact sheet as PNG bytes."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingMatplotlib(
            "the PNG contact sheet needs matplotlib: pip install 'mtlc[preview]'"
        ) from exc
    frames, skel = ir.frames, ir.skeleton
    assert frames is not None and skel is not None
    times = key_times(ir)
    idx = _frame_indices(ir, times)
    pose = forward(skel, frames.q[idx], frames.root_position[idx], frames.root_rotation[idx])
    sites = np.array([s["position"] for s in ir.sites], dtype=float).reshape(-1, 3)
    bones = _bones(ir)
    pieces = _model_pieces(ir)
    n = len(idx)
    with plt.rc_context({"font.family": "DejaVu Sans", "font.size": 8, "svg.hashsalt": "mtlc"}):
        fig = plt.figure(figsize=(max(2.0 * n, 8.0), 8.4), dpi=100)
        grid = fig.add_gridspec(3, n, height_ratios=[1, 1, 1.1], hspace=0.35, wspace=0.08)
        for k in range(n):
            p = pose.p[k]
            for row, (axes, name) in enumerate((((0, 1), "front"), ((2, 1), "side"))):
                ax = fig.add_subplot(grid[row, k])
                centre = p[0, axes[0]]
                if len(sites):
                    ax.plot(sites[:, axes[0]], sites[:, axes[1]], "o", color="#f08a24", ms=3)
                ax.axhline(ir.ground, color="#9aa1ad", lw=1)
                _draw_models(ax, pieces, int(idx[k]), axes)
                _draw_pose(ax, p, bones, axes)
                ax.set_xlim(centre - 1.0, centre + 1.0)
                ax.set_ylim(ir.ground - 0.05, ir.ground + 2.0)
                ax.set_aspect("equal")
                ax.set_xticks([])
                ax.set_yticks([])
                if row == 0:
                    ax.set_title(f"{float(frames.time[idx[k]]):.2f} s")
                if k == 0:
                    ax.set_ylabel(name)
        ax = fig.add_subplot(grid[2, :])
        names = list(skel.dof_names)
        for label, dofs in MAIN_ANGLES:
            cols = [names.index(d) for d in dofs if d in names]
            if cols:
                ax.plot(frames.time, np.degrees(frames.q[:, cols].sum(axis=1)), lw=1.2, label=label)
        for t in times:
            ax.axvline(float(t), color="#bbbbbb", lw=0.6)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("angle (°)")
        ax.legend(ncol=4, loc="upper right", frameon=False)
        ax.set_xlim(float(frames.time[0]), float(frames.time[-1]))
        fig.suptitle(f"{ir.title or ir.task} — mtlc preview", y=0.99)
        out = io.BytesIO()
        fig.savefig(out, format="png", metadata={"Software": None})
        plt.close(fig)
    return out.getvalue()
