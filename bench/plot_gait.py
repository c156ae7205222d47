"""Pelvis height over a walk, before and after issue 19's gait (docs/img/gait_pelvis.png).

    python bench/plot_gait.py BEFORE.ir.json AFTER.ir.json [-o docs/img/gait_pelvis.png]

Each file is an IR JSON of the same procedure (``mtlc compile ... --target ir --format json``,
one compiled with the old code); the first walk of each is drawn: the pelvis (root) height
above the floor, and the time each foot is in the air (its lowest sole point over 5 mm, as
bench/human.py counts a swing). Reads the files only, like bench/motion.py.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

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


def main(argv: list[str] | None = None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("-o", "--output", type=Path, default=Path("docs/img/gait_pelvis.png"))
    parser.add_argument("--title", default="")
    args = parser.parse_args(argv)
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
