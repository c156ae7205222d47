"""`mtlc.output`: all outputs or none, symlinks written through, modes kept, errors as one line."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from mtlc import output
from mtlc.output import OutputError, write_all_or_nothing, write_outputs


def _old_files(tmp_path: Path) -> dict[Path, str]:
    files = {tmp_path / "a.txt": "old a", tmp_path / "b.txt": "old b", tmp_path / "c.txt": "old c"}
    for path, text in files.items():
        path.write_text(text, encoding="utf-8")
    return files


def _contents(tmp_path: Path) -> dict[str, str]:
    return {
        p.name: "<folder>" if p.is_dir() else p.read_text(encoding="utf-8")
        for p in sorted(tmp_path.iterdir())
    }


def test_writes_every_file(tmp_path: Path) -> None:
    files = _old_files(tmp_path)
    write_all_or_nothing({p: f"new {p.stem}" for p in files} | {tmp_path / "d" / "e.txt": b"e"})
    assert _contents(tmp_path) == {
        "a.txt": "new a",
        "b.txt": "new b",
        "c.txt": "new c",
        "d": "<folder>",
    }
    assert (tmp_path / "d" / "e.txt").read_bytes() == b"e"


def test_a_folder_in_the_way_changes_nothing(tmp_path: Path) -> None:
    files = _old_files(tmp_path)
    (tmp_path / "z.txt").mkdir()
    with pytest.raises(OutputError, match=r"z\.txt: it is a folder"):
        write_all_or_nothing({p: "new" for p in files} | {tmp_path / "z.txt": "new"})
    assert _contents(tmp_path) == {
        "a.txt": "old a",
        "b.txt": "old b",
        "c.txt": "old c",
        "z.txt": "<folder>",
    }


def test_a_failing_rename_puts_back_every_earlier_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The third rename into place fails: the first two files are restored, the new one
    removed (the journal's own renames are not counted)."""
    files = _old_files(tmp_path)
    real_replace = os.replace
    calls = []

    def flaky(src: str, dst: str | Path) -> None:
        if Path(dst).parent == tmp_path:
            calls.append(dst)
            if len(calls) == 3:
                raise PermissionError(13, "Permission denied")
        real_replace(src, dst)

    monkeypatch.setattr(output.os, "replace", flaky)
    new = {tmp_path / "a.txt": "new a", tmp_path / "n.txt": "new n", tmp_path / "b.txt": "new b"}
    with pytest.raises(OutputError, match=r"b\.txt: Permission denied; nothing was written"):
        write_all_or_nothing(new)
    assert _contents(tmp_path) == {"a.txt": "old a", "b.txt": "old b", "c.txt": "old c"}
    assert files  # no temporary or backup file is left (checked by the listing above)


def test_an_existing_file_keeps_its_mode_and_a_new_one_gets_the_umask(tmp_path: Path) -> None:
    private = tmp_path / "p.txt"
    private.write_text("x", encoding="utf-8")
    private.chmod(0o600)
    write_all_or_nothing({private: "y", tmp_path / "new.txt": "z"})
    assert stat.S_IMODE(private.stat().st_mode) == 0o600
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE((tmp_path / "new.txt").stat().st_mode) == 0o666 & ~umask


def test_a_symlink_is_written_through(tmp_path: Path) -> None:
    target = tmp_path / "target.txt"
    target.write_text("old", encoding="utf-8")
    link = tmp_path / "link.txt"
    link.symlink_to("target.txt")
    write_all_or_nothing({link: "new"})
    assert link.is_symlink()
    assert target.read_text(encoding="utf-8") == "new"


def test_write_outputs_reports_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "file").write_text("", encoding="utf-8")
    assert write_outputs({tmp_path / "file" / "x.sarif": "{}"}, "mtlc lint") == 2
    err = capsys.readouterr().err
    assert err.startswith("mtlc lint: cannot write ")
    assert "x.sarif" in err and err.count("\n") == 1
    assert write_outputs({tmp_path / "ok.txt": "ok"}) is None


