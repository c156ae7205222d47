"""One test per diagnostic code: the code, the line and the column it points at."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from mtlc.diagnostics import CODES
from mtlc.frontend import FrontendOptions, run_frontend

HEADER = "use stdlib.actions\nuse stdlib.elements\n"
SCENE = "scene s {\n    site a at (0, 100, 50) cm\n    site b at (10, 100, 50) cm\n}\n"


def diagnose(
    tmp_path: Path, files: dict[str, str | bytes], **options
) -> list[tuple[str, str, int, int]]:
    for name, text in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text, encoding="utf-8")
    program = run_frontend([tmp_path / "main.mtask"], FrontendOptions(**options))
    return [
        (d.code, Path(d.span.file).name, d.span.line, d.span.column) for d in program.diagnostics
    ]


def task(body: str, extra: str = "") -> str:
    return f"{HEADER}{SCENE}{extra}task t {{\n    scene s\n{body}}}\n"


# code -> (files, (file, line, column)); `main.mtask` is the file checked
CASES: dict[str, tuple[dict[str, str | bytes], tuple[str, int, int]]] = {
    "MT0002": ({"main.mtask": b"task t {\n  x\xff\n}\n"}, ("main.mtask", 2, 4)),
    "MT0005": ({"main.mtask": 'scene s {\n    model m "m.glb"\n}\n'}, ("main.mtask", 2, 5)),
    "MT0006": (
        {"main.mtask": 'scene s {\n    model m "m.stl" units mm\n}\n', "m.stl": b"solid x\n"},
        ("main.mtask", 2, 5),
    ),
    "MT0008": ({"main.mtask": 'scene s {\n    model m "../m.glb"\n}\n'}, ("main.mtask", 2, 5)),
    "MT0211": (
        {"main.mtask": "scene s {\n    box b size (1, 1, 1) m\n    site x = b.bolt\n}\n"},
        ("main.mtask", 3, 16),
    ),
    "MT0212": ({"main.mtask": "scene s {\n    box b radius 1 m\n}\n"}, ("main.mtask", 2, 11)),
    "MT0408": (
        {
            "main.mtask": task("    walk_to(a)\n").replace(
                "    site b", "    box far size (1, 1, 1) m at (0, 0, 2000) m\n    site b"
            )
        },
        ("main.mtask", 5, 5),
    ),
    "MT0101": ({"main.mtask": "task t {\n    walk_to(a) b\n}\n"}, ("main.mtask", 2, 16)),
    "MT0102": ({"main.mtask": "task t {\n    @@\n}\n"}, ("main.mtask", 2, 5)),
    "MT0103": ({"main.mtask": 'task t "open title {\n}\n'}, ("main.mtask", 1, 8)),
    "MT0104": ({"main.mtask": "task t {\n" + "{" * 70 + "}" * 70 + "\n}\n"}, ("main.mtask", 2, 64)),
    "MT0105": ({"main.mtask": "task t {\n    walk_to(a)\n"}, ("main.mtask", 1, 8)),
    "MT0107": ({"main.mtask": 'task t "bad \\q escape" {\n}\n'}, ("main.mtask", 1, 13)),
    "MT0108": ({"main.mtask": "task t {\n    walk_to(螺栓①)\n}\n"}, ("main.mtask", 2, 13)),
    "MT0201": ({"main.mtask": task("    walk_too(a)\n")}, ("main.mtask", 9, 5)),
    "MT0202": (
        {
            "main.mtask": "element e() {\n    still over 1 s\n}\nelement e() {\n    still over 1 s\n}\n"
        },
        ("main.mtask", 4, 9),
    ),
    "MT0203": ({"main.mtask": "use bay.missing\n"}, ("main.mtask", 1, 5)),
    "MT0204": (
        {"main.mtask": "use other\n", "other.mtask": "use main\n"},
        ("other.mtask", 1, 5),
    ),
    "MT0206": (
        {
            "main.mtask": "use one\nuse two\ntask t {\n    e()\n}\n",
            "one.mtask": "element e() {\n    still over 1 s\n}\n",
            "two.mtask": "element e() {\n    still over 2 s\n}\n",
        },
        ("main.mtask", 4, 5),
    ),
    "MT0207": (
        {"main.mtask": "action a() {\n    b()\n}\naction b() {\n    a()\n}\n"},
        ("main.mtask", 5, 5),
    ),
    "MT0208": (
        {"main.mtask": HEADER + "element e() {\n    walk_to(x)\n}\n"},
        ("main.mtask", 4, 5),
    ),
    "MT0209": ({"main.mtask": task("    still over 1 s\n")}, ("main.mtask", 9, 5)),
    "MT0210": ({"main.mtask": task("    scene s\n")}, ("main.mtask", 9, 5)),
    "MT0301": ({"main.mtask": task("    walk_to(10 cm)\n")}, ("main.mtask", 9, 13)),
    "MT0302": ({"main.mtask": task("    unscrew(right, a, load: 2 s)\n")}, ("main.mtask", 9, 29)),
    "MT0303": ({"main.mtask": task("    inspect(a, 2 sec)\n")}, ("main.mtask", 9, 18)),
    "MT0304": (
        {"main.mtask": "element e(x: Lenght) {\n    still over 1 s\n}\n"},
        ("main.mtask", 1, 14),
    ),
    "MT0305": ({"main.mtask": task("    walk_to(a, b)\n")}, ("main.mtask", 9, 16)),
    "MT0306": ({"main.mtask": task("    unscrew(right, a, turn: 2)\n")}, ("main.mtask", 9, 23)),
    "MT0307": ({"main.mtask": task("    pick(right)\n")}, ("main.mtask", 9, 5)),
    "MT0308": ({"main.mtask": task("    walk_to(a, target: b)\n")}, ("main.mtask", 9, 16)),
    "MT0309": (
        {
            "main.mtask": task("    scene s\n", "").replace(
                "scene s\n    scene s", "manikin gb10000_1988 female p3\n    scene s"
            )
        },
        ("main.mtask", 8, 33),
    ),
    "MT0310": (
        {"main.mtask": "element e(x: Length, x: Angle) {\n    still over 1 s\n}\n"},
        ("main.mtask", 1, 22),
    ),
    "MT0311": ({"main.mtask": task("    unscrew(hand: right, a)\n")}, ("main.mtask", 9, 26)),
    "MT0401": (
        {"main.mtask": task("    repeat 1000 {\n        unscrew(right, a, turns: 100)\n    }\n")},
        ("main.mtask", 9, 5),
    ),
    "MT0402": ({"main.mtask": "task t {\n}\n"}, ("main.mtask", 1, 6)),
    "MT0407": (
        {"main.mtask": task("    inspect(a, 10 min)\n    inspect(b, 25 min)\n    inspect(a)\n")},
        ("main.mtask", 10, 5),
    ),
    "MT0312": (
        {"main.mtask": task("    for c in [A, C] {\n        reach(right, a, c)\n    }\n")},
        ("main.mtask", 9, 15),
    ),
    "MT0313": (
        {"main.mtask": "element e(n: Int = 1, where: Site) {\n    gaze at where\n}\n"},
        ("main.mtask", 1, 23),
    ),
    "MT0405": (
        {
            "main.mtask": HEADER
            + SCENE
            + "".join(f"action a{i}(x: Site) {{\n    a{i + 1}(x)\n}}\n" for i in range(200))
            + "action a200(x: Site) {\n    look(x)\n}\n"
            + "task t {\n    scene s\n    a0(a)\n}\n"
        },
        ("main.mtask", 612, 5),
    ),
    "MT0406": (
        {
            "main.mtask": task(
                "    parallel {\n        pick(right, a)\n        reach(right, b)\n    }\n"
            )
        },
        ("main.mtask", 11, 9),
    ),
    "MT0404": ({"main.mtask": task("    budget 1 s\n    inspect(a, 2 s)\n")}, ("main.mtask", 9, 5)),
    "MT0403": (
        {"main.mtask": task("    inspect(a, 2 s / 0)\n")},
        ("main.mtask", 9, 16),
    ),
}


@pytest.mark.parametrize("code", sorted(CASES))
def test_code_line_column(code: str, tmp_path: Path) -> None:
    files, where = CASES[code]
    found = diagnose(tmp_path, files)
    assert (code, *where) in found, found


def test_missing_file_is_mt0001(tmp_path: Path) -> None:
    program = run_frontend([tmp_path / "nope.mtask"])
    assert [d.code for d in program.diagnostics] == ["MT0001"]


def test_large_file_is_mt0003(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from mtlc.semantics import modules

    monkeypatch.setattr(modules, "MAX_FILE_BYTES", 100)
    found = diagnose(tmp_path, {"main.mtask": "# padding\n" * 20})
    assert found == [("MT0003", "main.mtask", 1, 1)]


@pytest.mark.parametrize("name", ["a" * 256, ".".join(["abcdefghij"] * 500)])
def test_a_use_name_too_long_for_the_file_system_is_mt0203(tmp_path: Path, name: str) -> None:
    """ENAMETOOLONG from the lookup was an internal error (issue 17)."""
    found = diagnose(tmp_path, {"main.mtask": f"use {name}\ntask t {{\n}}\n"})
    assert [c for c, *_ in found] == ["MT0203"]
    program = run_frontend([tmp_path / "main.mtask"])
    (diag,) = program.diagnostics
    assert "255 bytes" in (diag.help or "") and len(diag.message) < 200


def test_a_folder_is_mt0001_with_help(tmp_path: Path) -> None:
    program = run_frontend([tmp_path])
    (diag,) = program.diagnostics
    assert (diag.code, diag.message) == ("MT0001", "cannot read file: it is a folder")
    assert diag.help is not None


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs named pipes")
def test_a_fifo_is_refused_without_blocking(tmp_path: Path) -> None:
    """Opening a pipe with no writer would block; reading one would never end."""
    fifo = tmp_path / "steps.mtask"
    os.mkfifo(fifo)
    program = run_frontend([fifo])
    (diag,) = program.diagnostics
    assert diag.code == "MT0004" and "a pipe" in diag.message and diag.help


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_dev_zero_is_refused_not_read_forever() -> None:
    program = run_frontend([Path("/dev/zero")])
    assert [(d.code, d.span.line) for d in program.diagnostics] == [("MT0004", 1)]


def test_a_file_that_grows_past_the_limit_while_read_is_mt0003(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The size is checked before reading and again on what was read."""
    from mtlc.semantics import modules

    path = tmp_path / "main.mtask"
    path.write_text("# padding\n" * 20, encoding="utf-8")
    real_fstat = os.fstat
    monkeypatch.setattr(modules.os, "fstat", lambda fd: _shrunk(real_fstat(fd)))
    monkeypatch.setattr(modules, "MAX_FILE_BYTES", 100)
    program = run_frontend([path])
    (diag,) = program.diagnostics
    assert diag.code == "MT0003" and "larger than the limit" in diag.message


