"""JackScript generator: one importable Python module per `.mtask` file, one function per task.

Seed 000's host program runs ``import t`` then ``t.t()``, so every task becomes a function that
takes no arguments and drives one manikin through the documented ``js`` API (every Jack-side
name comes from mtlc.codegen.jack_api). The motion is written as timed keys that reproduce the
IR's *corrected* frames: the sampled frames are decimated (greedily, over the root and every
joint at once) to the fewest keys between which linear interpolation, which we assume Jack does,
stays within ANGLE_TOLERANCE_DEG and POSITION_TOLERANCE_CM of every frame. Walks are also
written as ``Walk`` calls and TA segments, with ``ta="jack"``, as ``Reach`` calls whose joints
are left to Jack's IK. Text from the task file reaches the script only as ``ascii()`` string
literals or as comments with every non-printable and non-ASCII character escaped, so the whole
script is printable ASCII and no title can break out into code. See docs/jackscript.md.
"""

from __future__ import annotations

import bisect
import itertools
import keyword
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mtlc.body.kinematics import axis_angle, quat_to_matrix
from mtlc.codegen.jack_api import DOF_MAP, EFFECTORS, GRASP_STATES, JACK_API, jack_joints
from mtlc.ir.model import MotionIR, Segment, SourceRef

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

TA_MODES = ("keyframes", "jack")
SOURCE_MAP_VERSION = 1
TIME_DECIMALS = 6  # 1 µs: frame times stay on their frames
LENGTH_DECIMALS = 3  # centimetres to 0.01 mm
ANGLE_DECIMALS = (
    3  # degrees to 0.001: coarser than BLAS noise (~1e-6°), finer than the replay's 1e-3° check
)
ANGLE_TOLERANCE_DEG = 0.05  # linear interpolation between keys stays this close to every frame
POSITION_TOLERANCE_CM = 0.03  # ... and each root coordinate this close (0.3 mm)
LINE_LENGTH = 100
INDENT = "    "
TIME_EPSILON = 1e-9
# Names a task's function must not take: Python 2 and 3 keywords and the API's own names.
RESERVED_NAMES = frozenset(
    {*keyword.kwlist, *keyword.softkwlist, "print", "exec", "nonlocal", "async", "await"}
    | {JACK_API.module, JACK_API.human_variable, *JACK_API.functions}
)


@dataclass
class JackScript:
    """A generated module: its text and a JSON-able map from script lines to source spans."""

    text: str
    source_map: dict[str, Any]


# -- text that comes from the task file ------------------------------------------------------


def comment_text(text: str) -> str:
    """``text`` as printable ASCII: no character in it can end a comment line.

    Python's tokenizer breaks lines on \\n, \\r and \\f-like characters, and str.splitlines on
    \\x0b, \\x1c-\\x1e, \\x85, \\u2028 and \\u2029 too; escaping everything outside 0x20-0x7e
    covers all of them at once.
    """
    return "".join(ch if " " <= ch <= "~" else _escape(ch) for ch in text)


def _escape(ch: str) -> str:
    code = ord(ch)
    if code < 0x100:
        return f"\\x{code:02x}"
    if code < 0x10000:
        return f"\\u{code:04x}"
    return f"\\U{code:08x}"


def string_literal(text: str) -> str:
    """A Python string literal (printable ASCII, every other character escaped) for ``text``."""
    return ascii(str(text))


def function_name(task: str, taken: set[str]) -> str:
    """An ASCII identifier for a task's function, unique in its module; records it in ``taken``.

    ASCII because Jack embeds an older Python and because Python NFKC-normalises non-ASCII
    identifiers, which could merge two task names.
    """
    name = "".join(ch if ch.isascii() and (ch.isalnum() or ch == "_") else _hex(ch) for ch in task)
    if not name or name[0].isdigit():
        name = f"task_{name}"
    if name in RESERVED_NAMES or name.startswith("__"):
        name = f"{name}_"
    unique, n = name, 2
    while unique in taken:
        unique, n = f"{name}_{n}", n + 1
    taken.add(unique)
    return unique


def _hex(ch: str) -> str:
    """`_u` and 4 hex digits, or `_U` and 8 beyond the BMP, so that no escape is a prefix of
    another (U+1000 then `0` is `_u10000`, U+10000 is `_U00010000`)."""
    code = ord(ch)
    return f"_u{code:04x}" if code <= 0xFFFF else f"_U{code:08x}"


