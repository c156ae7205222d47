"""Generators: the solved IR to the files a user takes away.

Each target is a function of finished IRs (every pass run, frames sampled) to text; this module
names the targets, decides the output file names, and keeps the CLI free of generator detail.
JackScript is one module per `.mtask` file (one function per task, as the seed's host program
imports it); BVH and the IR's JSON are one file per task.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from mtlc.codegen.bvh import emit_bvh
from mtlc.codegen.jackscript import emit_jackscript, function_name
from mtlc.ir.model import MotionIR
from mtlc.ir.serialize import to_json
from mtlc.jsontext import escape_surrogates

MOTION_TARGETS = ("jackscript", "bvh", "ir")
TARGET_CHOICES = (*MOTION_TARGETS, "all", "timeline")
DEFAULT_TARGET = "jackscript"
TA_MODES = ("keyframes", "jack")


@dataclass(frozen=True)
class GenerateOptions:
    targets: tuple[str, ...] = (DEFAULT_TARGET,)
    ta: str = "keyframes"  # TA segments as explicit keyframes, or as Jack reach commands
    source_map: bool = False  # also write <module>.py.map.json beside each script


def expand_target(target: str) -> tuple[str, ...]:
    return MOTION_TARGETS if target == "all" else (target,)


def python_module_name(stem: str) -> str:
    """A name `import NAME` accepts, from a file's stem: Jack's host imports the script by name.

    ASCII and never a keyword or `js`, by the same rule as the task functions inside it; never
    a standard-library module either, which `import` would find first (`os.mtask` is `os_.py`).
    """
    name = function_name(stem, set())
    return f"{name}_" if name in sys.stdlib_module_names else name


def generate_file(
    stem: str, irs: Sequence[MotionIR], options: GenerateOptions
) -> dict[str, str | bytes]:
    """Every output of one `.mtask` file's tasks, by file name (relative to the output folder)."""
    out: dict[str, str | bytes] = {}
    if "jackscript" in options.targets and irs:
        module = python_module_name(stem)
        script = emit_jackscript(irs, ta=options.ta)
        out[f"{module}.py"] = script.text
        if options.source_map:
            source_map = {**script.source_map, "script": f"{module}.py"}
            out[f"{module}.py.map.json"] = (
                escape_surrogates(
                    json.dumps(source_map, ensure_ascii=False, indent=1, sort_keys=True)
                )
                + "\n"
            )
    for ir in irs:
        if "bvh" in options.targets:
            out[f"{stem}.{ir.task}.bvh"] = emit_bvh(ir)
        if "ir" in options.targets:
            out[f"{stem}.{ir.task}.ir.json"] = to_json(ir)
    return out


def stem_of(file: str) -> str:
    return Path(file).stem


__all__ = [
    "DEFAULT_TARGET",
    "MOTION_TARGETS",
    "TARGET_CHOICES",
    "TA_MODES",
    "GenerateOptions",
    "expand_target",
    "generate_file",
    "python_module_name",
    "stem_of",
]
