"""A scalar fast path for the commonest TA call: one target, one position goal, one chain.

For a 7-dof arm, a numpy call costs about a microsecond whatever its size, and one DLS
iteration needs ~60 of them. Plain Python floats do the same work in fewer operations:
rotations about the manikin's coordinate axes touch two columns of the frame (12 multiplies),
the Jacobian has 7 columns, and the damped normal equations are a symmetric 3×3 system solved
by its adjugate. Same algorithm as :func:`mtlc.body.ik.dls.solve_ta` (error clamp, step cap,
limit clamping with a re-solve, null-space pull, restarts); the tests check both agree.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..skeleton import Skeleton
from .model import ChainModel

FloatArray = NDArray[np.float64]

# The null-space pull fades out linearly below this task error (m). The damped projector
# ``I − J⁺J`` is not exact: near a stretched (singular) arm it leaks ``λ²(JJᵀ + λ²I)⁻¹Jz``
# into the task, which with a constant gain holds some rows at a fixed point just above a
# 1 mm tolerance. Scaling the pull with the error makes zero error the only fixed point.
NULL_FADE = 0.01


# per joint of a chain: its offset, and its dofs as (axis index, sign, active column or -1,
# fixed angle)
ChainPlan = list[tuple[tuple[float, ...], list[tuple[int, float, int, float]]]]
Vec = tuple[float, float, float]


def chain_plan(model: ChainModel, live: list[int], q_base: FloatArray) -> ChainPlan:
    """The chain's joints for ``walk_chain``; every dof must turn about a coordinate axis."""
    base = [float(v) for v in q_base]
    return [
        (offset, [(k, sign, col, base[d]) for k, sign, col, d in dofs])
        for offset, dofs in _plan_shape(
            model.skel, tuple(live), tuple(int(d) for d in model.active)
        )
    ]


# per joint of a chain: its offset, and its dofs as (axis index, sign, active column or -1, dof)
PlanShape = list[tuple[tuple[float, ...], list[tuple[int, float, int, int]]]]


def _plan_shape(skel: Skeleton, live: tuple[int, ...], active: tuple[int, ...]) -> PlanShape:
    """What ``chain_plan`` reads off the skeleton, once per skeleton, chain and active dofs
    (the carry's continuation asked for the same arm's plan 500 times a path: a tenth of
    its solves' time)."""
    cache: dict[tuple[tuple[int, ...], tuple[int, ...]], PlanShape]
    cache = skel.__dict__.setdefault("_chain_plan_shapes", {})
    found = cache.get((live, active))
    if found is None:
        col = {d: i for i, d in enumerate(active)}
        found = []
        for j in live:
            dofs = []
            s = int(skel.joint_dof_start[j])
            for d in range(s, s + int(skel.joint_dof_count[j])):
                ax = skel.dof_axis[d]
                k = int(np.argmax(np.abs(ax)))
                if abs(abs(ax[k]) - 1.0) > 1e-12:
                    raise ValueError("fast path needs coordinate-axis dofs")
                dofs.append((k, float(np.sign(ax[k])), col.get(d, -1), d))
            found.append((tuple(float(x) for x in skel.offsets[j]), dofs))
        cache[(live, active)] = found
    return found


def walk_chain(
    R0: list[list[float]], p0: list[float], plan: ChainPlan, q: Sequence[float], n: int
) -> tuple[tuple[list[float], list[float], list[float]], Vec, list[Vec], list[Vec]]:
    """Down the chain on Python floats from the base frame (``R0`` as columns, ``p0``) at
    active angles ``q``: the last joint's frame (its columns and origin), and each active
    dof's world axis and the origin it turns about."""
    c0, c1, c2 = (list(c) for c in R0)
    px, py, pz = p0
    axes: list[Vec] = [(0.0, 0.0, 0.0)] * n
    origins: list[Vec] = [(0.0, 0.0, 0.0)] * n
    for (ox, oy, oz), dofs in plan:
        px, py, pz = (
            px + c0[0] * ox + c1[0] * oy + c2[0] * oz,
            py + c0[1] * ox + c1[1] * oy + c2[1] * oz,
            pz + c0[2] * ox + c1[2] * oy + c2[2] * oz,
        )
        for k, sg, ci, fixed in dofs:
            th = sg * (q[ci] if ci >= 0 else fixed)
            if ci >= 0:
                a = c0 if k == 0 else c1 if k == 1 else c2
                axes[ci] = (sg * a[0], sg * a[1], sg * a[2])
                origins[ci] = (px, py, pz)
            c, s = math.cos(th), math.sin(th)
            if k == 0:
                c1, c2 = (
                    [c * c1[0] + s * c2[0], c * c1[1] + s * c2[1], c * c1[2] + s * c2[2]],
                    [c * c2[0] - s * c1[0], c * c2[1] - s * c1[1], c * c2[2] - s * c1[2]],
                )
            elif k == 1:
                c0, c2 = (
                    [c * c0[0] - s * c2[0], c * c0[1] - s * c2[1], c * c0[2] - s * c2[2]],
                    [s * c0[0] + c * c2[0], s * c0[1] + c * c2[1], s * c0[2] + c * c2[2]],
                )
            else:
                c0, c1 = (
                    [c * c0[0] + s * c1[0], c * c0[1] + s * c1[1], c * c0[2] + s * c1[2]],
                    [c * c1[0] - s * c0[0], c * c1[1] - s * c0[1], c * c1[2] - s * c0[2]],
                )
    return (c0, c1, c2), (px, py, pz), axes, origins


