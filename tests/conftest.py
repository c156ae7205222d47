"""Shared fixtures: golden files (refresh with `pytest --update-goldens`) and helpers.

The motion goldens (``ir/``, ``bvh/``, ``jackscript/``) are compared **to a stated tolerance**,
not byte for byte: the text with every float replaced by a placeholder must be identical (so a
changed word, line, integer, key order or number of values fails), and each float must be within

    |actual - expected| <= GOLDEN_ABS[kind] + GOLDEN_REL * |expected|

of its golden value, ``kind`` being the golden's top folder. The absolute part is two units of the
last digit the generator prints for that kind (docs/ir.md, docs/bvh.md, docs/jackscript.md), so a
value that rounds the other way on a machine with another BLAS build passes, while a change of a
real quantity fails. The other goldens (AST, timeline, lint, report, fmt) involve no linear
algebra and stay byte for byte. Byte identity of the motion outputs on one machine is tested
separately (tests/codegen/test_outputs.py, ``test_every_target_is_byte_identical_on_one_machine``).
"""

from __future__ import annotations

import contextlib
import copy
import difflib
import functools
import hashlib
import os
import pickle
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import pytest
from hypothesis import settings

if TYPE_CHECKING:
    from mtlc.diagnostics import DiagnosticSink
    from mtlc.ir.model import MotionIR
    from mtlc.preview.compile import Compiled
    from mtlc.semantics.timeline import ManikinSpec

# In CI (``CI`` set, as .ci/run sets it) every property test draws the same examples on every run
# (``derandomize``): a run passes or fails for the code, not for the draw. Run locally, the draws
# are random and hypothesis keeps what fails in .hypothesis/ (a random draw found
# semantics.stand's 5 cm boundary, tests/test_stand.py).
settings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI"):
    settings.load_profile("ci")

ROOT = Path(__file__).resolve().parent.parent
T = TypeVar("T")
GOLDENS = Path(__file__).resolve().parent / "goldens"
EXAMPLES = sorted((ROOT / "examples").glob("*.mtask"))
STDLIB = sorted((ROOT / "stdlib").glob("*.mtask"))

# A float as the generators print it: digits with a decimal point and/or an exponent, not part of
# a name (``bolt_1``, ``MT0201``, ``v2``) and not an integer (integers are compared exactly).
FLOAT = re.compile(
    r"(?<![\w.])-?(?:\d+\.\d*(?:[eE][-+]?\d+)?|\d+[eE][-+]?\d+)(?![\w.])",
)
GOLDEN_REL = 1e-9
# Two units of the last printed digit: 0.01 mm and 1e-5 rad in the IR (m, rad), 0.01 mm and
# 0.001 degrees in BVH and JackScript (cm, degrees). Every other golden (AST, timeline, lint,
# report, fmt) is text the compiler computes without linear algebra: compared byte for byte.
GOLDEN_ABS = {"ir": 2e-5, "bvh": 2e-3, "jackscript": 2e-3}


# The slowest test modules (seconds on the 2-core machine, session 23), run first: the workers
# take modules in collection order (``--dist loadfile``), and one of these started last kept one
# worker busy for a minute after the other had finished.
SLOW_MODULES = {
    "passes/test_arm_steps.py": 83, "codegen/test_outputs.py": 56,
    "preview/test_preview_browser.py": 49, "geometry/test_equipment.py": 37,
    "lint/test_access.py": 36, "passes/test_balance_smooth_metrics.py": 34,
    "passes/test_selfcontact.py": 34, "preview/test_preview_server.py": 32,
    "passes/test_locomotion.py": 31, "geometry/test_penetration.py": 29,
    "test_fmt_paths.py": 29, "test_cli.py": 27, "passes/test_posture_ta_to.py": 23,
    "passes/test_fast_paths.py": 23, "codegen/test_jackscript.py": 22, "test_wheel.py": 20,
}  # fmt: skip