def _shrunk(info: os.stat_result) -> os.stat_result:
    fields = list(info)
    fields[6] = 0  # st_size: as if the file were empty when it was looked at
    return os.stat_result(fields)


def test_fmt_stdin_is_bounded(monkeypatch: pytest.MonkeyPatch, capsys) -> None:  # type: ignore[no-untyped-def]
    import io

    from mtlc.fmt.__main__ import main as fmt_main
    from mtlc.semantics import modules

    monkeypatch.setattr(modules, "MAX_FILE_BYTES", 100)
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(b"#" * 1000)))
    assert fmt_main(["-"]) == 1
    assert "MT0003" in capsys.readouterr().err


@pytest.mark.skipif(sys.platform == "win32", reason="symlinks need privileges on Windows")
def test_use_outside_roots_is_mt0205(tmp_path: Path) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "secret.mtask").write_text("element e() {\n    still over 1 s\n}\n")
    root = tmp_path / "proj"
    root.mkdir()
    (root / "secret.mtask").symlink_to(outside / "secret.mtask")
    (root / "main.mtask").write_text("use secret\n")
    program = run_frontend([root / "main.mtask"])
    assert [(d.code, d.span.line, d.span.column) for d in program.diagnostics] == [("MT0205", 1, 5)]


def test_too_many_errors_stops_at_mt0106(tmp_path: Path) -> None:
    text = "".join(f"element e{i}( {{\n}}\n" for i in range(80))
    codes = [c for c, *_ in diagnose(tmp_path, {"main.mtask": text})]
    assert codes.count("MT0106") == 1
    assert len(codes) < 60


