"""One figure, every tool (issue 18, "verdicts you can trust"): `compile --metrics`, `lint`,
`report` and the preview print the same balance margin and the same reach shortfalls for the
same manikin, because they read what verify measured once (docs/metrics.md).

The procedure is none of the examples: a one-knee kneel whose stepping foot lifts and lands (the
frames where the steps' records and the points that touch could disagree), reaches the manikin
falls short of, and a squat. Each tool runs through the command line, as a user runs it.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import pytest

from mtlc.cli import main

MANIKIN = "gb10000_1988:female:5"
TASK = """use stdlib.actions
use stdlib.elements

scene pump_bay {
    ground 0 cm
    site low_cap at (30, 15, 105) cm normal (0, 1, 0)
    site far_cap at (-70, 35, 125) cm normal (0, 0, -1)
}

task service_pump {
    scene pump_bay
    kneel(1)
    reach(right, low_cap)
    grasp(right)
    turn(right, -90 deg)
    release(right)
    reach(left, far_cap)
    stand()
    squat(30 cm)
    reach(right, far_cap)
    stand()
}
"""
SHORT = re.compile(r"cannot reach site `(\w+)`: (\d+) mm short")
OUTSIDE = re.compile(r"up to ([\d.]+) mm outside")


def _mm(metres: float) -> str:
    """How the diagnostics print a length (``mtlc.passes.balance._mm``)."""
    mm = metres * 1000
    return f"{mm:.0f}" if mm >= 9.5 else f"{mm:.1f}" if mm >= 0.95 else f"{mm:.2f}"


def _run(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[str, str]:
    capsys.readouterr()
    assert main(argv) in (0, 1), argv
    got = capsys.readouterr()
    return got.out, got.err


def _diagnostics(text: str) -> list[tuple[str, int, str]]:
    """(code, line, message) of the compile's JSON diagnostics."""
    start = text.index("{")
    doc = json.JSONDecoder().raw_decode(text[start:])[0]
    return [(d["code"], d["span"]["line"], d["message"]) for d in doc["diagnostics"]]


def test_compile_lint_report_and_preview_print_one_margin_and_one_shortfall(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    task = tmp_path / "service_pump.mtask"
    task.write_text(TASK, encoding="utf-8")
    motion = ["MT0501", "MT0502"]

    # compile --metrics: the diagnostics (JSON), then the table
    out, _ = _run(capsys, ["compile", str(task), "--manikin", MANIKIN, "--metrics",
                             "--format", "json", "-o", str(tmp_path / "out")])  # fmt: skip
    (row,) = [line for line in out.splitlines() if line.startswith("support margin, static")]
    compile_margin = row.split()[-2] if row.endswith("FAIL") else row.split()[-1]
    compiled = sorted(d for d in _diagnostics(out) if d[0] in motion)

    # lint, the same manikin
    out, _ = _run(capsys, ["lint", str(task), "--manikins", MANIKIN, "-j", "1", "--format",
                           "json", "--select", ",".join(motion), "--exit-zero"])  # fmt: skip
    findings = json.loads(out)["findings"]
    linted = sorted((f["code"], f["span"]["line"], f["message"]) for f in findings)

    # report: the reach shortfalls, as CSV
    table = tmp_path / "report.csv"
    _run(capsys, ["report", str(task), "--manikins", MANIKIN, "-j", "1", "--csv", str(table)])
    with table.open(encoding="utf-8") as fh:
        reach = [r for r in csv.DictReader(fh) if r["section"] == "reach"]
    reported = {
        (int(r["line"]), r["site"]): float(r["value"]) for r in reach if r["note"] == "short"
    }

    # the preview page: the per-frame margin it plots and the IR it embeds
    page = tmp_path / "page.html"
    _run(capsys, ["preview", str(task), "--manikin", MANIKIN, "-o", str(page)])
    html = page.read_text(encoding="utf-8")
    data = re.search(r'<script type="application/json" id="mtlc-data">(.*?)</script>', html, re.S)
    assert data is not None
    doc = json.loads(data.group(1))
    plotted = [m for m in doc["figures"]["com_margin"] if m is not None]
    static_margin = doc["ir"]["verification"]["static_margin"]

    # the margin: the preview's worst frame (no walk here: every frame is static) is the figure
    # verify stored, `--metrics` prints it, and it is negative here, so lint and compile both
    # report MT0502 with it as the worst "outside"
    assert min(plotted) == pytest.approx(static_margin, abs=1e-5)  # as the IR JSON rounds it
    assert compile_margin == f"{min(plotted) * 1e3:.1f}" == f"{static_margin * 1e3:.1f}"
    assert static_margin < 0
    assert linted == compiled  # the same findings, word for word
    worst = max(OUTSIDE.findall(" ".join(m for c, _, m in linted if c == "MT0502")), key=float)
    # the same millimetres, as printed (the JSON's rounding may put the margin on the other
    # side of a printing boundary: 0.9499 mm prints 0.95, 0.9500 prints 0.9)
    assert worst == _mm(-static_margin) or float(worst) == pytest.approx(
        -static_margin * 1e3, abs=0.051
    )

    # the shortfalls: each unreachable reach, the same millimetres in lint (and compile) and
    # the report
    short = {(line, m[0]): int(m[1]) for c, line, msg in linted for m in SHORT.findall(msg)}
    assert short and set(short) == set(reported)
    for key, mm in short.items():
        # lint prints whole millimetres, the report one decimal: 720.51 mm is "721" and
        # "720.5", and round(720.5) is 720, so the two agree within half a millimetre
        assert abs(mm - reported[key]) <= 0.5 + 0.05, key