def pytest_configure(config: pytest.Config) -> None:
    """Bytecode for the package before any worker or ``mtlc`` subprocess starts: with
    PYTHONDONTWRITEBYTECODE set (as on this machine) nothing writes it, and every process the
    suite starts compiled the package's sources again (0.7 s of each CLI compile's 2.6 s)."""
    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        import compileall

        compileall.compile_dir(ROOT / "src" / "mtlc", quiet=2)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The slowest modules first (``SLOW_MODULES``), each module's tests together and in order."""
    tests = Path(__file__).resolve().parent

    def weight(item: pytest.Item) -> float:
        path = Path(str(item.path))
        name = path.relative_to(tests).as_posix() if path.is_relative_to(tests) else ""
        return -SLOW_MODULES.get(name, 0)

    items.sort(key=weight)  # stable: the rest keep their order


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--update-goldens",
        action="store_true",
        default=False,
        help="rewrite golden files from the current output instead of comparing",
    )


@dataclass(frozen=True)
class Mismatch:
    """Why an output does not match its golden: a line of text, or a float out of tolerance."""

    line: int
    message: str


def compare_tolerant(expected: str, actual: str, abs_tol: float, rel_tol: float) -> list[Mismatch]:
    """Every difference beyond the tolerance: structure exactly, each float within abs + rel."""
    exp_lines, act_lines = expected.splitlines(), actual.splitlines()
    if len(exp_lines) != len(act_lines):
        return [Mismatch(0, f"{len(act_lines)} lines, golden has {len(exp_lines)}")]
    found: list[Mismatch] = []
    for n, (e, a) in enumerate(zip(exp_lines, act_lines, strict=True), start=1):
        if e == a:
            continue
        if FLOAT.sub("#", e) != FLOAT.sub("#", a):
            found.append(Mismatch(n, f"text differs:\n  golden: {e[:200]}\n  actual: {a[:200]}"))
            continue
        for x, y in zip(FLOAT.findall(e), FLOAT.findall(a), strict=True):
            want, got = float(x), float(y)
            if abs(got - want) > abs_tol + rel_tol * abs(want):
                found.append(
                    Mismatch(n, f"{y} differs from the golden {x} by {abs(got - want):.3g}")
                )
    return found


class Golden:
    def __init__(self, update: bool, root: Path = GOLDENS) -> None:
        self.update = update
        self.root = root

    def check(self, relpath: str, actual: str) -> None:
        path = self.root / relpath
        if self.update:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(actual, encoding="utf-8")
            return
        if not path.exists():
            pytest.fail(f"golden file {relpath} is missing: run pytest --update-goldens")
        expected = path.read_text(encoding="utf-8")
        if actual == expected:
            return
        abs_tol = GOLDEN_ABS.get(Path(relpath).parts[0])
        if abs_tol is None:  # text goldens (AST, timeline, lint, fmt...): byte for byte
            found = [Mismatch(0, "text differs")]
        else:
            found = compare_tolerant(expected, actual, abs_tol, GOLDEN_REL)
            if not found:
                return
        diff = "".join(
            list(
                difflib.unified_diff(
                    expected.splitlines(True), actual.splitlines(True), "golden", "actual"
                )
            )[:80]
        )
        first = "\n".join(f"line {m.line}: {m.message}" for m in found[:10])
        within = "" if abs_tol is None else f" beyond {abs_tol:g} + {GOLDEN_REL:g}·|x|"
        pytest.fail(
            f"{relpath} differs from its golden file{within}: {len(found)} difference(s)\n"
            f"{first}\n{diff}"
        )


@pytest.fixture
def golden(request: pytest.FixtureRequest) -> Golden:
    return Golden(request.config.getoption("--update-goldens"))


@pytest.fixture(autouse=True)
def _run_in_repo(monkeypatch: pytest.MonkeyPatch) -> None:
    """Display paths are relative to the cwd: run every test from the checkout's root."""
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("NO_COLOR", "1")


