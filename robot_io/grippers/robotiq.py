"""A Robotiq 2F-85 through the Robotiq URCap's gripper socket (``[gripper] kind = "robotiq_socket"``).

The URCap listens on the controller, TCP port 63352, one ASCII command a line: ``SET VAR n [VAR n …]``
(answered ``ack``) and ``GET VAR`` (answered ``VAR n``). The variables used here:

- ``ACT`` activation request, ``GTO`` go to the requested position, ``ATR`` automatic release;
- ``POS`` requested position when set, measured finger position when read (0 open … 255 closed),
  ``SPE`` speed and ``FOR`` force (0–255), ``PRE`` the echo of the requested position;
- ``STA`` gripper status (0 reset, 1 activating, 3 activated), ``FLT`` fault code (0 none), ``OBJ``
  object detection (0 moving, 1 stopped on contact while opening, 2 stopped on contact while closing —
  an object is held —, 3 at the requested position, no object).

Activation is the URCap's own ``rq_activate_and_wait``: only if ``STA`` is not 3, reset (``ACT 0``,
``ATR 0``) until ``ACT`` and ``STA`` read 0, then ``ACT 1`` until ``STA`` reads 3. A move sets
``POS``, ``SPE``, ``FOR`` and ``GTO 1`` in one line, waits for ``PRE`` to echo the position (until
then ``OBJ`` still describes the previous move), then for ``OBJ`` to leave 0.

The control loop must never wait on a network: one worker thread owns the socket. :meth:`close`
(in prepare, the arm still) waits for the fingers to stop on the object; :meth:`open` (in the hold, at
the control rate) only queues the move and returns, and the worker waits for it to end. While the
object is held the worker polls ``OBJ`` and ``FLT``; a URCap that stops answering, a fault code, or the
object lost (``OBJ`` leaving 2) is a :class:`~robot_io.errors.GripperFault` that :meth:`check` raises
in the control loop's next cycle, which stops the arm as every device fault does.
"""

from __future__ import annotations

import logging
import queue
import socket
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from enum import IntEnum
from typing import Annotated, Literal

from pydantic import Field, model_validator

from robot_io.arms.arm import ArmKind
from robot_io.bounds import in_range
from robot_io.errors import ConfigError, GripperFault
from robot_io.grippers.gripper import GripperKind

log = logging.getLogger(__name__)

#: How often the worker reads the gripper's state while it waits or holds [s].
POLL_S = 0.02
#: Activation opens and closes the fingers fully once (a few seconds on a 2F-85) [s].
ACTIVATION_TIMEOUT_S = 15.0
#: Status ``STA`` of an activated gripper.
ACTIVATED = 3


class ObjectFault(GripperFault):
    """No object where one should be: none detected by a close, or the held one slipped out (``OBJ``
    left 2). The trial's fault, not the gripper's: the gripper still moves, and the next close clears
    it."""


class Obj(IntEnum):
    """``OBJ``: what stopped the fingers."""

    MOVING = 0
    CONTACT_OPENING = 1
    CONTACT_CLOSING = 2  # the object is held
    AT_POSITION = 3  # no object


@dataclass(frozen=True)
class RobotiqStatus:
    """One reading of the gripper: activation status, finger position, object detection, fault."""

    sta: int
    pos: int
    obj: Obj
    flt: int

    def describe(self) -> str:
        activated = "activated" if self.sta == ACTIVATED else f"NOT activated (STA {self.sta})"
        fault = "no fault" if self.flt == 0 else f"fault code {self.flt}"
        return f"{activated}, position {self.pos}/255, OBJ {int(self.obj)} ({self.obj.name.lower()}), {fault}"


