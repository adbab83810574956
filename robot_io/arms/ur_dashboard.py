"""The UR controller's dashboard server (port 29999) as a stop path that does not need the rig process:
the rig client's backstop (robot_io.rig.client) when the rig hangs or does not acknowledge a Stop."""

from __future__ import annotations

import logging
import threading

log = logging.getLogger(__name__)


class DashboardStop:
    """The UR controller's dashboard server as an independent stop path (port 29999). ur_rtde's
    client is not thread-safe, and a stop may come from a screen's thread and the watchdog while
    the client closes: every use of it is under one lock. A stop after :meth:`close` connects again."""

    def __init__(self, host: str) -> None:
        import dashboard_client

        self.host = host
        self._lock = threading.Lock()
        self._client = dashboard_client.DashboardClient(host)
        try:
            self._client.connect(2000)
        except RuntimeError as exc:
            log.error("no dashboard connection to %s for the backstop: %s", host, exc)

    def stop(self) -> None:
        with self._lock:
            try:
                if not self._client.isConnected():
                    self._client.connect(1000)
                self._client.stop()
            except Exception:
                log.critical("the dashboard stop of %s failed: use the emergency stop", self.host,
                             exc_info=True)

    def close(self) -> None:
        with self._lock:
            try:
                self._client.disconnect()
            except Exception:
                log.warning("closing the dashboard connection failed", exc_info=True)
