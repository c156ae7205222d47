"""The JackScript generator: valid, API-only, injection-proof, deterministic, source-mapped.

Every example's script (both TA modes) must parse, be printable ASCII, and contain nothing but
``from js import *`` and argument-less functions whose calls are all names of the mapping
table. Nasty text (quotes, backslashes, line breaks Python or str.splitlines honours, triple
quotes, non-ASCII) is pushed through every place task-file text reaches the script: the title,
the file name, and task and site names that clash with Python and the API.
"""

from __future__ import annotations

import ast
import io
import json
import tokenize
from pathlib import Path

import numpy as np
import pytest
from conftest import compiled_example
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mtlc.body import build_manikin
from mtlc.codegen.jack_api import (
    DOF_MAP,
    EFFECTORS,
    GRASP_STATES,
    JACK_API,
    jack_joints,
    markdown_tables,
)
from mtlc.codegen.jackscript import (
    TA_MODES,
    comment_text,
    emit_jackscript,
    euler_from_matrix,
    function_name,
    matrix_from_euler,
    number,
)
from mtlc.frontend import run_frontend
from mtlc.ir.model import MotionIR
from mtlc.passes import run_motion

# not imported from conftest: another tests/ folder has a conftest module of its own
ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))

# Characters that end a line for Python's tokenizer or for str.splitlines, and other troubles.
NASTY = "'\"\\\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029#{}\x00\t'''\"\"\"é名😀"


def compile_file(path: Path) -> list[MotionIR]:
    program = run_frontend([path])
    assert not program.sink.has_errors, [d.message for d in program.diagnostics]
    return [run_motion(t, program.sink) for t in program.timelines]


@pytest.fixture(scope="module")
def example_irs() -> dict[str, list[MotionIR]]:
    return {p.stem: compiled_example(p).motions for p in EXAMPLES}


def api_call_names() -> set[str]:
    return set(JACK_API.functions) | {f"{JACK_API.human_variable}.{m}" for m in JACK_API.methods}


def call_name(call: ast.Call) -> str:
    func = call.func
    if isinstance(func, ast.Name):
        return func.id
    if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
        return f"{func.value.id}.{func.attr}"
    return ast.dump(func)


ALLOWED_NODES = (
    ast.Module,
    ast.ImportFrom,
    ast.alias,
    ast.FunctionDef,
    ast.arguments,
    ast.Expr,
    ast.Assign,
    ast.Call,
    ast.Name,
    ast.Attribute,
    ast.Load,
    ast.Store,
    ast.Constant,
    ast.Tuple,
    ast.Dict,
    ast.keyword,
    ast.UnaryOp,
    ast.USub,
)


def assert_api_only(text: str) -> ast.Module:
    """The script's shape: one star import of js, argument-less defs, API calls on literals."""
    assert all(" " <= ch <= "~" or ch == "\n" for ch in text), "script is not printable ASCII"
    assert text.count("\n") == len(text.splitlines()), "a line break hides in the script"
    tree = ast.parse(text)
    imports = [n for n in tree.body if isinstance(n, ast.ImportFrom)]
    assert [(i.module, [a.name for a in i.names]) for i in imports] == [(JACK_API.module, ["*"])]
    functions = [n for n in tree.body if isinstance(n, ast.FunctionDef)]
    assert len(functions) + len(imports) == len(tree.body)
    for fn in functions:
        assert fn.name.isidentifier() and fn.name.isascii()
        args = fn.args
        assert not (args.args or args.posonlyargs or args.kwonlyargs or args.vararg or args.kwarg)
        assert not fn.decorator_list and fn.returns is None
    allowed = api_call_names()
    for node in ast.walk(tree):
        assert isinstance(node, ALLOWED_NODES), ast.dump(node)
        if isinstance(node, ast.Call):
            assert call_name(node) in allowed
        if isinstance(node, ast.Name):
            assert node.id in {JACK_API.human_variable, *JACK_API.functions}
        if isinstance(node, ast.Assign):
            assert [call_name(node.value)] == [JACK_API.create_human]  # type: ignore[arg-type]
    return tree


def comments(text: str) -> list[str]:
    tokens = tokenize.generate_tokens(io.StringIO(text).readline)
    return [t.string for t in tokens if t.type == tokenize.COMMENT]


