"""`mtlc lint` output formats against golden files; SARIF against the 2.1.0 schema's required
fields (a compact subset written here: the official schema is 200 kB and pulls in a validator
dependency for checks a few lines express); GitHub workflow-command escaping."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mtlc.diagnostics import Span
from mtlc.lint import LintConfig, lint_paths
from mtlc.lint.engine import LintResult
from mtlc.lint.findings import Finding, merge
from mtlc.lint.output import (
    escape_data,
    escape_property,
    render_github,
    render_json,
    render_sarif,
    render_text,
)

BAY = Path("tests/lint/data/bay.mtask")
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def result() -> LintResult:
    return lint_paths([BAY], LintConfig())


@pytest.mark.parametrize(
    ("name", "render"),
    [("bay.txt", render_text), ("bay.json", render_json), ("bay.github", render_github),
     ("bay.sarif", render_sarif)],
)  # fmt: skip
def test_format_matches_golden(result: LintResult, golden, name: str, render) -> None:
    text = render(result, ROOT)
    if name.endswith(".sarif"):  # the help pages change with the docs: checked apart, below
        doc = json.loads(text)
        for rule in doc["runs"][0]["tool"]["driver"]["rules"]:
            rule["help"]["markdown"] = f"<docs/diagnostics/{rule['id']}.md>"
        text = json.dumps(doc, indent=2, ensure_ascii=False) + "\n"
    golden.check(f"lint/{name}", text)


def test_json_is_versioned_and_names_manikins(result: LintResult) -> None:
    doc = json.loads(render_json(result, ROOT))
    assert (doc["format"], doc["version"]) == ("mtlc-lint", 1)
    (reach,) = [f for f in doc["findings"] if f["code"] == "MT0501"]
    assert [m["manikin"] for m in reach["manikins"]] == doc["manikins"]
    assert doc["summary"]["warnings"] == len(doc["findings"])


# -- SARIF 2.1.0: required properties and value constraints of the objects we emit ----------

REQUIRED = {
    "sarifLog": ("version", "runs"),
    "run": ("tool",),
    "tool": ("driver",),
    "toolComponent": ("name",),
    "reportingDescriptor": ("id",),
    "result": ("message",),
    "artifactLocation": (),
    "region": (),
}


def _requires(obj: dict[str, Any], kind: str) -> None:
    missing = [k for k in REQUIRED[kind] if k not in obj]
    assert not missing, f"{kind} lacks {missing}"


def _message(msg: dict[str, Any]) -> None:
    assert "text" in msg or "id" in msg  # message: one of text or id
    assert isinstance(msg.get("text", ""), str)


def validate_sarif(doc: dict[str, Any]) -> None:
    _requires(doc, "sarifLog")
    assert doc["version"] == "2.1.0"
    assert isinstance(doc["runs"], list)
    for run in doc["runs"]:
        _requires(run, "run")
        _requires(run["tool"], "tool")
        driver = run["tool"]["driver"]
        _requires(driver, "toolComponent")
        ids = []
        for rule in driver.get("rules", []):
            _requires(rule, "reportingDescriptor")
            ids.append(rule["id"])
            for key in ("shortDescription", "fullDescription"):
                assert isinstance(rule[key]["text"], str) and rule[key]["text"]
            assert rule["help"]["text"] and rule["help"]["markdown"]  # GitHub shows help
            assert rule["defaultConfiguration"]["level"] in ("none", "note", "warning", "error")
        assert len(set(ids)) == len(ids)
        assert run.get("columnKind", "unicodeCodePoints") in ("utf16CodeUnits", "unicodeCodePoints")
        for res in run.get("results", []):
            _requires(res, "result")
            _message(res["message"])
            assert res["level"] in ("none", "note", "warning", "error")
            assert ids[res["ruleIndex"]] == res["ruleId"]
            for loc in res["locations"]:
                phys = loc["physicalLocation"]
                uri = phys["artifactLocation"]["uri"]
                assert not uri.startswith("/") and "\\" not in uri  # repo-relative
                region = phys["region"]
                assert region["startLine"] >= 1 and region["startColumn"] >= 1
                assert region["endLine"] >= region["startLine"]
                if region["endLine"] == region["startLine"]:
                    assert region["endColumn"] >= region["startColumn"]


def test_sarif_has_the_required_fields(result: LintResult) -> None:
    doc = json.loads(render_sarif(result, ROOT))
    validate_sarif(doc)
    rules = doc["runs"][0]["tool"]["driver"]["rules"]
    assert {r["id"] for r in rules} == {f.code for f in result.findings}
    assert all(r["help"]["markdown"].startswith(f"# {r['id']}") for r in rules)
    assert doc["runs"][0]["results"], "the bay has findings"


def test_sarif_validator_rejects_broken_documents(result: LintResult) -> None:
    doc = json.loads(render_sarif(result, ROOT))
    doc["runs"][0]["results"][0]["locations"][0]["physicalLocation"]["region"]["startLine"] = 0
    with pytest.raises(AssertionError):
        validate_sarif(doc)
    with pytest.raises(AssertionError):
        validate_sarif({"version": "2.1.0"})


# -- GitHub annotations ------------------------------------------------------------------------


def test_github_escapes() -> None:
    assert escape_data("50% done\r\nnext: a, b") == "50%25 done%0D%0Anext: a, b"
    assert escape_property("dir,a/b:c%") == "dir%2Ca/b%3Ac%25"


def _unescape(text: str) -> str:
    for raw, esc in (("\r", "%0D"), ("\n", "%0A"), (":", "%3A"), (",", "%2C"), ("%", "%25")):
        text = text.replace(esc, raw)
    return text


@given(st.text())
def test_github_escape_round_trips_and_leaves_no_separator(text: str) -> None:
    prop = escape_property(text)
    assert not any(c in prop for c in "\r\n:,")
    assert _unescape(prop) == text
    data = escape_data(text)
    assert "\n" not in data and "\r" not in data


def test_github_one_line_per_finding(result: LintResult) -> None:
    lines = render_github(result, ROOT).splitlines()
    assert len(lines) == len(result.findings)
    assert all(ln.startswith("::warning file=tests/lint/data/bay.mtask,line=") for ln in lines)


def test_sarif_uris_are_valid_uris(tmp_path: Path) -> None:
    """Spaces, `%`, `,`, `:` and `#` in a folder name are escaped, so the URI reads back as the
    same path; a file outside the root is a file:// URI of its own, with no base."""
    from urllib.parse import unquote, urlsplit

    from mtlc.lint.output import artifact_location

    weird = "we ird%2C,:#dir/a b%20,c:#.mtask"
    inside = artifact_location(weird, tmp_path)
    assert inside == {
        "uri": "we%20ird%252C%2C%3A%23dir/a%20b%2520%2Cc%3A%23.mtask",
        "uriBaseId": "%SRCROOT%",
    }
    parts = urlsplit(inside["uri"])
    assert (parts.scheme, parts.fragment, unquote(parts.path)) == ("", "", weird)
    assert artifact_location(str(tmp_path / weird), tmp_path)["uri"] == inside["uri"]
    outside = artifact_location("/elsewhere/x y.mtask", tmp_path)
    assert outside == {"uri": "file:///elsewhere/x%20y.mtask"}
    assert artifact_location("../up.mtask", tmp_path / "root") == {
        "uri": (tmp_path / "up.mtask").as_uri()
    }
    assert artifact_location("bad\udcffname.mtask", tmp_path)["uri"] == "bad%FFname.mtask"


def test_merge_keeps_the_reported_order_of_one_manikins_details() -> None:
    """Two findings of one manikin that merge (the same reach short at two times) are named in
    the order reported, not in a set's order, which changes with the process's hash seed."""
    span = Span("a.mtask", 3, 5, 3, 9)
    details = [f"the hand cannot reach site `s0`: {n} mm short" for n in (90, 10, 55, 7, 3, 41)]
    findings = [
        Finding("MT0501", d, span, manikins=(m,), details=(d,))
        for m in ("gb:female:5", "gb:male:95")
        for d in details
    ]
    (merged,) = merge(findings, ["gb:female:5", "gb:male:95"])
    assert merged.manikins == ("gb:female:5",) * 6 + ("gb:male:95",) * 6
    assert list(merged.details) == details + details