def test_every_code_is_tested() -> None:
    tested = set(CASES) | {
        "MT0001",
        "MT0003",
        "MT0004",
        "MT0007",  # tests/geometry/test_models.py
        "MT0106",
        "MT0109",  # tests/test_fmt.py
        "MT0205",
        "MT0501",
        "MT0502",
        "MT0503",
        *(f"MT051{i}" for i in range(5)),  # the verify pass: tests/passes/test_verify.py
        "MT0515",  # tests/geometry/test_equipment.py
        "MT0520",  # retired (never raised): tests/lint/test_lint_cli.py, test_holds.py
        "MT0525",  # retired (never raised): tests/lint/test_lint_cli.py, test_loads_support.py
    }
    tested |= {f"MT060{i}" for i in range(1, 10)}  # lint: tests/lint/, tests/test_analyses.py
    tested |= {"MT0610", "MT0611"}  # tests/lint/test_access.py
    tested |= {"MT0612"}  # tests/lint/test_crossing.py
    assert set(CODES) - tested == {"MT0900"}  # internal errors have no input that makes them


def test_all_errors_are_reported_not_only_the_first(tmp_path: Path) -> None:
    body = "    walk_too(a)\n    inspect(a, 2 sec)\n    walk_to(a b)\n    pick(right)\n"
    codes = sorted(c for c, *_ in diagnose(tmp_path, {"main.mtask": task(body)}))
    assert codes == ["MT0101", "MT0201", "MT0303", "MT0307"]


