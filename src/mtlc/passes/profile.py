"""Progress profiles of human point-to-point movements (shared by the pace and tool passes), and
the Gaussian low-pass that the pace and carry passes smooth paths and corrections with.

A point-to-point hand movement minimises the integrated squared jerk (Flash & Hogan 1985, "The
coordination of arm movements: an experimentally confirmed mathematical model", J Neurosci
5(7):1688-1703): its progress follows ``s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5``, one bell of
speed from rest to rest. A movement that ends by placing something precisely spends longer
decelerating than accelerating (MacKenzie, Marteniuk, Dugas, Liske & Eickmeier 1987,
"Three-dimensional movement trajectories in Fitts' task: implications for control", Q J Exp
Psychol 39A:629-647): ``placing_clock`` runs a movement's own smooth parameter on a clock that
slows toward the end, so the bell's tail is longer than its rise.
"""

from __future__ import annotations

import numpy as np

from mtlc.ir.model import FloatArray
from mtlc.ir.pchip import pchip

JOINT_WEIGHT = 0.02  # m of a reach's progress per radian of its joints (L2 over its dofs)

PLACING_SKEW = 1.5  # tau -> 1 - (1 - tau)^1.5: the end approached more slowly than the start left


def minimum_jerk(tau: FloatArray) -> FloatArray:
    """Flash & Hogan's progress of a point-to-point movement at normalised time ``tau``."""
    t = np.clip(tau, 0.0, 1.0)
    return t**3 * (10.0 - 15.0 * t + 6.0 * t**2)


def placing_clock(tau: FloatArray) -> FloatArray:
    """A placing movement's parameter at normalised time ``tau``: it leaves at speed (the
    path's own shape starts from rest) and arrives with a long deceleration."""
    t = np.clip(tau, 0.0, 1.0)
    return 1.0 - (1.0 - t) ** PLACING_SKEW


def gaussian_rows(x: FloatArray, sigma: float, truncate: float = 4.0) -> FloatArray:
    """scipy's ``gaussian_filter1d(x, sigma, axis=0, mode="nearest")`` in numpy, summed in its
    order (the kernel's symmetric pairs from the outside in), so the same numbers: importing
    ``scipy.ndimage`` was a third of every compile's start-up (issue 21)."""
    radius = int(truncate * float(sigma) + 0.5)
    offsets = np.arange(-radius, radius + 1)
    weights = np.exp(-0.5 / (sigma * sigma) * offsets**2)
    weights = weights / weights.sum()
    x = np.asarray(x, dtype=float)
    padded = np.concatenate(
        [np.repeat(x[:1], radius, axis=0), x, np.repeat(x[-1:], radius, axis=0)]
    )
    n = len(x)
    out = padded[radius : radius + n] * weights[radius]
    for j in range(radius, 0, -1):
        out = (
            out
            + (padded[radius - j : radius - j + n] + padded[radius + j : radius + j + n])
            * weights[radius - j]
        )
    return out


def smooth_path(q: FloatArray, sigma: float) -> FloatArray:
    """A Gaussian low-pass of a (N, D) path along its samples, both ends kept exactly (odd
    reflection about each end): the gradient path's zig-zag and the corner at the approach
    point would each cost a jerk that no timing removes."""
    if sigma <= 0.0 or len(q) < 3:
        return q
    n = min(len(q) - 1, int(np.ceil(4 * sigma)))
    padded = np.concatenate([2 * q[0] - q[n:0:-1], q, 2 * q[-1] - q[-2 : -n - 2 : -1]])
    return gaussian_rows(padded, sigma)[n : n + len(q)]


def bell_ldlj(paths: list[FloatArray], u: FloatArray, points: int) -> float:
    """The log dimensionless jerk (docs/metrics.md's reach figure; Balasubramanian et al. 2012)
    of the roughest of ``paths`` ((K, 3) each, at rising progress ``u`` from 0 to 1) when the
    progress follows one minimum-jerk bell, sampled at ``points``: how a path will score once
    ``pace`` times it, before there are frames. 0.0 where nothing moves."""
    tau = np.linspace(0.0, 1.0, points)
    dt = tau[1] - tau[0]
    worst = np.inf
    for p in paths:
        path = pchip(u, p)(minimum_jerk(tau))
        speed = np.linalg.norm(np.diff(path, axis=0), axis=1) / dt
        top = float(speed.max())
        if top <= 1e-9:
            continue
        jerk = float(np.sum(np.diff(path, n=3, axis=0) ** 2) / dt**5)
        worst = min(worst, -float(np.log(max(jerk / top**2, 1e-300))))
    return float(worst) if np.isfinite(worst) else 0.0
