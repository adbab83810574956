"""The web app closed to the outside: what ``handover serve`` puts around each viser server.

* **No share links.** viser lets any connected page ask the server to open a public tunnel
  (``ShareUrlRequest`` → ``share.viser.studio``). Its handlers are removed and a refusal is logged.
* **Same-origin websockets only.** A browser page on another site can open a websocket to a server on
  this machine or LAN; the browser then sends that site's ``Origin``. A connection is kept only if its
  ``Origin`` names the host and port the page was served from (its ``Host`` header), and that host is
  an IP address, ``localhost`` or this machine's name (so a DNS-rebinding name is refused too); any
  other connection is closed (1008, policy violation) before the server sends or reads a message.
* **A busy port is an error naming it.** viser moves on to the next free port without a word, so the
  tablet could end up on the dashboard's port; here the port actually bound must be the one asked for.
* **Token attempts slowed down and logged** (:class:`TokenGate`), per remote address; the right
  token is never refused.
* **GUI updates a page never sends are refused** (:mod:`app.ui.gui_updates`): a value of the wrong
  kind or outside an input's range, a property other than the value; one line in the log each.
* **The browser's id** (:meth:`Guard.browser_of`): the cookie the study's page sets
  (:mod:`app.ui.client_page`), read from the websocket's request headers; an id of any other form
  is no id.

viser 1.1.1 offers no switch for the first three, so this module reaches into its infra server
(``ViserServer._websock_server``): ``unregister_handler``/``register_handler`` and ``on_client_connect``
are that server's own hooks; the websocket of a client is read from its ``_live_connections``. Nothing
of viser is patched. Re-check these names when viser is upgraded.
"""

from __future__ import annotations

import ipaddress
import logging
import re
import socket
import threading
import time
from collections.abc import Callable
from http.cookies import CookieError, SimpleCookie
from urllib.parse import urlsplit

import viser
from viser import _messages
from viser._gui_api import GuiApi
from viser.infra import WebsockClientConnection, WebsockMessageHandler
from websockets.asyncio.server import ServerConnection
from websockets.http11 import Request

from app.session.access import AttemptLimit, KnownBrowsers
from app.ui.client_page import BROWSER_ID_PATTERN, ClientPage, StudyViserServer, client_folder
from app.ui.gui_updates import checked
from app.ui.streams import safe_streams

log = logging.getLogger(__name__)

#: The viser version whose internals this module was written against.
VISER_VERSION = "1.1.1"
#: Close code of a refused websocket (RFC 6455: policy violation).
POLICY_VIOLATION = 1008


class PortInUse(ValueError):
    """The port asked for a screen is taken; viser would have moved to another one."""


def open_server(host: str, port: int, role: str, page: ClientPage | None = None,
                **kwargs) -> tuple[viser.ViserServer, Guard]:
    """A viser server for ``role`` ("tablet", "dashboard") on exactly ``host:port``, guarded, its
    message streams woken safely from any thread (:mod:`app.ui.streams`), its browsers served
    ``page`` (None: viser's own page)."""
    server = StudyViserServer(host=host, port=port, verbose=False,
                              client_root=None if page is None else client_folder(page), **kwargs)
    bound = server.get_port()
    if port != 0 and bound != port:
        server.stop()
        raise PortInUse(f"{role} port {port} on {host} is in use (by another program, or the other "
                        f"screen); free it or choose another {role} port")
    safe_streams(server)
    return server, Guard(server, role)


