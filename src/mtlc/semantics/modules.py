"""Find, read and parse the modules a file uses, through the search path.

``use stdlib.actions`` reads the standard library; ``use bay.scenes`` reads ``bay/scenes.mtask``
from the using file's own folder or an ``-I`` folder, in that order. A module is read once. A
`use` may not leave its search root (a symlink pointing elsewhere is refused), cycles and missing
modules are diagnostics.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from mtlc.diagnostics import DiagnosticSink, Span
from mtlc.diagnostics.suggest import did_you_mean
from mtlc.resources import stdlib_dir
from mtlc.syntax import ast, parse_module

MAX_FILE_BYTES = 8 * 1024 * 1024
STDLIB_PREFIX = "stdlib"
STDLIB_DISPLAY = "<stdlib>"


@dataclass
class LoadedModule:
    display: str  # the name diagnostics use for the file
    path: Path
    tree: ast.Module
    imports: list[tuple[ast.Use, LoadedModule]] = field(default_factory=list)
    is_stdlib: bool = False
    failed_use: bool = False  # a `use` here was not loaded: unknown names may come from it


def display_name(path: Path) -> str:
    """A stable, readable name: stdlib files as <stdlib>/x.mtask, others relative to the cwd."""
    real = path.resolve()
    try:
        return f"{STDLIB_DISPLAY}/{real.relative_to(stdlib_dir().resolve()).as_posix()}"
    except ValueError:
        pass
    try:
        return real.relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return real.as_posix()


class InputRefused(Exception):
    """An input that is not read: a folder (MT0001), not a regular file (MT0004), too large
    (MT0003). ``str(exc)`` is the message, ``help`` the fix."""

    def __init__(self, code: str, message: str, help: str) -> None:
        super().__init__(message)
        self.code = code
        self.help = help


def probe(path: Path, test: Callable[[Path], bool]) -> bool:
    """``test(path)`` (``Path.is_file``, ``is_dir``, ``exists``), False where the system cannot
    look the path up at all (a name too long for it, ENAMETOOLONG): reading it then says why."""
    try:
        return test(path)
    except OSError:
        return False


def read_input_bytes(path: Path | str, limit: int | None = None) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (default MAX_FILE_BYTES);
    InputRefused or OSError otherwise.

    The file is opened without blocking (a FIFO with no writer would block the open), checked
    with fstat on the open descriptor (no race with a rename), and read with a bound even if it
    grows: `/dev/zero`, a pipe or a socket is refused before a byte is read.
    """
    limit = MAX_FILE_BYTES if limit is None else limit
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputRefused(
                "MT0001",
                "cannot read file: it is a folder",
                "pass the .mtask files inside it, for example `folder/*.mtask`",
            )
        if not stat.S_ISREG(info.st_mode):
            raise InputRefused(
                "MT0004",
                f"not a regular file ({_file_kind(info.st_mode)}): mtlc reads only files",
                "save the text to a file and pass that file's name",
            )
        if info.st_size > limit:
            raise _too_large(info.st_size, limit)
        with os.fdopen(fd, "rb", buffering=0, closefd=False) as f:
            data = _read_at_most(f, limit + 1)
        if len(data) > limit:  # it grew while it was read
            raise _too_large(None, limit)
        return data
    finally:
        os.close(fd)


def read_source(path: Path, display: str, sink: DiagnosticSink) -> str | None:
    """The file's text, or None after reporting why it cannot be had (MT0001-MT0004)."""
    try:
        data = read_input_bytes(path)
    except InputRefused as exc:
        sink.report(exc.code, str(exc), Span.whole_file(display), help=exc.help)
        return None
    except OSError as err:
        sink.report(
            "MT0001",
            f"cannot read file: {err.strerror or err}",
            Span.whole_file(display),
            help=_unreadable_help(err),
        )
        return None
    return decode_source(data, display, sink)