def _serial_base(model: ChainModel) -> int:
    """The joint a ChainModel's one serial chain hangs from; ValueError when it is not one."""
    if len(model.sites) != 1:
        raise ValueError("one site only")
    skel = model.skel
    live = model.live
    for a, b in itertools.pairwise(live):
        if int(skel.parent[b]) != a:
            raise ValueError("not a serial chain")
    if live[-1] != model._site_joint[0]:
        raise ValueError("site must be on the chain's last joint")
    return int(skel.parent[live[0]])


class SerialChain:
    """Scalar kinematics of a ChainModel with one site on one serial chain (base row ``row``,
    the chain's own fixed angles those of ``q_base``, by default the row's)."""

    def __init__(
        self,
        model: ChainModel,
        row: int = 0,
        q_base: FloatArray | None = None,
        *,
        base: int | None = None,
    ) -> None:
        first_parent = _serial_base(model) if base is None else base
        R0 = model._base_R[first_parent][row]
        p0 = model._base_p[first_parent][row]
        self.R0 = [[float(R0[i, j]) for i in range(3)] for j in range(3)]  # columns
        self.p0 = [float(x) for x in p0]
        self.plan = chain_plan(model, model.live, model.q_base[row] if q_base is None else q_base)
        self.site_off = [float(x) for x in model._site_off[0]]
        self.n = model.n

    def eval(self, q: list[float]) -> tuple[list[float], list[list[float]]]:
        """Site position and the 3×n Jacobian (as columns) at active angles ``q``."""
        (c0, c1, c2), (px, py, pz), axes, origins = walk_chain(
            self.R0, self.p0, self.plan, q, self.n
        )
        sx, sy, sz = self.site_off
        ex = px + c0[0] * sx + c1[0] * sy + c2[0] * sz
        ey = py + c0[1] * sx + c1[1] * sy + c2[1] * sz
        ez = pz + c0[2] * sx + c1[2] * sy + c2[2] * sz
        J = []
        for (ax, ay, az), (qx, qy, qz) in zip(axes, origins, strict=True):
            dx, dy, dz = ex - qx, ey - qy, ez - qz
            J.append([ay * dz - az * dy, az * dx - ax * dz, ax * dy - ay * dx])
        return [ex, ey, ez], J


class SerialRows:
    """One serial chain on every row of a batched ChainModel: the base frames of all the rows
    computed together (numpy's arithmetic, row by row the same as a model of that row alone),
    the chain of a row built without a model of its own (the carry's continuation solves an
    arm at each of a path's hundreds of points: building a model for each was two thirds of
    the solve)."""

    def __init__(self, model: ChainModel) -> None:
        self.model = model
        self._base = _serial_base(model)
        # every dof about a coordinate axis, or ValueError now (the caller then solves by
        # ``solve_ta``), not in the middle of a path
        _plan_shape(model.skel, tuple(model.live), tuple(int(d) for d in model.active))

    def describes(self, row: int, q_full: FloatArray) -> bool:
        """Whether row ``row`` was built for the body of ``q_full`` (D,): the same angles of
        every dof the chain hangs from (a model places the chain where its own trunk is)."""
        baked = self.model.baked
        return bool(np.array_equal(q_full[baked], self.model.q_base[row, baked]))

    def chain(self, row: int, q_full: FloatArray) -> SerialChain:
        """Row ``row``'s chain, its own fixed angles (dofs of its joints that do not move)
        those of ``q_full`` (D,)."""
        return SerialChain(self.model, row, q_full, base=self._base)

    def site(self, row: int, q_full: FloatArray) -> list[float]:
        """The site's position on row ``row`` with the full angles ``q_full`` (D,), on Python
        floats: forward kinematics' to rounding (1e-16 m), not to the bit."""
        return self.chain(row, q_full).eval([float(v) for v in q_full[self.model.active]])[0]


