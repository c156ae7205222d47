"""Bad input never gives a traceback or a hang: mutated examples, random bytes, huge inputs."""

from __future__ import annotations

import tempfile
from pathlib import Path

from conftest import EXAMPLES
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mtlc.diagnostics import DiagnosticSink
from mtlc.frontend import run_frontend
from mtlc.syntax import parse_module
from mtlc.syntax.lexer import tokenize

SOURCES = [p.read_text(encoding="utf-8") for p in EXAMPLES]


def _check_text(data: bytes) -> list[str]:
    """Run the whole front end on a file; only diagnostics may come out."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.mtask"
        path.write_bytes(data)
        program = run_frontend([path])
        codes = [d.code for d in program.diagnostics]
    assert "MT0900" not in codes
    return codes


@st.composite
def mutated_example(draw: st.DrawFn) -> bytes:
    text = draw(st.sampled_from(SOURCES))
    tokens = [t for t in _split(text)]
    for _ in range(draw(st.integers(1, 4))):
        if not tokens:
            break
        op = draw(st.sampled_from(["delete", "duplicate", "swap", "truncate", "bytes", "insert"]))
        i = draw(st.integers(0, len(tokens) - 1))
        if op == "delete":
            del tokens[i]
        elif op == "duplicate":
            tokens.insert(i, tokens[i])
        elif op == "swap":
            j = draw(st.integers(0, len(tokens) - 1))
            tokens[i], tokens[j] = tokens[j], tokens[i]
        elif op == "truncate":
            tokens = tokens[:i]
        elif op == "insert":
            tokens.insert(
                i,
                draw(
                    st.sampled_from(
                        [
                            "{",
                            "}",
                            "(",
                            ")",
                            "[",
                            ",",
                            ":",
                            "\n",
                            '"',
                            "repeat 99999999",
                            "-",
                            "deg",
                            "use x",
                        ]
                    )
                ),
            )
        else:
            tokens.insert(i, draw(st.binary(min_size=1, max_size=8)).decode("latin-1"))
    return " ".join(tokens).encode("utf-8", errors="surrogateescape")


def _split(text: str) -> list[str]:
    import re

    return re.findall(r"\w+|[^\w\s]|\n", text)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_example())
def test_mutated_examples_give_diagnostics_not_tracebacks(data: bytes) -> None:
    _check_text(data)


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes(data: bytes) -> None:
    _check_text(data)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(
        st.sampled_from(
            [
                *'{}()[],:;.=+-*/#"\\\n\t abc019_',
                "task",
                "use",
                "element",
                "repeat",
                "goal",
                "at",
                "cm",
            ]
        ),
        max_size=80,
    )
)
def test_token_soup(parts: list[str]) -> None:
    _check_text("".join(parts).encode("utf-8"))


def test_one_megabyte_of_garbage_ends_in_diagnostics() -> None:
    import random

    rng = random.Random(7)
    data = bytes(rng.randrange(256) for _ in range(1 << 20))
    codes = _check_text(data)
    assert codes  # invalid UTF-8, reported once


def test_one_megabyte_of_valid_text_with_errors() -> None:
    line = "element e( x: ) { goal at at }\n"
    codes = _check_text((line * (1_000_000 // len(line))).encode())
    assert "MT0106" in codes


def test_deep_nesting_is_refused_without_recursion_error() -> None:
    sink = DiagnosticSink()
    parse_module("task t {\n" + "{" * 100_000 + "\n}\n", "deep.mtask", sink)
    assert "MT0104" in [d.code for d in sink.items]


def test_long_expression_is_refused_without_recursion_error() -> None:
    codes = _check_text(
        ("task t {\n    inspect(a, " + " + ".join(["1 s"] * 20_000) + ")\n}\n").encode()
    )
    assert "MT0104" in codes


def test_every_character_is_tokenized_or_reported() -> None:
    """The tokenizer must not skip characters silently (control and unicode space included)."""
    for ch in ["\x00", "\x1c", "\x1f", "\u2028", "\u00a0", "\ufeff", "\u3000", "😀"]:
        sink = DiagnosticSink()
        tokenize(f"task t {{ {ch} }}", "x.mtask", sink)
        assert [d.code for d in sink.items] == ["MT0102"], repr(ch)


def test_huge_repeat_count_is_a_budget_error_quickly() -> None:
    text = "use stdlib.elements\nscene s {\n    site a at (0, 1, 0) m\n}\ntask t {\n    scene s\n    repeat 1000000000 {\n        repeat 1000000000 {\n            look(a)\n        }\n    }\n}\n"
    assert _check_text(text.encode()) == ["MT0401"]


def test_empty_repeat_does_not_loop() -> None:
    text = "use stdlib.elements\nscene s {\n    site a at (0, 1, 0) m\n}\ntask t {\n    scene s\n    look(a)\n    repeat 1000000000000 {\n    }\n}\n"
    assert _check_text(text.encode()) == []


def test_paths_too_long_for_the_system_are_missing_files_not_internal_errors(
    tmp_path: Path, capsys
) -> None:
    """A 300-character file name (ENAMETOOLONG) reached report and lint's --config as MT0900."""
    from mtlc.cli import main

    long_name = str(tmp_path / ("b" * 300 + ".mtask"))
    for argv in (
        ["report", long_name],
        ["lint", str(EXAMPLES[0]), "--config", str(tmp_path / ("c" * 300 + ".toml"))],
        ["check", long_name],
    ):
        status = main(argv)
        err = capsys.readouterr().err
        assert "MT0900" not in err and "Traceback" not in err, argv
        assert status in (1, 2), argv
        assert "no such" in err or "MT0001" in err, err