def test_did_you_mean(tmp_path: Path) -> None:
    program_files = {"main.mtask": task("    walk_too(a)\n")}
    diagnose(tmp_path, program_files)
    program = run_frontend([tmp_path / "main.mtask"])
    (diag,) = program.diagnostics
    assert diag.help == "did you mean `walk_to`?"


def test_expansion_budget_is_configurable(tmp_path: Path) -> None:
    text = task("    repeat 30 {\n        inspect(a)\n    }\n")
    assert diagnose(tmp_path, {"main.mtask": text}) == []
    found = diagnose(tmp_path, {"main.mtask": text}, expansion_budget=50)
    assert [c for c, *_ in found] == ["MT0401"]


def test_motion_budget_is_configurable_and_names_itself(tmp_path: Path) -> None:
    """MT0407 at the first line whose step ends past the budget; the task gives no timeline."""
    text = task("    inspect(a, 50 s)\n    inspect(b, 50 s)\n    inspect(a, 50 s)\n")
    assert diagnose(tmp_path, {"main.mtask": text}) == []
    program = run_frontend([tmp_path / "main.mtask"], FrontendOptions(motion_budget=90.0))
    (diag,) = program.diagnostics
    assert (diag.code, diag.span.line, diag.span.column) == ("MT0407", 10, 5)
    assert "more than the motion budget of 1 min 30 s" in diag.message
    assert "--motion-budget" in (diag.help or "")
    assert program.timelines == []


def test_motion_budget_option_takes_a_duration_with_its_unit(tmp_path: Path) -> None:
    from mtlc.cli import build_parser

    def budget(*argv: str) -> float:
        return build_parser().parse_args(["check", "f.mtask", *argv]).motion_budget

    assert budget() == 900.0
    assert budget("--motion-budget", "2h") == 7200.0
    assert budget("--motion-budget", "45min") == 2700.0
    assert budget("--motion-budget", "1.5 min") == 90.0
    for bad in ("90", "2 days", "inf h", "nan s", "0s", "-1min"):
        with pytest.raises(SystemExit):
            budget("--motion-budget", bad)


def test_unit_mismatch_in_arithmetic(tmp_path: Path) -> None:
    text = task("    inspect(a, 2 s + 3 cm)\n")
    found = diagnose(tmp_path, {"main.mtask": text})
    assert found == [("MT0302", "main.mtask", 9, 16)]


def test_duration_where_angle_wanted(tmp_path: Path) -> None:
    text = HEADER + "element e(hand: Hand) {\n    turn(hand, 2 s)\n}\n"
    assert diagnose(tmp_path, {"main.mtask": text}) == [("MT0302", "main.mtask", 4, 16)]


def test_type_error_length_for_site(tmp_path: Path) -> None:
    text = HEADER + "element e(hand: Hand, d: Length) {\n    reach(hand, d)\n}\n"
    assert diagnose(tmp_path, {"main.mtask": text}) == [("MT0301", "main.mtask", 4, 17)]


