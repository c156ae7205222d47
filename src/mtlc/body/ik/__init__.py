"""Inverse kinematics: TA (damped least squares), TO (gradient path), Jacobian transpose.

>>> import numpy as np
>>> from mtlc.body import build_manikin
>>> from mtlc.body.ik import Goal, solve_ta
>>> sk = build_manikin()
>>> res = solve_ta(sk, [Goal("r_hand", position=[-0.25, 1.1, 0.35])])
>>> bool(res.success[0])
True
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ..skeleton import Skeleton
from .dls import prepare, solve_ta, solve_ta_row
from .fast import SerialRows
from .goals import CHAINS, Goal, default_dofs
from .gradient import solve_to
from .model import ChainModel
from .result import IKResult
from .transpose import solve_transpose

METHODS = {"dls": solve_ta, "gradient": solve_to, "transpose": solve_transpose}


def solve(
    skel: Skeleton, goals: Sequence[Goal], q0: Any = None, *, method: str = "dls", **kw: Any
) -> IKResult:
    """Dispatch to a solver by name: ``"dls"`` (TA), ``"gradient"`` (TO) or ``"transpose"``."""
    try:
        fn = METHODS[method]
    except KeyError:
        raise ValueError(f"unknown IK method {method!r}; choose one of {sorted(METHODS)}") from None
    return fn(skel, goals, q0, **kw)


__all__ = [
    "CHAINS",
    "METHODS",
    "ChainModel",
    "Goal",
    "IKResult",
    "SerialRows",
    "default_dofs",
    "prepare",
    "solve",
    "solve_ta",
    "solve_ta_row",
    "solve_to",
    "solve_transpose",
]
