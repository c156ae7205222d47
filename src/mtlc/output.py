"""Write output files as one transaction: the set is all old or all new, even after a SIGKILL.

Every command that writes files goes through ``write_outputs``, so a file that cannot be written
is reported the same way everywhere: one line naming it, exit 2, nothing changed.

How (docs/output-files.md): under an exclusive ``flock`` of each folder written into, every new
file is written into a fresh staging folder ``.mtlc-stage-<random>`` beside its target, with a
hard link to each file it replaces. The rename of ``journal.json`` into the (first) staging
folder is the commit point; then each staged file is renamed over its target and the staging
folders are removed. The next write into the folder recovers whatever a kill left: a staging
folder with a journal is rolled forward (or, if a failing rename had begun undoing it, back),
one without is thrown away, and so are the `.NAME.XXXXXXXX.tmp` / `.old` files of the former
scheme.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import secrets
import shutil
import stat
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from mtlc.diagnostics.render import terminal_safe
from mtlc.jsontext import escape_surrogates

EXIT_USAGE = 2
LOCK_TIMEOUT_S = 30.0  # a second write into a folder waits this long for the first, then fails
STAGE_PREFIX = ".mtlc-stage-"
JOURNAL = "journal.json"  # in the first staging folder; its rename is the commit point
PRIMARY = "primary"  # in every other staging folder: the path of the one with the journal
_FORMER_TEMP = re.compile(r"^\.(?P<name>.+)\.(?:[a-z0-9_]{8}\.tmp|[0-9a-f]{12}\.old)$")


class OutputError(Exception):
    """An output could not be written; every existing file is as it was."""

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f"cannot write {path}: {reason}; nothing was written")
        self.path = path


@dataclass
class _Entry:
    staged: Path  # the new content, in the staging folder beside the target
    target: Path  # where it goes (a symlink's resolved file)
    backup: Path | None  # a hard link to the file it replaces (None: a new file)

    def as_dict(self) -> dict[str, str | None]:
        backup = None if self.backup is None else os.fsdecode(self.backup)
        return {"staged": os.fsdecode(self.staged), "target": os.fsdecode(self.target),
                "backup": backup}  # fmt: skip

    @staticmethod
    def from_dict(d: dict[str, str | None]) -> _Entry:
        backup = d.get("backup")
        return _Entry(Path(str(d["staged"])), Path(str(d["target"])),
                      None if backup is None else Path(backup))  # fmt: skip


# A file name must not hold what a terminal or a file manager would obey or reorder: controls
# (a newline splits `ls` output), DEL, C1, bidi controls (U+202E shows `gnp.exe` as `exe.png`),
# line separators; nor a path separator.
_UNSAFE_IN_NAME = re.compile(
    "[\x00-\x1f\x7f-\x9f/\\\\\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]"
)


def safe_file_name(name: str) -> str:
    """``name`` (an output's file name, made of a source's stem and a task's name) with each
    unsafe character percent-encoded as its UTF-8 bytes: a newline is ``%0A``, U+202E
    ``%E2%80%AE``, ``/`` ``%2F``. Everything else (Chinese, accents, a lone surrogate standing
    for a non-UTF-8 byte) is kept. Deterministic; a name that already reads ``%0A`` could meet
    an encoded one, which the caller refuses as a collision (docs/output-files.md)."""
    return _UNSAFE_IN_NAME.sub(
        lambda m: "".join(f"%{b:02X}" for b in m.group().encode("utf-8")), name
    )


def write_outputs(files: dict[Path, str | bytes], command: str = "mtlc") -> int | None:
    """Write every file, or report (to stderr) why not and return exit code 2; None on success."""
    try:
        write_all_or_nothing(files)
    except OutputError as exc:
        sys.stderr.write(f"{command}: {terminal_safe(str(exc))}\n")
        return EXIT_USAGE
    return None


def write_all_or_nothing(files: dict[Path, str | bytes]) -> None:
    """Write every file, or (if one write fails) leave every existing file as it was; after a
    kill at any point, the next write into the folder completes or undoes this one.

    A symlink is written through (its target gets the content) and a replaced file keeps its
    mode. Two writes into one folder are serialised (``flock``, ``LOCK_TIMEOUT_S``).
    """
    if not files:
        return
    targets = {path: Path(os.path.abspath(_target(path))) for path in files}
    for path, target in targets.items():
        _check_writable(path, target)
    folders: dict[Path, Path] = {}  # folder -> the first path the user named in it
    for path, target in targets.items():
        folders.setdefault(target.parent, path)
    for folder, path in folders.items():
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(path, _reason(exc)) from exc
    ordered = sorted(folders, key=os.fsencode)  # one order for every writer: no deadlock
    with _locked(ordered, folders) as locked:
        for folder in ordered:
            if folder in locked:  # unlocked, another writer's staging folder could be live
                recover(folder, keep={t.name for t in targets.values() if t.parent == folder})
        _Transaction(ordered, folders).run(files, targets)


def recover(folder: Path, keep: set[str] | frozenset[str] = frozenset()) -> None:
    """Finish or undo what a killed write left in ``folder`` (the caller holds its lock).

    A staging folder whose transaction committed (its journal, or its primary's, exists) is
    rolled forward; any other is removed. Temporaries of the former scheme
    (``.NAME.XXXXXXXX.tmp``, ``.NAME.<12 hex>.old``) are removed when NAME exists or is in
    ``keep``: a name of that shape is never removed blindly from a folder of sources.
    """
    try:
        names = os.listdir(folder)
    except OSError:
        return
    for name in names:
        path = folder / name
        if name.startswith(STAGE_PREFIX) and path.is_dir() and not path.is_symlink():
            journal = path / JOURNAL
            pointer = path / PRIMARY
            if journal.exists():
                _finish(journal)
            elif pointer.exists():  # the journal is in another folder: finish it there
                primary = Path(os.fsdecode(pointer.read_bytes()))
                if (primary / JOURNAL).exists() and not _finish_elsewhere(primary):
                    continue  # that folder is busy: its next write (or ours) finishes it
            shutil.rmtree(path, ignore_errors=True)
        elif (
            (m := _FORMER_TEMP.match(name))
            and path.is_file()
            and (m["name"] in keep or (folder / m["name"]).exists())
        ):
            path.unlink(missing_ok=True)


def _step() -> None:
    """Called before every change to the file system: the crash tests kill the process here."""


class _Transaction:
    """One write: stage, commit (the journal's rename), apply, clean up."""

    def __init__(self, ordered: list[Path], named: dict[Path, Path]) -> None:
        token = secrets.token_hex(6)
        self.named = named
        self.stages = {folder: folder / f"{STAGE_PREFIX}{token}" for folder in ordered}
        self.primary = self.stages[ordered[0]]
        self.entries: list[_Entry] = []
        self.asked: dict[Path, Path] = {}  # target -> the path as the user named it
        self.settled = True  # False from the commit until every file is new (or old) again

    def run(self, files: dict[Path, str | bytes], targets: dict[Path, Path]) -> None:
        try:
            self._stage(files, targets)
            self._commit()
            self._apply()
        finally:
            if self.settled:  # else (an interrupt mid-apply) the next write finishes it
                self._clean()

    def _stage(self, files: dict[Path, str | bytes], targets: dict[Path, Path]) -> None:
        for folder, stage in self.stages.items():
            try:
                _step()
                stage.mkdir()
                if stage != self.primary:
                    _write(stage / PRIMARY, os.fsencode(self.primary), 0o600)
            except OSError as exc:
                raise OutputError(self.named[folder], _reason(exc)) from exc
        for k, (path, data) in enumerate(files.items()):
            target = targets[path]
            self.asked[target] = path
            stage = self.stages[target.parent]
            raw = data.encode("utf-8") if isinstance(data, str) else data
            entry = _Entry(stage / f"{k}.new", target, None)
            try:
                _step()
                _write(entry.staged, raw, _mode_for(target))
                if target.exists():
                    entry.backup = stage / f"{k}.old"
                    _step()
                    _link_or_copy(target, entry.backup)
            except OSError as exc:
                raise OutputError(path, _reason(exc)) from exc
            self.entries.append(entry)
        for stage in self.stages.values():
            _fsync_dir(stage)

    def _commit(self) -> None:
        """The commit point: after this rename the new set is what the folder will hold."""
        self._journal("forward")
        self.settled = False  # (cleaning before any rename is safe: the set stays all old)

    def _journal(self, state: str) -> None:
        doc = {"version": 1, "state": state, "entries": [e.as_dict() for e in self.entries]}
        tmp = self.primary / f"{JOURNAL}.tmp"
        tmp.unlink(missing_ok=True)
        try:
            _step()
            _write(tmp, escape_surrogates(json.dumps(doc)).encode("utf-8"), 0o600)
            _step()
            os.replace(tmp, self.primary / JOURNAL)
            _fsync_dir(self.primary)
        except OSError as exc:
            raise OutputError(self.asked[self.entries[0].target], _reason(exc)) from exc

    def _apply(self) -> None:
        for entry in self.entries:
            try:
                _step()
                os.replace(entry.staged, entry.target)
            except OSError as exc:
                self._undo()
                raise OutputError(self.asked[entry.target], _reason(exc)) from exc
        for folder in self.stages:
            _fsync_dir(folder)
        self.settled = True

    def _undo(self) -> None:
        """A rename failed after the commit: mark the journal "back" and put every file back
        (if that fails too, the journal stays and the next write finishes undoing)."""
        self._journal("back")
        for entry in reversed(self.entries):
            _roll(entry, "back")
        self.settled = True

    def _clean(self) -> None:
        """Remove the staging folders, the primary (with the journal) last."""
        for stage in sorted(self.stages.values(), key=lambda s: s == self.primary):
            _step()
            shutil.rmtree(stage, ignore_errors=True)


def _finish(journal: Path) -> None:
    """Roll a committed transaction forward (or back, if it was being undone), then remove its
    other staging folders; idempotent, so a kill during recovery is recovered the same way."""
    try:
        doc = json.loads(journal.read_text(encoding="utf-8"))
        entries = [_Entry.from_dict(d) for d in doc["entries"]]
        state = doc["state"]
    except (OSError, ValueError, KeyError, TypeError):
        return  # not a journal mtlc wrote: the staging folder is removed, nothing applied
    if state not in ("forward", "back") or not all(_contained(e) for e in entries):
        return  # a journal that would move files elsewhere is not one mtlc wrote
    for entry in entries if state == "forward" else reversed(entries):
        _roll(entry, state)
    for entry in entries:
        if entry.staged.parent != journal.parent:
            shutil.rmtree(entry.staged.parent, ignore_errors=True)


def _finish_elsewhere(primary: Path) -> bool:
    """Finish the transaction whose journal is in ``primary`` (a staging folder in another
    folder) if that folder's lock is free, and remove its staging folder; False if busy."""
    if not primary.name.startswith(STAGE_PREFIX):
        return True  # not a pointer mtlc wrote: this staging folder is removed
    try:
        fd = os.open(primary.parent, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return False
    try:
        _finish(primary / JOURNAL)
        shutil.rmtree(primary, ignore_errors=True)
    finally:
        os.close(fd)
    return True


def _contained(entry: _Entry) -> bool:
    """Whether an entry only moves files between a staging folder and the folder holding it:
    a journal planted in a shared folder cannot make a recovery overwrite files elsewhere."""
    stage = entry.staged.parent
    return (
        stage.name.startswith(STAGE_PREFIX)
        and stage.parent == entry.target.parent
        and (entry.backup is None or entry.backup.parent == stage)
        and ".." not in entry.staged.parts + entry.target.parts
    )


def _roll(entry: _Entry, state: str) -> None:
    """Forward: the staged file into place, if not there yet. Back: the old file into place
    (its hard link), or a file that was new removed."""
    if state == "forward":
        if entry.staged.exists():
            _step()
            os.replace(entry.staged, entry.target)
    elif entry.backup is not None:
        if entry.backup.exists():
            _step()
            os.replace(entry.backup, entry.target)
    elif not entry.staged.exists():  # it was placed
        _step()
        entry.target.unlink(missing_ok=True)


@contextmanager
def _locked(folders: list[Path], named: dict[Path, Path]) -> Iterator[set[Path]]:
    """An exclusive ``flock`` on each folder itself (no lock file is left among the outputs),
    waiting at most ``LOCK_TIMEOUT_S`` for another mtlc writing there; yields the folders
    locked (a file system without ``flock`` is written unserialised)."""
    fds: list[int] = []
    locked: set[Path] = set()
    try:
        for folder in folders:
            try:
                fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
            except OSError as exc:
                raise OutputError(named[folder], _reason(exc)) from exc
            fds.append(fd)
            deadline = time.monotonic() + LOCK_TIMEOUT_S
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    locked.add(folder)
                    break
                except BlockingIOError:
                    if time.monotonic() >= deadline:
                        raise OutputError(
                            named[folder],
                            f"another mtlc has been writing into {folder} for "
                            f"{LOCK_TIMEOUT_S:g} s; run again when it has finished",
                        ) from None
                    time.sleep(0.05)
                except OSError:  # a file system without locks: write unserialised
                    break
        yield locked
    finally:
        for fd in fds:
            os.close(fd)


def _write(path: Path, raw: bytes, mode: int) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        path.unlink(missing_ok=True)
        raise


def _link_or_copy(target: Path, backup: Path) -> None:
    try:
        os.link(target, backup)
    except OSError:  # a file system without hard links
        shutil.copy2(target, backup)


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


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


def _mode_for(target: Path) -> int:
    """An existing file keeps its permissions; a new one is an ordinary file (0666 - umask)."""
    try:
        return stat.S_IMODE(target.stat().st_mode)
    except OSError:
        return 0o666 & ~_umask()


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
