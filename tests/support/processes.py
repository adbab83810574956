"""What is left of a process tree after its root was killed: a killed ``handover serve`` leaves its
rig process and its learner process behind, which are to end by themselves when they see it gone
(robot_io/rig/process.py, app/learning/worker.py)."""

from __future__ import annotations

import logging
import os
from pathlib import Path

from support.waiting import WaitTimeout, wait_for

log = logging.getLogger(__name__)

PROC = Path("/proc")
#: Clock ticks per second of /proc's CPU times.
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def _fields(pid: int) -> list[str] | None:
    """The fields of /proc/<pid>/stat after "pid (comm) ": state, ppid, … (None: no such process)."""
    return _stat_fields(PROC / str(pid) / "stat")


def _stat_fields(stat: Path) -> list[str] | None:
    """The fields of a process's or a thread's ``stat`` file after "id (comm) " (None: gone)."""
    try:
        text = stat.read_text()
    except (FileNotFoundError, ProcessLookupError):
        return None
    return text[text.rindex(")") + 2:].split()


def thread_states(pid: int) -> dict[int, str]:
    """The state letter of each thread of ``pid``, by thread id (empty: no such process)."""
    try:
        tasks = list((PROC / str(pid) / "task").iterdir())
    except (FileNotFoundError, ProcessLookupError):
        return {}
    return {int(task.name): fields[0] for task in tasks
            if (fields := _stat_fields(task / "stat")) is not None}


def stopped(pid: int) -> bool:
    """Every thread of ``pid`` is stopped (state T). ``kill(pid, SIGSTOP)`` returns before the
    signal has taken hold: measured beside a CPU hog, right after it some thread still ran in 66 of
    100 tries, and in 12 of 100 a thread committed an SQLite transaction after it."""
    states = thread_states(pid)
    return bool(states) and all(state == "T" for state in states.values())


def signal_masks(pid: int) -> dict[str, int]:
    """The signal sets of ``pid`` from /proc/<pid>/status, bit ``n - 1`` for signal ``n``: SigPnd and
    ShdPnd (pending), SigBlk (blocked: its main thread's), SigIgn (ignored), SigCgt (caught by a
    handler). Empty: no such process."""
    try:
        text = (PROC / str(pid) / "status").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return {}
    return {name: int(value, 16) for name, _, value in
            (line.partition(":\t") for line in text.splitlines())
            if name in ("SigPnd", "ShdPnd", "SigBlk", "SigIgn", "SigCgt")}


def has_signal(mask: int, signum: int) -> bool:
    """``signum`` is in a set of :func:`signal_masks`."""
    return bool(mask & (1 << (signum - 1)))


def _stat(pid: int) -> tuple[str, int] | None:
    """The state letter and the parent pid of ``pid`` (None: no such process)."""
    fields = _fields(pid)
    return None if fields is None else (fields[0], int(fields[1]))


def cpu_seconds(pid: int) -> float | None:
    """The user + system seconds ``pid`` has used (None: it has ended, a zombie included)."""
    fields = _fields(pid)
    if fields is None or fields[0] in ("Z", "X"):
        return None
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (children, their children, …), read from /proc."""
    parents: dict[int, list[int]] = {}
    for entry in PROC.iterdir():
        if entry.name.isdigit() and (stat := _stat(int(entry.name))) is not None:
            parents.setdefault(stat[1], []).append(int(entry.name))
    found, todo = [], [pid]
    while todo:
        children = parents.get(todo.pop(), [])
        found += children
        todo += children
    return found


def alive(pid: int) -> bool:
    """``pid`` runs (a zombie, dead but not yet reaped, does not)."""
    stat = _stat(pid)
    return stat is not None and stat[0] not in ("Z", "X")


def command_line(pid: int) -> str:
    """The command line of ``pid``, its arguments joined by spaces ("?": no such process)."""
    try:
        return (PROC / str(pid) / "cmdline").read_bytes().replace(b"\0", b" ").decode().strip()
    except OSError:
        return "?"


def describe(pid: int) -> str:
    """``pid``, its command line and its state letter, for a wait's message."""
    stat = _stat(pid)
    return f"{pid} [{'gone' if stat is None else stat[0]}] {command_line(pid)[:200]}"


def still_alive(pids: list[int], timeout_s: float) -> list[int]:
    """Wait for every one of ``pids`` to end (the state "all of them gone"); those still running
    after ``timeout_s`` — a ceiling for processes that never end, not a measurement — are returned
    and logged with their command lines, so that the caller's ``assert still_alive(...) == []``
    says which process stayed."""
    try:
        wait_for(lambda: not any(alive(p) for p in pids), f"processes {pids} to end",
                 timeout=timeout_s, poll=0.1)
    except WaitTimeout:
        running = [p for p in pids if alive(p)]
        log.error("still running after %g s: %s", timeout_s, "; ".join(map(describe, running)))
        return running
    return []


def forkserver_in_preload(pid: int) -> int | None:
    """The pid of ``pid``'s multiprocessing forkserver once torch's library is mapped in it (it is
    inside its preload, app.learning.forkserver_preload), else None."""
    import psutil

    for child in psutil.Process(pid).children():
        try:
            if ("multiprocessing.forkserver" in " ".join(child.cmdline())
                    and any("libtorch" in region.path for region in child.memory_maps())):
                return child.pid
        except psutil.Error:  # ended between the listing and the reading
            continue
    return None
