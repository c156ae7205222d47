"""A Python stand-in for Jack's ``js`` API: run a generated script and rebuild its motion.

Jack cannot run in the test suite, so this module implements exactly the documented names of
mtlc.codegen.jack_api, records what a script asks for, and reconstructs the frames the way
docs/jackscript.md says Jack plays them: every channel (the root's position and Euler angles,
each Jack joint's angles) interpolated linearly between its keys and held before the first and
after the last. ``Walk`` moves the root horizontally in a straight line from where it is at the
walk's start to the target at its end (Jack's own gait would fill the legs; the generated
scripts key the legs and refine the root themselves). ``Reach``, ``Grasp`` and ``LookAt`` are
recorded but move nothing here: Jack's IK is not available, our skeleton has no fingers, and
the scripts key the neck. A script runs with ``exec`` in a namespace whose builtins hold only
an ``__import__`` that serves the fake ``js`` module (``sys.modules`` is never touched).
This is a check of our own output, not a sandbox for hostile code.
"""

from __future__ import annotations

import ast
import types
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mtlc.body.kinematics import matrix_to_quat
from mtlc.codegen.jack_api import DOF_MAP, EFFECTORS, JACK_API, joint_dof_count
from mtlc.codegen.jackscript import jack_axes, matrix_from_euler

FloatArray = NDArray[np.float64]
HORIZONTAL = (0, 2)  # our x and z: the floor plane a walk moves in


class ReplayError(Exception):
    """A script did something the documented API does not allow."""


# -- channels: keys by time, linear in between ------------------------------------------------


@dataclass
class Channel:
    """One scalar track; a later key at the same time replaces an earlier one."""

    keys: dict[float, float] = field(default_factory=dict)

    def at(self, times: FloatArray, default: float = 0.0) -> FloatArray:
        if not self.keys:
            return np.full(len(times), default)
        t = np.array(sorted(self.keys))
        return np.interp(times, t, np.array([self.keys[k] for k in t]))


@dataclass
class Walk:
    target: FloatArray  # our axes, metres
    start: float
    duration: float


@dataclass
class Recording:
    """Everything one manikin was told, in Jack's units as the script wrote them."""

    anthropometry: dict[str, Any] = field(default_factory=dict)
    root_position: list[Channel] = field(default_factory=lambda: [Channel() for _ in range(3)])
    root_euler: list[Channel] = field(default_factory=lambda: [Channel() for _ in range(3)])
    joints: dict[str, list[Channel]] = field(default_factory=dict)
    walks: list[Walk] = field(default_factory=list)
    calls: list[tuple[str, tuple[Any, ...], dict[str, Any]]] = field(default_factory=list)


# -- the fake js module ------------------------------------------------------------------------


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ReplayError(f"{what} must be a number, not {value!r}")
    return float(value)


def _triple(value: Any, what: str) -> FloatArray:
    if not isinstance(value, tuple | list) or len(value) != 3:
        raise ReplayError(f"{what} must be three numbers, not {value!r}")
    return np.array([_number(v, what) for v in value])


def _effector(name: Any) -> str:
    if name not in EFFECTORS.values():
        raise ReplayError(f"unknown effector {name!r}")
    return str(name)


def _to_ours(position_cm: FloatArray) -> FloatArray:
    return jack_axes().T @ position_cm / JACK_API.length_per_metre