def _solve3(
    J: list[list[float]], free: list[bool], lam2: float, rhs: list[list[float]]
) -> list[list[float]]:
    """Solve (J Jᵀ + λ²I) y = r for each r, using only the free columns of J."""
    a00 = a01 = a02 = a11 = a12 = a22 = 0.0
    for col, f in zip(J, free, strict=True):
        if f:
            x, y, z = col
            a00 += x * x
            a01 += x * y
            a02 += x * z
            a11 += y * y
            a12 += y * z
            a22 += z * z
    a00 += lam2
    a11 += lam2
    a22 += lam2
    i00 = a11 * a22 - a12 * a12
    i01 = a02 * a12 - a01 * a22
    i02 = a01 * a12 - a02 * a11
    i11 = a00 * a22 - a02 * a02
    i12 = a01 * a02 - a00 * a12
    i22 = a00 * a11 - a01 * a01
    det = a00 * i00 + a01 * i01 + a02 * i02
    inv = 1.0 / det
    out = []
    for r0, r1, r2 in rhs:
        out.append(
            [
                (i00 * r0 + i01 * r1 + i02 * r2) * inv,
                (i01 * r0 + i11 * r1 + i12 * r2) * inv,
                (i02 * r0 + i12 * r1 + i22 * r2) * inv,
            ]
        )
    return out


def solve_one(
    chain: SerialChain,
    target: FloatArray,
    q0: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    comfort: FloatArray,
    *,
    tol: float,
    max_iter: int,
    restarts: int,
    patience: int,
    damping: float,
    max_error: float,
    max_step: float,
    null_gain: float,
    rng: np.random.Generator,
) -> tuple[list[float], float, int, int]:
    """DLS for one position target. Returns (best q, best error, iterations, restarts)."""
    tx, ty, tz = (float(v) for v in target)
    lo = [float(v) for v in lower]
    hi = [float(v) for v in upper]
    cf = [float(v) for v in comfort]
    n = chain.n
    q = [min(max(float(v), lo[i]), hi[i]) for i, v in enumerate(q0)]
    lam2 = damping * damping
    best_q, best_err = list(q), math.inf
    iters = n_restart = attempt_it = since = 0
    attempt_best = math.inf
    all_free = [True] * n
    while True:
        p, J = chain.eval(q)
        ex, ey, ez = tx - p[0], ty - p[1], tz - p[2]
        err = math.sqrt(ex * ex + ey * ey + ez * ez)
        if err < best_err:
            best_err, best_q = err, list(q)
        if err <= tol:
            break
        if err < 0.9 * attempt_best:
            attempt_best, since = err, 0
        else:
            since += 1
        if since >= patience or attempt_it >= max_iter:
            if n_restart >= restarts:
                break
            n_restart += 1
            attempt_it = since = 0
            attempt_best = math.inf
            q = [lo[i] + (hi[i] - lo[i]) * float(u) for i, u in enumerate(rng.random(n))]
            continue
        if err > max_error:
            s = max_error / err
            ex, ey, ez = ex * s, ey * s, ez * s
        gain = null_gain * min(1.0, err / NULL_FADE)
        z = [gain * (cf[i] - q[i]) for i in range(n)]
        jz = [0.0, 0.0, 0.0]
        for col, zi in zip(J, z, strict=True):
            jz[0] += col[0] * zi
            jz[1] += col[1] * zi
            jz[2] += col[2] * zi
        y1, y2 = _solve3(J, all_free, lam2, [[ex, ey, ez], jz])
        w0, w1, w2 = y1[0] - y2[0], y1[1] - y2[1], y1[2] - y2[2]
        dq = [col[0] * w0 + col[1] * w1 + col[2] * w2 + z[i] for i, col in enumerate(J)]
        over = [not (lo[i] <= q[i] + dq[i] <= hi[i]) for i in range(n)]
        if any(over):
            pin = [
                min(max(q[i] + dq[i], lo[i]), hi[i]) - q[i] if over[i] else 0.0 for i in range(n)
            ]
            r = [ex, ey, ez]
            for col, d in zip(J, pin, strict=True):
                if d:
                    r[0] -= col[0] * d
                    r[1] -= col[1] * d
                    r[2] -= col[2] * d
            free = [not o for o in over]
            (y,) = _solve3(J, free, lam2, [r])
            dq = [
                pin[i] if over[i] else col[0] * y[0] + col[1] * y[1] + col[2] * y[2]
                for i, col in enumerate(J)
            ]
        big = max(abs(d) for d in dq)
        sc = max_step / big if big > max_step else 1.0
        q = [min(max(q[i] + sc * dq[i], lo[i]), hi[i]) for i in range(n)]
        iters += 1
        attempt_it += 1
    return best_q, best_err, iters, n_restart