COMPILES = ROOT / ".pytest_cache" / "mtlc-compiles"  # the examples' compiles, shared by workers


@functools.cache
def _code_key() -> str:
    """A digest of everything a compile reads besides its task file: the package's files, the
    standard library, the grammar, Python's and numpy's versions. A cached compile made by
    other code is never read."""
    digest = hashlib.sha256(f"{sys.version} {np.__version__}".encode())
    for base in (ROOT / "src" / "mtlc", ROOT / "stdlib", ROOT / "grammar"):
        _add_tree(digest, base, ROOT)
    return digest.hexdigest()[:24]


def _add_tree(digest: Any, folder: Path, relative_to: Path) -> None:
    """Every file under ``folder`` (its path from ``relative_to``, then its bytes) into
    ``digest``, in a fixed order."""
    for file in sorted(folder.rglob("*")):
        if file.is_file() and "__pycache__" not in file.parts:
            digest.update(file.relative_to(relative_to).as_posix().encode() + b"\0")
            digest.update(file.read_bytes())


def shared(name: str, folder: Path, make: Callable[[], T]) -> T:
    """``make()``, made once for the whole run: the test workers share it through a file
    (``COMPILES``) keyed by ``_code_key``, ``name`` and every file under ``folder`` (a task
    file's folder: the task, the files it uses, its models); a worker that finds another making
    it waits for it. Compiles on one machine are identical to the bit, so a shared one is what
    each worker would have made."""
    try:
        import fcntl
    except ImportError:  # no file locks (Windows): each worker makes its own
        return make()
    digest = hashlib.sha256(name.encode())
    _add_tree(digest, folder, folder)
    COMPILES.mkdir(parents=True, exist_ok=True)
    stored = COMPILES / f"{_code_key()}-{digest.hexdigest()[:24]}.pickle"
    with open(stored.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        for stale in COMPILES.glob("*"):  # made by other code: never read again
            if not stale.name.startswith(_code_key()):
                stale.unlink(missing_ok=True)
        if stored.exists():
            with contextlib.suppress(Exception):  # unreadable: made again below
                return pickle.loads(stored.read_bytes())  # type: ignore[no-any-return]
        made = make()
        partial = stored.with_suffix(f".{os.getpid()}.part")
        partial.write_bytes(pickle.dumps(made))
        partial.replace(stored)
        return made


@functools.cache
def _compiled_once(path: Path) -> Compiled:
    """The example compiled with the default options (``shared``: once for the whole run)."""
    from mtlc.frontend import FrontendOptions
    from mtlc.preview.compile import compile_motions

    def compile_it() -> Compiled:
        with contextlib.chdir(ROOT):  # display paths relative to the checkout, as tests run
            return compile_motions([path.relative_to(ROOT)], FrontendOptions())

    return shared(f"compile_motions {path.name}", path.parent, compile_it)


def compiled_example(path: Path) -> Compiled:
    """An example compiled with the default options, once per test process and copied for each
    caller: the BVH, JackScript, replay and preview modules read the same compiles (each module
    compiling every example took 11-13 s of the suite). A copy, so that no module sees what
    another changed."""
    return copy.deepcopy(_compiled_once(path))


def example_ir(path: Path) -> MotionIR:
    """The one task of an example compiled with the default options (``compiled_example``)."""
    (ir,) = compiled_example(path).motions
    return ir


@functools.cache
def _until_once(path: Path, until: str) -> tuple[MotionIR, DiagnosticSink]:
    """``example_until``'s compile, once for the whole run (``shared``)."""
    from mtlc.frontend import run_frontend
    from mtlc.passes import run_motion

    def compile_it() -> tuple[MotionIR, DiagnosticSink]:
        prog = run_frontend([path])
        assert prog.timelines, [d.message for d in prog.diagnostics]
        return run_motion(prog.timelines[0], prog.sink, until=until), prog.sink

    return shared(f"until {until} {path.name}", path.parent, compile_it)


def example_until(path: Path, until: str) -> tuple[MotionIR, DiagnosticSink]:
    """An example's first task compiled with the default options up to the pass ``until``,
    and the sink with the front end's and the passes' diagnostics: once for the whole run
    (test_state_many, test_fast_paths, test_posture_ta_to and test_gaze each compiled the
    examples up to the gaze), and copied for each caller."""
    return copy.deepcopy(_until_once(path, until))


def compile_on(
    path: Path, manikin: ManikinSpec | tuple[str, int] | None = None, *, until: str | None = None
) -> tuple[MotionIR, DiagnosticSink]:
    """A one-task file that checks clean, its motion compiled for one manikin (a spec, or the
    GB 10000-88 sex and percentile; None: the file's own) up to ``until``, with the motion
    passes' diagnostics in a sink of their own."""
    from mtlc.diagnostics import DiagnosticSink
    from mtlc.frontend import run_frontend
    from mtlc.passes import MotionOptions, run_motion
    from mtlc.semantics import schedule
    from mtlc.semantics.timeline import ManikinSpec

    program = run_frontend([path])
    assert not program.sink.has_errors, [d.message for d in program.sink.items]
    (timeline,) = program.timelines
    if isinstance(manikin, tuple):
        manikin = ManikinSpec("gb10000_1988", *manikin)
    if manikin is not None:
        timeline = schedule.for_manikin(timeline, manikin)
    sink = DiagnosticSink()
    return run_motion(timeline, sink, MotionOptions(), until=until), sink


def reach_on_frames(
    ir: MotionIR, site: str, line: int | None = None, effector: str = "r_hand"
) -> tuple[np.ndarray, np.ndarray, float, Any]:
    """A reach's rows of the frames (its TA's start to the end of the TO that continues it, to
    ``site``; ``line``: the task line that asked for it), the ``effector``'s positions on them
    by forward kinematics, the frames' step (s) and the TO segment."""
    from mtlc.body import forward, site_positions

    fr = ir.frames
    assert fr is not None
    (ta,) = [s for s in ir.segments if s.kind == "TA" and s.goal.site == site
             and s.goal.effector == effector
             and (line is None or s.provenance.origin.line == line)]  # fmt: skip
    (to,) = [s for s in ir.segments if s.kind == "TO" and s.goal.site == site
             and s.track == ta.track and abs(s.start - ta.end) < 1e-6]  # fmt: skip
    rows = np.flatnonzero((fr.time >= ta.start - 1e-9) & (fr.time <= to.end + 1e-9))
    pose = forward(ir.skeleton, fr.q[rows], fr.root_position[rows], fr.root_rotation[rows],
                   with_axes=False)  # fmt: skip
    hand = np.asarray(site_positions(ir.skeleton, pose, [effector]))[:, 0]
    return rows, hand, float(np.median(np.diff(fr.time))), to


def hands_apart(ir: MotionIR, rows: np.ndarray) -> np.ndarray:
    """(len(rows),) how far apart the two hands are on the frames' ``rows``: a part held in
    both keeps it."""
    from mtlc.body import forward, site_positions

    fr = ir.frames
    assert fr is not None
    pose = forward(ir.skeleton, fr.q[rows], fr.root_position[rows], fr.root_rotation[rows],
                   with_axes=False)  # fmt: skip
    hands = np.asarray(site_positions(ir.skeleton, pose, ["r_hand", "l_hand"]))
    return np.linalg.norm(hands[:, 0] - hands[:, 1], axis=1)


@functools.cache
def bench_human() -> Any:
    """bench/human.py, the motion bench's own figures (LDLJ, peaks), loaded as a module."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("mtlc_bench_human", ROOT / "bench" / "human.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
