"""What every solver returns, and the residual all of them minimise."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..kinematics import cross, einsum, rotation_error
from .goals import GoalArrays
from .model import ChainModel, _take

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class IKResult:
    """Best configurations found, one row per target.

    ``q`` (B, n_dofs) full joint angles (dofs the solver did not move keep their input value);
    ``position_error`` (B,) the largest remaining position distance over the goals (m);
    ``orientation_error`` (B,) the largest remaining angle (rad; orientation and aim goals);
    ``success`` (B,) within tolerance with every joint inside its limits;
    ``iterations`` (B,) iterations spent (all attempts); ``restarts`` (B,) restarts used;
    ``path`` (T, B, n_dofs) every accepted configuration (gradient-path solvers only);
    ``first`` (B, n_dofs) the best of the first attempt alone, what ``restarts=0`` returns
    (``solve_ta(..., first_attempt=True)`` of one row on the general path only).
    """

    q: FloatArray
    position_error: FloatArray
    orientation_error: FloatArray
    success: NDArray[np.bool_]
    iterations: NDArray[np.intp]
    restarts: NDArray[np.intp]
    method: str
    path: FloatArray | None = None
    first: FloatArray | None = None

    @property
    def success_rate(self) -> float:
        """Fraction of targets solved."""
        return float(np.mean(self.success))


def returned_errors(
    model: ChainModel, ga: GoalArrays, q_out: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Position and orientation errors (B,) of the configurations a solver returns, from the
    forward kinematics of ``q_out`` itself (a model built for its baked angles, so a model
    prepared for another start cannot vouch for a pose it does not describe)."""
    exact = model.for_start(q_out)
    r = residual(exact, ga, q_out[:, exact.active])
    return r.pos_err, r.ori_err


def position_targets(ga: GoalArrays) -> FloatArray | None:
    """The goals' positions side by side (B, S, 3) when every goal is a position alone
    (``residual``'s ``targets``), else None."""
    if any(p is None for p in ga.position) or any(
        x is not None for x in (*ga.orientation, *ga.aim)
    ):
        return None
    return np.stack(ga.position, axis=1)  # type: ignore[arg-type]


@dataclass
class Residual:
    """Stacked task error ``e`` (b, m), its Jacobian ``J`` (b, m, nA), and error measures."""

    e: FloatArray
    J: FloatArray
    pos_err: FloatArray
    ori_err: FloatArray
    cost: FloatArray  # 0.5 |e|^2, what the gradient methods descend


def residual(
    model: ChainModel,
    ga: GoalArrays,
    qa: FloatArray,
    rows: NDArray[np.intp] | None = None,
    *,
    with_cost: bool = True,
    targets: FloatArray | None = None,
) -> Residual:
    """Evaluate every goal at active angles ``qa`` (b, nA) for batch ``rows``
    (``with_cost=False``: no ``cost``, which only the gradient methods read). ``targets``:
    ``position_targets(ga)`` of goals that are positions alone, for ``rows`` (the same
    numbers in a third of the numpy calls: one subtraction and one sum for every site)."""
    b = qa.shape[0]
    site_p, site_R, Jp, Jw = model.evaluate(qa, rows)
    if targets is not None:
        e3 = targets - site_p  # (b, S, 3)
        n_rows = 3 * e3.shape[1]
        e = e3.reshape(b, n_rows)
        # the sites' rows side by side: Jp is a dof-major array, so this is a view in the
        # layout np.concatenate of the sites' blocks gives (what the solvers' BLAS calls see)
        J = Jp.transpose(0, 3, 1, 2).reshape(b, Jp.shape[-1], n_rows).swapaxes(1, 2)
        pos_err = np.sqrt(einsum("bsi,bsi->bs", e3, e3)).max(axis=1)
        cost = 0.5 * einsum("bi,bi->b", e, e) if with_cost else np.empty(0)
        return Residual(e=e, J=J, pos_err=pos_err, ori_err=np.zeros(b), cost=cost)
    es: list[FloatArray] = []
    Js: list[FloatArray] = []
    pos_err: FloatArray | None = None
    ori_err: FloatArray | None = None
    skel = model.skel
    for i in range(len(ga.sites)):
        if ga.position[i] is not None:
            e = _take(ga.position[i], rows, b) - site_p[:, i]
            es.append(e)
            Js.append(Jp[:, i])
            d = np.sqrt(einsum("bi,bi->b", e, e))
            pos_err = d if pos_err is None else np.maximum(pos_err, d)
        if ga.orientation[i] is not None:
            r = rotation_error(_take(ga.orientation[i], rows, b), site_R[:, i])
            w = ga.weight[i]
            es.append(w * r)
            Js.append(w * Jw[:, i])
            a = np.linalg.norm(r, axis=-1)
            ori_err = a if ori_err is None else np.maximum(ori_err, a)
        if ga.aim[i] is not None:
            direction = np.asarray(skel.site(ga.sites[i]).direction, dtype=float)
            d = site_R[:, i] @ direction
            u = _take(ga.aim[i], rows, b) - site_p[:, i]
            u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
            cr = cross(d, u)
            sn = np.linalg.norm(cr, axis=-1)
            ang = np.arctan2(sn, einsum("bi,bi->b", d, u))
            axis = np.where(sn[:, None] > 1e-12, cr / np.maximum(sn, 1e-300)[:, None], 0.0)
            r = axis * ang[:, None]
            w = ga.weight[i]
            es.append(w * r)
            Js.append(w * Jw[:, i])
            ori_err = ang if ori_err is None else np.maximum(ori_err, ang)
    # (the largest goal's error: each is a norm or an angle in [0, pi], never below 0)
    pos_err = np.zeros(b) if pos_err is None else pos_err
    ori_err = np.zeros(b) if ori_err is None else ori_err
    e = es[0] if len(es) == 1 else np.concatenate(es, axis=1)
    J = Js[0] if len(Js) == 1 else np.concatenate(Js, axis=1)
    cost = 0.5 * einsum("bi,bi->b", e, e) if with_cost else np.empty(0)
    return Residual(e=e, J=J, pos_err=pos_err, ori_err=ori_err, cost=cost)
