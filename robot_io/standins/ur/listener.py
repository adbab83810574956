"""TCP listeners of the stand-in: one thread per port accepting, one thread per connection serving."""

from __future__ import annotations

import contextlib
import logging
import socket
import threading
from collections.abc import Callable

log = logging.getLogger(__name__)


class Listener:
    """Accepts connections on ``(host, port)`` and serves each with ``handler(sock)`` in a thread.

    :meth:`drop_all` closes every open connection (the listener stays up), as a network fault would.
    """

    def __init__(self, host: str, port: int, handler: Callable[[socket.socket], None]) -> None:
        self.address = (host, port)
        self.handler = handler
        self.connections: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._server = socket.create_server(self.address, reuse_port=False)
        self._server.settimeout(0.2)
        self._running = True
        self._thread = threading.Thread(target=self._accept, name=f"listen-{port}", daemon=True)
        self._thread.start()

    def _accept(self) -> None:
        while self._running:
            try:
                sock, peer = self._server.accept()
            except TimeoutError:
                continue
            except OSError:
                break
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                self.connections.add(sock)
            log.debug("port %d: connection from %s", self.address[1], peer)
            threading.Thread(target=self._serve, args=(sock,), daemon=True,
                             name=f"serve-{self.address[1]}").start()

    def _serve(self, sock: socket.socket) -> None:
        try:
            self.handler(sock)
        except (OSError, ConnectionError, ValueError) as exc:
            log.debug("port %d: connection ended: %s", self.address[1], exc)
        finally:
            with self._lock:
                self.connections.discard(sock)
            sock.close()

    def open_connections(self) -> int:
        """How many client connections are open (each ends when its client closes it)."""
        with self._lock:
            return len(self.connections)

    def drop_all(self) -> int:
        """Close every open connection; returns how many."""
        with self._lock:
            dropped = list(self.connections)
        for sock in dropped:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            sock.close()
        return len(dropped)

    def close(self) -> None:
        self._running = False
        self._server.close()
        self.drop_all()


def read_exactly(sock: socket.socket, size: int) -> bytes:
    """``size`` bytes, or ConnectionError when the peer closes first."""
    data = bytearray()
    while len(data) < size:
        chunk = sock.recv(size - len(data))
        if not chunk:
            raise ConnectionError("peer closed the connection")
        data += chunk
    return bytes(data)


def read_lines(sock: socket.socket):
    """Yield the lines (without the newline) a peer sends until it closes."""
    buffer = b""
    while True:
        chunk = sock.recv(4096)
        if not chunk:
            return
        buffer += chunk
        while b"\n" in buffer:
            line, buffer = buffer.split(b"\n", 1)
            yield line.decode("utf-8", "replace").rstrip("\r")
