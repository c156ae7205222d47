"""Find, read and parse the modules a file uses, through the search path.

``use stdlib.actions`` reads the standard library; ``use bay.scenes`` reads ``bay/scenes.mtask``
from the using file's own folder or an ``-I`` folder, in that order. A module is read once. A
`use` may not leave its search root (a symlink pointing elsewhere is refused), cycles and missing
modules are diagnostics.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from pathlib import Path

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


def read_source(path: Path, display: str, sink: DiagnosticSink) -> str | None:
    """The file's text, or None after reporting why it cannot be had."""
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            sink.report(
                "MT0003",
                f"file is {size:,} bytes; mtlc reads at most {MAX_FILE_BYTES:,}",
                Span.whole_file(display),
            )
            return None
        data = path.read_bytes()
    except OSError as err:
        sink.report("MT0001", f"cannot read file: {err.strerror or err}", Span.whole_file(display))
        return None
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
            tree = parse_module(text, display, self.sink)
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
            if candidate.is_file():
                real = candidate.resolve()
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
            f"module `{dotted}` not found",
            use.module_span,
            help=did_you_mean(dotted, known) or f"searched in: {where}",
        )
        return None
