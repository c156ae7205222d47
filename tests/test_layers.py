"""Imports go one way, down the layers (docs/architecture.md's rule, the developers' guide):
cli -> commands -> passes -> semantics, metrics, codegen -> syntax, ir -> body.

Every ``import`` and ``from ... import`` of every module under src/mtlc (at module level or
inside a function: a lazy import is still a dependency) is read with ``ast``; an import from
a higher layer than the importer's is a failure naming both.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

# The layer of each top-level package or module of mtlc: lower numbers sit higher.
LAYERS: dict[str, int] = {
    "mtlc.cli": 0,
    "mtlc.__main__": 0,
    # commands: what one `mtlc` command runs
    "mtlc.preview": 1,
    "mtlc.report": 1,
    "mtlc.lint": 1,
    "mtlc.fmt": 1,
    "mtlc.executor": 1,
    "mtlc.output": 1,
    "mtlc.frontend": 1,
    "mtlc.passes": 2,
    "mtlc.semantics": 3,
    "mtlc.metrics": 3,
    "mtlc.codegen": 3,
    "mtlc.ergonomics": 3,
    "mtlc.geometry": 3,
    "mtlc.loads": 3,
    "mtlc.syntax": 4,
    "mtlc.ir": 4,
    "mtlc.diagnostics": 5,
    "mtlc.body": 5,
    "mtlc.jsontext": 6,
    "mtlc.resources": 6,
    "mtlc.data": 6,
    "mtlc": 6,
}
# Entry points that call the command line on purpose (``python -m mtlc.preview``).
ENTRY_POINTS = {"mtlc.preview.__main__"}


def _package(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2])


def _imports(path: Path, module: str) -> list[tuple[str, int]]:
    """(imported module, line) for every mtlc import in the file."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ""
            found.append((name, node.lineno))
        elif isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
    return [(name, line) for name, line in found if name.split(".")[0] == "mtlc"]


def _modules() -> list[tuple[str, Path]]:
    out = []
    for path in sorted((SRC / "mtlc").rglob("*.py")):
        module = ".".join(path.with_suffix("").relative_to(SRC).parts)
        out.append((module.removesuffix(".__init__"), path))
    return out


def test_every_package_has_a_layer() -> None:
    unknown = {_package(m) for m, _ in _modules()} - set(LAYERS)
    assert not unknown, f"give these packages a layer in tests/test_layers.py: {sorted(unknown)}"


def upward_imports(module: str, path: Path) -> list[str]:
    """Each import of ``module`` (read from ``path``) from a higher layer than its own."""
    here = _package(module)
    return [
        f"{module} line {line}: {name} (layer {LAYERS[_package(name)]}) from {here} "
        f"(layer {LAYERS[here]})"
        for name, line in _imports(path, module)
        if _package(name) != here and LAYERS[_package(name)] < LAYERS[here]
    ]


def test_imports_go_down_the_layers() -> None:
    upward = [
        line
        for module, path in _modules()
        if module not in ENTRY_POINTS
        for line in upward_imports(module, path)
    ]
    assert not upward, "imports upward:\n" + "\n".join(upward)


def test_an_upward_import_is_found(tmp_path: Path) -> None:
    """The check can fail: body importing a pass, lazily inside a function, is caught."""
    path = tmp_path / "fake.py"
    path.write_text("def f():\n    from ..passes import tool\n", encoding="utf-8")
    (found,) = upward_imports("mtlc.body.fake", path)
    assert "mtlc.passes" in found and "line 2" in found