def number(value: float, decimals: int) -> str:
    """Fixed decimals, trailing zeros dropped, never ``-0.0``: the same value, the same bytes."""
    if not math.isfinite(value):
        raise ValueError(f"cannot write a non-finite number ({value}) into a script")
    text = f"{value:.{decimals}f}"
    if not text.strip("-0."):  # every digit a zero: 0.0, whatever the sign and the decimals
        return "0.0"
    if decimals <= 0:
        return f"{text}.0"
    text = text.rstrip("0")
    return f"{text}0" if text[-1] == "." else text


def vector(values: Sequence[float] | FloatArray, decimals: int) -> str:
    """A tuple literal; a one-element tuple keeps its comma (``(4.5,)``)."""
    if isinstance(values, np.ndarray):
        values = values.tolist()  # Python floats at once, not one conversion per element
    items = []
    for value in values:  # number(), inline: a script has a hundred thousand of them
        value = float(value)
        text = f"{value:.{decimals}f}"
        if not math.isfinite(value) or decimals <= 0 or not text.strip("-0."):
            text = number(value, decimals)
        else:
            text = text.rstrip("0")
            if text[-1] == ".":
                text += "0"
        items.append(text)
    return "(" + ", ".join(items) + ("," if len(items) == 1 else "") + ")"


# -- units, axes and the root's orientation ---------------------------------------------------


def jack_axes() -> FloatArray:
    """Rows: Jack's world axes written in ours; p_jack = A @ p, R_jack = A R Aᵀ."""
    return np.asarray(JACK_API.world_axes, dtype=float)


def _euler_axes(order: str) -> tuple[int, int, int]:
    i, j, k = ("XYZ".index(letter) for letter in order)
    return i, j, k


def euler_from_matrix(rotation: FloatArray, order: str) -> FloatArray:
    """Intrinsic Tait–Bryan angles (..., 3) in radians with R = R_i(a) · R_j(b) · R_k(c)."""
    i, j, k = _euler_axes(order)
    parity = 1.0 if (j - i) % 3 == 1 else -1.0
    b = np.arcsin(np.clip(parity * rotation[..., i, k], -1.0, 1.0))
    a = np.arctan2(-parity * rotation[..., j, k], rotation[..., k, k])
    c = np.arctan2(-parity * rotation[..., i, j], rotation[..., i, i])
    return np.stack([a, b, c], axis=-1)


def matrix_from_euler(angles: FloatArray, order: str) -> FloatArray:
    """The inverse of euler_from_matrix: rotation matrices (..., 3, 3) from angles (..., 3)."""
    basis = np.eye(3)
    a = np.asarray(angles, dtype=float)
    result = np.broadcast_to(np.eye(3), (*a.shape[:-1], 3, 3)).copy()
    for column, axis in enumerate(_euler_axes(order)):
        result = result @ axis_angle(basis[axis], a[..., column])
    return result


@dataclass
class JackFrames:
    """The IR's frames in Jack's units and axes: what the keys are cut from."""

    time: FloatArray  # (N,) s
    root_position: FloatArray  # (N, 3) cm, Jack axes
    root_euler: FloatArray  # (N, 3) deg, unwrapped so that keys interpolate the short way
    joints: FloatArray  # (N, len(DOF_MAP)) deg, Jack's sign, DOF_MAP order


def jack_frames(ir: MotionIR) -> JackFrames:
    """Convert the sampled frames once, at the edge: SI and our axes to Jack's."""
    assert ir.frames is not None
    frames = ir.frames
    axes = jack_axes()
    rotation = axes @ quat_to_matrix(frames.root_rotation) @ axes.T
    euler = np.unwrap(euler_from_matrix(rotation, JACK_API.root_euler_order), axis=0)
    columns = [ir.skeleton.dof_index(dof) for dof, *_ in DOF_MAP]
    signs = np.array([sign for *_, sign in DOF_MAP], dtype=float)
    return JackFrames(
        time=np.asarray(frames.time, dtype=float),
        root_position=frames.root_position @ axes.T * JACK_API.length_per_metre,
        root_euler=np.degrees(euler),
        joints=np.degrees(frames.q[:, columns]) * signs,
    )


def to_jack_position(position: Sequence[float]) -> FloatArray:
    return jack_axes() @ np.asarray(position, dtype=float) * JACK_API.length_per_metre


# -- which frames become keys -----------------------------------------------------------------


