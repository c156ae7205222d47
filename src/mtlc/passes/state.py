"""The body's pose at a time, from the keyframes written so far: what the solving passes start from.

Passes fill segments in time order and each segment starts from the pose the body is in, so they
need "the value of every dof just before this segment". ``PoseState`` indexes every keyframe by
dof and time and answers that with a bisection. It keeps *references* to the keyframe arrays, not
copies, so a pass that rewrites a keyframe in place (``reanchor``) is seen by every later query.

The rule matches interpolation (``interpolate.py``) at keyframe times: a dof holds its rest value
(``q_comfort``) until its first keyframe and its latest keyframe's value after; at equal times
the keyframe added later wins. Between two keyframes of one dof interpolation blends, but every
segment here starts with a keyframe that holds the current pose, so between segments dofs hold.
The root is the plan's ground position and heading at the height that puts the lowest foot
point on the ground, as the base correction does for a body standing still.
"""

from __future__ import annotations

import copy
from bisect import bisect_left, bisect_right
from collections.abc import Callable, Collection, Sequence
from typing import Any

import numpy as np

from mtlc.body import forward_part, site_positions
from mtlc.body.ik import ChainModel, Goal, IKResult
from mtlc.ir.model import FloatArray, Keyframes, MotionIR, Segment, yaw_quaternion
from mtlc.passes.interpolate import (
    anchored_root,
    foot_chain_dofs,
    gait_window,
    keyed_windows,
    track,
)
from mtlc.passes.profile import minimum_jerk

TRUNK_DOFS = tuple(f"{j}_{a}" for j in ("lumbar", "thorax") for a in ("flex", "lat", "rot"))
# a keyframe column: (segment id, keyframes, column); column −1 for a posture root height
_Block = tuple[int, Keyframes, int]
FEW_TIMES = 48  # up to this many times ``q_at_many`` bisects per time (its set-up costs more)
ROW_BITS = 24  # a reference is block << ROW_BITS | row: the index holds ints, not tuples
# the segment(s) whose keyframes a query ignores
Skip = Segment | Collection[Segment] | None


def _skip_ids(skip: Skip) -> frozenset[int]:
    if skip is None:
        return frozenset()
    if isinstance(skip, Segment):
        return frozenset({id(skip)})
    return frozenset(id(s) for s in skip)