@pytest.mark.parametrize("ta", TA_MODES)
def test_every_example_script_is_api_only_python(
    example_irs: dict[str, list[MotionIR]], ta: str
) -> None:
    for stem, irs in example_irs.items():
        script = emit_jackscript(irs, ta=ta)
        tree = assert_api_only(script.text)
        names = [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
        assert names == list(script.source_map["functions"]), stem
        assert list(script.source_map["functions"].values()) == [ir.task for ir in irs]
        reaches = script.text.count(f".{JACK_API.reach}(")
        assert (reaches > 0) == (ta == "jack"), stem
        assert script.text.count(f".{JACK_API.walk}(") == sum(
            s.kind == "locomotion" for ir in irs for s in ir.segments
        )


def test_joint_keys_name_only_table_joints(example_irs: dict[str, list[MotionIR]]) -> None:
    irs = example_irs["remove_access_panel"]
    tree = ast.parse(emit_jackscript(irs).text)
    keyed: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and call_name(node).endswith(f".{JACK_API.key_joints}"):
            joints = node.args[1]
            assert isinstance(joints, ast.Dict)
            for key, value in zip(joints.keys, joints.values, strict=True):
                joint = ast.literal_eval(key)  # type: ignore[arg-type]
                assert len(ast.literal_eval(value)) == sum(r[1] == joint for r in DOF_MAP)
                keyed.add(joint)
    assert keyed == set(jack_joints())


def test_output_is_byte_identical_across_compilations() -> None:
    path = ROOT / "examples" / "drain_hydraulic_reservoir.mtask"
    first = emit_jackscript(compile_file(path), ta="jack")
    second = emit_jackscript(compile_file(path), ta="jack")
    assert first.text == second.text
    assert json.dumps(first.source_map) == json.dumps(second.source_map)


def test_source_map_points_at_real_task_lines(example_irs: dict[str, list[MotionIR]]) -> None:
    for stem, irs in example_irs.items():
        script = emit_jackscript(irs)
        script_lines = script.text.splitlines()
        task_file = irs[0].file
        source_lines = Path(task_file).read_text(encoding="utf-8").splitlines()
        entries = script.source_map["lines"]
        assert entries, stem
        previous_end = 0
        for entry in entries:
            assert previous_end < entry["script_start"] <= entry["script_end"]
            assert entry["script_end"] <= len(script_lines)
            previous_end = entry["script_end"]
            assert entry["file"] == task_file
            statement = source_lines[entry["line"] - 1].strip()
            assert statement and not statement.startswith("#"), (stem, entry)
            first = script_lines[entry["script_start"] - 1].strip()
            if entry["kind"] != "task":
                assert first.startswith(f"# {task_file}:{entry['line']}:{entry['column']} ")
        mapped = sum(e["script_end"] - e["script_start"] + 1 for e in entries)
        assert mapped > 0.9 * len(script_lines), "most of the script maps back to the task"


# -- nasty text --------------------------------------------------------------------------------


def mtask_string(text: str) -> str:
    """An .mtask string literal for any text: every character as a \\u{...} escape."""
    return '"' + "".join(f"\\u{{{ord(ch):x}}}" for ch in text) + '"'


CLASHING_NAMES = ("print", "human", "CreateHuman", "js", "class", "__init__", "t", "Walk")


def nasty_source(title: str, task_a: str, task_b: str, site: str) -> str:
    return f"""use stdlib.actions

scene bay {{
    site {site} at (0, 120, 60) cm normal (0, 0, -1)
    site spot at (0, 0, 30) cm
}}

task {task_a} {mtask_string(title)} {{
    scene bay
    walk_to(spot)
    unscrew(right, {site}, turns: 1)
}}

task {task_b} {{
    scene bay
    pick(both, {site})
}}
"""


@settings(
    max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    title=st.text(alphabet=st.sampled_from(NASTY) | st.characters(), max_size=24),
    file_text=st.text(
        alphabet=st.sampled_from(NASTY.replace("\x00", "")) | st.sampled_from("az_."), max_size=12
    ),
    names=st.lists(st.sampled_from(CLASHING_NAMES), min_size=3, max_size=3, unique=True),
)
def test_task_file_text_never_breaks_out(
    tmp_path: Path, title: str, file_text: str, names: list[str]
) -> None:
    task_a, task_b, site = names
    path = tmp_path / f"{file_text.replace('/', '_') or 'x'}{len(title)}.mtask"
    path.write_text(nasty_source(title, task_a, task_b, site), encoding="utf-8")
    irs = compile_file(path)
    for ta in TA_MODES:
        script = emit_jackscript(irs, ta=ta)
        tree = assert_api_only(script.text)
        functions = [n for n in tree.body if isinstance(n, ast.FunctionDef)]
        assert len({f.name for f in functions}) == 2
        assert ast.get_docstring(functions[0], clean=False) == title
        assert ast.get_docstring(functions[1], clean=False) == task_b
        strings = {
            n.value
            for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str)
        }
        expected = {title, task_b, *jack_joints(), *EFFECTORS.values(), *GRASP_STATES.values()}
        assert strings <= expected | {"gb10000_1988", "male", "female"}
        assert all(c.startswith("#") and "\n" not in c for c in comments(script.text))
        assert any(comment_text(irs[0].file) in c for c in comments(script.text))


