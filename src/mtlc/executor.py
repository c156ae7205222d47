"""Where a population sweep runs: one interface, in this process or in local worker processes.

``run(fn, shared, items, jobs)`` calls ``fn(shared, item)`` for every item and returns one
outcome per item, in the items' order, whatever the number of jobs: a `Done` with the value or a
`Failed` that says why (an exception in ``fn``, or a worker process that died). Rules and reports
never start processes themselves; they hand a function to this module (docs/lint.md, "Sweeps").

Local workers are forked processes (spawned where fork does not exist) that each receive
``shared`` once (pickled once, e.g. the front end's timelines) and then one item at a time, so a
worker that dies is charged to exactly one item and replaced; the sweep goes on. They ignore
SIGINT: on Ctrl-C the parent terminates them and re-raises KeyboardInterrupt. ``fn`` and the
items must be picklable (a module-level function). A later cluster executor keeps this interface.
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import multiprocessing.connection
import os
import pickle
import signal
import traceback
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

S = TypeVar("S")
T = TypeVar("T")
R = TypeVar("R")

# how long a stopping worker gets to exit before it is killed (s)
STOP_GRACE = 2.0
_IN_WORKER = False  # set in worker processes (daemons may not start processes of their own)


@dataclass(frozen=True)
class Done(Generic[R]):
    value: R


@dataclass(frozen=True)
class Failed:
    """Why an item has no value: ``crashed`` when its worker process died (a signal, an exit,
    memory), else the exception ``fn`` raised, as 'TypeName: message'."""

    message: str
    crashed: bool = False


Outcome = Done[R] | Failed


def default_jobs() -> int:
    """The CPUs this process may run on (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def parse_jobs(text: str) -> int:
    """`--jobs N`: a positive integer, or 0 / 'auto' for the number of CPUs."""
    word = text.strip().lower()
    if word in ("auto", "0"):
        return default_jobs()
    if not word.isdigit():
        raise ValueError(f"--jobs {text!r}: expected a positive number of processes or 'auto'")
    return int(word)


def add_jobs(p: argparse.ArgumentParser) -> None:
    """`--jobs N`: worker processes for the per-manikin compiles (lint and report)."""
    p.add_argument(
        "-j",
        "--jobs",
        metavar="N",
        default="auto",
        help="compile the manikins in N worker processes (default 'auto': one per CPU; "
        "1: in this process); the findings are the same whatever N",
    )


def run(
    fn: Callable[[S, T], R], shared: S, items: Sequence[T], jobs: int | None = None
) -> list[Outcome[R]]:
    """``fn(shared, item)`` for each item, in ``jobs`` processes (default: the CPUs); one
    outcome per item in order. One job or one item runs in this process."""
    n = default_jobs() if jobs is None else max(1, jobs)
    if n == 1 or len(items) <= 1 or _IN_WORKER:  # a worker's own sweeps run in the worker
        return [_call(fn, shared, item) for item in items]
    return _Pool(fn, shared, min(n, len(items))).run(items)


def _call(fn: Callable[[S, T], R], shared: S, item: T) -> Outcome[R]:
    try:
        return Done(fn(shared, item))
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as exc:
        return Failed(f"{type(exc).__name__}: {exc}")


def _context() -> multiprocessing.context.BaseContext:
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("fork" if "fork" in methods else "spawn")


def _worker(conn: multiprocessing.connection.Connection, parent: int) -> None:
    """A worker's loop: ``fn`` and the shared payload once, then (index, item) until None."""
    global _IN_WORKER
    _IN_WORKER = True
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops us on Ctrl-C
    try:
        fn, shared = pickle.loads(conn.recv_bytes())
        while True:
            # forked siblings hold copies of our pipe's far end, so a parent killed outright
            # never shows as end-of-file here: look at who the parent is instead
            while not conn.poll(1.0):
                if os.getppid() != parent:
                    return
            task = conn.recv()
            if task is None:
                return
            index, item = task
            outcome = _call(fn, shared, item)
            try:
                payload = pickle.dumps((index, outcome), protocol=pickle.HIGHEST_PROTOCOL)
            except Exception as exc:
                msg = f"result not transferable: {type(exc).__name__}: {exc}"
                payload = pickle.dumps((index, Failed(msg)))
            conn.send_bytes(payload)
    except (EOFError, OSError, BrokenPipeError):
        return  # the parent went away: nothing left to do
    except BaseException:
        traceback.print_exc()
        os._exit(3)


@dataclass
class _Slot:
    process: Any  # multiprocessing.Process of the context
    conn: multiprocessing.connection.Connection
    index: int | None = None  # the item it is working on


class _Pool:
    def __init__(self, fn: Callable[[S, T], R], shared: S, size: int) -> None:
        self.payload = pickle.dumps((fn, shared), protocol=pickle.HIGHEST_PROTOCOL)
        self.size = size
        self.ctx = _context()
        self.slots: list[_Slot] = []

    def _start(self) -> _Slot:
        parent, child = self.ctx.Pipe(duplex=True)
        process = self.ctx.Process(target=_worker, args=(child, os.getpid()), daemon=True)
        process.start()
        child.close()
        # a worker that died at once shows when it is given an item (and fails that one)
        with contextlib.suppress(OSError):
            parent.send_bytes(self.payload)
        slot = _Slot(process, parent)
        self.slots.append(slot)
        return slot

    def run(self, items: Sequence[T]) -> list[Outcome[R]]:
        results: list[Outcome[R] | None] = [None] * len(items)
        todo = deque(range(len(items)))
        try:
            for _ in range(self.size):
                self._start()
            while todo or any(s.index is not None for s in self.slots):
                for slot in self.slots:
                    if slot.index is None and todo:
                        slot.index = todo.popleft()
                        self._send(slot, (slot.index, items[slot.index]), results)
                busy = [s for s in self.slots if s.index is not None]
                waits: list[Any] = [s.conn for s in busy] + [s.process.sentinel for s in busy]
                ready = set(multiprocessing.connection.wait(waits))
                for slot in busy:
                    if slot.conn in ready or slot.process.sentinel in ready:
                        self._collect(slot, results)
        finally:
            self._stop()
        return [r if r is not None else Failed("not run") for r in results]

    def _send(self, slot: _Slot, task: tuple[int, T], results: list[Outcome[R] | None]) -> None:
        try:
            slot.conn.send(task)
        except (OSError, BrokenPipeError):
            self._lost(slot, results)
        except Exception as exc:
            assert slot.index is not None
            results[slot.index] = Failed(f"item not transferable: {type(exc).__name__}: {exc}")
            slot.index = None

    def _collect(self, slot: _Slot, results: list[Outcome[R] | None]) -> None:
        try:
            if slot.conn.poll():
                index, outcome = pickle.loads(slot.conn.recv_bytes())
                results[index] = outcome
                slot.index = None
                return
        except (EOFError, OSError, pickle.UnpicklingError):
            pass
        if not slot.process.is_alive() or not slot.conn.poll():
            self._lost(slot, results)

    def _lost(self, slot: _Slot, results: list[Outcome[R] | None]) -> None:
        """The worker died with an item: that item failed; a fresh worker takes its place."""
        slot.process.join(STOP_GRACE)
        code = slot.process.exitcode
        if code is not None and code < 0:
            how = f"killed by signal {signal.Signals(-code).name}"
        else:
            how = f"exited with code {code}"
        if slot.index is not None:
            results[slot.index] = Failed(f"worker process {how}", crashed=True)
        slot.conn.close()
        self.slots.remove(slot)
        self._start()

    def _stop(self) -> None:
        for slot in self.slots:
            with contextlib.suppress(OSError, BrokenPipeError):
                slot.conn.send(None)
        for slot in self.slots:
            if slot.index is not None:  # interrupted mid-item: do not wait for it
                slot.process.terminate()
        for slot in self.slots:
            slot.process.join(STOP_GRACE)
            if slot.process.is_alive():
                slot.process.kill()
                slot.process.join()
            slot.conn.close()
        self.slots.clear()