def key_indices(time: FloatArray, values: FloatArray, breakpoints: Sequence[int]) -> IntArray:
    """Frame indices to key so that linear interpolation stays within 1 of ``values``.

    ``values`` (N, M) are pre-scaled by their tolerances. Between consecutive breakpoints (the
    first and last frame always are) a greedy pass takes the furthest frame whose straight line
    from the previous key fits every frame in between, for all M channels at once.
    """
    n = len(time)
    marks = sorted({0, n - 1, *(int(b) for b in breakpoints if 0 <= b < n)})
    fit = _LineFit(time, values)
    keys = [0]
    for a, b in itertools.pairwise(marks):
        i = a
        while i < b:
            i = _furthest_fit(fit, i, b)
            keys.append(i)
    return np.asarray(keys, dtype=np.intp)


class _LineFit:
    """Whether the straight line from frame i to frame j stays within 1 of every frame between.

    The search asks first about j = i + 2, then i + 4, i + 8 or i + 3 (most keys are a few
    frames apart, so most questions are these): those answers are computed for every i at
    once, the others one by one, all with the same arithmetic (the same operations on the same
    numbers, element by element), so the answers and the keys are those of one by one.
    """

    PRECOMPUTED = (2, 3, 4, 6, 8)

    def __init__(self, time: FloatArray, values: FloatArray) -> None:
        self.time = time
        self.values = values
        self.short = {span: self._every_start(span) for span in self.PRECOMPUTED}

    def _every_start(self, span: int) -> NDArray[np.bool_]:
        """fits(i, i + span) for every i < N - span."""
        time, values = self.time, self.values
        starts = len(time) - span
        if starts <= 0:
            return np.zeros(0, dtype=bool)
        t0, v0 = time[:starts], values[:starts]
        dt = time[span:] - t0
        dv = values[span:] - v0
        ok = np.ones(starts, dtype=bool)
        for offset in range(1, span):
            weight = (time[offset : starts + offset] - t0) / dt
            line = v0 + weight[:, None] * dv
            ok &= np.abs(values[offset : starts + offset] - line).max(axis=1) <= 1.0
        return ok

    def fits(self, i: int, j: int) -> bool:
        span = j - i
        if span < 2:
            return True
        short = self.short.get(span)
        if short is not None:
            return bool(short[i])
        time, values = self.time, self.values
        t0 = time[i]
        weight = (time[i + 1 : j] - t0) / (time[j] - t0)
        v0 = values[i]
        line = v0 + weight[:, None] * (values[j] - v0)
        return bool(np.abs(values[i + 1 : j] - line).max() <= 1.0)


def _furthest_fit(fit: _LineFit, i: int, stop: int) -> int:
    """The furthest j ≤ stop that fits from i (galloping, then bisection)."""
    good, step = i + 1, 1
    bad = stop + 1
    while good < stop:
        candidate = min(good + step, stop)
        if not fit.fits(i, candidate):
            bad = candidate
            break
        good, step = candidate, step * 2
    while bad - good > 1:
        middle = (good + bad) // 2
        if fit.fits(i, middle):
            good = middle
        else:
            bad = middle
    return good


def frame_before(time: FloatArray, t: float) -> int:
    """The last frame at or before ``t`` (0 if none)."""
    return max(int(np.searchsorted(time, t + TIME_EPSILON, side="right")) - 1, 0)


def frame_after(time: FloatArray, t: float) -> int:
    """The first frame at or after ``t`` (the last frame if none)."""
    return min(int(np.searchsorted(time, t - TIME_EPSILON, side="left")), len(time) - 1)


# -- blocks: one per segment, in start order ---------------------------------------------------


@dataclass
class Block:
    """Script lines that came from one place in the task file (a comment heads them)."""

    start: float
    header: str
    source: dict[str, Any]
    lines: list[str] = field(default_factory=list)


def _span(ref: SourceRef, path: str, kind: str) -> dict[str, Any]:
    return {
        "file": ref.file,
        "line": ref.line,
        "column": ref.column,
        "end_line": ref.end_line,
        "end_column": ref.end_column,
        "path": path,
        "kind": kind,
    }


def _header(ref: SourceRef, path: str, what: str) -> str:
    return "# " + comment_text(f"{ref.file}:{ref.line}:{ref.column} {path}: {what}")


def _segment_block(
    segment: Segment, ta: str, time: FloatArray, jack: JackFrames, ground: float
) -> Block:
    path = " > ".join(segment.provenance.path)
    site = f" at {segment.goal.site}" if segment.goal.site else ""
    what = f"{segment.kind} on {segment.track}{site}"
    block = Block(
        segment.start,
        _header(segment.provenance.origin, path, what),
        _span(segment.provenance.origin, path, segment.kind),
    )
    call = _segment_call(segment, ta, time, jack, ground)
    if call:
        block.lines.append(call)
    return block


