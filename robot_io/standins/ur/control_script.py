"""A Python model of the register handshake of ``ur_rtde``'s uploaded ``rtde_control`` program.

The program (``rtde_control.script`` in ur_rtde 1.6) reads a command id from input integer register
0 (+ the offset 24 with ``FLAG_UPPER_RANGE_REGISTERS``), its arguments from input double registers 0…,
and answers through output integer register 0: 1 = ready for a command, 2 = done with it. Its main
loop, modelled here once per controller cycle:

* a *continuous* command (servoL 24, servoJ 11, speedJ 9, speedL 10, force mode 6, …) is processed
  and the program signals ready at once;
* ``NO_CMD`` (0) clears "executing" and signals ready;
* any other command is processed once (until the client clears it with ``NO_CMD``) and the program
  signals done when it has finished — a synchronous ``moveL`` only when the arm has arrived;
* ``STOP_SCRIPT`` (255) ends the program.

``setWatchdog(f)`` makes the program stop if input integer register 0 is not written for 1/f s, as
``rtde_set_watchdog(..., "stop")`` does on a controller. Commands the model does not know are logged,
answered "done", and otherwise ignored.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np

log = logging.getLogger(__name__)

NO_CMD, MOVEL, SERVO_STOP, SERVOL, PROTECTIVE_STOP, STOPL, SET_WATCHDOG, STOP_SCRIPT = (
    0, 3, 16, 24, 31, 33, 35, 255)
CONTINUOUS = {24, 11, 9, 10, 6, 25, 26, 27, 38, 58, 66, 67, 68, 69, 70, 71}
READY, DONE = 1, 2
#: Deceleration [m/s²] when the program stops without being told one (watchdog, script stop).
DEFAULT_DECELERATION = 10.0


class ControlScript:
    """The running ``rtde_control`` program, with the register offset it was uploaded with."""

    name = "rtde_control"

    def __init__(self, register_offset: int) -> None:
        self.offset = register_offset
        self.executing = False
        self.motion: Callable[[float], bool] | None = None  # blocking command in progress
        self.background: Callable[[float], bool] | None = None  # servo / async move / stop
        self.watchdog_hz: float | None = None
        self.started = time.monotonic()
        self._signalled = False

    def _in_int(self, controller, index: int) -> int:
        return int(controller.inputs.get(f"input_int_register_{index + self.offset}", 0))

    def _in_double(self, controller, index: int) -> float:
        return float(controller.inputs.get(f"input_double_register_{index + self.offset}", 0.0))

    def _signal(self, controller, value: int) -> None:
        controller.outputs[f"output_int_register_{self.offset}"] = value

    def step(self, controller, dt: float) -> bool:
        """One controller cycle; False when the program ends."""
        if not self._signalled:
            self._signal(controller, READY)
            self._signalled = True
        if self._watchdog_expired(controller):
            assert self.watchdog_hz is not None, "only a watchdog that is set expires"
            controller.event(f"watchdog: input_int_register_{self.offset} not written for "
                             f"{1.0 / self.watchdog_hz:.3f} s; program stopped")
            return False
        keep_running = True
        if self.motion is not None:
            if self.motion(dt):
                self.motion = None
                self._signal(controller, DONE)
        else:
            command = self._in_int(controller, 0)
            if command in CONTINUOUS:
                keep_running = self._process(controller, command)
                self._signal(controller, READY)
            elif command == NO_CMD:
                self.executing = False
                self._signal(controller, READY)
            elif not self.executing:
                self.executing = True
                keep_running = self._process(controller, command)
                if self.motion is None and keep_running:
                    self._signal(controller, DONE)
        if self.background is not None and self.motion is None and self.background(dt):
            self.background = None
        return keep_running

    def _watchdog_expired(self, controller) -> bool:
        if self.watchdog_hz is None:
            return False
        written = controller.input_times.get(f"input_int_register_{self.offset}", self.started)
        return time.monotonic() - max(written, self.started) > 1.0 / self.watchdog_hz

    def _pose(self, controller) -> np.ndarray:
        return np.array([self._in_double(controller, i) for i in range(6)])

    def _process(self, controller, command: int) -> bool:
        arm = controller.arm
        if command == SERVOL:
            target = self._pose(controller)
            lookahead = self._in_double(controller, 9)

            def servo(dt: float) -> bool:
                arm.follow(target, lookahead, dt)
                return False  # a servo target is followed until the next one or a stop

            self.background = servo
        elif command == MOVEL:
            target = self._pose(controller)
            speed, acceleration = self._in_double(controller, 6), self._in_double(controller, 7)
            move = lambda dt: arm.approach(target, speed, acceleration, dt)  # noqa: E731
            if self._in_int(controller, 1):
                self.background = move
            else:
                self.background, self.motion = None, move
        elif command in (SERVO_STOP, STOPL):
            deceleration = self._in_double(controller, 0) or DEFAULT_DECELERATION
            self.background = lambda dt: arm.decelerate(deceleration, dt)
        elif command == SET_WATCHDOG:
            self.watchdog_hz = self._in_double(controller, 0)
            controller.event(f"watchdog set to {self.watchdog_hz:g} Hz")
        elif command == PROTECTIVE_STOP:
            controller.protective_stop("triggered by the client")
        elif command == STOP_SCRIPT:
            controller.event("received stop script")
            return False
        elif command not in CONTINUOUS:
            controller.event(f"command {command} is not modelled by the stand-in; answered done")
        return True