# --------------------------------------------------------------------- crashes and locking


def _killed_at(step: int, files: dict[Path, str | bytes], recovering: Path | None = None) -> bool:
    """In a forked child, write ``files`` (or recover ``recovering``), SIGKILLed just before its
    ``step``-th change to the file system; True if the kill happened (False: it finished)."""
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        count = 0

        def die() -> None:
            nonlocal count
            count += 1
            if count == step:
                os.kill(os.getpid(), signal.SIGKILL)

        output._step = die  # type: ignore[assignment]
        try:
            if recovering is None:
                write_all_or_nothing(files)
            else:
                output.recover(recovering)
        finally:
            os._exit(0)
    _, status = os.waitpid(pid, 0)
    return os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL


def _state(targets: dict[Path, str], new: dict[Path, str | bytes]) -> str:
    """ "old" or "new" when every target holds one version, else a description of the mix."""
    now = {p: p.read_text(encoding="utf-8") if p.exists() else None for p in new}
    if now == {p: targets.get(p) for p in new}:
        return "old"
    if now == {p: v for p, v in new.items()}:
        return "new"
    return f"mixed: {now}"


def _leftovers(*folders: Path) -> list[str]:
    return sorted(p.name for f in folders for p in f.iterdir() if p.name.startswith("."))


def test_a_kill_at_any_step_leaves_all_old_or_all_new_after_recovery(tmp_path: Path) -> None:
    """SIGKILL before each change to the file system (staging, the journal, every rename,
    the clean-up), over two folders: after the next run's recovery the set is all old or all
    new (new from the journal's rename on), and no staging folder or temporary is left."""
    main, other = tmp_path / "out", tmp_path / "other"
    main.mkdir()
    other.mkdir()
    old = {main / "a.txt": "old a", main / "b.txt": "old b", other / "c.txt": "old c"}
    new: dict[Path, str | bytes] = {
        main / "a.txt": "new a",
        main / "n.txt": "new n",
        main / "b.txt": "new b",
        other / "c.txt": "new c",
    }
    seen = set()
    step = 1
    while True:
        for path in main.iterdir():
            path.unlink()
        for path in other.iterdir():
            path.unlink()
        for path, text in old.items():
            path.write_text(text, encoding="utf-8")
        if not _killed_at(step, new):
            break
        for folder in (main, other):  # what the next run does first
            output.recover(folder)
        state = _state(old, new)
        assert state in ("old", "new"), f"killed at step {step}: {state}"
        assert _leftovers(main, other) == [], f"killed at step {step}"
        seen.add(state)
        step += 1
    assert step > 15 and seen == {"old", "new"}  # the kills did land on both sides
    assert _state(old, new) == "new" and _leftovers(main, other) == []


def test_a_kill_during_recovery_is_recovered_by_the_next_run(tmp_path: Path) -> None:
    """Killed between two renames into place, then killed again at each step of recovering."""
    old = {tmp_path / f"{k}.txt": f"old {k}" for k in range(4)}
    new: dict[Path, str | bytes] = {p: f"new {p.stem}" for p in old}
    first = 1
    while True:  # find a kill that leaves a mix: a rename into place between two others
        for path in tmp_path.iterdir():
            shutil.rmtree(path) if path.is_dir() else path.unlink()
        for path, text in old.items():
            path.write_text(text, encoding="utf-8")
        assert _killed_at(first, new)
        if _state(old, new).startswith("mixed"):
            break
        first += 1
    stage = [p for p in tmp_path.iterdir() if p.is_dir()]
    snapshot = {p: p.read_bytes() for p in old} | {
        f: f.read_bytes() for s in stage for f in s.iterdir()
    }
    again = 1
    while True:
        for path in tmp_path.iterdir():
            shutil.rmtree(path) if path.is_dir() else path.unlink()
        for path, data in snapshot.items():
            path.parent.mkdir(exist_ok=True)
            path.write_bytes(data)
        if not _killed_at(again, {}, recovering=tmp_path):
            break
        output.recover(tmp_path)
        assert _state(old, new) == "new", f"killed at recovery step {again}"
        assert _leftovers(tmp_path) == []
        again += 1
    assert again > 2


