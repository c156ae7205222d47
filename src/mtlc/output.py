"""Write output files atomically: a reader sees the old files or the new ones, never a mix.

Every command that writes files goes through ``write_outputs``, so a file that cannot be written
is reported the same way everywhere: one line naming it, exit 2, nothing changed.
"""

from __future__ import annotations

import os
import re
import secrets
import shutil
import stat
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

EXIT_USAGE = 2


class OutputError(Exception):
    """An output could not be written; every existing file is as it was."""

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f"cannot write {path}: {reason}; nothing was written")
        self.path = path


@dataclass
class _Staged:
    tmp: str  # the new content, beside the target
    target: Path  # where it goes (a symlink's resolved file)
    backup: str | None = None  # a link to the file it replaces, until all are in place
    placed: bool = False


_SURROGATE = re.compile("[\ud800-\udfff]")


def escape_surrogates(json_text: str) -> str:
    """JSON with each lone surrogate (a byte of a file name that is not UTF-8, as Python decodes
    it) written as a `\\uXXXX` escape: the file is valid UTF-8 and reads back as the same name."""
    return _SURROGATE.sub(lambda m: f"\\u{ord(m.group()):04x}", json_text)


def write_outputs(files: dict[Path, str | bytes], command: str = "mtlc") -> int | None:
    """Write every file, or report (to stderr) why not and return exit code 2; None on success."""
    try:
        write_all_or_nothing(files)
    except OutputError as exc:
        sys.stderr.write(f"{command}: {exc}\n")
        return EXIT_USAGE
    return None


def write_all_or_nothing(files: dict[Path, str | bytes]) -> None:
    """Write every file, or (if one write fails) leave every existing file as it was.

    Each file is staged beside its target first; only when all are staged are they moved into
    place, one rename each, each replaced file kept under a temporary name until the last
    rename has succeeded, so that a failing rename puts every earlier one back. A symlink is
    written through (its target gets the content) and a replaced file keeps its mode.
    """
    targets = {path: _target(path) for path in files}
    for path, target in targets.items():
        _check_writable(path, target)
    staged: list[_Staged] = []
    try:
        for path, data in files.items():
            staged.append(_stage(path, targets[path], data))
        _commit(staged)
    finally:
        for s in staged:
            for leftover in (s.tmp, s.backup):
                if leftover is not None:
                    Path(leftover).unlink(missing_ok=True)


def _target(path: Path) -> Path:
    """The file that ``path`` names: through symlinks, so a link keeps pointing at the output."""
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def _check_writable(path: Path, target: Path) -> None:
    """Refuse before anything is renamed: a folder in the way cannot be replaced by a file."""
    if target.is_dir():
        raise OutputError(path, "it is a folder")
    for parent in target.parents:
        if parent.exists():
            if not parent.is_dir():
                raise OutputError(path, f"{parent} is not a folder")
            break


def _stage(path: Path, target: Path, data: str | bytes) -> _Staged:
    raw = data.encode("utf-8") if isinstance(data, str) else data
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise OutputError(path, _reason(exc)) from exc
    staged = _Staged(tmp, target)
    try:
        os.chmod(tmp, _mode_for(target))  # mkstemp makes 0600
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
            f.flush()
            os.fsync(f.fileno())
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(path, _reason(exc)) from exc
    return staged


def _mode_for(target: Path) -> int:
    """An existing file keeps its permissions; a new one is an ordinary file (0666 - umask)."""
    try:
        return stat.S_IMODE(target.stat().st_mode)
    except OSError:
        return 0o666 & ~_umask()


def _commit(staged: list[_Staged]) -> None:
    """Rename every staged file into place; on any failure put back what was there."""
    try:
        for s in staged:
            s.backup = _keep_old(s.target)
            os.replace(s.tmp, s.target)
            s.placed = True
    except OSError as exc:
        _restore(staged)
        raise OutputError(s.target, _reason(exc)) from exc


def _keep_old(target: Path) -> str | None:
    """A second name for the file about to be replaced (a hard link, else a copy), or None."""
    if not target.exists():
        return None
    backup = str(target.parent / f".{target.name}.{secrets.token_hex(6)}.old")
    try:
        os.link(target, backup)
    except OSError:  # a file system without hard links
        shutil.copy2(target, backup)
    return backup


def _restore(staged: list[_Staged]) -> None:
    for s in reversed(staged):
        if not s.placed:
            continue
        if s.backup is not None:
            os.replace(s.backup, s.target)
            s.backup = None
        else:
            s.target.unlink(missing_ok=True)


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