class _Human:
    """The recorder behind the object CreateHuman returns; Jack names are bound onto it."""

    def __init__(self) -> None:
        self.recording = Recording()

    def _log(self, method: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
        self.recording.calls.append((method, args, kwargs))

    def set_anthropometry(self, **values: Any) -> None:
        self._log(JACK_API.set_anthropometry, (), values)
        self.recording.anthropometry.update(values)

    def walk(self, position: Any, duration: Any = 0.0, start: Any = None) -> None:
        self._log(JACK_API.walk, (position,), {"duration": duration, "start": start})
        walks = self.recording.walks
        begin = walks[-1].start + walks[-1].duration if walks else 0.0
        if start is not None:
            begin = _number(start, "start")
        target = _to_ours(_triple(position, "a walk's target"))
        walks.append(Walk(target, begin, _number(duration, "duration")))

    def key_root(self, time: Any, position: Any, orientation: Any) -> None:
        self._log(JACK_API.key_root, (time, position, orientation), {})
        t = _number(time, "time")
        where, turn = _triple(position, "position"), _triple(orientation, "orientation")
        for channel, value in zip(self.recording.root_position, where, strict=True):
            channel.keys[t] = float(value)
        for channel, value in zip(self.recording.root_euler, turn, strict=True):
            channel.keys[t] = float(value)

    def key_joints(self, time: Any, joints: Any) -> None:
        self._log(JACK_API.key_joints, (time, joints), {})
        t = _number(time, "time")
        if not isinstance(joints, dict):
            raise ReplayError(f"joint keys must be a dict, not {joints!r}")
        for joint, values in joints.items():
            count = joint_dof_count(joint) if isinstance(joint, str) else 0
            if count == 0:
                raise ReplayError(f"unknown Jack joint {joint!r}")
            if not isinstance(values, tuple | list) or len(values) != count:
                raise ReplayError(f"joint {joint} takes {count} angles, not {values!r}")
            channels = self.recording.joints.setdefault(joint, [Channel() for _ in range(count)])
            for channel, value in zip(channels, values, strict=True):
                channel.keys[t] = _number(value, f"an angle of {joint}")

    def reach(self, effector: Any, position: Any, start: Any = 0.0, duration: Any = 0.0) -> None:
        _effector(effector)
        _triple(position, "a reach target")
        self._log(JACK_API.reach, (effector, position), {"start": start, "duration": duration})

    def grasp(self, effector: Any, state: Any, start: Any = 0.0, duration: Any = 0.0) -> None:
        _effector(effector)
        self._log(JACK_API.grasp, (effector, state), {"start": start, "duration": duration})

    def look_at(self, position: Any, start: Any = 0.0, duration: Any = 0.0) -> None:
        _triple(position, "a look-at target")
        self._log(JACK_API.look_at, (position,), {"start": start, "duration": duration})


def _human_class() -> type:
    """_Human with its methods under the names the table gives them, and no others."""
    bound: dict[str, Callable[..., None]] = {
        JACK_API.set_anthropometry: _Human.set_anthropometry,
        JACK_API.walk: _Human.walk,
        JACK_API.key_root: _Human.key_root,
        JACK_API.key_joints: _Human.key_joints,
        JACK_API.reach: _Human.reach,
        JACK_API.grasp: _Human.grasp,
        JACK_API.look_at: _Human.look_at,
    }
    return type("Human", (_Human,), bound)


def fake_js_module(humans: list[_Human]) -> types.ModuleType:
    """A module object named like Jack's; each CreateHuman() call appends to ``humans``."""
    human_class = _human_class()

    def create_human(*args: Any, **kwargs: Any) -> _Human:
        human = human_class()
        humans.append(human)
        return human

    def load_model(*args: Any, **kwargs: Any) -> None:
        """Scene geometry: the replay rebuilds the manikin's motion only."""

    module = types.ModuleType(JACK_API.module)
    setattr(module, JACK_API.create_human, create_human)
    setattr(module, JACK_API.load_model, load_model)
    module.__all__ = list(JACK_API.functions)  # type: ignore[attr-defined]
    return module


# -- the reconstructed motion ------------------------------------------------------------------


@dataclass
class ReplayedMotion:
    """Frames rebuilt from a script: SI units, our axes, the skeleton's dof order."""

    time: FloatArray  # (N,)
    root_position: FloatArray  # (N, 3) m
    root_rotation: FloatArray  # (N, 4) w first
    q: FloatArray  # (N, n_dofs) rad
    dof_names: tuple[str, ...]
    recording: Recording

    def sample(self, times: ArrayLike) -> ReplayedMotion:
        """The motion at other times, interpolated as Jack is documented to interpolate."""
        return reconstruct(self.recording, np.asarray(times, dtype=float))

    @property
    def calls(self) -> list[tuple[str, tuple[Any, ...], dict[str, Any]]]:
        return self.recording.calls


def key_times(recording: Recording) -> FloatArray:
    """Every time at which some channel has a key or a walk starts or ends."""
    times: set[float] = set()
    for channel in [*recording.root_position, *recording.root_euler]:
        times.update(channel.keys)
    for channels in recording.joints.values():
        for channel in channels:
            times.update(channel.keys)
    for walk in recording.walks:
        times.update((walk.start, walk.start + walk.duration))
    return np.array(sorted(times), dtype=float)


def _root_positions(recording: Recording, times: FloatArray) -> FloatArray:
    """Root keys (cm, Jack axes) to metres in ours, with each walk's straight line added in."""
    axes = jack_axes()
    key_t = sorted(set().union(*(c.keys for c in recording.root_position)))
    jack_cm = np.stack([c.at(np.array(key_t)) for c in recording.root_position], axis=-1)
    ours = [Channel() for _ in range(3)]
    for t, p in zip(key_t, jack_cm @ axes / JACK_API.length_per_metre, strict=True):
        for axis in range(3):
            ours[axis].keys[t] = float(p[axis])
    for walk in sorted(recording.walks, key=lambda w: w.start):
        for axis in HORIZONTAL:
            here = float(ours[axis].at(np.array([walk.start]))[0])
            ours[axis].keys.setdefault(walk.start, here)
            ours[axis].keys[walk.start + walk.duration] = float(walk.target[axis])
    return np.stack([c.at(times) for c in ours], axis=-1)


def _root_rotations(recording: Recording, times: FloatArray) -> FloatArray:
    axes = jack_axes()
    euler = np.radians(np.stack([c.at(times) for c in recording.root_euler], axis=-1))
    jack_rotation = matrix_from_euler(euler, JACK_API.root_euler_order)
    return matrix_to_quat(axes.T @ jack_rotation @ axes)


def _joint_angles(recording: Recording, times: FloatArray) -> FloatArray:
    q = np.zeros((len(times), len(DOF_MAP)))
    for column, (_, joint, index, sign) in enumerate(DOF_MAP):
        channels = recording.joints.get(joint)
        if channels is not None:
            q[:, column] = sign * np.radians(channels[index].at(times))
    return q


def reconstruct(recording: Recording, times: FloatArray) -> ReplayedMotion:
    return ReplayedMotion(
        time=times,
        root_position=_root_positions(recording, times),
        root_rotation=_root_rotations(recording, times),
        q=_joint_angles(recording, times),
        dof_names=tuple(row[0] for row in DOF_MAP),
        recording=recording,
    )


# -- running a script --------------------------------------------------------------------------


def check_names(tree: ast.AST) -> None:
    """Refuse dunder and private names: the scripts we emit never need them."""
    for node in ast.walk(tree):
        name = node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")
        if isinstance(name, str) and name.startswith("_"):
            raise ReplayError(f"line {getattr(node, 'lineno', '?')}: name {name!r} not allowed")


def replay(script_text: str, function: str) -> ReplayedMotion:
    """Run ``function()`` of a generated script against the fake API; frames at its key times."""
    tree = ast.parse(script_text)
    check_names(tree)
    humans: list[_Human] = []
    module = fake_js_module(humans)

    def import_js(name: str, *args: Any, **kwargs: Any) -> types.ModuleType:
        if name != JACK_API.module:
            raise ReplayError(f"a JackScript may import only {JACK_API.module!r}, not {name!r}")
        return module

    namespace: dict[str, Any] = {"__builtins__": {"__import__": import_js}, "__name__": "t"}
    exec(compile(tree, "<jackscript>", "exec"), namespace)
    entry = namespace.get(function)
    if not callable(entry):
        raise ReplayError(f"the script defines no function {function!r}")
    entry()
    if len(humans) != 1:
        raise ReplayError(f"{function}() created {len(humans)} humans; expected one")
    recording = humans[0].recording
    return reconstruct(recording, key_times(recording))


__all__ = ["ReplayError", "ReplayedMotion", "fake_js_module", "replay"]