def _timing(segment: Segment) -> str:
    start = number(segment.start, TIME_DECIMALS)
    duration = number(segment.end - segment.start, TIME_DECIMALS)
    return f"{JACK_API.start_keyword}={start}, {JACK_API.duration_keyword}={duration}"


def _method(name: str, *args: str) -> str:
    return f"{INDENT}{JACK_API.human_variable}.{name}({', '.join(args)})"


def _segment_call(
    segment: Segment, ta: str, time: FloatArray, jack: JackFrames, ground: float
) -> str | None:
    """The API call a segment makes besides its keys, if any (Walk, Reach, Grasp, LookAt)."""
    goal = segment.goal
    effector = EFFECTORS.get(goal.effector)
    if segment.kind == "locomotion":
        end = np.array([np.interp(segment.end, time, jack.root_position[:, i]) for i in range(3)])
        floor = _floor_point(end, ground)
        return _method(JACK_API.walk, vector(floor, LENGTH_DECIMALS), _timing(segment))
    if segment.kind == "TA" and ta == "jack" and effector is not None:
        target = segment.result.get("approach_point", goal.position)
        if target is None:
            return None
        where = vector(to_jack_position(target), LENGTH_DECIMALS)
        return _method(JACK_API.reach, string_literal(effector), where, _timing(segment))
    if segment.kind == "grip" and effector is not None:
        state = str(goal.params.get("state", ""))
        jack_state = string_literal(GRASP_STATES.get(state, state))
        return _method(JACK_API.grasp, string_literal(effector), jack_state, _timing(segment))
    if segment.kind == "gaze" and goal.position is not None:
        where = vector(to_jack_position(goal.position), LENGTH_DECIMALS)
        return _method(JACK_API.look_at, where, _timing(segment))
    return None


def _floor_point(root_cm: FloatArray, ground: float) -> FloatArray:
    """Where the walk ends, on the floor under the root (the seed's Walk takes y = 0)."""
    axes = jack_axes()
    ours = axes.T @ root_cm
    ours[1] = ground * JACK_API.length_per_metre
    return axes @ ours


# -- keys --------------------------------------------------------------------------------------


@dataclass
class Keys:
    """The chosen key frames and, per channel, the text each key writes (None: not written)."""

    frames: IntArray
    root: list[str | None]
    joints: dict[str, list[str | None]]


def choose_keys(ir: MotionIR, jack: JackFrames, ta: str) -> Keys:
    """Key frames chosen per channel group (the root, each Jack joint), then merged by time.

    Each group is decimated on its own, so a joint that twists back and forth does not force
    keys on every other joint. The frames on both sides of a walk's start and end are root keys,
    so that the walk's own waypoints fall on straight lines the keys already draw; with
    ``ta="jack"`` a TA window's bounding frames are keys and the joints its Reach leaves to
    Jack's IK have none inside it.
    """
    time = jack.time
    walk_marks = [
        index
        for segment in ir.segments
        if segment.kind == "locomotion"
        for t in (segment.start, segment.end)
        for index in (frame_before(time, t), frame_after(time, t))
    ]
    root_values = np.hstack(
        [jack.root_position / POSITION_TOLERANCE_CM, jack.root_euler / ANGLE_TOLERANCE_DEG]
    )
    root_frames = key_indices(time, root_values, walk_marks)
    windows = _ta_windows(ir, time) if ta == "jack" else []
    joint_frames = {
        joint: _joint_key_frames(time, jack.joints[:, _joint_columns(joint)], joint, windows)
        for joint in jack_joints()
    }
    frames = np.unique(np.concatenate([root_frames, *joint_frames.values()]))
    # each channel's rows gathered once and made Python floats at once, then written
    root_text = {
        k: f"{vector(position, LENGTH_DECIMALS)}, {vector(euler, ANGLE_DECIMALS)}"
        for k, position, euler in zip(
            root_frames.tolist(),
            jack.root_position[root_frames].tolist(),
            jack.root_euler[root_frames].tolist(),
            strict=True,
        )
    }
    every = frames.tolist()
    joints = {}
    for joint, kept in joint_frames.items():
        rows = jack.joints[np.ix_(kept, _joint_columns(joint))].tolist()
        texts = {k: vector(row, ANGLE_DECIMALS) for k, row in zip(kept.tolist(), rows, strict=True)}
        joints[joint] = _drop_constant_runs([texts.get(k) for k in every])
    return Keys(frames, _drop_constant_runs([root_text.get(k) for k in every]), joints)