class PoseState:
    """Index of the keyframes so far: ``q_at(t)`` and ``root_at(t)``, optionally ignoring one
    segment (its own start keyframe is what is being computed)."""

    def __init__(self, ir: MotionIR) -> None:
        skel = ir.skeleton
        self.ir = ir
        self.skel = skel
        self.rest = np.asarray(skel.q_comfort, dtype=float)
        self.stand_y = ir.ground + float(np.asarray(skel.root_position)[1])
        self._blocks: list[_Block] = []
        # each block's keyframes (an index into ``_kfs``: one per ``add``) and column
        self._kfs: list[Keyframes] = []
        self._block_kf: list[int] = []
        self._block_col: list[int] = []
        # derived from the segments and keyframes, keyed by what they depend on (see root_at)
        self.memo: dict[Any, Any] = {}
        self._t: list[list[float]] = [[] for _ in range(skel.n_dofs)]
        self._r: list[list[int]] = [[] for _ in range(skel.n_dofs)]
        self._rt: list[float] = []
        self._rr: list[int] = []
        # per dof, its index as arrays (times, blocks, rows) for queries of many times at once;
        # dropped whenever a segment is indexed (``add`` may insert in the middle)
        self._arrays: dict[Any, Any] = {}
        # for ``_keyed_windows``: the segments listed now, the segments indexed later that
        # cannot place the root and were not listed, and the indexed ones that can
        self._listed = {id(s) for s in ir.segments}
        self._plain_added = 0
        self._movers_added = 0
        for seg in ir.segments:
            if seg.keyframes is not None:
                self.add(seg)
        # walks whose gait sets the root (the locomotion pass runs before every solving pass)
        self._walks = [
            (seg, gait_window(seg))
            for seg in ir.segments
            if seg.kind == "locomotion" and seg.keyframes is not None
        ]
        # the whole-body postures by start (the first of equal starts), for ``standing_before``
        self._posture_starts: list[float] = []
        self._posture_kinds: list[Any] = []
        for seg in sorted(ir.on_track("root"), key=lambda s: s.start):
            if seg.kind == "posture" and not (
                self._posture_starts and seg.start == self._posture_starts[-1]
            ):
                self._posture_starts.append(seg.start)
                self._posture_kinds.append(seg.goal.params.get("posture"))

    def standing_before(self, seg: Segment) -> bool:
        """The body stands (or bends) when ``seg`` starts: no squat, kneel or sit is its
        posture (the last whole-body posture that starts before it, found by bisection: a scan
        of every segment for every posture, in each pass's restating, grew with their product)."""
        k = bisect_left(self._posture_starts, seg.start - 1e-9)
        return k == 0 or self._posture_kinds[k - 1] in ("stand", "bend")

    def add(self, seg: Segment) -> None:
        """Index a segment's keyframes (call after setting ``seg.keyframes``)."""
        kf = seg.keyframes
        if kf is None:
            return
        sid = id(seg)
        self._arrays.clear()
        if seg.kind in ("locomotion", "posture"):
            self._movers_added += 1
        elif sid not in self._listed:  # a new segment, inserted in the list (a gaze's)
            self._listed.add(sid)
            self._plain_added += 1
        times = np.asarray(kf.time, dtype=float).tolist()
        ordered = bool(np.all(np.diff(kf.time) >= 0.0))
        columns = [(self.skel.dof_index(name), c) for c, name in enumerate(kf.dofs)]
        if seg.kind == "posture" and kf.root_position is not None:
            columns.append((-1, -1))
        for d, c in columns:
            ts, refs = (self._t[d], self._r[d]) if d >= 0 else (self._rt, self._rr)
            code = len(self._blocks) << ROW_BITS
            self._blocks.append((sid, kf, c))
            self._block_kf.append(len(self._kfs))
            self._block_col.append(c)
            if ordered and (not ts or times[0] >= ts[-1]):  # all after the rest: append
                ts.extend(times)
                refs.extend(range(code, code + len(times)))
                continue
            for row, t in enumerate(times):
                i = bisect_right(ts, t)
                ts.insert(i, t)
                refs.insert(i, code + row)
        self._kfs.append(kf)

    def _latest(
        self, times: list[float], refs: list[int], t: float, skip: frozenset[int]
    ) -> tuple[Keyframes, int, int] | None:
        """The keyframe that sets a value at ``t``: (keyframes, row, column)."""
        i = bisect_right(times, t + 1e-9) - 1
        while i >= 0:
            sid, kf, c = self._blocks[refs[i] >> ROW_BITS]
            if sid not in skip:
                return kf, refs[i] & ((1 << ROW_BITS) - 1), c
            i -= 1
        return None

    def q_at(self, t: float, skip: Skip = None) -> FloatArray:
        """Every dof at time ``t`` (after the keyframes at ``t``), ignoring the ``skip`` segment(s)."""
        sid = _skip_ids(skip)
        q = self.rest.copy()
        for d in range(len(q)):
            ref = self._latest(self._t[d], self._r[d], t, sid)
            if ref is not None:
                q[d] = ref[0].q[ref[1], ref[2]]
        return q

    def _index_arrays(self, d: int) -> tuple[FloatArray, np.ndarray, np.ndarray]:
        """Dof ``d``'s index as arrays: keyframe times, their blocks and rows."""
        found = self._arrays.get(d)
        if found is None:
            refs = np.asarray(self._r[d], dtype=np.int64)
            found = self._arrays[d] = (
                np.asarray(self._t[d], dtype=float),
                refs >> ROW_BITS,
                refs & ((1 << ROW_BITS) - 1),
            )
        return found

    def q_at_many(
        self, times: FloatArray, skip: Skip = None, dofs: Collection[int] | None = None
    ) -> FloatArray:
        """``q_at`` at each of ``times`` (N, n_dofs), with one sorted search per dof for all of
        them (a gaze pass asked ``q_at`` ten thousand times, one bisection per dof each). Only
        ``dofs`` (default: all) are looked up; the others hold their rest values."""
        t = np.asarray(times, dtype=float).reshape(-1)
        if len(t) <= FEW_TIMES:  # a bisection per dof and time costs less than the set-up
            q = np.tile(self.rest, (len(t), 1))
            for k, tk in enumerate(t.tolist()):
                q[k] = self.q_at(tk, skip)
            if dofs is not None:
                keep = np.zeros(len(self.rest), dtype=bool)
                keep[list(dofs)] = True
                q[:, ~keep] = self.rest[~keep]
            return q
        sid = _skip_ids(skip)
        q = np.tile(self.rest, (len(t), 1))
        # per dof, the frames a keyframe sets and which one: (frames, dof, block, row)
        found: list[tuple[np.ndarray, int, np.ndarray, np.ndarray]] = []
        for d in range(len(self.rest)) if dofs is None else sorted(dofs):
            if not self._t[d]:
                continue
            ts, blocks, rows = self._index_arrays(d)
            # the last keyframe at or before t (+1e-9), as ``_latest``'s bisection
            i = np.searchsorted(ts, t + 1e-9, side="right") - 1
            if sid:  # step back over the skipped segments' keyframes
                kept = np.array([self._blocks[b][0] not in sid for b in blocks.tolist()])
                latest_kept = np.maximum.accumulate(np.where(kept, np.arange(len(ts)), -1))
                i = np.where(i >= 0, latest_kept[np.maximum(i, 0)], -1)
            at = np.flatnonzero(i >= 0)
            if len(at):
                found.append((at, d, blocks[i[at]], rows[i[at]]))
        if not found:
            return q
        # the values are read now (a pass may rewrite a keyframe in place), one segment's
        # keyframes at a time (a gather of its rows and columns)
        frames = np.concatenate([f[0] for f in found])
        dof = np.concatenate([np.full(len(f[0]), f[1]) for f in found])
        block = np.concatenate([f[2] for f in found])
        row = np.concatenate([f[3] for f in found])
        block_kf, block_col = self._block_arrays()
        kf_of = block_kf[block]
        order = np.argsort(kf_of, kind="stable")
        frames, dof, row, kf_of = frames[order], dof[order], row[order], kf_of[order]
        col = block_col[block[order]]
        cuts = np.flatnonzero(kf_of[1:] != kf_of[:-1]) + 1
        for a, b in zip(np.r_[0, cuts].tolist(), np.r_[cuts, len(kf_of)].tolist(), strict=True):
            q[frames[a:b], dof[a:b]] = self._kfs[int(kf_of[a])].q[row[a:b], col[a:b]]
        return q

    def _block_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Each block's keyframes (index into ``_kfs``) and column, as arrays."""
        found = self._arrays.get("blocks")
        if found is None:
            found = self._arrays["blocks"] = (
                np.asarray(self._block_kf, dtype=np.intp),
                np.asarray(self._block_col, dtype=np.intp),
            )
        return found  # type: ignore[no-any-return]

    def height_at(self, t: float, skip: Skip = None) -> float:
        """Root height at ``t`` (the standing height until a posture changes it)."""
        ref = self._latest(self._rt, self._rr, t, _skip_ids(skip))
        if ref is None:
            return self.stand_y
        rp = ref[0].root_position
        assert rp is not None
        return float(rp[ref[1], 1])

    def root_at(self, t: float, skip: Skip = None) -> tuple[FloatArray, FloatArray]:
        """Root position and rotation (w first) at ``t``: the plan's ground position and heading,
        at the height that stands the legs' pose at ``t`` on the ground. That is where the base
        correction (seed 001, h = L − x) puts a body standing still, so a hand solved here is
        where the frames will show it."""
        plan = self.ir.root_plan
        assert plan is not None
        pos, heading = plan.at(t)
        pos = np.array(pos, dtype=float)
        rot = yaw_quaternion(np.asarray(heading))
        for seg, (start, end) in self._walks:  # the gait drives the root while it walks
            kf = seg.keyframes
            if kf is not None and kf.root_position is not None and start <= t <= end:
                grid = np.array([t])
                gp = track(list(kf.time), list(kf.root_position), grid)[0]
                if kf.root_rotation is not None:
                    gr = track(list(kf.time), list(kf.root_rotation), grid)[0]
                    rot = gr / np.linalg.norm(gr)
                return gp, rot
        skipped = _skip_ids(skip)
        for seg, start, end in self._keyed_windows():  # a stepping kneel places the root
            kf = seg.keyframes
            if id(seg) in skipped or kf is None or kf.root_position is None:
                continue
            if start + 1e-9 < t <= end + 1e-9:
                return track(list(kf.time), list(kf.root_position), np.array([t]))[0], rot
        q = self.q_at(t, skip)
        pos = anchored_root(self.skel, q[None], pos[None], rot[None], self.ir.ground)[0]
        return pos, rot

    def root_at_many(self, times: FloatArray, skip: Skip = None) -> tuple[FloatArray, FloatArray]:
        """``root_at`` at each of ``times``: positions (N, 3) and rotations (N, 4), the legs'
        poses anchored in one batch. The same numbers row by row (each row's arithmetic is
        its own; tests/test_state.py compares them)."""
        t = np.asarray(times, dtype=float).reshape(-1)
        plan = self.ir.root_plan
        assert plan is not None
        pos, heading = plan.at(t)
        pos = np.array(pos, dtype=float).reshape(len(t), 3)
        rot = yaw_quaternion(np.asarray(heading)).reshape(len(t), 4)
        done = np.zeros(len(t), dtype=bool)
        for seg, (start, end) in self._walks:  # the first walk whose gait covers t
            kf = seg.keyframes
            if kf is None or kf.root_position is None:
                continue
            inside = ~done & (start <= t) & (t <= end)
            if not inside.any():
                continue
            done |= inside
            pos[inside] = track(list(kf.time), list(kf.root_position), t[inside])
            if kf.root_rotation is not None:
                gr = track(list(kf.time), list(kf.root_rotation), t[inside])
                # a row at a time: a vector's norm is not a batch's row norm to the last bit
                rot[inside] = [g / np.linalg.norm(g) for g in gr]
        skipped = _skip_ids(skip)
        for seg, start, end in self._keyed_windows():
            kf = seg.keyframes
            if id(seg) in skipped or kf is None or kf.root_position is None:
                continue
            inside = ~done & (start + 1e-9 < t) & (t <= end + 1e-9)
            if inside.any():
                done |= inside
                pos[inside] = track(list(kf.time), list(kf.root_position), t[inside])
        rest = ~done
        if rest.any():
            # the legs' dofs only: the anchoring reads nothing else (``foot_chain_dofs``)
            q = self.q_at_many(t[rest], skip, dofs=foot_chain_dofs(self.skel).tolist())
            pos[rest] = anchored_root(self.skel, q, pos[rest], rot[rest], self.ir.ground)
        return pos, rot

    def _keyed_windows(self) -> list[tuple[Any, float, float]]:
        """``keyed_windows`` of the IR, computed again only when the segments that can place
        the root may have changed (not by sorting every segment on every call): a walk or a
        posture indexed (``add``), or a segment listed that was not indexed here. A gaze
        segment, inserted and indexed (or listed and then given keyframes), changes no window
        (the gaze pass adds hundreds)."""
        key = ("keyed_windows", len(self.ir.segments) - self._plain_added, self._movers_added)
        if key not in self.memo:
            self.memo = {k: v for k, v in self.memo.items() if k[0] != "keyed_windows"}
            self.memo[key] = keyed_windows(self.ir)
        found: list[tuple[Any, float, float]] = self.memo[key]
        return found

    def site(self, name: str, q: FloatArray, root: tuple[FloatArray, FloatArray]) -> FloatArray:
        """World position of one body site (or joint centre, with ``joint:`` prefix): the
        chain that carries it only (``forward_part``: the whole body's numbers)."""
        carrier = name[6:] if name.startswith("joint:") else name
        pose = forward_part(self.skel, q[None], root[0][None], root[1][None], [carrier])
        if name.startswith("joint:"):
            return np.asarray(pose.p[0, self.skel.joint_index(carrier)])
        return np.asarray(site_positions(self.skel, pose, name)[0])


