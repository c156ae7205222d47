"""Corrections that do not make a joint turn faster than a person's (issue 19).

The balance and clearance passes correct the motion frame by frame and blend the corrections
in over a few frames; where the motion already turns a joint fast (a kneel at 300 deg/s), or
the correction itself is large (a free arm turned 21 deg out of the trunk), the blend's ramp
stepped a joint 12.6-16.4 deg in one 30 fps output frame. ``speed_limited`` widens such a
correction in time instead: it starts earlier and is let go later, and is never made smaller,
so what it corrects (balance, clearance) is not given back.
"""

from __future__ import annotations

import numpy as np

from mtlc.ir.model import FloatArray


def speed_limited(
    q: FloatArray, dq: FloatArray, lower: FloatArray, upper: FloatArray, t: FloatArray,
    speed: float, fixed: np.ndarray | None = None,
) -> FloatArray:  # fmt: skip
    """The corrections ``dq`` (N, D) of frames ``q`` (times ``t``) widened in time so that no
    corrected dof turns faster than ``speed`` (rad/s) where the motion itself did not. Per
    dof the positive and the negative parts each take their smallest envelope with the
    allowed slopes (one pass back in time, one forward); ``fixed`` (N,) frames keep their own
    correction (a hand held on its goal). Returned within the joint limits; unchanged where
    nothing is too fast."""
    if len(q) < 2:
        return dq
    done = np.clip(q + dq, lower, upper) - q  # what the correction does within the limits
    step = np.diff(q, axis=0)
    room = np.maximum(np.abs(step), speed * np.diff(t)[:, None]) + 1e-9
    lo, hi = -room - step, room - step  # allowed change of the correction between frames
    change = np.diff(done, axis=0)
    if not ((change < lo).any() or (change > hi).any()):
        return dq
    cols = np.flatnonzero(np.abs(done).max(axis=0) > 0.0)  # the dofs corrected at all
    up, down = np.maximum(done[:, cols], 0.0), np.minimum(done[:, cols], 0.0)
    lo, hi = lo[:, cols], hi[:, cols]
    keep = np.zeros(len(q), dtype=bool) if fixed is None else np.asarray(fixed, dtype=bool)
    for i in range(len(q) - 2, -1, -1):  # started earlier
        if not keep[i]:
            up[i] = np.maximum(up[i], up[i + 1] - hi[i])
            down[i] = np.minimum(down[i], down[i + 1] - lo[i])
    for i in range(len(q) - 1):  # let go later
        if not keep[i + 1]:
            up[i + 1] = np.maximum(up[i + 1], up[i] + lo[i])
            down[i + 1] = np.minimum(down[i + 1], down[i] + hi[i])
    out = done.copy()
    out[:, cols] = np.clip(q[:, cols] + up + down, lower[cols], upper[cols]) - q[:, cols]
    return out