class Guard:
    """Refuses share links and foreign origins on one viser server; remembers client addresses."""

    def __init__(self, server: viser.ViserServer, role: str) -> None:
        if viser.__version__ != VISER_VERSION:
            log.warning("app.ui.guard was written for viser %s, this is %s: re-check it",
                        VISER_VERSION, viser.__version__)
        self.role = role
        self.port = server.get_port()
        self.refused: list[str] = []  # what was refused, in order (for the log and for tests)
        self._infra = server._websock_server
        self._addresses: dict[int, str] = {}
        for message in (_messages.ShareUrlRequest, _messages.ShareUrlDisconnect):
            self._infra.unregister_handler(message)  # viser's own: it would open a public tunnel
            self._infra.register_handler(message, self._refuse_share_link)
        self._guard_gui_updates(self._infra)  # the server's own GUI (the pages use their own)
        self._infra.on_client_connect(self._check_origin)
        self._infra.on_client_disconnect(self._forget)

    def _guard_gui_updates(self, interface: WebsockMessageHandler) -> None:
        """Put :func:`~app.ui.gui_updates.checked` before each of viser's GUI-update handlers on
        ``interface`` (the server's, or a page's connection once its ClientHandle registered)."""
        handlers = interface._incoming_handlers.get(_messages.GuiUpdateMessage, [])
        for handler in list(handlers):
            gui = getattr(handler, "__self__", None)
            if isinstance(gui, GuiApi):
                interface.unregister_handler(_messages.GuiUpdateMessage, handler)
                interface.register_handler(_messages.GuiUpdateMessage,
                                           checked(gui, handler, self._refuse_update))

    def _refuse_update(self, client_id: int, why: str) -> None:
        self._refuse(f"{why} (client {client_id} at {self.source_of(client_id)})")

    def source_of(self, client_id: int) -> str:
        """The remote address of a connected client ("unknown" once it has gone)."""
        if client_id not in self._addresses:  # asked before the origin check ran
            connection = self._infra._live_connections.get(client_id)
            if connection is not None and connection.remote_address:
                return connection.remote_address[0]
        return self._addresses.get(client_id, "unknown")

    def browser_of(self, client_id: int) -> str | None:
        """The id of a connected client's browser (its ``hl-<role>-browser`` cookie), if it sent
        one of the right form from the page this server served. (Cookies do not tell ports apart:
        a page of this host on another port would send it too, and may be answered before the
        origin check has closed it.)"""
        connection = self._infra._live_connections.get(client_id)
        if connection is None:
            return None
        headers = _request(connection).headers
        if not same_origin(headers.get("Origin"), headers.get("Host"), self.port):
            return None
        cookie = SimpleCookie()
        try:
            cookie.load(headers.get("Cookie", ""))
        except CookieError:
            return None
        morsel = cookie.get(f"hl-{self.role}-browser")
        if morsel is None or not re.fullmatch(BROWSER_ID_PATTERN, morsel.value):
            return None
        return morsel.value

    def _forget(self, conn: WebsockClientConnection) -> None:
        self._addresses.pop(conn.client_id, None)

    def _refuse(self, what: str) -> None:
        self.refused.append(what)
        log.warning("%s: refused %s", self.role, what)

    def _refuse_share_link(self, client_id: int, message: object) -> None:
        self._refuse(f"share-link request ({type(message).__name__}) from client {client_id} at "
                     f"{self.source_of(client_id)}: public tunnels are disabled")

    async def _check_origin(self, conn: WebsockClientConnection) -> None:
        connection = self._infra._live_connections.get(conn.client_id)
        if connection is None:
            return
        address = connection.remote_address[0] if connection.remote_address else "unknown"
        self._addresses[conn.client_id] = address
        self._guard_gui_updates(conn)  # viser's ClientHandle has registered its handler by now
        headers = _request(connection).headers
        origin, host = headers.get("Origin"), headers.get("Host")
        if not same_origin(origin, host, self.port):
            self._refuse(f"websocket from {address} with Origin {origin!r} (served as {host!r})")
            await connection.close(POLICY_VIOLATION, "origin not allowed")


def _request(connection: ServerConnection) -> Request:
    """The opening handshake's request of a live websocket (viser lists a connection once its
    handshake is done)."""
    assert connection.request is not None, "a live connection has had its handshake"
    return connection.request


