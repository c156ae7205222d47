"""`mtlc.output`: all outputs or none, symlinks written through, modes kept, errors as one line."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from mtlc import output
from mtlc.output import OutputError, write_all_or_nothing, write_outputs


def _old_files(tmp_path: Path) -> dict[Path, str]:
    files = {tmp_path / "a.txt": "old a", tmp_path / "b.txt": "old b", tmp_path / "c.txt": "old c"}
    for path, text in files.items():
        path.write_text(text, encoding="utf-8")
    return files


def _contents(tmp_path: Path) -> dict[str, str]:
    return {
        p.name: "<folder>" if p.is_dir() else p.read_text(encoding="utf-8")
        for p in sorted(tmp_path.iterdir())
    }


def test_writes_every_file(tmp_path: Path) -> None:
    files = _old_files(tmp_path)
    write_all_or_nothing({p: f"new {p.stem}" for p in files} | {tmp_path / "d" / "e.txt": b"e"})
    assert _contents(tmp_path) == {
        "a.txt": "new a",
        "b.txt": "new b",
        "c.txt": "new c",
        "d": "<folder>",
    }
    assert (tmp_path / "d" / "e.txt").read_bytes() == b"e"


def test_a_folder_in_the_way_changes_nothing(tmp_path: Path) -> None:
    files = _old_files(tmp_path)
    (tmp_path / "z.txt").mkdir()
    with pytest.raises(OutputError, match=r"z\.txt: it is a folder"):
        write_all_or_nothing({p: "new" for p in files} | {tmp_path / "z.txt": "new"})
    assert _contents(tmp_path) == {
        "a.txt": "old a",
        "b.txt": "old b",
        "c.txt": "old c",
        "z.txt": "<folder>",
    }


def test_a_failing_rename_puts_back_every_earlier_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The third rename fails: the first two files are restored, the new one removed."""
    files = _old_files(tmp_path)
    real_replace = os.replace
    calls = []

    def flaky(src: str, dst: str | Path) -> None:
        calls.append(dst)
        if len(calls) == 3:
            raise PermissionError(13, "Permission denied")
        real_replace(src, dst)

    monkeypatch.setattr(output.os, "replace", flaky)
    new = {tmp_path / "a.txt": "new a", tmp_path / "n.txt": "new n", tmp_path / "b.txt": "new b"}
    with pytest.raises(OutputError, match=r"b\.txt: Permission denied; nothing was written"):
        write_all_or_nothing(new)
    assert _contents(tmp_path) == {"a.txt": "old a", "b.txt": "old b", "c.txt": "old c"}
    assert files  # no temporary or backup file is left (checked by the listing above)


def test_an_existing_file_keeps_its_mode_and_a_new_one_gets_the_umask(tmp_path: Path) -> None:
    private = tmp_path / "p.txt"
    private.write_text("x", encoding="utf-8")
    private.chmod(0o600)
    write_all_or_nothing({private: "y", tmp_path / "new.txt": "z"})
    assert stat.S_IMODE(private.stat().st_mode) == 0o600
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE((tmp_path / "new.txt").stat().st_mode) == 0o666 & ~umask


def test_a_symlink_is_written_through(tmp_path: Path) -> None:
    target = tmp_path / "target.txt"
    target.write_text("old", encoding="utf-8")
    link = tmp_path / "link.txt"
    link.symlink_to("target.txt")
    write_all_or_nothing({link: "new"})
    assert link.is_symlink()
    assert target.read_text(encoding="utf-8") == "new"


def test_write_outputs_reports_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "file").write_text("", encoding="utf-8")
    assert write_outputs({tmp_path / "file" / "x.sarif": "{}"}, "mtlc lint") == 2
    err = capsys.readouterr().err
    assert err.startswith("mtlc lint: cannot write ")
    assert "x.sarif" in err and err.count("\n") == 1
    assert write_outputs({tmp_path / "ok.txt": "ok"}) is None