class URCapLink:
    """The request–reply socket of the URCap: one line out, one answer in, each within ``timeout``."""

    def __init__(self, host: str, port: int, timeout: float) -> None:
        self.address, self.timeout = f"{host}:{port}", timeout
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout)
        except OSError as exc:
            raise GripperFault(f"gripper: no Robotiq URCap answering on {self.address} ({exc}): is the "
                               "URCap installed and the gripper connected, and [gripper] host and port "
                               "right?") from exc
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def request(self, line: str) -> str:
        """Send ``line``; its answer (the URCap ends none with a newline: one reply, one read)."""
        try:
            self._sock.sendall(f"{line}\n".encode("ascii"))
            reply = self._sock.recv(1024)
        except TimeoutError as exc:
            raise GripperFault(f"gripper: the Robotiq URCap on {self.address} did not answer {line!r} "
                               f"within reply_timeout_s = {self.timeout:g} s") from exc
        except OSError as exc:
            raise GripperFault(f"gripper: the connection to the Robotiq URCap on {self.address} "
                               f"failed: {exc}") from exc
        if not reply:
            raise GripperFault(f"gripper: the Robotiq URCap on {self.address} closed the connection")
        return reply.decode("ascii", "replace").strip()

    def set(self, **values: int) -> None:
        line = "SET " + " ".join(f"{name} {value}" for name, value in values.items())
        if (reply := self.request(line)) != "ack":
            raise GripperFault(f"gripper: the Robotiq URCap on {self.address} answered {reply!r} to "
                               f"{line!r}, not 'ack'")

    def get(self, name: str) -> int:
        reply = self.request(f"GET {name}")
        words = reply.split()
        if len(words) != 2 or words[0] != name or not words[1].isdigit():
            raise GripperFault(f"gripper: the Robotiq URCap on {self.address} answered {reply!r} to "
                               f"'GET {name}'")
        return int(words[1])

    def object_status(self) -> Obj:
        value = self.get("OBJ")
        if value not in Obj._value2member_map_:
            raise GripperFault(f"gripper: the Robotiq URCap on {self.address} answered OBJ {value} "
                               "(0–3 expected)")
        return Obj(value)

    def status(self) -> RobotiqStatus:
        return RobotiqStatus(sta=self.get("STA"), pos=self.get("POS"), obj=self.object_status(),
                             flt=self.get("FLT"))

    def await_value(self, ready: Callable[[], bool], what: str, timeout: float) -> None:
        """Poll until ``ready()``; a fault naming ``what`` after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while not ready():
            if time.monotonic() > deadline:
                raise GripperFault(f"gripper: {what} within {timeout:g} s")
            time.sleep(POLL_S)

    def close(self) -> None:
        self._sock.close()


def activate(link: URCapLink) -> None:
    """Activate the gripper unless it is (the fingers open and close fully once)."""
    if link.get("STA") == ACTIVATED:
        return
    log.info("gripper: activating the Robotiq gripper on %s", link.address)
    link.set(ACT=0, ATR=0)
    link.await_value(lambda: link.get("ACT") == 0 and link.get("STA") == 0,
                     "the Robotiq gripper did not reset (ACT 0, STA 0)", ACTIVATION_TIMEOUT_S)
    link.set(ACT=1)
    link.await_value(lambda: link.get("STA") == ACTIVATED, "the Robotiq gripper did not activate (STA 3)",
                     ACTIVATION_TIMEOUT_S)
    link.set(GTO=1)


def probe(host: str, config: RobotiqSocketKind) -> RobotiqStatus:
    """The gripper's status, read without activating or moving it (``handover check-devices``)."""
    link = URCapLink(host, config.port, config.reply_timeout_s)
    try:
        return link.status()
    finally:
        link.close()


