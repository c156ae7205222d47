"""Compile with some scene sites moved: what `mtlc serve` does when a site is dragged.

The site's new position must be known while the task expands (MTM times depend on reach and
walk distances), so the substitution happens inside expansion, not on the finished timeline:
the front end runs as usual with its expansion stage swapped for one whose expander reads the
overridden positions. Nothing in the front end changes for other callers.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

from mtlc.frontend import FRONTEND, FrontendOptions, Program
from mtlc.semantics.expand import Expander
from mtlc.semantics.scopes import Symbol
from mtlc.semantics.timeline import Site
from mtlc.syntax import ast

Vec3 = tuple[float, float, float]


class _MovedSitesExpander(Expander):
    """An expander whose scene sites take the given positions (by site name)."""

    moved: Mapping[str, Vec3] = {}

    def _scene_sites(self, sym: Symbol) -> dict[str, Site]:
        sites = super()._scene_sites(sym)
        for name, position in self.moved.items():
            if name in sites and sites[name].position != position:
                sites[name] = replace(sites[name], position=position)
        return sites


def _expand_with(moved: Mapping[str, Vec3]):  # type: ignore[no-untyped-def]
    def expand_tasks(program: Program) -> Program:
        """The front end's expansion stage, with the moved sites."""
        if not program.options.expand or program.sink.has_errors:
            return program
        assert program.checker is not None
        expander = _MovedSitesExpander(
            program.sink,
            program.scopes,
            program.checker.resolved,
            program.checker.callees,
            program.options.expansion_budget,
            program.options.manikin,
        )
        expander.moved = dict(moved)
        for module in program.roots:
            scope = program.scopes[id(module)]
            for decl in module.tree.decls:
                if isinstance(decl, ast.Task) and scope.own.get(decl.name) is not None:
                    timeline = expander.expand_task(decl, scope)
                    if timeline is not None:
                        program.timelines.append(timeline)
        return program

    return expand_tasks


def run_frontend_with_sites(
    paths: list[Path], options: FrontendOptions | None, moved: Mapping[str, Vec3]
) -> Program:
    """``run_frontend``, with the named scene sites at the given positions (metres)."""
    program = Program(list(paths), options or FrontendOptions())
    for name, stage in FRONTEND:
        program = (_expand_with(moved) if name == "expand" else stage)(program)
    return program
