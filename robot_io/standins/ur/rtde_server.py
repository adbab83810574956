"""The RTDE server (port 30004): recipes, start/pause, output packages each cycle, input packages."""

from __future__ import annotations

import collections
import contextlib
import logging
import socket
import struct
import threading
import time

from robot_io.standins.ur import rtde_protocol as rtde
from robot_io.standins.ur.listener import read_exactly
from robot_io.standins.ur.model import Controller

log = logging.getLogger(__name__)

PROTOCOL_VERSION = 2
#: How long a client may leave the controller's messages unread before the controller closes its
#: connection: a real one does (a client that connects, starts and reads nothing for 10 s finds
#: "received 0 bytes from Controller": UniversalRobots/RTDE_Python_Client_Library issue #6), and
#: meanwhile sends every other client its packages on time.
UNREAD_LIMIT_S = 10.0


class Recipe:
    """Names, RTDE types and packed layout of one recipe."""

    def __init__(self, names: list[str], types: list[str]) -> None:
        self.names, self.types = names, types
        self.layout = rtde.recipe_format(types)


class RTDEConnection:
    """One client of the RTDE server.

    Every message to the client goes through one outgoing buffer that is written without blocking
    (the reply to a request from the client's own thread, the output packages from the cycle
    thread), so a client that stops reading holds up nobody: its messages wait for it, in order,
    and once none of them has left for :data:`UNREAD_LIMIT_S` the connection is closed."""

    def __init__(self, sock: socket.socket, server: RTDEServer) -> None:
        self.sock, self.server = sock, server
        self.send_lock = threading.Lock()
        self.output: Recipe | None = None
        self.output_every = 1
        self.inputs: dict[int, Recipe] = {}
        self.started = False
        self._late: collections.deque[tuple[float, bytes]] = collections.deque()
        self._outgoing = bytearray()  # guarded by send_lock
        self._last_sent = time.monotonic()  # when bytes last left, or the buffer was last empty

    def send(self, message_type: int, payload: bytes = b"") -> None:
        with self.send_lock:
            self._outgoing += rtde.frame(message_type, payload)
            self._write()

    def flush(self) -> None:
        """Write what the client has not taken yet (each cycle: a client that reads again gets it)."""
        with self.send_lock:
            self._write()

    def _write(self) -> None:
        """As much of the outgoing buffer as the socket takes now; close a client that has taken
        nothing for the server's unread limit (its reader thread then sees the connection end)."""
        now = time.monotonic()
        if self._outgoing:
            with contextlib.suppress(BlockingIOError):
                sent = self.sock.send(self._outgoing, socket.MSG_DONTWAIT)
                del self._outgoing[:sent]
                self._last_sent = now
        if not self._outgoing:
            self._last_sent = now
        elif now - self._last_sent > self.server.unread_limit_s:
            log.warning("RTDE client left %d bytes unread for %.1f s: connection closed",
                        len(self._outgoing), now - self._last_sent)
            self._outgoing.clear()
            self.sock.shutdown(socket.SHUT_RDWR)

    def serve(self) -> None:
        try:
            while True:
                size, message_type = rtde.HEADER.unpack(read_exactly(self.sock, rtde.HEADER.size))
                self._handle(message_type, read_exactly(self.sock, size - rtde.HEADER.size))
        finally:
            self.started = False
            self.server.release(self)

    def _handle(self, message_type: int, payload: bytes) -> None:
        controller = self.server.controller
        if message_type == rtde.REQUEST_PROTOCOL_VERSION:
            (version,) = struct.unpack(">H", payload)
            self.send(message_type, struct.pack(">B", version == PROTOCOL_VERSION))
        elif message_type == rtde.GET_URCONTROL_VERSION:
            self.send(message_type, struct.pack(">4I", *controller.series.version))
        elif message_type == rtde.SETUP_OUTPUTS:
            (frequency,) = struct.unpack(">d", payload[:8])
            names = [n for n in payload[8:].decode().split(",") if n]
            types = [rtde.OUTPUT_TYPES.get(n, "NOT_FOUND") for n in names]
            if "NOT_FOUND" not in types:
                self.output = Recipe(names, types)
                rate = controller.series.rate_hz
                self.output_every = max(1, round(rate / frequency)) if frequency > 0 else 1
            self.send(message_type, struct.pack(">B", 1) + ",".join(types).encode())
        elif message_type == rtde.SETUP_INPUTS:
            names = [n for n in payload.decode().split(",") if n]
            types = self.server.claim(self, names)
            recipe_id = 0
            if "NOT_FOUND" not in types and "IN_USE" not in types:
                recipe_id = len(self.inputs) + 1
                self.inputs[recipe_id] = Recipe(names, types)
            self.send(message_type, struct.pack(">B", recipe_id) + ",".join(types).encode())
        elif message_type == rtde.START:
            self.started = self.output is not None or bool(self.inputs)
            self.send(message_type, struct.pack(">B", self.started))
        elif message_type == rtde.PAUSE:
            self.started = False
            self.send(message_type, struct.pack(">B", 1))
        elif message_type == rtde.DATA_PACKAGE:
            recipe = self.inputs.get(payload[0])
            if recipe is None:
                log.warning("data package for unknown input recipe %d", payload[0])
                return
            values = rtde.group(recipe.types, recipe.layout.unpack(payload[1:]))
            with controller.lock:
                controller.write_inputs(recipe.names, values)
        else:
            log.warning("RTDE message type %d not handled", message_type)

    def send_outputs(self, cycle: int) -> None:
        """The output package of this cycle, if the client's frequency asks for one."""
        recipe = self.output
        if not self.started or recipe is None or cycle % self.output_every:
            return
        controller = self.server.controller
        with controller.lock:
            values = controller.output_values(recipe.names)
            lag = 0.0 if self.inputs else controller.reader_lag_s
        package = b"\x01" + recipe.layout.pack(*rtde.flatten(values))
        if lag <= 0.0 and not self._late:
            self.send(rtde.DATA_PACKAGE, package)
            return
        # a client that only reads (RTDEReceiveInterface) gets each package ``lag`` late, in order:
        # as a reader on a loaded host or a congested link sees the controller
        now = time.monotonic()
        self._late.append((now, package))
        while self._late and self._late[0][0] <= now - lag:
            self.send(rtde.DATA_PACKAGE, self._late.popleft()[1])


