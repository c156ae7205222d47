"""Pelvis height over a walk, before and after issue 19's gait (docs/img/gait_pelvis.png).

    python bench/plot_gait.py BEFORE.ir.json AFTER.ir.json [-o docs/img/gait_pelvis.png]
    python bench/plot_gait.py BEFORE.ir.json AFTER.ir.json --knee [-o docs/img/gait_knee.png]

Each file is an IR JSON of the same procedure (``mtlc compile ... --target ir --format json``,
one compiled with the old code); the first walk of each is drawn: the pelvis (root) height
above the floor, and the time each foot is in the air (its lowest sole point over 5 mm, as
bench/human.py counts a swing). With ``--knee``, the knees' flexion over the longest walk and
its largest one-frame step instead. Reads the files only, like bench/motion.py.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import human
import motion


def walk_trace(path: Path) -> tuple[np.ndarray, np.ndarray, dict[str, list[tuple[float, float]]]]:
    doc = json.loads(path.read_text(encoding="utf-8"))
    body = motion.Body.of(doc)
    seg = next(s for s in doc["segments"] if s["kind"] == "locomotion")
    t = body.time
    on = (t >= seg["t_start"] - 1e-9) & (t <= seg["t_end"] + 1e-9)
    ground = float(doc["scene"]["ground"])
    contacts = {c["name"] for c in doc["manikin"]["contact_points"]}
    air: dict[str, list[tuple[float, float]]] = {}
    for side in ("r", "l"):
        names = [n for n in contacts if n.startswith(f"{side}_")]
        low = np.min(np.stack([body.points[n][on, 1] for n in names]), axis=0) - ground
        tt = t[on] - seg["t_start"]
        air[side] = [(tt[a], tt[b]) for a, b in human._runs(low > human.SWING_HEIGHT)]
    return t[on] - seg["t_start"], body.points["pelvis"][on, 1] - ground, air


def knee_trace(path: Path) -> tuple[np.ndarray, dict[str, np.ndarray], float]:
    """Seconds from the longest walk's start, each knee's flexion (deg) over it, and the
    largest one-frame step of a knee inside it."""
    doc = json.loads(path.read_text(encoding="utf-8"))
    f = doc["frames"]
    t = np.asarray(f["time"], float)
    q = np.asarray(f["q"], float).reshape(len(t), -1)
    walks = [s for s in doc["segments"] if s["kind"] == "locomotion"]
    seg = max(walks, key=lambda s: s["t_end"] - s["t_start"])
    on = (t >= seg["t_start"] - 1e-9) & (t <= seg["t_end"] + 1e-9)
    knees = {s: np.degrees(q[on, f["dof_names"].index(f"{s}_knee_flex")]) for s in ("r", "l")}
    step = max(float(np.max(np.abs(np.diff(k)))) for k in knees.values())
    return t[on] - seg["t_start"], knees, step


def plot_knees(args: argparse.Namespace, plt: Any) -> Any:
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True, sharey=True)
    for ax, path, label in zip(axes, (args.before, args.after), ("before", "after"), strict=True):
        t, knees, step = knee_trace(path)
        for side, colour in (("r", "tab:red"), ("l", "tab:blue")):
            ax.plot(t, knees[side], color=colour, lw=1.2, marker=".", ms=3, label=f"{side} knee")
        peak = max(float(k.max()) for k in knees.values())
        ax.set_title(
            f"{label}: peak flexion {peak:.0f} deg, largest one-frame step {step:.1f} deg",
            fontsize=10,
        )
        ax.set_ylabel("knee flexion deg")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("s from the walk's start (dots: 30 fps output frames)")
    return fig


def main(argv: list[str] | None = None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("-o", "--output", type=Path, default=Path("docs/img/gait_pelvis.png"))
    parser.add_argument("--title", default="")
    parser.add_argument("--knee", action="store_true", help="the knees' flexion, not the pelvis")
    args = parser.parse_args(argv)
    if args.knee:
        fig = plot_knees(args, plt)
        if args.title:
            fig.suptitle(args.title)
        fig.tight_layout()
        args.output.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.output, dpi=110)
        print(args.output)
        return 0
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True, sharey=True)
    for ax, path, label in zip(axes, (args.before, args.after), ("before", "after"), strict=True):
        t, y, air = walk_trace(path)
        exc = 100 * (y.max() - y.min())
        steps = sum(len(v) for v in air.values())
        cad = 60 * steps / (t[-1] - t[0]) if t[-1] > t[0] else 0.0
        ax.plot(t, 100 * y, color="k", lw=1.5, label="pelvis height")
        for k, (side, colour) in enumerate((("r", "tab:red"), ("l", "tab:blue"))):
            for a, b in air[side]:
                ax.axvspan(a, b, ymin=0.02 + 0.05 * k, ymax=0.06 + 0.05 * k, color=colour)
        ax.set_ylabel("cm above floor")
        ax.set_title(
            f"{label}: excursion {exc:.1f} cm, {steps} steps in {t[-1]:.2f} s ({cad:.0f}/min)",
            fontsize=10,
        )
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("s from the walk's start (bars: right/left foot in the air)")
    if args.title:
        fig.suptitle(args.title)
    fig.tight_layout()
    args.output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.output, dpi=110)
    print(args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
