"""A correction pass does not turn last-bit noise into a different motion (issue 17).

Two machines' BLAS builds differ in the last bits of a product; the goldens compare numbers to
a tolerance, so a pass must not amplify those bits. Here the frames the clearance pass starts
from are disturbed by 1e-13 rad (what another kernel does) and its output compared: the access
panel's last left-arm pose moved 0.045 rad when the choice of frames to solve again was made by
exact equality (``clearance.swings_ramped``).
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.passes import MotionOptions, PassContext, clearance, run_motion

ROOT = Path(__file__).resolve().parents[2]


def test_clearance_output_does_not_amplify_last_bit_noise() -> None:
    program = run_frontend([ROOT / "examples" / "remove_access_panel.mtask"])
    options = MotionOptions(fps=10)
    ir = run_motion(program.timelines[0], DiagnosticSink(), options, until="carry")
    rng = np.random.default_rng(0)
    outputs = []
    for noise in (0.0, 1e-13, -1e-13):
        disturbed = copy.deepcopy(ir)
        disturbed.frames.q = disturbed.frames.q + noise * rng.standard_normal(ir.frames.q.shape)
        clearance.run(disturbed, PassContext(DiagnosticSink(), options))
        outputs.append(disturbed.frames.q)
    for out in outputs[1:]:
        assert np.abs(out - outputs[0]).max() < 1e-6
