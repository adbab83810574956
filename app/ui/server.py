"""``handover serve``'s servers: the tablet and the dashboard, two viser servers in one process.

Roles are told apart by port, since viser passes no URL query to the server. The dashboard is
token-gated (attempts rate-limited per address); the tablet offers nothing but rating and answering.
Both are closed to the outside (:mod:`app.ui.guard`): exactly the ports asked for, no share links,
same-origin websockets only. Each screen's browser loads the study's own page
(:mod:`app.ui.client_page`: its title, its cover from the first byte, its watchdog, its browser
id). A ticker thread redraws the
dashboard's live view ten times a second while the control loop runs in its own thread.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

from app.session.access import (
    DASHBOARD_BROWSERS_FILE,
    KNOWN_DASHBOARDS,
    KnownBrowsers,
    check_access_files,
    dashboard_token,
)
from app.session.runner import SessionRunner
from app.ui.client_page import ClientPage
from app.ui.dashboard import Dashboard
from app.ui.guard import TokenGate, open_server
from app.ui.style import DASHBOARD_CSS, DASHBOARD_OFFLINE_CSS, OFFLINE_CSS
from app.ui.tablet import Tablet
from app.ui.unreadable import quiet_unreadable_messages

log = logging.getLogger(__name__)

#: Live-view refresh period [s].
TICK_S = 0.1
#: The participant's page: a title that tells nothing of θ or the condition, the cover. (Not the
#: kiosk CSS, which comes with the first screen: hidden from the start, viser's 3-D canvas never
#: starts the frame loop that also applies the server's messages, and the page stays blank.)
TABLET_PAGE = ClientPage(role="tablet", title="Handover study", css=OFFLINE_CSS,
                         enter={"Code": "Connect"})
#: The experimenter's page.
DASHBOARD_PAGE = ClientPage(role="dashboard", title="handover-lab dashboard",
                            css=DASHBOARD_CSS + DASHBOARD_OFFLINE_CSS, enter={"Token": "Unlock"})


@dataclass(frozen=True)
class ServeOptions:
    host: str = "127.0.0.1"
    tablet_port: int = 8080
    dashboard_port: int = 8081
    token: str | None = None  # None: the study's stored token (created on first use)
    blind: bool = True  # blind validation: no θ or origin of validation trials shown (False: --unblind)


class HandoverServers:
    """Both screens over one :class:`SessionRunner`. :meth:`close` stops the arm first."""

    def __init__(self, runner: SessionRunner, options: ServeOptions) -> None:
        quiet_unreadable_messages()
        self.runner, self.options = runner, options
        self.token = dashboard_token(runner.study, options.token)
        check_access_files(runner.study)  # before a page is served, which would read them
        self.tablet_server, self.tablet_guard = open_server(options.host, options.tablet_port,
                                                            "tablet", TABLET_PAGE)
        try:
            self.dashboard_server, self.dashboard_guard = open_server(
                options.host, options.dashboard_port, "dashboard", DASHBOARD_PAGE,
                label="handover-lab dashboard")
        except Exception:
            self.tablet_server.stop()
            raise
        self.tablet = Tablet(self.tablet_server, runner, self.tablet_guard.source_of,
                             self.tablet_guard.browser_of)
        self.gate = TokenGate(self.token, self.dashboard_guard.source_of,
                              known=KnownBrowsers(runner.study, DASHBOARD_BROWSERS_FILE,
                                                  salt=self.token, keep=KNOWN_DASHBOARDS),
                              browser_of=self.dashboard_guard.browser_of)
        self.dashboard = Dashboard(self.dashboard_server, runner, self.gate,
                                   self.dashboard_guard.source_of, blind=options.blind)
        runner.set_blinding(options.blind)  # recorded in each session this dashboard serves
        self._closed = threading.Event()
        self._ticker = threading.Thread(target=self._tick, name="live-view", daemon=True)
        self._ticker.start()

    def urls(self) -> tuple[str, str]:
        host = self.options.host
        return (f"http://{host}:{self.tablet_server.get_port()}",
                f"http://{host}:{self.dashboard_server.get_port()}")

    def _tick(self) -> None:
        while not self._closed.wait(TICK_S):
            try:
                self.dashboard.tick()
            except Exception:
                log.exception("live view update failed")

    def close(self) -> None:
        """End the live view's ticker (a reader of the rig's samples) and the dashboard's replays
        (their threads draw on the pages), then stop the arm and end the session cleanly, then the
        dashboard's pages and the servers (the pages' STOP ARM stays until the arm is stopped)."""
        self._closed.set()
        self._ticker.join()
        self.dashboard.end_replays()
        self.runner.close()
        self.dashboard.close_pages()
        self.tablet_server.stop()
        self.dashboard_server.stop()