class RobotiqSocketGripper:
    """The :class:`~robot_io.grippers.gripper.Gripper` of a Robotiq 2F-85 on the URCap socket at ``host``.

    Connects and activates (only if not activated) when made. :attr:`holding` is True once a close
    stopped on the object (``OBJ`` 2) and until the next open is commanded; :attr:`detected` says
    whether the last close found an object.
    """

    def __init__(self, host: str, config: RobotiqSocketKind) -> None:
        self.config = config
        self._link = URCapLink(host, config.port, config.reply_timeout_s)
        try:
            activate(self._link)
            self.status = self._link.status()
            if self.status.flt:
                raise GripperFault(f"gripper: the Robotiq gripper on {self._link.address} reports fault "
                                   f"code {self.status.flt} (GET FLT): clear it on the teach pendant")
        except BaseException:
            self._link.close()
            raise
        self._holding = False
        self.detected: bool | None = None
        self._fault: GripperFault | None = None
        self._jobs: queue.Queue[tuple[Callable[[], None], Future] | None] = queue.Queue()  # None: end
        self._worker = threading.Thread(target=self._work, name="robotiq-gripper", daemon=True)
        self._worker.start()
        log.info("gripper: Robotiq on %s, %s", self._link.address, self.status.describe())

    @property
    def holding(self) -> bool:
        """Closed on the object (as last commanded and detected)."""
        return self._holding

    # -- the Gripper interface ---------------------------------------------------------------------
    def close(self) -> None:
        """Close on the object and wait until the fingers stop; a fault unless they stopped on it."""
        if isinstance(self._fault, ObjectFault):
            self._fault = None  # a new object, a new grip
        self.check()
        done = self._submit(self._close)
        try:  # a ceiling: the worker bounds each request and each move (an open may be queued first)
            done.result(timeout=2 * (self.config.move_timeout_s + 4 * self.config.reply_timeout_s))
        except TimeoutError as exc:
            raise GripperFault(f"gripper: the close did not end within move_timeout_s = "
                               f"{self.config.move_timeout_s:g} s") from exc

    def open(self) -> None:
        """Command the fingers open and return at once (the worker waits for the move to end)."""
        self._holding = False
        self._submit(self._open)

    def check(self) -> None:
        """Raise the fault the worker found (no I/O: cheap enough for every control cycle)."""
        if self._fault is not None:
            raise self._fault

    def disconnect(self) -> None:
        """End the worker, then close its socket (never under a worker still in a request: the
        socket's number could be reused by then); a worker that does not end keeps it (logged)."""
        self._jobs.put(None)
        self._worker.join(timeout=self.config.move_timeout_s + 2 * self.config.reply_timeout_s)
        if self._worker.is_alive():
            log.error("gripper: its worker did not end; its URCap socket stays open until the rig "
                      "exits")
            return
        self._link.close()

    # -- the worker --------------------------------------------------------------------------------
    def _submit(self, job: Callable[[], None]) -> Future:
        done: Future = Future()
        self._jobs.put((job, done))
        return done

    def _work(self) -> None:
        """Run the queued moves; between them, while holding, watch the object and the fault code.
        A fault stays (the link's or the gripper's state is unknown after it): every later move
        raises it — except an :class:`ObjectFault`, which the next close clears."""
        while True:
            try:
                job = self._jobs.get(timeout=POLL_S)
            except queue.Empty:
                if self._holding and self._fault is None:
                    self._attempt(self._watch)
                continue
            if job is None:
                return
            move, done = job
            sticky = None if isinstance(self._fault, ObjectFault) else self._fault
            if (fault := sticky or self._attempt(move)) is not None:
                done.set_exception(fault)
            else:
                done.set_result(None)

    def _attempt(self, action: Callable[[], None]) -> GripperFault | None:
        """Run ``action``; the fault it met (recorded, the object no longer held), or None. An
        unexpected error is a fault too: the worker must outlive it to report it."""
        try:
            action()
        except Exception as exc:
            fault = exc if isinstance(exc, GripperFault) else GripperFault(
                f"gripper: the Robotiq gripper's worker failed: {type(exc).__name__}: {exc}")
            log.error("%s", fault)
            self._fault = self._fault or fault
            self._holding = False
            return fault
        return None

    def _move(self, position: int) -> RobotiqStatus:
        """Go to ``position`` at the configured speed and force; the status once the fingers stop."""
        config, link = self.config, self._link
        link.set(POS=position, SPE=config.speed, FOR=config.force, GTO=1)
        link.await_value(lambda: link.get("PRE") == position,
                         f"the Robotiq gripper did not take position request {position} (GET PRE)",
                         config.move_timeout_s)
        link.await_value(lambda: link.get("OBJ") != Obj.MOVING,
                         f"the Robotiq gripper's move to {position} did not end "
                         f"(move_timeout_s = {config.move_timeout_s:g})", config.move_timeout_s)
        status = link.status()
        if status.flt:
            raise GripperFault(f"gripper: the Robotiq gripper reports fault code {status.flt} (GET FLT) "
                               f"after a move to {position}: {status.describe()}")
        return status

    def _close(self) -> None:
        status = self._move(self.config.closed_position)
        self.status = status
        self.detected = status.obj is Obj.CONTACT_CLOSING
        if not self.detected:  # open again, so that the object can be loaded for the repeat
            self.status = self._move(self.config.open_position)
            raise ObjectFault(f"gripper: the Robotiq gripper closed to {status.pos}/255 without "
                              f"detecting an object (OBJ {int(status.obj)}) and opened again: is the "
                              "object loaded?")
        self._holding = True
        log.info("gripper closed on the object at position %d", status.pos)

    def _open(self) -> None:
        self.status = self._move(self.config.open_position)
        self.detected = False
        if self.status.obj is Obj.CONTACT_OPENING:
            log.warning("gripper: the fingers stopped on contact while opening, at %d/255",
                        self.status.pos)
        log.info("gripper opened to position %d", self.status.pos)

    def _watch(self) -> None:
        """One look at the held object: lost (``OBJ`` left 2) or a fault code is a fault."""
        obj, flt = self._link.object_status(), self._link.get("FLT")
        if flt:
            raise GripperFault(f"gripper: the Robotiq gripper reports fault code {flt} (GET FLT) while "
                               "holding the object")
        if self._holding and obj is not Obj.CONTACT_CLOSING:
            raise ObjectFault(f"gripper: the object was lost while holding (OBJ went from 2 to "
                              f"{int(obj)}): the fingers closed past it")