def test_site_named_like_a_hand_does_not_hijack_the_hand(tmp_path: Path) -> None:
    files = {
        "main.mtask": HEADER
        + "scene s {\n    site right at (0, 1, 0.5) m\n    site B at (0, 1, 0.4) m\n}\n"
        "task t {\n    scene s\n    pick(right, right)\n    reach(left, B)\n}\n"
    }
    assert diagnose(tmp_path, files) == []


def test_enum_member_where_a_site_is_wanted_is_a_type_error(tmp_path: Path) -> None:
    assert diagnose(tmp_path, {"main.mtask": task("    walk_to(right)\n")}) == [
        ("MT0301", "main.mtask", 9, 13)
    ]


def test_ambiguous_enum_member_and_qualified_form(tmp_path: Path) -> None:
    loop = "    for c in [{}, {}] {{\n        reach(right, a, c)\n    }}\n"
    found = diagnose(tmp_path, {"main.mtask": task(loop.format("A", "C"))})
    assert [c for c, *_ in found] == ["MT0312", "MT0312"]
    assert diagnose(tmp_path, {"main.mtask": task(loop.format("ReachCase.A", "ReachCase.C"))}) == []
    found = diagnose(tmp_path, {"main.mtask": task("    reach(right, a, ReachCase.Q)\n")})
    assert found == [("MT0201", "main.mtask", 9, 31)]


def test_mtm_code_through_a_parameter_is_checked_when_expanding(tmp_path: Path) -> None:
    extra = (
        "element look_with(x: Site, code: String) {\n    gaze at x\n    time mtm.code(code)\n}\n"
    )
    text = HEADER + SCENE + extra + 'task t {\n    scene s\n    look_with(a, "EF2")\n}\n'
    assert [c for c, *_ in diagnose(tmp_path, {"main.mtask": text})] == ["MT0309"]


def test_missing_tool_property_is_a_diagnostic(tmp_path: Path) -> None:
    extra = "tool probe {\n    mass 0.2 kg\n}\n"
    found = diagnose(
        tmp_path, {"main.mtask": task("    reach(right, a, approach: probe.length)\n", extra)}
    )
    assert [c for c, *_ in found] == ["MT0309"]


def test_time_must_be_at_the_top_of_an_element_and_only_once(tmp_path: Path) -> None:
    nested = "element e(x: Site) {\n    {\n        gaze at x\n        time 1 s\n    }\n}\n"
    assert diagnose(tmp_path, {"main.mtask": nested}) == [("MT0209", "main.mtask", 4, 9)]
    twice = "element e(x: Site) {\n    gaze at x\n    time 1 s\n    time 2 s\n}\n"
    assert diagnose(tmp_path, {"main.mtask": twice}) == [("MT0210", "main.mtask", 4, 5)]


def test_a_failed_use_does_not_cascade_into_unknown_names(tmp_path: Path) -> None:
    text = "use stdlib.actionz\ntask t {\n    walk_to(x)\n    pick(right, y)\n}\n"
    assert [c for c, *_ in diagnose(tmp_path, {"main.mtask": text})] == ["MT0203"]


# ---------------------------------------------------------------- from the front-end review


def codes_of(tmp_path: Path, text: str) -> list[str]:
    return [c for c, *_ in diagnose(tmp_path, {"main.mtask": text})]


def test_vector_sizes_are_checked_through_arithmetic(tmp_path: Path) -> None:
    scene = HEADER + "scene s {\n    site x at (0, 100) cm + (0, 0) cm\n}\n"
    assert codes_of(tmp_path, scene) == ["MT0309"]
    assert codes_of(tmp_path, "element e() {\n    walk by (1, 2) m * 2\n}\n") == ["MT0309"]
    assert codes_of(tmp_path, "element e() {\n    walk by (1, 2, 3) m + (1, 2) m\n}\n") == [
        "MT0302"
    ]


def test_sites_of_two_scenes_with_one_name_stay_apart(tmp_path: Path) -> None:
    text = (
        HEADER
        + "scene a {\n    site p at (0, 100, 50) cm\n}\nscene b {\n    site p at (0, 100, 90) cm\n}\n"
        + "task t {\n    scene a\n    reach(right, b.p)\n    reach(left, p)\n}\n"
    )
    path = tmp_path / "main.mtask"
    path.write_text(text)
    (timeline,) = run_frontend([path]).timelines
    right, left = timeline.primitives
    assert right.params["position"] == pytest.approx((0, 1.0, 0.9))
    assert left.params["position"] == pytest.approx((0, 1.0, 0.5))
    assert [s.name for s in timeline.sites] == ["p", "b.p"]