def _joint_columns(joint: str) -> list[int]:
    """Columns of DOF_MAP that feed a Jack joint, in Jack's dof order."""
    columns = [c for c, row in enumerate(DOF_MAP) if row[1] == joint]
    return sorted(columns, key=lambda c: DOF_MAP[c][2])


def _joint_key_frames(
    time: FloatArray, degrees: FloatArray, joint: str, windows: list[tuple[int, int, set[str]]]
) -> IntArray:
    own = [(first, last) for first, last, omitted in windows if joint in omitted]
    marks = [index for window in own for index in window]
    kept = key_indices(time, degrees / ANGLE_TOLERANCE_DEG, marks)
    inside = np.zeros(len(kept), dtype=bool)
    for first, last in own:
        inside |= (kept > first) & (kept < last)
    return kept[~inside]


def _ta_windows(ir: MotionIR, time: FloatArray) -> list[tuple[int, int, set[str]]]:
    """Frames bounding each TA segment and the Jack joints its Reach leaves to Jack's IK."""
    joint_of = {dof: joint for dof, joint, *_ in DOF_MAP}
    windows = []
    for segment in ir.segments:
        if segment.kind != "TA" or segment.goal.effector not in EFFECTORS:
            continue
        dofs = segment.keyframes.dofs if segment.keyframes is not None else ()
        omitted = {joint_of[d] for d in dofs if d in joint_of}
        first, last = frame_before(time, segment.start), frame_after(time, segment.end)
        windows.append((first, last, omitted))
    return windows


def _drop_constant_runs(texts: list[str | None]) -> list[str | None]:
    """Drop a key equal to the written keys on both sides of it: interpolation gives it back."""
    present = [n for n, t in enumerate(texts) if t is not None]
    out = list(texts)
    for before, here, after in zip(present, present[1:], present[2:], strict=False):
        if texts[before] == texts[here] == texts[after]:
            out[here] = None
    return out


def _key_lines(keys: Keys, n: int, t: float) -> list[str]:
    when = number(t, TIME_DECIMALS)
    lines = []
    if keys.root[n] is not None:
        lines.append(_method(JACK_API.key_root, when, keys.root[n]))
    items = [f"{string_literal(j)}: {texts[n]}" for j, texts in keys.joints.items() if texts[n]]
    if items:
        lines.extend(_wrapped_call(JACK_API.key_joints, when, items))
    return lines


def _wrapped_call(method: str, when: str, items: list[str]) -> list[str]:
    """``human.KeyJoints(t, {...})`` on one line if it fits, else one wrapped dict."""
    one_line = _method(method, when, "{" + ", ".join(items) + "}")
    if len(one_line) <= LINE_LENGTH:
        return [one_line]
    lines = [f"{INDENT}{JACK_API.human_variable}.{method}({when}, {{"]
    current = INDENT * 2
    for item in items:
        piece = f"{item},"
        if current.strip() and len(current) + 1 + len(piece) > LINE_LENGTH:
            lines.append(current)
            current = INDENT * 2
        current = f"{current} {piece}" if current.strip() else f"{current}{piece}"
    lines.append(current)
    lines.append(f"{INDENT}}})")
    return lines


# -- one task ----------------------------------------------------------------------------------


def _prelude(ir: MotionIR, name: str) -> Block:
    """def, docstring, CreateHuman and the anthropometry, mapped to the task's first line."""
    origins = [s.provenance.origin for s in ir.segments if s.provenance.origin.file == ir.file]
    first = min(origins, key=lambda r: (r.line, r.column), default=SourceRef(ir.file, 1, 1, 1, 1))
    block = Block(-np.inf, "", _span(first, ir.task, "task"))
    block.lines = [
        f"def {name}():",
        f"{INDENT}{string_literal(ir.title if ir.title is not None else ir.task)}",
        f"{INDENT}# " + comment_text(f"task {ir.task} from {ir.file}"),
        *_model_lines(ir),
        f"{INDENT}{JACK_API.human_variable} = {JACK_API.create_human}()",
        _method(JACK_API.set_anthropometry, *_anthropometry(ir)),
    ]
    return block


