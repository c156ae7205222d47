"""Module-level names: what each module defines and what its `use`s bring in.

One name, one definition: a name defined twice in a module, or defined locally and also
imported, is an error; a name imported from two modules is ambiguous where it is used.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mtlc.diagnostics import DiagnosticSink, Label
from mtlc.semantics.modules import LoadedModule
from mtlc.syntax import ast

KIND_OF = {
    ast.Scene: "scene",
    ast.ToolDecl: "tool",
    ast.Task: "task",
}


def kind_of(decl: ast.Decl) -> str:
    if isinstance(decl, ast.Definition):
        return decl.kind
    return KIND_OF[type(decl)]


@dataclass(frozen=True)
class Symbol:
    name: str
    kind: str  # element, action, task, scene, tool
    decl: ast.Decl
    module: LoadedModule = field(compare=False, hash=False)


@dataclass
class Scope:
    module: LoadedModule
    own: dict[str, Symbol] = field(default_factory=dict)
    names: dict[str, Symbol] = field(default_factory=dict)
    ambiguous: dict[str, list[Symbol]] = field(default_factory=dict)
    # `use a.b` makes `a.b.x` and `b.x` work; None marks a short name two modules share
    aliases: dict[str, Scope | None] = field(default_factory=dict)

    @property
    def broken(self) -> frozenset[str]:
        """Names of items that failed to parse here or in an import: no 'unknown name' for them."""
        out = set(self.module.tree.broken_names)
        if self.module.failed_use:
            out.add("*")
        for _, child in self.module.imports:
            out |= child.tree.broken_names
        return frozenset(out)

    def lookup(self, name: str) -> Symbol | None:
        return self.names.get(name)


def build_scopes(modules: list[LoadedModule], sink: DiagnosticSink) -> dict[int, Scope]:
    scopes: dict[int, Scope] = {}
    for module in modules:
        scope = Scope(module)
        for decl in module.tree.decls:
            sym = Symbol(decl.name, kind_of(decl), decl, module)
            first = scope.own.get(decl.name)
            if first is not None:
                sink.report(
                    "MT0202",
                    f"`{decl.name}` is defined twice in this file",
                    decl.name_span,
                    labels=(Label(first.decl.name_span, "first defined here"),),
                    help="rename one of them",
                )
                continue
            scope.own[decl.name] = sym
        scopes[id(module)] = scope
    for module in modules:
        scope = scopes[id(module)]
        scope.names.update(scope.own)
        for use, child in module.imports:
            child_scope = scopes[id(child)]
            scope.aliases[".".join(use.module)] = child_scope
            short = use.module[-1]
            if short in scope.aliases and scope.aliases[short] is not child_scope:
                scope.aliases[short] = None  # two used modules end in the same name: say the path
            else:
                scope.aliases[short] = child_scope
            for name, sym in child_scope.own.items():
                if sym.kind == "task":
                    continue  # tasks are entry points, not building blocks
                local = scope.own.get(name)
                if local is not None:
                    sink.report(
                        "MT0202",
                        f"`{name}` is already defined by `use {'.'.join(use.module)}`",
                        local.decl.name_span,
                        labels=(Label(sym.decl.name_span, "imported definition"),),
                        help="rename this definition; one name has one definition",
                    )
                    continue
                other = scope.names.get(name)
                if other is not None and other is not sym and other.decl is not sym.decl:
                    scope.ambiguous.setdefault(name, [other]).append(sym)
                    continue
                scope.names[name] = sym
    return scopes