def test_scene_in_another_module_evaluates_in_its_own_scope(tmp_path: Path) -> None:
    scene = "use stdlib.tools\nscene bay {\n    site p at wrench_10mm.tip + (0, 100, 50) cm\n}\n"
    main = HEADER + "use bay\ntask t {\n    scene bay\n    reach(right, p)\n}\n"
    assert diagnose(tmp_path, {"bay.mtask": scene, "main.mtask": main}) == []


def test_huge_coordinates_and_durations_give_diagnostics(tmp_path: Path) -> None:
    far = (
        HEADER
        + "scene s {\n    site far at (1e300, 0, 0) m\n}\ntask t {\n    scene s\n    walk_to(far)\n}\n"
    )
    assert "MT0900" not in codes_of(tmp_path, far)
    inf = "element e() {\n    still over 1e308 s * 10\n}\ntask t {\n    e()\n}\n"
    assert codes_of(tmp_path, inf) == ["MT0309"]
    neg = "element e() {\n    posture bend\n    time -5 s\n}\ntask t {\n    e()\n}\n"
    assert codes_of(tmp_path, neg) == ["MT0309"]


def test_top_level_keywords_at_column_one_inside_a_block_are_statements(tmp_path: Path) -> None:
    text = HEADER + SCENE + "use stdlib.tools\ntask t {\nscene s\ntool wrench_10mm\nlook(a)\n}\n"
    assert diagnose(tmp_path, {"main.mtask": text}) == []


def test_value_errors_point_at_the_users_line(tmp_path: Path) -> None:
    found = diagnose(tmp_path, {"main.mtask": task("    unscrew(right, a, turns: -1)\n")})
    assert found == [("MT0309", "main.mtask", 9, 5)]
    found = diagnose(tmp_path, {"main.mtask": task("    kneel(7)\n")})
    assert found == [("MT0309", "main.mtask", 9, 5)]
    found = diagnose(tmp_path, {"main.mtask": task("    reach(right, a, approach: -2 cm)\n")})
    assert found == [("MT0309", "main.mtask", 9, 5)]


def test_qualified_names_by_whole_path_and_alias_clash(tmp_path: Path) -> None:
    assert (
        diagnose(
            tmp_path, {"main.mtask": task("    stdlib.elements.kneel()\n    elements.stand()\n")}
        )
        == []
    )
    files = {
        "main.mtask": "use a.x\nuse b.x\ntask t {\n    x.ping()\n}\n",
        "a/x.mtask": "element ping() {\n    still over 1 s\n}\n",
        "b/x.mtask": "element pong() {\n    still over 1 s\n}\n",
    }
    assert [c for c, *_ in diagnose(tmp_path, files)] == ["MT0206"]
    files["main.mtask"] = "use a.x\nuse b.x\ntask t {\n    a.x.ping()\n    b.x.pong()\n}\n"
    assert diagnose(tmp_path, files) == []


def test_retried_items_do_not_count_builder_errors_twice(tmp_path: Path) -> None:
    body = "".join(f'element e{i}() {{\n    gaze at "\\q" oops\n}}\n' for i in range(20))
    found = codes_of(tmp_path, body)
    assert "MT0106" not in found


def test_misspelt_keyword_gets_a_hint(tmp_path: Path) -> None:
    path = tmp_path / "main.mtask"
    path.write_text(task("    repet 3 {\n        look(a)\n    }\n"))
    (diag,) = run_frontend([path]).diagnostics
    assert diag.code == "MT0101" and "did you mean `repeat`?" in (diag.help or "")


def test_unicode_digits_are_not_numbers(tmp_path: Path) -> None:
    """Arabic-Indic `٣`: one diagnostic, then read as `3` so the statement still checks."""
    assert codes_of(tmp_path, task("    inspect(a, \u0663 s)\n")) == ["MT0102"]


def test_unknown_callee_does_not_cascade(tmp_path: Path) -> None:
    text = (
        "use stdlib.actions\n" + SCENE + "task t {\n    scene s\n    reach(right, a, case: A)\n}\n"
    )
    assert codes_of(tmp_path, text) == ["MT0201"]
