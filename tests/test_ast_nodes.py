"""The AST's node classes are the classes ``@dataclass(frozen=True, slots=True, kw_only=True)``
makes (issue 21: ``ast._node`` makes them with one ``exec`` each, for start-up): the module is
run again with the dataclass decorator, and every class compared with its twin."""

from __future__ import annotations

import copy
import dataclasses
import inspect
import pickle
import sys
import types
from pathlib import Path
from typing import Any

import pytest

from mtlc.diagnostics import Span
from mtlc.syntax import ast

_REFERENCE = "mtlc_ast_reference"  # the module run again, its nodes made by dataclasses


def _reference() -> types.ModuleType:
    if _REFERENCE in sys.modules:
        return sys.modules[_REFERENCE]
    source = Path(ast.__file__).read_text(encoding="utf-8")
    assert source.count("\n@_node\n") >= 40
    module = types.ModuleType(_REFERENCE)
    module.__file__ = ast.__file__
    sys.modules[_REFERENCE] = module  # dataclasses and pickle look classes up by module
    exec(compile(source.replace("\n@_node\n", "\n@_dataclass_node\n"), ast.__file__, "exec"),
         module.__dict__)  # fmt: skip
    return module


def _node_classes(module: Any) -> dict[str, type]:
    return {
        name: value
        for name, value in vars(module).items()
        if isinstance(value, type) and dataclasses.is_dataclass(value)
    }


CLASSES = sorted(_node_classes(ast))


def _field_facts(cls: type) -> list[tuple[Any, ...]]:
    return [
        (f.name, f.type, f.default, f.default_factory, f.init, f.repr, f.hash, f.compare,
         dict(f.metadata), f.kw_only, f._field_type)  # type: ignore[attr-defined]
        for f in dataclasses.fields(cls)
    ]  # fmt: skip


def _sample(cls: type, seed: int) -> Any:
    """An instance with a distinct value in every field (nodes need not be well-formed)."""
    values = {}
    for i, f in enumerate(dataclasses.fields(cls)):
        if f.name == "span":
            values[f.name] = Span("f.mtask", seed, i, seed, i + 1, seed, seed + 1)
        elif f.name == "depth":
            values[f.name] = seed + 2
        else:
            values[f.name] = (f"{f.name}-{seed}", i, (seed,))
    return cls(**values)


def test_the_reference_is_made_by_dataclasses() -> None:
    assert sorted(_node_classes(_reference())) == CLASSES
    assert len(CLASSES) >= 40


@pytest.mark.parametrize("name", CLASSES)
def test_node_class_is_what_dataclass_makes(name: str) -> None:
    ours, theirs = getattr(ast, name), getattr(_reference(), name)
    assert _field_facts(ours) == _field_facts(theirs)
    for attr in ("__slots__", "__match_args__", "__doc__", "__qualname__", "__name__"):
        assert getattr(ours, attr) == getattr(theirs, attr), attr
    assert repr(ours.__dataclass_params__) == repr(theirs.__dataclass_params__)
    assert [c.__name__ for c in ours.__mro__] == [c.__name__ for c in theirs.__mro__]
    assert sorted(vars(ours)) == sorted(vars(theirs))
    assert str(inspect.signature(ours)) == str(inspect.signature(theirs))
    assert ours.__init__.__annotations__ == theirs.__init__.__annotations__
    for method in ("__init__", "__repr__", "__eq__", "__hash__", "__setattr__", "__delattr__"):
        assert getattr(ours, method).__qualname__ == getattr(theirs, method).__qualname__
    assert not hasattr(_sample(ours, 1), "__dict__")


@pytest.mark.parametrize("name", CLASSES)
def test_node_instances_behave_as_dataclass_ones(name: str) -> None:
    ours, theirs = getattr(ast, name), getattr(_reference(), name)
    a, b, a_again = _sample(ours, 1), _sample(ours, 2), _sample(ours, 1)
    ref_a, ref_b = _sample(theirs, 1), _sample(theirs, 2)
    assert repr(a) == repr(ref_a) and repr(b) == repr(ref_b)
    assert hash(a) == hash(ref_a) and hash(b) == hash(ref_b)
    assert (a == a_again, a == b, a != b) == (ref_a == _sample(theirs, 1), ref_a == ref_b, True)
    assert a.__eq__(ref_a) is NotImplemented  # another class
    if "depth" in ours.__dataclass_fields__:
        deeper = dataclasses.replace(a, depth=99)
        assert deeper == a and hash(deeper) == hash(a)  # depth is not compared
    outcomes = []  # assigning to and deleting a field, or a name that is none
    for target in (a, ref_a):
        for field_name in ("span", "nonexistent"):
            for change, args in (
                (setattr, (target, field_name, 0)),
                (delattr, (target, field_name)),
            ):
                try:
                    change(*args)
                    outcomes.append(None)
                except Exception as exc:
                    outcomes.append((type(exc), str(exc).replace(_REFERENCE, ast.__name__)))
    assert outcomes[:4] == outcomes[4:], outcomes
    assert pickle.loads(pickle.dumps(a)) == a
    assert copy.deepcopy(a) == a and copy.copy(a) == a
    assert a.__getstate__() == ref_a.__getstate__()