def hold_keyframes(
    seg: Segment, dofs: tuple[str, ...], q_start: FloatArray, q_end: FloatArray
) -> Keyframes:
    """Two keyframes: the pose at the segment's start (held until then) and its goal."""
    return Keyframes(
        time=np.array([seg.start, seg.end]), dofs=dofs, q=np.stack([q_start, q_end]).astype(float)
    )


# A segment that starts from the current pose may recompute its keyframes once the pose before
# it is known better (a later pass solved what comes before it); passes register how, by kind.
Restate = Callable[[Segment, PoseState], None]


def mark(cache: dict[str, Any], seg: Segment, how: str = "hold") -> None:
    """Register a segment whose first keyframe is "the current pose" (``how``: a restater name)."""
    cache.setdefault("passes.state.restate", {})[id(seg)] = how


def reanchor(
    ir: MotionIR, cache: dict[str, Any], restaters: dict[str, Restate] | None = None
) -> None:
    """Rewrite every "starts from the current pose" keyframe from the pose before it, in time
    order, so a segment solved before the segments preceding it starts where they left off.

    Segments that start together (both arms of a two-handed reach, which share the trunk) are
    restated from the pose before all of them: each one's own first keyframe is no evidence
    of that pose, and reading a sibling's stale one would keep a trunk from before a later pass
    moved it (the gaze at the access panel's handle ended 7.8° off that way)."""
    restaters = restaters or {}
    marks: dict[int, str] = cache.get("passes.state.restate", {})
    state = PoseState(ir)
    ordered = sorted(ir.segments, key=lambda s: s.start)
    starts = [s.start for s in ordered]
    for seg in ordered:
        kf = seg.keyframes
        how = marks.get(id(seg))
        if kf is None or how is None:
            continue
        if how in restaters:
            restaters[how](seg, state)
            continue
        # default: the first keyframe holds the pose just before the segment (and its siblings)
        # the segments that start with this one: a window of the sorted starts (a bisect, not
        # a scan of every segment per segment), widened a little and then tested exactly
        lo = bisect_left(starts, seg.start - 2e-9)
        hi = bisect_right(starts, seg.start + 2e-9, lo=lo)
        together = [
            s for s in ordered[lo:hi] if id(s) in marks and abs(s.start - seg.start) <= 1e-9
        ]
        q = state.q_at(seg.start, skip=together)
        idx = [state.skel.dof_index(n) for n in kf.dofs]
        if seg.kind == "posture":
            start_posture_from(seg, q[idx], state.standing_before(seg))
            if kf.root_position is not None:
                kf.root_position[0, 1] = state.height_at(seg.start, skip=together)
        else:
            kf.q[0] = q[idx]