class RTDEServer:
    """All RTDE connections and which of them owns which input variable."""

    def __init__(self, controller: Controller, unread_limit_s: float = UNREAD_LIMIT_S) -> None:
        self.controller = controller
        self.unread_limit_s = unread_limit_s
        self.connections: list[RTDEConnection] = []
        self._owners: dict[str, RTDEConnection] = {}
        self._lock = threading.Lock()

    def handle(self, sock: socket.socket) -> None:
        connection = RTDEConnection(sock, self)
        with self._lock:
            self.connections.append(connection)
        connection.serve()

    def claim(self, connection: RTDEConnection, names: list[str]) -> list[str]:
        """Types of an input recipe; ``IN_USE`` where another client owns the variable."""
        with self._lock:
            types = []
            for name in names:
                owner = self._owners.get(name)
                if name not in rtde.INPUT_TYPES:
                    types.append("NOT_FOUND")
                elif owner is not None and owner is not connection:
                    types.append("IN_USE")
                else:
                    types.append(rtde.INPUT_TYPES[name])
            if "NOT_FOUND" not in types and "IN_USE" not in types:
                for name in names:
                    self._owners[name] = connection
            return types

    def release(self, connection: RTDEConnection) -> None:
        with self._lock:
            self._owners = {n: c for n, c in self._owners.items() if c is not connection}
            if connection in self.connections:
                self.connections.remove(connection)

    def broadcast(self, cycle: int) -> None:
        with self._lock:
            connections = list(self.connections)
        for connection in connections:
            # a closed socket: its reader thread sees it and releases the connection
            with contextlib.suppress(OSError):
                connection.send_outputs(cycle)
                connection.flush()