def test_a_second_writer_waits_for_the_lock_then_fails_clearly(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(output, "LOCK_TIMEOUT_S", 0.2)
    fd = os.open(tmp_path, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # another mtlc writing into the folder
        with pytest.raises(OutputError, match=r"another mtlc has been writing into .* 0\.2 s"):
            write_all_or_nothing({tmp_path / "a.txt": "a"})
        assert not (tmp_path / "a.txt").exists()
        assert write_outputs({tmp_path / "a.txt": "a"}) == 2
    finally:
        os.close(fd)
    write_all_or_nothing({tmp_path / "a.txt": "a"})  # the lock is free again
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "a"


def test_two_writers_into_one_folder_are_serialised(tmp_path: Path) -> None:
    """A writer holding the folder's lock and a second one: the second's whole set lands after
    the first's (never interleaved), whichever order the threads start in."""
    order: list[str] = []
    release = threading.Event()
    real_step = output._step
    steps = []

    def slow_step() -> None:
        if threading.current_thread().name == "first":
            steps.append(1)
            if len(steps) == 2:  # its staging folder made, nothing renamed yet
                release.wait(10)
        real_step()

    files = {tmp_path / f"{k}.txt": "" for k in range(3)}
    first = threading.Thread(
        name="first",
        target=lambda: (write_all_or_nothing({p: "first" for p in files}), order.append("first")),
    )
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(output, "_step", slow_step)
        first.start()
        second = threading.Thread(
            target=lambda: (
                write_all_or_nothing({p: "second" for p in files}),
                order.append("second"),
            )
        )
        while not any(p.name.startswith(".mtlc-stage-") for p in tmp_path.iterdir()):
            threading.Event().wait(0.01)  # the first holds the lock (its staging folder exists)
        second.start()
        release.set()
        first.join(20)
        second.join(20)
    assert order == ["first", "second"]
    assert {p.read_text(encoding="utf-8") for p in files} == {"second"}
    assert _leftovers(tmp_path) == []


def test_temporaries_of_the_former_scheme_are_cleaned(tmp_path: Path) -> None:
    _old_files(tmp_path)
    stale = [".a.txt.k3j_9xq2.tmp", ".b.txt.0123456789ab.old", ".n.txt.abcdefgh.tmp"]
    kept = [".notes.abcdefgh.tmp", ".a.txt.short.tmp"]  # not ours: no such file, or no pattern
    for name in stale + kept:
        (tmp_path / name).write_text("x", encoding="utf-8")
    (tmp_path / ".mtlc-stage-0123456789ab").mkdir()  # a write killed before its commit
    (tmp_path / ".mtlc-stage-0123456789ab" / "0.new").write_text("half", encoding="utf-8")
    write_all_or_nothing({tmp_path / "n.txt": "n"})
    assert _leftovers(tmp_path) == sorted(kept)
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "old a"


KILLED_COMPILE = r"""
import json, os, signal, sys
from pathlib import Path
import mtlc.cli as cli, mtlc.output as output

task, out = sys.argv[1], Path(sys.argv[2])
real = cli.write_outputs
states = []

def read():
    return {p.name: p.read_bytes() for p in out.iterdir()}

def killing_write(files, command="mtlc"):
    # the compile is done: fork it once per step of the swap, SIGKILL the fork at that step
    old = read()
    new = {p.name: d.encode() if isinstance(d, str) else d for p, d in files.items()}
    step = 1
    while True:
        for p in out.iterdir():
            p.unlink()
        for name, data in old.items():
            (out / name).write_bytes(data)
        pid = os.fork()
        if pid == 0:
            count = [0]
            def die():
                count[0] += 1
                if count[0] == step:
                    os.kill(os.getpid(), signal.SIGKILL)
            output._step = die
            real(files, command)
            os._exit(0)
        _, status = os.waitpid(pid, 0)
        if not os.WIFSIGNALED(status):
            break
        output.recover(out)  # what the next compile does first
        now = read()
        states.append("old" if now == old else "new" if now == new else "mixed")
        step += 1
    return real(files, command)

cli.write_outputs = killing_write
rc = cli.main(["compile", task, "--target", "all", "-o", str(out), "--fps", "10"])
print(json.dumps({"rc": rc, "states": states, "files": sorted(read())}))
"""

TWO_TASKS = """use stdlib.actions

scene s {
    ground 0 cm
    site button at (0, 100, 60) cm normal (0, 0, -1)
}

task one "press a button" {
    manikin gb10000_1988 female p50
    scene s
    press(right, button)
}

task two "press it again" {
    manikin gb10000_1988 male p50
    scene s
    press(left, button)
}
"""


def test_a_compile_killed_at_each_step_of_its_swap(tmp_path: Path) -> None:
    """A real `mtlc compile` of five files over an earlier compile's five: forked and SIGKILLed
    before each change the swap makes; after recovery the folder is all old or all new."""
    task = tmp_path / "two.mtask"
    task.write_text(TWO_TASKS, encoding="utf-8")
    out = tmp_path / "out"
    out.mkdir()
    names = ["two.one.bvh", "two.one.ir.json", "two.py", "two.two.bvh", "two.two.ir.json"]
    for name in names:
        (out / name).write_text(f"an earlier {name}", encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": str(Path(output.__file__).parents[1])}
    run = subprocess.run(
        [sys.executable, "-c", KILLED_COMPILE, str(task), str(out)],
        capture_output=True, text=True, timeout=300, env=env, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout.splitlines()[-1])
    assert result["rc"] == 0 and result["files"] == names  # no staging folder, no temporary
    assert len(result["states"]) > 10
    assert set(result["states"]) == {"old", "new"}, result["states"]
    first_new = result["states"].index("new")
    assert all(s == "new" for s in result["states"][first_new:])  # from the commit on


def test_a_planted_journal_cannot_move_files_outside_its_folder(tmp_path: Path) -> None:
    """A journal that would rename a staged file over a file in another folder is not one
    mtlc wrote: recovery removes its staging folder and touches nothing else."""
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.mkdir()
    (victim / "precious.txt").write_text("precious", encoding="utf-8")
    stage = out / ".mtlc-stage-0123456789ab"
    stage.mkdir()
    (stage / "0.new").write_text("evil", encoding="utf-8")
    entry = {"staged": str(stage / "0.new"), "target": str(victim / "precious.txt"), "backup": None}
    doc = {"version": 1, "state": "forward", "entries": [entry]}
    (stage / "journal.json").write_text(json.dumps(doc), encoding="utf-8")
    output.recover(out)
    assert (victim / "precious.txt").read_text(encoding="utf-8") == "precious"
    assert list(out.iterdir()) == []


def test_a_busy_primary_folder_is_left_to_its_own_recovery(tmp_path: Path) -> None:
    """Killed mid-apply over two folders; recovering the second folder while the first (which
    holds the journal) is locked by another writer leaves the transaction alone; recovering
    the first then finishes it in both."""
    first, second = tmp_path / "a", tmp_path / "b"  # "a" sorts first: it holds the journal
    first.mkdir()
    second.mkdir()
    old = {first / "x.txt": "old x", second / "y.txt": "old y"}
    new: dict[Path, str | bytes] = {first / "x.txt": "new x", second / "y.txt": "new y"}
    step = 1
    while True:
        for folder in (first, second):
            for path in folder.iterdir():
                shutil.rmtree(path) if path.is_dir() else path.unlink()
        for path, text in old.items():
            path.write_text(text, encoding="utf-8")
        assert _killed_at(step, new)
        if _state(old, new).startswith("mixed"):
            break
        step += 1
    fd = os.open(first, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        output.recover(second)
        assert _state(old, new).startswith("mixed") and _leftovers(second) != []
    finally:
        os.close(fd)
    output.recover(first)
    assert _state(old, new) == "new" and _leftovers(first, second) == []
