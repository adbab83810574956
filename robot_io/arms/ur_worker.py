"""``RTDEControlInterface`` in a worker process of its own, driven through a pipe.

Why a process: ur_rtde 1.6.5's control interface reconnects by itself when its RTDE socket drops, and
that path is broken — its receive thread never clears ``should_reconnect`` and starts a second
receive thread from inside itself; against the stand-in this segfaulted the process within a second
of a dropped socket, or left it hung (see ``docs/hardware.md``). Isolated here, a crash or hang takes
down only this worker: the arm backend sees the pipe close, reports the fault, and starts a fresh
worker for the next trial. It also keeps the constructor, which holds the GIL while it waits for
the controller, off the control loop's interpreter.

Parent → worker messages: ``("servo", args)`` (servoL, no reply: one per control cycle) and
``("call", number, method, args)`` answered by ``("ok", number, result)`` or ``("error", number,
message)``; the connection is answered as call 0. The number pairs an answer with its call: an answer
that comes after its call gave up waiting (a loaded host, a stalled controller) is dropped, never
taken as the answer to the next call (a late ``stopL``'s ``None`` read as ``isProgramRunning``).
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import time
import traceback
from multiprocessing.connection import Connection

from robot_io.child_signals import ends_with_its_parent
from robot_io.clock import children_start_on_the_normal_policy, raise_priority
from robot_io.errors import ArmFault

log = logging.getLogger(__name__)

#: Methods of RTDEControlInterface the arm backend may call through the worker.
CALLS = frozenset({"moveL", "stopL", "servoStop", "stopScript", "setWatchdog", "reuploadScript",
                   "isProgramRunning"})


#: How far below ur_rtde's own threads the worker's command thread runs. ur_rtde 1.6's
#: ``sendCommand`` waits for the control script's "ready" in a loop that never sleeps (measured: a
#: servoL sent while the controller did not answer for 1.0 s used 1.0 CPU-s). At their priority,
#: two such waits held both cores of a 2-core machine under SCHED_FIFO, and the threads that would
#: have ended them (ur_rtde's receiver, which reads "ready"; the stand-in; the arm's reader) could
#: not run: the stand-in "sent no new state", the servoL targets never arrived. Below them, a wait
#: lasts until the answer comes, as it should; it still runs above every normal-policy process.
COMMAND_PRIORITY_BELOW = 5


def _serve(conn: Connection, host: str, flags: int, priority: int | None, parent: int) -> None:
    """The worker process: ends with the thread that started it (:func:`ends_with_its_parent`), at
    once, also while a ur_rtde call does not return (a stalled or dead controller); a rig that died
    or was killed meanwhile left such a worker holding the arm's control connection for good (seen
    after a rehearsal's stand-in controller died mid-trial). A parent already gone: nothing to do."""
    with ends_with_its_parent():
        if os.getppid() == parent:
            _work(conn, host, flags, priority)


def _work(conn: Connection, host: str, flags: int, priority: int | None) -> None:
    """Construct the interface, then execute messages until the pipe closes. It starts on the
    normal policy and, with a ``priority``, runs under SCHED_FIFO once its imports are done:
    ur_rtde's threads, started by the constructor, at ``priority``; this thread, which sends the
    commands and spins in ur_rtde's waits, COMMAND_PRIORITY_BELOW below it."""
    import rtde_control

    if priority is not None:
        raise_priority(priority)
    try:
        control = rtde_control.RTDEControlInterface(host, -1.0, flags)
    except Exception as exc:  # the constructor throws RuntimeError, std::logic_error, ...
        conn.send(("error", 0, f"{type(exc).__name__}: {exc}"))
        return
    if priority is not None:
        raise_priority(priority - COMMAND_PRIORITY_BELOW)  # this thread only (Linux: per thread)
    conn.send(("ok", 0, None))
    try:
        while True:
            message = conn.recv()
            if message[0] == "servo":
                control.servoL(*message[1])
                continue
            _, number, method, args = message
            try:
                conn.send(("ok", number, getattr(control, method)(*args)))
            except Exception as exc:
                conn.send(("error", number, f"{method}: {type(exc).__name__}: {exc}"))
    except (EOFError, OSError):
        pass  # the arm backend is gone: the controller's watchdog stops the program
    except Exception:  # servoL's (it has no answer to carry it)
        traceback.print_exc()  # os._exit below would end the process before Python printed it
    finally:
        try:
            control.servoStop(5.0)
        finally:
            try:
                control.stopScript()
            finally:
                os._exit(0)  # not ur_rtde's destructor: it can hang on a dead connection


class ControlWorker:
    """The arm backend's handle on the worker process. The worker lives no longer than the thread
    that made this handle (the rig's main thread, which opens and runs the arm)."""

    def __init__(self, host: str, upper_range_registers: bool, timeout: float) -> None:
        import rtde_control

        flags = rtde_control.RTDEControlInterface.FLAG_UPLOAD_SCRIPT
        if upper_range_registers:
            flags |= rtde_control.RTDEControlInterface.FLAG_UPPER_RANGE_REGISTERS
        context = multiprocessing.get_context("spawn")  # no fork: the parent runs ur_rtde threads
        self._conn, child = context.Pipe()
        with children_start_on_the_normal_policy() as priority:
            self.process = context.Process(target=_serve,
                                           args=(child, host, flags, priority, os.getpid()),
                                           name=f"ur_rtde-control-{host}", daemon=True)
            self.process.start()
        child.close()
        self._calls = 0  # the number of the last call; the connection is call 0
        self._wait_reply(timeout, f"connecting the control interface to {host}")

    @property
    def alive(self) -> bool:
        return self.process.is_alive()

    def servo(self, pose: list[float], speed: float, acceleration: float, time: float,
              lookahead: float, gain: float) -> None:
        """One servoL target; raises ArmFault if the worker is gone."""
        try:
            self._conn.send(("servo", (pose, speed, acceleration, time, lookahead, gain)))
        except (OSError, ValueError) as exc:
            raise ArmFault(f"the ur_rtde control process is gone ({exc})") from exc

    def call(self, method: str, *args, timeout: float = 5.0):
        """Call a method of RTDEControlInterface in the worker and return its result."""
        if method not in CALLS:
            raise ValueError(f"method = {method!r} is not one of {sorted(CALLS)}")
        self._calls += 1
        try:
            self._conn.send(("call", self._calls, method, args))
        except (OSError, ValueError) as exc:
            raise ArmFault(f"the ur_rtde control process is gone ({exc})") from exc
        return self._wait_reply(timeout, method)

    def _wait_reply(self, timeout: float, what: str):
        """The answer to call number ``self._calls``; answers to earlier calls, which gave up
        waiting for them, are dropped."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                if not self._conn.poll(max(0.0, deadline - time.monotonic())):
                    raise ArmFault(f"{what}: no answer from the ur_rtde control process within "
                                   f"{timeout} s")
                status, number, value = self._conn.recv()
            except (EOFError, OSError) as exc:
                raise ArmFault(f"{what}: the ur_rtde control process exited "
                               f"(exit code {self.process.exitcode})") from exc
            if number == self._calls:
                break
            log.warning("dropped a late answer of the ur_rtde control process (call %d, %s: %r) "
                        "while waiting for call %d, %s", number, status, value, self._calls, what)
        if status == "error":
            raise ArmFault(f"{what}: {value}")
        return value

    def close(self) -> None:
        """End the worker: it stops servoing and the script; killed if it does not exit in 2 s."""
        self._conn.close()
        self.process.join(2.0)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(1.0)