def start_posture_from(seg: Segment, first: FloatArray, fade: bool = True) -> None:
    """A posture's keys from ``first``, the pose before it: its first key is that pose, and
    (``fade``) what the trunk has there that the keys did not see (the posture pass runs
    before the reaches: a reach to the floor leaned it 90°) is let go over the whole posture
    with a minimum-jerk share, not between the first two keys (a stand after such a reach
    brought the trunk up 60° in 0.3 s). The legs keep the posture's plan (the feet stand on
    it), the arms their own ramps (``posture.restate_stand_arms``); a posture right after a
    kneel keeps the kneel's plan, and one from a squat or a kneel is not faded (``fade``
    false: rising with a carried part, a trunk still leaned put the fingertips 91 mm under
    the floor, tests/passes/test_lift_carry_pose.py)."""
    kf = seg.keyframes
    assert kf is not None
    trunk = [k for k, name in enumerate(kf.dofs) if name in TRUNK_DOFS]
    after_kneel = (seg.result or {}).get("root") == "keyed"  # the kneel's plan paces it
    if fade and trunk and not after_kneel:
        change = first[trunk] - kf.q[0, trunk]
        share = minimum_jerk((kf.time - seg.start) / max(seg.end - seg.start, 1e-9))
        kf.q[:, trunk] += (1.0 - share)[:, None] * change[None, :]
    kf.q[0] = first