def _model_lines(ir: MotionIR) -> list[str]:
    """One LoadModel call per model file (its path a string literal: text of the task file,
    never code); a solid, which Jack's documented API cannot build, as a comment."""
    axes = jack_axes()
    lines = []
    for m in ir.models:
        matrix = np.asarray(m["transform"], dtype=float)
        jack = np.eye(4)
        jack[:3, :3] = axes @ matrix[:3, :3] * JACK_API.length_per_metre
        jack[:3, 3] = to_jack_position(matrix[:3, 3])
        rows = "(" + ", ".join(vector(row, 6) for row in jack) + ")"
        if m["kind"] == "model":
            lines.append(
                f"{INDENT}{JACK_API.load_model}({string_literal(m['path'])}, "
                f"name={string_literal(m['name'])}, transform={rows})"
            )
        else:
            lines.append(
                f"{INDENT}# " + comment_text(f"{m['kind']} {m['name']} (not loaded): {rows}")
            )
    return lines


def _anthropometry(ir: MotionIR) -> list[str]:
    args = [f"{key}={string_literal(str(ir.manikin[key]))}" for key in ("population", "sex")]
    args.append(f"percentile={int(ir.manikin['percentile'])}")
    dims = getattr(ir.skeleton, "dims", None)
    if dims is not None:
        args.append(f"stature={number(dims.stature * JACK_API.length_per_metre, LENGTH_DECIMALS)}")
        args.append(f"mass={number(dims.mass, 3)}")
    return args


def task_blocks(ir: MotionIR, name: str, ta: str) -> list[Block]:
    """The prelude, then one block per segment in start order, each followed by its keys."""
    prelude = _prelude(ir, name)
    if ir.frames is None or not len(ir.frames.time):
        return [prelude]
    jack = jack_frames(ir)
    order = sorted(range(len(ir.segments)), key=lambda i: (ir.segments[i].start, i))
    blocks = [prelude] + [
        _segment_block(ir.segments[i], ta, jack.time, jack, ir.ground) for i in order
    ]
    starts = [b.start for b in blocks]
    keys = choose_keys(ir, jack, ta)
    for n, k in enumerate(keys.frames):
        t = float(jack.time[k])
        owner = blocks[max(bisect.bisect_right(starts, t + TIME_EPSILON) - 1, 0)]
        owner.lines.extend(_key_lines(keys, n, t))
    return blocks


# -- the module --------------------------------------------------------------------------------


def emit_jackscript(irs: Sequence[MotionIR], *, ta: str = "keyframes") -> JackScript:
    """The JackScript module for the tasks of one `.mtask` file (IRs with their frames set)."""
    if ta not in TA_MODES:
        raise ValueError(f"ta must be one of {TA_MODES}, not {ta!r}")
    files = list(dict.fromkeys(ir.file for ir in irs))
    lines = [
        # Lines 1 and 2 may declare the source's encoding (PEP 263): they hold fixed text only,
        # so a file name such as `coding=utf-7 .mtask` cannot re-decode the script.
        "# -*- coding: ascii -*-",
        "# JackScript generated by mtlc. One function per task, callable with no arguments.",
        "# From " + comment_text(", ".join(files)) + ". Units: cm, deg, s; Y up.",
        f"# Jack-side names: mtlc.codegen.jack_api (docs/jackscript.md). TA as {ta}.",
        f"from {JACK_API.module} import *",
    ]
    entries: list[dict[str, Any]] = []
    functions: dict[str, str] = {}
    taken: set[str] = set()
    for ir in irs:
        name = function_name(ir.task, taken)
        functions[name] = ir.task
        lines += ["", ""]
        for block in task_blocks(ir, name, ta):
            first = len(lines) + 1
            if block.header:
                lines.append(INDENT + block.header)
            lines.extend(block.lines)
            if len(lines) >= first:
                entries.append({"script_start": first, "script_end": len(lines), **block.source})
                entries[-1]["function"] = name
    text = "\n".join(lines) + "\n"
    source_map = {
        "version": SOURCE_MAP_VERSION,
        "sources": files,
        "ta": ta,
        "functions": functions,
        "lines": entries,
    }
    return JackScript(text=text, source_map=source_map)


__all__ = [
    "ANGLE_TOLERANCE_DEG",
    "POSITION_TOLERANCE_CM",
    "TA_MODES",
    "JackScript",
    "comment_text",
    "emit_jackscript",
    "euler_from_matrix",
    "function_name",
    "matrix_from_euler",
    "string_literal",
]