def decode_source(data: bytes, display: str, sink: DiagnosticSink) -> str | None:
    """A file's bytes as text (a UTF-8 byte-order mark dropped), or None after MT0002."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        before = data[: err.start].decode("utf-8", errors="replace")
        line = before.count("\n") + 1
        col = len(before) - (before.rfind("\n") + 1) + 1
        sink.report(
            "MT0002",
            f"file is not valid UTF-8 (byte 0x{data[err.start]:02x} at offset {err.start})",
            Span(display, line, col, line, col + 1, len(before), len(before) + 1),
            help="save the file as UTF-8",
        )
        return None
    return text.removeprefix("\ufeff")


def _read_at_most(f: BinaryIO, limit: int) -> bytes:
    chunks: list[bytes] = []
    size = 0
    while size < limit:
        chunk = f.read(min(1 << 20, limit - size))
        if not chunk:
            break
        chunks.append(chunk)
        size += len(chunk)
    return b"".join(chunks)


def read_bounded_stream(stream: BinaryIO, display: str, sink: DiagnosticSink) -> bytes | None:
    """At most MAX_FILE_BYTES of a stream (standard input), or None after MT0003."""
    data = _read_at_most(stream, MAX_FILE_BYTES + 1)
    if len(data) > MAX_FILE_BYTES:
        exc = _too_large(None, MAX_FILE_BYTES)
        sink.report(exc.code, str(exc), Span.whole_file(display), help=exc.help)
        return None
    return data


def _too_large(size: int | None, limit: int) -> InputRefused:
    what = f"file is {size:,} bytes" if size is not None else "file is larger than the limit"
    return InputRefused(
        "MT0003",
        f"{what}; mtlc reads at most {limit:,}",
        "check that this is the right file; split a large procedure into modules joined with `use`",
    )


def _file_kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a pipe"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a special file"


def _unreadable_help(err: OSError) -> str | None:
    if err.errno == errno.ENOENT:
        return "check the path and the current folder"
    if err.errno in (errno.EACCES, errno.EPERM):
        return "make the file readable"
    if err.errno == errno.ENAMETOOLONG:
        return "use a shorter path"
    return None


_PARSED: dict[tuple[str, str], ast.Module] = {}  # (file name, text) -> its clean parse
_PARSED_MAX = 16


def _parse(text: str, display: str, sink: DiagnosticSink) -> ast.Module:
    """``parse_module``, remembering the last few files that parse without a diagnostic: the
    standard library is read by almost every program, and a tree is immutable, so programs
    (a server's recompiles, a test suite, a fuzzer) can share it. Keyed by the text itself."""
    key = (display, text)
    tree = _PARSED.get(key)
    if tree is not None:
        return tree
    local = DiagnosticSink()
    tree = parse_module(text, display, local)
    sink.items.extend(local.items)
    if not local.items:
        if len(_PARSED) >= _PARSED_MAX:
            _PARSED.pop(next(iter(_PARSED)))
        _PARSED[key] = tree
    return tree


class ModuleLoader:
    def __init__(self, include_dirs: list[Path], sink: DiagnosticSink) -> None:
        self.include_dirs = [d for d in include_dirs]
        self.sink = sink
        self.sources: dict[str, str] = {}
        self.modules: dict[Path, LoadedModule] = {}  # by real path, in load order
        self._loading: list[Path] = []

    def load_root(self, path: Path) -> LoadedModule | None:
        return self._load(path, is_stdlib=False)

    def _load(self, path: Path, *, is_stdlib: bool) -> LoadedModule | None:
        real = path.resolve()
        if real in self.modules:
            return self.modules[real]
        display = display_name(path)
        text = read_source(path, display, self.sink)
        if text is None:
            tree = ast.Module(
                span=Span.whole_file(display), path=display, uses=(), decls=(),
                broken_names=frozenset({"*"}),
            )  # fmt: skip
        else:
            self.sources[display] = text
            tree = _parse(text, display, self.sink)
        module = LoadedModule(display, real, tree, is_stdlib=is_stdlib)
        self.modules[real] = module
        self._loading.append(real)
        for use in tree.uses:
            target = self._resolve_use(use, real.parent)
            if target is None:
                module.failed_use = True
                continue
            if target.resolve() in self._loading:
                cycle = [*self._loading[self._loading.index(target.resolve()) :], target.resolve()]
                chain = " → ".join(display_name(p) for p in cycle)
                self.sink.report(
                    "MT0204",
                    f"modules use each other in a cycle: {chain}",
                    use.module_span,
                    help="move what both need into a third module that both use",
                )
                module.failed_use = True
                continue
            child = self._load(target, is_stdlib=is_stdlib or self._is_stdlib_use(use))
            if child is not None:
                module.imports.append((use, child))
        self._loading.pop()
        return module

    @staticmethod
    def _is_stdlib_use(use: ast.Use) -> bool:
        return use.module[0] == STDLIB_PREFIX

    def _roots(self, own_dir: Path) -> list[Path]:
        roots = [own_dir, *self.include_dirs]
        seen: list[Path] = []
        for r in roots:
            if r.resolve() not in seen:
                seen.append(r.resolve())
        return seen

    def _resolve_use(self, use: ast.Use, own_dir: Path) -> Path | None:
        parts = use.module
        if parts[0] == STDLIB_PREFIX:
            roots, rel = [stdlib_dir().resolve()], parts[1:]
        else:
            roots, rel = self._roots(own_dir), parts
        dotted = ".".join(parts)
        if not rel:
            self.sink.report(
                "MT0203",
                f"`{dotted}` names the standard library itself, not one of its modules",
                use.module_span,
                help="use a module of it, for example `use stdlib.actions`",
            )
            return None
        relpath = Path(*rel[:-1], rel[-1] + ".mtask")
        for root in roots:
            candidate = root / relpath
            try:
                found = candidate.is_file()
                real = candidate.resolve() if found else candidate
            except OSError as err:  # a name too long for the file system, a loop of links
                self.sink.report(
                    "MT0203",
                    f"module `{_shortened(dotted)}` cannot be looked up: {err.strerror or err}",
                    use.module_span,
                    help="module names are file and folder names: keep each part under 255 "
                    "bytes and the whole path short"
                    if err.errno == errno.ENAMETOOLONG
                    else f"searched in: {display_name(root)}",
                )
                return None
            if found:
                if not real.is_relative_to(root):
                    self.sink.report(
                        "MT0205",
                        f"module `{dotted}` resolves to {real.as_posix()}, outside its search "
                        f"folder {root.as_posix()}",
                        use.module_span,
                        help="copy the module into a search folder, or add its folder with -I",
                    )
                    return None
                return candidate
        known = []
        for root in roots:
            with contextlib.suppress(OSError):
                known += [p.stem for p in root.glob("*.mtask")]
        if parts[0] == STDLIB_PREFIX:
            known = [f"{STDLIB_PREFIX}.{k}" for k in known]
        where = ", ".join(display_name(r) for r in roots)
        self.sink.report(
            "MT0203",
            f"module `{_shortened(dotted)}` not found",
            use.module_span,
            help=did_you_mean(dotted, known) or f"searched in: {where}",
        )
        return None


def _shortened(name: str, limit: int = 80) -> str:
    """A name for a message: a very long one is cut in the middle."""
    return name if len(name) <= limit else f"{name[: limit // 2]}…{name[-limit // 2 :]}"
