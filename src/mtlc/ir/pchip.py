"""Shape-preserving cubic interpolation (PCHIP) and cubic Hermite curves in numpy.

The keyframe IR's curves are PCHIP (docs/ir.md): no overshoot past a keyframe, so no joint limit
is crossed between two keyframes within limits. scipy's ``PchipInterpolator`` computed them, and
importing ``scipy.interpolate`` was 40 % of every command's start-up (issue 21). This module
computes the same numbers: the slopes by Fritsch and Carlson's weighted harmonic mean with
Moler's one-sided end slopes (Fritsch & Carlson 1980, SIAM J. Numer. Anal. 17(2):238-246;
Moler, *Numerical Computing with MATLAB*, 3.6, ``pchiptx``), as scipy's ``_find_derivatives``,
and each piece evaluated as scipy's ``PPoly`` does (powers of the offset summed from the constant
term up), so the values agree to the last bits (tests/test_pchip.py compares them, 1e-12).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

FloatArray = np.ndarray


def _edge_slope(h0: FloatArray, h1: FloatArray, m0: FloatArray, m1: FloatArray) -> FloatArray:
    """A one-sided three-point end slope, kept from overshooting (scipy's ``_edge_case``)."""
    d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
    wrong_sign = np.sign(d) != np.sign(m0)
    too_steep = (np.sign(m0) != np.sign(m1)) & (np.abs(d) > 3.0 * np.abs(m0))
    d = np.where(wrong_sign, 0.0, d)
    return np.where(~wrong_sign & too_steep, 3.0 * m0, d)


def _knots(x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray]:
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.ndim != 1 or len(x) < 2 or len(y) != len(x) or not np.all(np.diff(x) > 0):
        raise ValueError("x must be strictly increasing, with at least two knots, one per y row")
    return x, y


def pchip_slopes(x: ArrayLike, y: ArrayLike) -> FloatArray:
    """The PCHIP slope at each knot, for ``y`` of shape (n, ...) over increasing ``x`` (n,)."""
    return _slopes(*_knots(x, y))


def _slopes(x: FloatArray, y: FloatArray) -> FloatArray:
    shape = y.shape
    y2 = y.reshape(len(y), -1)
    h = np.diff(x)[:, None]
    m = np.diff(y2, axis=0) / h
    if len(y2) == 2:  # two knots: the line through them
        return np.stack([m[0], m[0]]).reshape(shape)
    sign = np.sign(m)
    flat = (sign[1:] != sign[:-1]) | (m[1:] == 0) | (m[:-1] == 0)
    w1 = 2.0 * h[1:] + h[:-1]
    w2 = h[1:] + 2.0 * h[:-1]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        harmonic = (w1 / m[:-1] + w2 / m[1:]) / (w1 + w2)
        inner = np.where(flat, 0.0, 1.0 / harmonic)
    d = np.empty_like(y2)
    d[1:-1] = inner
    d[0] = _edge_slope(h[0], h[1], m[0], m[1])
    d[-1] = _edge_slope(h[-1], h[-2], m[-1], m[-2])
    return d.reshape(shape)


@dataclass(frozen=True)
class Hermite:
    """A piecewise cubic through ``y`` at ``x`` with slopes ``dydx``: called on times, its values.

    Outside the knots it extends the end pieces (``extrapolate``) or gives NaN, as scipy does.
    """

    x: FloatArray  # (n,)
    coef: FloatArray  # (4, n - 1, m): cubic, quadratic, linear and constant terms of each piece
    shape: tuple[int, ...]  # a value's shape (y.shape[1:])
    extrapolate: bool = True

    def __call__(self, t: ArrayLike) -> FloatArray:
        t = np.asarray(t, dtype=float)
        flat = t.reshape(-1)
        piece = np.clip(np.searchsorted(self.x, flat, side="right") - 1, 0, len(self.x) - 2)
        s = (flat - self.x[piece])[:, None]
        c = self.coef[:, piece]
        # scipy's PPoly: the constant term, then each power of s in turn (not Horner's rule)
        out = c[3] * 1.0
        z = s
        out = out + c[2] * z
        z = z * s
        out = out + c[1] * z
        z = z * s
        out = out + c[0] * z
        if not self.extrapolate:
            outside = (flat < self.x[0]) | (flat > self.x[-1]) | np.isnan(flat)
            out[outside] = np.nan
        return out.reshape(t.shape + self.shape)


def hermite(x: ArrayLike, y: ArrayLike, dydx: ArrayLike, extrapolate: bool = True) -> Hermite:
    """The cubic Hermite curve through ``y`` (n, ...) at increasing ``x`` with slopes ``dydx``
    (scipy's ``CubicHermiteSpline`` with ``axis=0``)."""
    return _hermite(*_knots(x, y), dydx, extrapolate)


def _hermite(x: FloatArray, y: FloatArray, dydx: ArrayLike, extrapolate: bool) -> Hermite:
    shape = y.shape[1:]
    y2 = y.reshape(len(y), -1)
    d2 = np.asarray(dydx, dtype=float).reshape(len(y), -1)
    dx = np.diff(x)[:, None]
    slope = np.diff(y2, axis=0) / dx
    t = (d2[:-1] + d2[1:] - 2.0 * slope) / dx
    coef = np.stack([t / dx, (slope - d2[:-1]) / dx - t, d2[:-1], y2[:-1]])
    return Hermite(x, coef, shape, extrapolate)


def pchip(x: ArrayLike, y: ArrayLike, extrapolate: bool = True) -> Hermite:
    """The PCHIP curve through ``y`` (n, ...) at increasing ``x`` (scipy's ``PchipInterpolator``
    with ``axis=0``)."""
    x, y = _knots(x, y)  # checked once for both steps
    return _hermite(x, y, _slopes(x, y), extrapolate)