#: A Robotiq register value (position, speed, force): one byte.
RobotiqByte = Annotated[int, Field(ge=0, le=255)]
#: The Robotiq URCap's gripper socket on the controller (its manual, "Control over the socket").
ROBOTIQ_PORT = 63352


class RobotiqSocketKind(GripperKind):
    """``[gripper] kind = "robotiq_socket"``: a Robotiq 2F-85 through its URCap's socket
    (:class:`RobotiqSocketGripper`)."""

    kind: Literal["robotiq_socket"]
    host: str | None = Field(
        None, description="robotiq_socket: address of the controller whose URCap drives the gripper; "
                          "unset: [ur] host (the URCap runs on the UR's controller); never assumed")
    port: int = Field(ROBOTIQ_PORT, ge=1, le=65535,
                      description="robotiq_socket: the URCap's gripper socket (63352 on every controller)")
    speed: RobotiqByte = Field(255, description="robotiq_socket: finger speed, 0 (20 mm/s) to 255 "
                                                "(150 mm/s on a 2F-85)")
    force: RobotiqByte = Field(50, description="robotiq_socket: grip force, 0 (20 N) to 255 (235 N on a "
                                               "2F-85); low enough that a pull opens no finger")
    open_position: RobotiqByte = Field(0, description="robotiq_socket: finger position that opens "
                                                      "(0: fully open, 85 mm on a 2F-85)")
    closed_position: RobotiqByte = Field(255, description="robotiq_socket: finger position commanded "
                                                          "to close (255: fully closed); the object "
                                                          "stops the fingers before it")
    move_timeout_s: Annotated[float, in_range(0, 30, "s")] = Field(
        5.0, description="robotiq_socket: a close or an open that has not ended within this long is "
                         "a fault [s] (a full 2F-85 stroke takes 0.6 s at speed 255, 4.3 s at 0)")
    reply_timeout_s: Annotated[float, in_range(0, 10, "s")] = Field(
        1.0, description="robotiq_socket: no answer from the URCap within this long is a fault [s]")

    def complete(self, arm: ArmKind, controller: str | None) -> None:
        """The URCap's address is never assumed."""
        if self.host is None and controller is None:
            raise ConfigError('[gripper] host is not set and neither is [ur] host; [gripper] kind = '
                              '"robotiq_socket" needs the address of the controller its URCap runs '
                              'on. Set [gripper] host (or [ur] host): it has no default')

    def address(self, controller: str | None) -> str | None:
        return self.host or controller

    def open(self, controller: str | None) -> RobotiqSocketGripper:
        return RobotiqSocketGripper(self._at(controller), self)

    def describe(self, controller: str | None) -> str:
        return f"Robotiq 2F-85 on {self.address(controller)}:{self.port}"

    def check(self, controller: str | None) -> str:
        """Reachable, and its activation, position and fault code (read, never activated or moved)."""
        status = probe(self._at(controller), self)
        where = f"Robotiq URCap on {self.address(controller)}:{self.port}, {status.describe()}"
        if status.flt:
            return f"NOT OK — {where}: clear the fault on the teach pendant"
        if status.sta != ACTIVATED:
            return (f"{where}; not moved: it activates when the rig opens it (the fingers open and "
                    "close once)")
        return f"{where} (not moved)"

    @model_validator(mode="after")
    def _closes_past_open(self) -> RobotiqSocketKind:
        if self.closed_position <= self.open_position:
            raise ConfigError(f"gripper.closed_position = {self.closed_position} must be above "
                              f"gripper.open_position = {self.open_position} (0 open … 255 closed)")
        return self


