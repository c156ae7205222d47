"""The kneel's analytic Jacobian (``Body._linearise``) against central differences of the
residual it linearises (``Body.residual``), on every phase's targets (a wrong term would be
off by its weight, at least 1; the entries reach 1000)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin
from mtlc.passes import kneel
from mtlc.passes.posture import root_height

SKEL = build_manikin("gb10000_1988", "male", 95)
Q = np.asarray(SKEL.q_comfort, dtype=float)
BODY = kneel.Body(SKEL, Q)
X0 = np.concatenate([[0.0, root_height(SKEL, Q, 0.0), 0.0], Q[BODY.idx]])
GEOMETRY = kneel.geometry(BODY, X0)


@settings(max_examples=25, deadline=None)
@given(
    u=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**31 - 1),
)
def test_the_analytic_jacobian_matches_central_differences(u: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x = X0 + rng.normal(0.0, 0.05, len(X0))
    x[3:] = np.clip(x[3:], BODY.lo + 0.01, BODY.hi - 0.01)
    targets = kneel.kneel_targets(BODY, GEOMETRY, X0, len(kneel.PHASES))
    for v in np.arange(0.0, u, 0.05):  # the targets note each phase's start as they pass it
        targets(float(v), x)
    tg = targets(u, x)
    r, jac = BODY._linearise(x, tg, X0)
    np.testing.assert_allclose(r, BODY.residual(x[None], tg, X0)[0], rtol=1e-9, atol=1e-9)
    h = 1e-6
    step = np.eye(len(x)) * h
    up = BODY.residual(x + step, tg, X0)
    down = BODY.residual(x - step, tg, X0)
    numeric = ((up - down) / (2 * h)).T
    np.testing.assert_allclose(jac, numeric, atol=0.05, rtol=1e-4)
