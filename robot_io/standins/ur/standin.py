"""The stand-in controller: the model, its ports, and the cycle thread that drives them."""

from __future__ import annotations

import functools
import logging
import threading
import time

import numpy as np

from robot_io.grippers.robotiq import ROBOTIQ_PORT
from robot_io.standins import urcap
from robot_io.standins.ur import control, dashboard, script_server
from robot_io.standins.ur.listener import Listener
from robot_io.standins.ur.model import Controller, Series
from robot_io.standins.ur.rtde_server import RTDEServer

log = logging.getLogger(__name__)

RTDE_PORT, DASHBOARD_PORT = 30004, 29999


class StandinController:
    """Listens on ``host`` (RTDE, dashboard, script ports, the Robotiq URCap's socket, control port)
    and runs the controller cycle at 125 Hz (CB-series) or 500 Hz (e-Series) until :meth:`close`."""

    def __init__(self, host: str, series: Series = Series.CB3,
                 start_pose: np.ndarray | None = None, control_port: int = control.DEFAULT_PORT) -> None:
        pose = np.array([0.35, -0.35, 0.35, 0.0, 3.14159, 0.0]) if start_pose is None else start_pose
        self.controller = Controller(series, pose)
        self.rtde = RTDEServer(self.controller)
        self.listeners: list[Listener] = [
            Listener(host, RTDE_PORT, self.rtde.handle),
            Listener(host, DASHBOARD_PORT, functools.partial(dashboard.serve, self.controller)),
            *(Listener(host, port, functools.partial(script_server.serve, self.controller))
              for port in script_server.PORTS),
            Listener(host, ROBOTIQ_PORT, functools.partial(
                urcap.serve, self.controller.robotiq, self.controller.lock, self.controller.event)),
        ]
        self.control = Listener(host, control_port,
                                functools.partial(control.serve, self.controller, self.listeners))
        self._running = True
        self._thread = threading.Thread(target=self._cycle, name="controller-cycle", daemon=True)
        self._thread.start()
        log.info("stand-in %s controller on %s", series.name, host)

    def _cycle(self) -> None:
        controller, period = self.controller, self.controller.period
        cycle, deadline, last = 0, time.monotonic(), None
        while self._running:
            deadline += period
            delay = deadline - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            elif delay < -10 * period:
                deadline = time.monotonic()  # far behind (machine busy): resync, no burst
            with controller.lock:  # a stall injected before a command is seen by its cycle
                now = time.monotonic()
                if now < controller.stalled_until:
                    last = None  # an injected stall is no late cycle
                    continue
                if last is not None:
                    controller.longest_gap_s = max(controller.longest_gap_s, now - last)
                controller.tick()
            last = now
            self.rtde.broadcast(cycle)
            cycle += 1

    def wait(self) -> None:
        self._thread.join()

    def close(self) -> None:
        self._running = False
        for listener in [*self.listeners, self.control]:
            listener.close()
        self._thread.join(timeout=1.0)
