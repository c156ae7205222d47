"""Hand misses and hold drift on the sampled output frames, per task and manikin (issue 18).

    python bench/holds.py examples/*.mtask bench/hold_tasks/*.mtask [-m female:5,male:95] [-v]

Per task and manikin (gb10000_1988, default female P5/P50, male P50/P95), compiled in process
and measured on the sampled frames by forward kinematics: ``miss`` the worst distance of a
goal's effector from its site at the first frame at or after the goal's end; ``drift`` the
worst distance of a hand from the site it holds, from its contact's end until its next arm
segment or a walk, while its grip is closed (standing frames only); ``(rep)`` when an MT05xx
diagnostic names that goal's line (an MT0511 counts for its hand's contact before it); ``jump`` the
largest one-frame change of any dof and how many frame-dof steps exceed 20 degrees; the MT05xx
codes raised. A number without ``(rep)`` over 1 mm is a silent miss.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mtlc.body import forward, site_positions
from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.passes import MotionOptions, run_motion
from mtlc.semantics import schedule
from mtlc.semantics.timeline import ManikinSpec

MANIKINS = ["female:5", "female:50", "male:50", "male:95"]


def measure(ir, sink):
    fr = ir.frames
    skel = ir.skeleton
    pose = forward(skel, fr.q, fr.root_position, fr.root_rotation, with_axes=False)
    effs = sorted({s.goal.effector for s in ir.segments if s.kind == "TO"})
    pts = {e: np.asarray(site_positions(skel, pose, e)) for e in effs}
    diag_lines = {d.span.line for d in sink.items if d.code.startswith("MT05")} if sink else set()
    for d in sink.items:
        if d.code != "MT0511":
            continue
        # verify's MT0511 names the grasp (or the reach) of a hand that slips: it counts for
        # that hand's last contact up to that line (the hold pass's MT0520 is retired)
        hand = "r_hand" if "right hand" in d.message else "l_hand"
        lines = [s.provenance.origin.line for s in ir.segments
                 if s.kind == "TO" and s.goal.effector == hand
                 and s.provenance.origin.line <= d.span.line]  # fmt: skip
        if lines:
            diag_lines.add(max(lines))
    walking = np.zeros(len(fr.time), bool)
    for s in ir.segments:
        if s.kind == "locomotion":
            walking |= (fr.time >= s.start - 1e-9) & (fr.time <= s.end + 1e-9)
    misses, drifts = [], []
    for s in ir.segments:
        if s.kind != "TO" or s.goal.position is None:
            continue
        tgt = np.asarray(s.goal.position)
        i = int(np.searchsorted(fr.time, s.end - 1e-6))
        i = min(i, len(fr.time) - 1)
        d = float(np.linalg.norm(pts[s.goal.effector][i] - tgt))
        rep = s.provenance.origin.line in diag_lines
        misses.append((s.provenance.origin.line, s.goal.effector, s.goal.site, d, rep, s.end))
        hand = "r_hand" if s.track == "r_arm" else "l_hand"
        later = [
            o.start
            for o in ir.segments
            if o.track == s.track and o.start > s.end - 1e-9 and o is not s
        ]
        later += [o.start for o in ir.segments if o.kind == "locomotion" and o.start > s.end - 1e-9]
        hi = min(later, default=fr.time[-1] + 1)
        closed = np.zeros(len(fr.time), bool)
        grips = sorted(
            (o for o in ir.segments if o.track == hand and o.kind == "grip"), key=lambda o: o.start
        )
        for o in grips:
            if o.goal.params.get("state") == "closed":
                closed |= (fr.time >= o.end - 1e-6) & (fr.time < hi)
            else:
                closed &= ~(fr.time >= o.start - 1e-9)
        win = (fr.time >= s.end - 1e-6) & (fr.time < hi - 1e-9) & ~walking & closed
        if win.any():
            dd = np.linalg.norm(pts[s.goal.effector][win] - tgt, axis=1)
            k = int(np.argmax(dd))
            drifts.append(
                (
                    s.provenance.origin.line,
                    s.goal.effector,
                    s.goal.site,
                    float(dd.max()),
                    rep,
                    float(fr.time[win][k]),
                )
            )
    dj = np.degrees(np.abs(np.diff(fr.q, axis=0)))
    jump = (float(dj.max()) if len(fr.q) > 1 else 0.0, int((dj > 20).sum()))
    return misses, drifts, jump


def run(path, manikins, verbose):
    rows = []
    for m in manikins:
        sex, pct = m.split(":")
        prog = run_frontend([Path(path)])
        if prog.sink.has_errors:
            print("front-end errors", path, [d.message for d in prog.sink.items])
            return rows
        for tl in prog.timelines:
            tl = schedule.for_manikin(tl, ManikinSpec("gb10000_1988", sex, int(pct)))
            sink = DiagnosticSink()
            ir = run_motion(tl, sink, MotionOptions())
            misses, drifts, jump = measure(ir, sink)
            wm = max(misses, key=lambda r: r[3] if not r[4] else -1, default=None)
            wd = max(drifts, key=lambda r: r[3] if not r[4] else -1, default=None)
            codes = sorted({d.code for d in sink.items if d.code.startswith("MT05")})
            print(
                f"{Path(path).stem:28s} {m:10s} miss{'(rep)' if wm and wm[4] else '     '} {wm[3] * 1000 if wm else 0:7.1f}mm L{wm[0] if wm else '-'} {wm[2] if wm else ''}"
                f" | drift{'(rep)' if wd and wd[4] else '     '} {wd[3] * 1000 if wd else 0:7.1f}mm L{wd[0] if wd else '-'} {wd[2] if wd else ''} t={wd[5] if wd else 0:.2f}"
                f" | jump {jump[0]:5.1f}deg n>20 {jump[1]:3d} | {codes}"
            )
            if verbose:
                for r in misses:
                    print("   miss", r)
                for r in drifts:
                    print("   drift", r)
            rows.append((path, m, wm, wd, jump, codes))
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="+")
    ap.add_argument("-m", "--manikins", default=",".join(MANIKINS))
    ap.add_argument("-v", action="store_true")
    a = ap.parse_args()
    for f in a.files:
        run(f, a.manikins.split(","), a.v)