def same_origin(origin: str | None, host: str | None, port: int) -> bool:
    """True if ``origin`` is the page this server served: same host and ``port`` as the ``Host``
    header, and a host that cannot be a rebound DNS name (an IP address, localhost, this machine)."""
    if not origin or not host:
        return False
    try:
        parts, served = urlsplit(origin), urlsplit(f"//{host}")
        origin_port = parts.port or {"http": 80, "https": 443}.get(parts.scheme)
        served_port = served.port or 80
    except ValueError:
        return False
    if parts.scheme not in ("http", "https") or not parts.hostname or not served.hostname:
        return False
    if (parts.hostname.lower(), origin_port) != (served.hostname.lower(), served_port):
        return False
    return served_port == port and _trusted_name(served.hostname)


def _trusted_name(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
        return True
    except ValueError:
        pass
    own = {"localhost", socket.gethostname().lower(), socket.getfqdn().lower()}
    return name.lower() in own or name.lower().removesuffix(".local") in own


def later(delay_s: float, then: Callable[[], None]) -> None:
    """Run ``then`` on a timer thread of its own after ``delay_s`` (never on viser's callback pool,
    which STOP ARM's click needs)."""
    timer = threading.Timer(delay_s, then)
    timer.daemon = True
    timer.start()


class TokenGate:
    """The dashboard token, checked per remote address (:class:`~app.session.access.AttemptLimit`):
    ``max_failures`` wrong tries per ``window_s`` are answered at once; past them each try from that
    address waits (:meth:`AttemptLimit.wait_s`, up to MAX_WAIT_S) before it is checked, on a timer
    (``later``), the right token included (a quick answer would tell it apart), and is never
    refused unchecked: others on the experimenter's address (a shared NAT, the lab PC) slow their
    own guesses down, not the experimenter out. A page has at most one try waiting, the latest it
    gave. A browser in which the token was given is ``known`` (its id from ``browser_of``) and needs
    no token again, across restarts."""

    def __init__(self, token: str, source_of: Callable[[int], str], max_failures: int = 5,
                 window_s: float = 60.0, clock: Callable[[], float] = time.monotonic,
                 known: KnownBrowsers | None = None,
                 browser_of: Callable[[int], str | None] = lambda _: None,
                 later: Callable[[float, Callable[[], None]], None] = later) -> None:
        self._token, self._source_of = token, source_of
        self._known, self._browser_of, self._later = known, browser_of, later
        self._limit = AttemptLimit(max_failures, window_s, clock, what="token", role="dashboard")
        self._waiting: dict[int, tuple[str, Callable[[str | None], None]]] = {}  # page → its try
        self._lock = threading.Lock()

    def recognised(self, client_id: int) -> bool:
        """Whether the client's browser was unlocked before (with this token)."""
        return self._known is not None and self._known.known(self._browser_of(client_id))

    def attempt(self, client_id: int, given: str,
                answer: Callable[[str | None], None]) -> str | None:
        """Check ``given`` for page ``client_id``: ``answer`` gets None (the token: the page may
        unlock) or why not, for the screen; at once, or once the address's wait is over. Returns
        what the page shows meanwhile (None: answered already). Nothing typed is no attempt (not
        counted)."""
        if not given:
            answer("Type the token first.")
            return None
        source = self._source_of(client_id)
        wait = self._limit.wait_s(source)
        if wait == 0.0:
            self._judge(client_id, source, given, answer)
            return None
        with self._lock:
            queued = client_id in self._waiting
            self._waiting[client_id] = (given, answer)  # the latest try of the page is checked
        if not queued:
            log.warning("dashboard: a token from %s waits %.0f s (%d wrong from there in the last "
                        "%g s)", source, wait, self._limit.recent(source), self._limit.window_s)
            self._later(wait, lambda: self._checked_later(client_id, source))
        return (f"Checking the token in {wait:.0f} s: {self._limit.recent(source)} wrong tokens "
                "came from this address in the last minute, so each try waits.")

    def _checked_later(self, client_id: int, source: str) -> None:
        with self._lock:
            given, answer = self._waiting.pop(client_id)
        self._judge(client_id, source, given, answer)

    def _judge(self, client_id: int, source: str, given: str,
               answer: Callable[[str | None], None]) -> None:
        refusal = self._limit.judge(source, given, self._token)
        if refusal is None and self._known is not None:
            self._known.remember(self._browser_of(client_id))
        answer(refusal)
