"""IK benchmark: mtlc's solvers against ikpy, pink (pin-pink) and roboticstoolbox ``ik_LM``.

Run:  python bench/ik.py [--n 500] [--batch 1000] [--batch-repeat 5] [--seed 0] [--skip-peers]

Problems (GB 10000-88 male P50 manikin, root fixed, other dofs at the comfortable posture):
  arm   7 dofs (right shoulder 3, elbow + forearm 2, wrist 2), goal: r_hand position;
  body  36 dofs (spine 6, both girdles 4, arms 14, legs 12), goals: both hands and both feet.
Targets: forward kinematics of ``--n`` uniformly random in-limit configurations. Seeds: the
middle of every joint range ("middle"), and the true solution plus N(0, 0.25 rad) noise,
clipped into the limits ("near"). Success: every goal within 1 mm and every joint within its
limits. Times are wall-clock per solve (single calls; setup such as URDF loading excluded);
"batched" solves ``--batch`` targets in one call (TA: best of ``--batch-repeat`` calls, as
the machine is shared). A peer that cannot be imported is listed with the reason and skipped.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mtlc.body import Skeleton, build_manikin, forward, site_positions
from mtlc.body.ik import Goal, default_dofs, prepare, solve_ta, solve_to, solve_transpose
from mtlc.body.ik.model import ChainModel

TOL = 1e-3


@dataclass
class Row:
    problem: str
    solver: str
    seed: str
    success: float | None
    median_ms: float | None
    mean_ms: float | None
    batched_us: float | None = None
    note: str = ""


# --------------------------------------------------------------------------------------
# URDF export of a skeleton (every dof a revolute joint; frozen dofs kept at their values)
# --------------------------------------------------------------------------------------
def _rpy(R: np.ndarray) -> tuple[float, float, float]:
    from scipy.spatial.transform import Rotation

    r, p, y = Rotation.from_matrix(R).as_euler("xyz")
    return float(r), float(p), float(y)


def to_urdf(skel: Skeleton, joints: Sequence[str], sites: Sequence[str], q_base: np.ndarray) -> str:
    """URDF of ``joints`` (a connected sub-tree) hung from a fixed base at its parent's frame.

    Dofs of the listed joints are revolute joints named like the dof; each site becomes a
    fixed child link named like the site.
    """
    pose = forward(skel, q_base)
    jset = set(joints)
    roots = [j for j in joints if skel.joints[skel.joint_index(j)].parent not in jset]
    out = ['<?xml version="1.0"?>', '<robot name="mtlc_manikin">', '<link name="world"/>']
    last_link: dict[str, str] = {}
    for j in joints:
        ji = skel.joint_index(j)
        jt = skel.joints[ji]
        if j in roots:
            pi = int(skel.parent[ji])
            R, p = pose.R[pi], pose.p[pi] + pose.R[pi] @ skel.offsets[ji]
            parent, xyz, rpy = "world", p, _rpy(R)
        else:
            parent, xyz, rpy = last_link[jt.parent], skel.offsets[ji], (0.0, 0.0, 0.0)  # type: ignore[index]
        if not jt.dofs:
            out.append(f'<link name="{j}_l"/>')
            out.append(
                f'<joint name="{j}_fix" type="fixed"><parent link="{parent}"/>'
                f'<child link="{j}_l"/><origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" '
                f'rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/></joint>'
            )
            last_link[j] = f"{j}_l"
            continue
        for k, d in enumerate(jt.dofs):
            link = f"{d.name}_l"
            out.append(f'<link name="{link}"/>')
            o = xyz if k == 0 else (0.0, 0.0, 0.0)
            r = rpy if k == 0 else (0.0, 0.0, 0.0)
            out.append(
                f'<joint name="{d.name}" type="revolute"><parent link="{parent}"/>'
                f'<child link="{link}"/><origin xyz="{o[0]} {o[1]} {o[2]}" '
                f'rpy="{r[0]} {r[1]} {r[2]}"/>'
                f'<axis xyz="{d.axis[0]} {d.axis[1]} {d.axis[2]}"/>'
                f'<limit lower="{d.min}" upper="{d.max}" effort="100" velocity="10"/></joint>'
            )
            parent = link
        last_link[j] = parent
    for s in sites:
        st = skel.site(s)
        o = st.offset
        out.append(f'<link name="{s}"/>')
        out.append(
            f'<joint name="{s}_site" type="fixed"><parent link="{last_link[st.joint]}"/>'
            f'<child link="{s}"/><origin xyz="{o[0]} {o[1]} {o[2]}" rpy="0 0 0"/></joint>'
        )
    out.append("</robot>")
    return "\n".join(out)


# --------------------------------------------------------------------------------------
# Problems
# --------------------------------------------------------------------------------------
@dataclass
class Problem:
    name: str
    skel: Skeleton
    sites: list[str]
    joints: list[str]
    dofs: list[int]
    targets: np.ndarray  # (N, S, 3)
    q_true: np.ndarray  # (N, D)
    seeds: dict[str, np.ndarray]  # name -> (N, D)


def make_problem(
    name: str, skel: Skeleton, sites: list[str], dofs: list[int], n: int, seed: int
) -> Problem:
    rng = np.random.default_rng(seed)
    q = np.tile(skel.q_comfort, (n, 1))
    q[:, dofs] = skel.random_q(rng, n)[:, dofs]
    targets = site_positions(skel, forward(skel, q), sites)
    mid = np.tile(skel.q_comfort, (n, 1))
    mid[:, dofs] = skel.q_middle[dofs]
    near = q.copy()
    near[:, dofs] = skel.clip(q + rng.normal(0, 0.25, q.shape))[:, dofs]
    joints = sorted({skel.joint_names[int(skel.dof_joint[d])] for d in dofs}, key=skel.joint_index)
    return Problem(name, skel, sites, joints, dofs, targets, q, {"middle": mid, "near": near})


def check(p: Problem, q: np.ndarray) -> np.ndarray:
    """Success per row: every goal within 1 mm, every joint in its limits."""
    got = site_positions(p.skel, forward(p.skel, q), p.sites)
    err = np.linalg.norm(got - p.targets[: len(q)], axis=-1).max(axis=-1)
    return (err <= TOL) & p.skel.within_limits(q, tol=1e-9)


def time_single(
    p: Problem, seed: str, fn: Callable[[int, np.ndarray], np.ndarray], limit: int | None = None
) -> tuple[float, float, float]:
    n = len(p.targets) if limit is None else min(limit, len(p.targets))
    ts, qs = [], []
    for i in range(n):
        q0 = p.seeds[seed][i]
        t = time.perf_counter()
        qs.append(fn(i, q0))
        ts.append(time.perf_counter() - t)
    ok = check(p, np.array(qs))
    return float(ok.mean()), statistics.median(ts) * 1e3, statistics.fmean(ts) * 1e3


# --------------------------------------------------------------------------------------
# Solvers
# --------------------------------------------------------------------------------------
def mtlc_rows(p: Problem, batch: int, batch_repeat: int = 5) -> list[Row]:
    rows = []
    model: ChainModel = prepare(p.skel, p.sites, p.skel.q_comfort, dofs=p.dofs)
    methods = {
        "mtlc TA (DLS)": solve_ta,
        "mtlc TO (gradient)": solve_to,
        "mtlc transpose": solve_transpose,
    }
    for label, fn in methods.items():
        kw = {"record_path": False} if fn is solve_to else {}
        if fn is not solve_ta:
            kw["max_iter"] = 2000

        def one(i: int, q0: np.ndarray, fn=fn, kw=kw) -> np.ndarray:  # type: ignore[no-untyped-def]
            goals = [Goal(s, position=p.targets[i, k]) for k, s in enumerate(p.sites)]
            return fn(p.skel, goals, q0, model=model, **kw).q[0]

        for seed in ("middle", "near"):
            limit = None if fn is solve_ta else 100
            ok, med, mean = time_single(p, seed, one, limit)
            note = "" if limit is None else f"first {limit} targets"
            bt = None
            if seed == "middle":
                nb = batch
                rng = np.random.default_rng(99)
                q = np.tile(p.skel.q_comfort, (nb, 1))
                q[:, p.dofs] = p.skel.random_q(rng, nb)[:, p.dofs]
                T = site_positions(p.skel, forward(p.skel, q), p.sites)
                goals = [Goal(s, position=T[:, k]) for k, s in enumerate(p.sites)]
                q0 = np.tile(p.seeds["middle"][0], (nb, 1))
                # Best of a few runs for the fast solver: the machine is shared and noisy.
                reps = batch_repeat if fn is solve_ta else 1
                times = []
                for _ in range(reps):
                    t = time.perf_counter()
                    res = fn(p.skel, goals, q0, model=model, **kw)
                    times.append(time.perf_counter() - t)
                bt = min(times) / nb * 1e6
                tag = f"best of {reps}; " if reps > 1 else ""
                tag += f"batched success {res.success_rate:.1%}"
                note = f"{note}; {tag}" if note else tag
            rows.append(Row(p.name, label, seed, ok, med, mean, bt, note))
    return rows


def ikpy_rows(p: Problem, urdf: Path) -> list[Row]:
    if len(p.sites) != 1:
        return [
            Row(p.name, "ikpy", s, None, None, None, note="n/a: single chain, one target")
            for s in ("middle", "near")
        ]
    try:
        from ikpy.chain import Chain
    except Exception as exc:  # pragma: no cover - depends on the machine
        return [Row(p.name, "ikpy", "-", None, None, None, note=f"not installed: {exc}")]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        chain = Chain.from_urdf_file(str(urdf), base_elements=["world"], last_link_vector=None)
    names = [lk.name for lk in chain.links]
    mask = [n in {p.skel.dof_names[d] for d in p.dofs} for n in names]
    chain.active_links_mask = np.array(mask)
    idx = [names.index(p.skel.dof_names[d]) for d in p.dofs]
    rows = []
    for seed in ("middle", "near"):

        def one(i: int, q0: np.ndarray, seed: str = seed) -> np.ndarray:
            init = np.zeros(len(names))
            init[idx] = q0[p.dofs]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                sol = chain.inverse_kinematics(p.targets[i, 0], initial_position=init)
            q = p.seeds[seed][i].copy()
            q[p.dofs] = sol[idx]
            return q

        ok, med, mean = time_single(p, seed, one, 100)
        rows.append(Row(p.name, "ikpy", seed, ok, med, mean, note="first 100 targets"))
    return rows


def pink_rows(p: Problem, urdf: Path) -> list[Row]:
    try:
        import pink
        import pinocchio as pin
        from pink.tasks import FrameTask
    except Exception as exc:  # pragma: no cover
        return [Row(p.name, "pink", "-", None, None, None, note=f"not installed: {exc}")]
    import qpsolvers

    solvers = [
        s for s in ("daqp", "quadprog", "proxqp", "osqp") if s in qpsolvers.available_solvers
    ]
    if not solvers:
        return [Row(p.name, "pink", "-", None, None, None, note="no QP solver (pip install daqp)")]
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    qidx = [model.joints[model.getJointId(p.skel.dof_names[d])].idx_q for d in p.dofs]
    tasks = [FrameTask(s, position_cost=1.0, orientation_cost=0.0) for s in p.sites]
    rows = []
    for seed in ("middle", "near"):

        def one(i: int, q0: np.ndarray, seed: str = seed) -> np.ndarray:
            qp = np.zeros(model.nq)
            qp[qidx] = q0[p.dofs]
            conf = pink.Configuration(model, data, qp)
            for k, t in enumerate(tasks):
                t.set_target(pin.SE3(np.eye(3), p.targets[i, k]))
            for _ in range(100):
                err = max(
                    np.linalg.norm(
                        conf.get_transform_frame_to_world(s).translation - p.targets[i, k]
                    )
                    for k, s in enumerate(p.sites)
                )
                if err <= TOL:
                    break
                v = pink.solve_ik(conf, tasks, 1.0, solver=solvers[0])
                conf.integrate_inplace(v, 1.0)
            q = p.seeds[seed][i].copy()
            q[p.dofs] = conf.q[qidx]
            return q

        ok, med, mean = time_single(p, seed, one)
        rows.append(
            Row(
                p.name,
                "pink",
                seed,
                ok,
                med,
                mean,
                note=f"QP {solvers[0]}; dt=1, ≤100 steps",
            )
        )
    return rows


def rtb_rows(p: Problem) -> list[Row]:
    if len(p.sites) != 1:
        return [
            Row(p.name, "rtb ik_LM", s, None, None, None, note="n/a: ETS is one serial chain")
            for s in ("middle", "near")
        ]
    try:
        import roboticstoolbox as rtb
        from spatialmath import SE3
    except Exception as exc:  # pragma: no cover
        return [Row(p.name, "rtb ik_LM", "-", None, None, None, note=f"not installed: {exc}")]
    sk = p.skel
    pose = forward(sk, sk.q_comfort)
    first = sk.joint_index(p.joints[0])
    pi = int(sk.parent[first])
    T0 = np.eye(4)
    T0[:3, :3] = pose.R[pi]
    T0[:3, 3] = pose.p[pi]
    ets = rtb.ET.SE3(SE3(T0, check=False))
    for j in p.joints:
        ji = sk.joint_index(j)
        o = sk.offsets[ji]
        ets = ets * rtb.ET.tx(o[0]) * rtb.ET.ty(o[1]) * rtb.ET.tz(o[2])
        for d in sk.joints[ji].dofs:
            k = int(np.argmax(np.abs(d.axis)))
            flip = d.axis[k] < 0
            ets = ets * (rtb.ET.Rx, rtb.ET.Ry, rtb.ET.Rz)[k](flip=flip, qlim=[d.min, d.max])
    so = sk.site(p.sites[0]).offset
    ets = ets * rtb.ET.tx(so[0]) * rtb.ET.ty(so[1]) * rtb.ET.tz(so[2])
    rows = []
    for seed in ("middle", "near"):

        def one(i: int, q0: np.ndarray, seed: str = seed) -> np.ndarray:
            Tep = np.eye(4)
            Tep[:3, 3] = p.targets[i, 0]
            sol = ets.ik_LM(Tep, q0=q0[p.dofs], ilimit=30, slimit=100, tol=1e-7,
                            mask=np.array([1.0, 1, 1, 0, 0, 0]), joint_limits=True)  # fmt: skip
            q = p.seeds[seed][i].copy()
            q[p.dofs] = sol[0]
            return q

        ok, med, mean = time_single(p, seed, one)
        rows.append(Row(p.name, "rtb ik_LM", seed, ok, med, mean, note="C++; position mask"))
    return rows


# --------------------------------------------------------------------------------------
def fmt(rows: list[Row]) -> str:
    head = (
        "| problem | solver | seed | success (1 mm, in limits) | median ms | mean ms "
        "| batched µs/target | note |"
    )
    lines = [head, "|---|---|---|---|---|---|---|---|"]
    for r in rows:

        def f(v: float | None, pat: str) -> str:
            return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else pat.format(v)

        lines.append(
            f"| {r.problem} | {r.solver} | {r.seed} | {f(r.success, '{:.1%}')} "
            f"| {f(r.median_ms, '{:.3f}')} | {f(r.mean_ms, '{:.3f}')} "
            f"| {f(r.batched_us, '{:.1f}')} | {r.note} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=500)
    ap.add_argument("--batch", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--batch-repeat", type=int, default=5, help="batched TA: best of this many")
    ap.add_argument("--skip-peers", action="store_true")
    ap.add_argument("--problems", default="arm,body")
    a = ap.parse_args(argv)
    sk = build_manikin("gb10000_1988", "male", 50)
    probs = []
    if "arm" in a.problems:
        probs.append(make_problem("arm", sk, ["r_hand"], default_dofs(sk, ["r_hand"]), a.n, a.seed))
    if "body" in a.problems:
        effs = ["r_hand", "l_hand", "r_foot", "l_foot"]
        probs.append(
            make_problem("body", sk, effs, default_dofs(sk, effs, "torso"), a.n, a.seed + 1)
        )
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        for p in probs:
            urdf = Path(tmp) / f"{p.name}.urdf"
            urdf.write_text(to_urdf(sk, p.joints, p.sites, sk.q_comfort))
            rows += mtlc_rows(p, a.batch, a.batch_repeat)
            if not a.skip_peers:
                rows += ikpy_rows(p, urdf) + pink_rows(p, urdf) + rtb_rows(p)
            print(fmt([r for r in rows if r.problem == p.name]), flush=True)
            print(flush=True)
    print(f"python {sys.version.split()[0]}, numpy {np.__version__}, n={a.n}, batch={a.batch}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