def memo(store: dict[Any, Any], key: Any, make: Callable[[], Any], limit: int) -> Any:
    """``make()`` once for an exact ``key`` in ``store``, returned as it is (not copied: for
    what callers only read); ``store`` is emptied when it holds ``limit`` entries, so a
    compile's memo stays bounded."""
    if key not in store:
        if len(store) >= limit:
            store.clear()
        store[key] = make()
    return store[key]


def cached(ctx_cache: dict[str, Any], key: Any, make: Callable[[], Any]) -> Any:
    """Memoise a solver model per compile (ChainModel setup costs more than a small solve)."""
    return memo(ctx_cache.setdefault("passes.state.models", {}), key, make, 257)


SOLVES_KEPT = 512  # solver results a compile remembers (a TO path is ~100 KB at most)


def array_key(a: Any) -> Any:
    """An exact, hashable key of an array (its type, shape and bytes): the same question asked
    again is recognised bit for bit."""
    if a is None:
        return None
    x = np.asarray(a)
    return (x.dtype.str, x.shape, x.tobytes())


def _goal_key(g: Goal) -> tuple[Any, ...]:
    return (
        g.effector, array_key(g.position), array_key(g.orientation), array_key(g.aim),
        g.orientation_weight,
    )  # fmt: skip


def solved(
    ctx_cache: dict[str, Any],
    solver: Callable[..., IKResult],
    skel: Any,
    goals: Sequence[Goal],
    q0: FloatArray,
    model: ChainModel,
    **options: Any,
) -> IKResult:
    """``solver(skel, goals, q0, model=model, **options)``, solved once per compile.

    A procedure that repeats an action (``repeat 3 { reach(...) }``, a loop over the same
    sites) asks the solvers the same question again from the same pose: the solvers are
    deterministic (a fixed seed), so the same goals, start, model and options give the same
    result, which is returned (a copy) instead of solved again. The key is exact: the goals'
    and the start's bytes, the model's identity (the entry keeps the model alive, so its id
    stays its own)."""
    key = (
        solver.__module__, solver.__name__, id(skel), tuple(_goal_key(g) for g in goals),
        array_key(q0), id(model), tuple(sorted(options.items())),
    )  # fmt: skip
    return remembered(  # type: ignore[no-any-return]
        ctx_cache, "passes.state.solves", key,
        lambda: solver(skel, goals, q0, model=model, **options), skel, model,
    )  # fmt: skip


def remembered(
    ctx_cache: dict[str, Any], store: str, key: Any, make: Callable[[], Any], *alive: Any
) -> Any:
    """``make()`` once per compile for an exact ``key`` (at most ``SOLVES_KEPT`` in ``store``),
    a deep copy each time (callers change what they get). ``alive``: the objects whose ids the
    key holds, kept alive with the entry so that no other object takes their id."""
    found: dict[Any, tuple[Any, tuple[Any, ...]]] = ctx_cache.setdefault(store, {})
    hit = found.get(key)
    if hit is None:
        if len(found) >= SOLVES_KEPT:
            found.clear()
        hit = found[key] = (make(), alive)
    return copy.deepcopy(hit[0])