@given(st.text())
def test_comment_text_is_one_printable_comment(text: str) -> None:
    safe = comment_text(text)
    assert all(" " <= ch <= "~" for ch in safe)
    source = f"# {safe}\nx = 1\n"
    assert len(ast.parse(source).body) == 1
    assert len(source.splitlines()) == 2


@given(st.lists(st.text(max_size=8), max_size=8))
def test_function_names_are_unique_safe_identifiers(tasks: list[str]) -> None:
    taken: set[str] = set()
    names = [function_name(task, taken) for task in tasks]
    assert len(set(names)) == len(names)
    for name in names:
        assert name.isidentifier() and name.isascii()
        assert name not in {
            "print",
            "exec",
            "class",
            "None",
            JACK_API.module,
            "human",
            "CreateHuman",
        }


def test_function_names_keep_plain_task_names() -> None:
    taken: set[str] = set()
    assert function_name("remove_panel", taken) == "remove_panel"
    assert function_name("remove_panel", taken) == "remove_panel_2"
    assert function_name("print", taken) == "print_"


@given(st.floats(-1e6, 1e6), st.integers(0, 6))
def test_numbers_are_fixed_precision(value: float, decimals: int) -> None:
    text = number(value, decimals)
    assert abs(float(text) - value) <= 0.5 * 10.0**-decimals + 1e-9 * abs(value)
    assert not text.startswith("-0.0") or float(text) != 0.0
    assert "." in text and "e" not in text


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
@given(
    angles=st.tuples(st.floats(-3.1, 3.1), st.floats(-1.5, 1.5), st.floats(-3.1, 3.1)),
)
def test_root_euler_angles_round_trip(order: str, angles: tuple[float, float, float]) -> None:
    rotation = matrix_from_euler(np.array(angles), order)
    back = euler_from_matrix(rotation, order)
    np.testing.assert_allclose(back, angles, atol=1e-7)


def test_dof_map_covers_the_skeleton_in_its_order() -> None:
    for manikin in (build_manikin(), build_manikin("gb10000_1988", "female", 5)):
        assert tuple(row[0] for row in DOF_MAP) == manikin.dof_names
    for joint in jack_joints():
        indices = sorted(row[2] for row in DOF_MAP if row[1] == joint)
        assert indices == list(range(len(indices)))
    assert all(row[3] in (1, -1) for row in DOF_MAP)
    axes = np.asarray(JACK_API.world_axes)
    np.testing.assert_allclose(axes @ axes.T, np.eye(3), atol=1e-12)


def test_docs_hold_the_mapping_table() -> None:
    doc = (ROOT / "docs" / "jackscript.md").read_text(encoding="utf-8")
    begin, end = "<!-- jack_api table: begin -->\n", "<!-- jack_api table: end -->"
    assert begin in doc and end in doc
    embedded = doc.split(begin, 1)[1].split(end, 1)[0]
    assert embedded.strip() == markdown_tables().strip(), (
        "docs/jackscript.md's table differs from mtlc.codegen.jack_api.markdown_tables()"
    )


@pytest.mark.parametrize(
    "stem", ["coding=utf-7 ", "coding:latin-1", "vim: set fileencoding=utf-16 :"]
)
def test_a_file_name_cannot_declare_the_scripts_encoding(tmp_path: Path, stem: str) -> None:
    """Python reads a coding cookie on line 1 or 2 of a file: only fixed text may sit there."""
    title = "+ACc-;import os;os.system(+ACI-echo PWNED+ACI-);x=+ACc-"  # a quote, in UTF-7
    path = tmp_path / f"{stem}.mtask"
    path.write_text(nasty_source(title, "t", "u", "a"), encoding="utf-8")
    script = emit_jackscript(compile_file(path))
    assert script.text.splitlines()[0] == "# -*- coding: ascii -*-"
    assert "coding" not in script.text.splitlines()[1]
    on_disk = tmp_path / "script.py"
    on_disk.write_bytes(script.text.encode("ascii"))
    tree = ast.parse(on_disk.read_bytes())  # bytes: the way `import` decodes a module
    assert ast.dump(tree) == ast.dump(assert_api_only(script.text))
    (first,) = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "t"]
    assert ast.get_docstring(first, clean=False) == title
