"""A child started while SIGINT is held (robot_io.child_signals) does not die of a Ctrl-C that comes
before its own code ignores it (as while it imports): the signal waits, and is dropped."""

from __future__ import annotations

import multiprocessing
import os
import signal
from multiprocessing.connection import Connection
from pathlib import Path

import pytest
from support.processes import has_signal, signal_masks
from support.waiting import wait_for

from robot_io.child_signals import ignore_interrupts, interrupts_held

pytestmark = pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc")


def _starting_child(conn: Connection) -> None:  # pragma: no cover - child process
    """A child that is not done starting until told (``go``), then ignores SIGINT and says so."""
    conn.send("started")
    conn.recv()  # a KeyboardInterrupt here, if the SIGINT was not held
    ignore_interrupts()
    conn.send("ignoring")
    conn.recv()


def sigint_pending(pid: int) -> bool:
    return has_signal(signal_masks(pid).get("ShdPnd", 0), signal.SIGINT)


@pytest.mark.parametrize("held", [True, False], ids=["held", "not held (as before)"])
def test_a_ctrl_c_while_a_child_starts_waits_and_is_dropped(held):
    context = multiprocessing.get_context("spawn")
    conn, child_end = context.Pipe()
    child = context.Process(target=_starting_child, args=(child_end,), daemon=True)
    if held:
        with interrupts_held():
            child.start()
    else:
        child.start()
    child_end.close()
    try:
        assert conn.poll(60) and conn.recv() == "started"
        assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, []), \
            "interrupts_held gives the starting thread its mask back"
        os.kill(child.pid, signal.SIGINT)  # a Ctrl-C in its first moments
        if held:
            wait_for(lambda: sigint_pending(child.pid), "the child's SIGINT to wait (pending)",
                     seen=lambda: signal_masks(child.pid))
            conn.send("go")
            assert conn.poll(60) and conn.recv() == "ignoring"
            assert not sigint_pending(child.pid), "ignore_interrupts dropped the waiting SIGINT"
            conn.send("end")
            child.join(60)
            assert child.exitcode == 0
        else:
            child.join(60)
            assert child.exitcode == 1  # KeyboardInterrupt: what a held SIGINT prevents
    finally:
        if child.is_alive():
            child.kill()
        child.join()
        conn.close()
