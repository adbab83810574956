"""A stand-in Robotiq URCap: its gripper socket (port 63352, on the stand-in UR controller) and the
2F-85 it drives. It knows nothing of the controller: the controller holds a :class:`RobotiqModel`,
advances it each cycle and serves the socket under its own lock (:func:`serve`).

``SET VAR n [VAR n …]`` is answered ``ack``, ``GET VAR`` with ``VAR n`` (no newline, as the URCap
answers), an unknown command or variable with ``?``. The model, advanced each controller cycle:

- activation: ``ACT 1`` from reset makes ``STA`` 1 for :data:`ACTIVATION_S`, then 3; ``ACT 0``
  resets (``STA`` 0). Nothing moves before ``STA`` 3.
- a move: ``GTO 1`` with the requested ``POS`` (echoed by ``PRE``) ramps the fingers at the speed
  ``SPE`` stands for on a 2F-85 (20–150 mm/s over its 85 mm stroke), ``OBJ`` 0 meanwhile.
- the object: one of a given width sits between the fingers (``object_position``: the finger
  position where it stops them; None: no object). Closing past it stops there with ``OBJ`` 2; at the
  requested position with nothing in the way ``OBJ`` is 3. Taking the object away while it is held
  lets the fingers close on (``OBJ`` 0, then 3): the object lost.
- faults: ``fault`` is what ``GET FLT`` answers; ``answering`` False swallows every command unanswered
  (a URCap that hangs). The control port sets all three (``configure_robotiq``).
"""

from __future__ import annotations

import socket
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass

from robot_io.standins.ur.listener import read_lines

Event = Callable[[str], None]

#: How long activation takes in the model [s] (a real 2F-85 opens and closes once: seconds).
ACTIVATION_S = 0.5
#: A 2F-85's stroke [mm] and its finger speed at SPE 0 and 255 [mm/s].
STROKE_MM, SLOWEST_MM_S, FASTEST_MM_S = 85.0, 20.0, 150.0
#: The object the stand-in's gripper holds unless told otherwise: about 40 mm wide.
DEFAULT_OBJECT_POSITION = 135
MOVING, CONTACT_CLOSING, AT_POSITION = 0, 2, 3


@dataclass
class RobotiqModel:
    """The 2F-85's registers and fingers; guarded by the controller's lock."""

    act: int = 0
    gto: int = 0
    atr: int = 0
    sta: int = 0
    pre: int = 0
    spe: int = 255
    force: int = 0
    obj: int = AT_POSITION
    position: float = 0.0
    fault: int = 0
    answering: bool = True
    object_position: int | None = DEFAULT_OBJECT_POSITION
    activating_s: float = 0.0

    def read(self, name: str) -> int | None:
        values = {"ACT": self.act, "GTO": self.gto, "ATR": self.atr, "STA": self.sta, "PRE": self.pre,
                  "SPE": self.spe, "FOR": self.force, "OBJ": self.obj, "POS": round(self.position),
                  "FLT": self.fault}
        return values.get(name)

    def write(self, name: str, value: int) -> bool:
        """Set one register; False for an unknown one."""
        value = min(max(value, 0), 255)
        if name == "ACT":
            self.act = value
            if value == 0:
                self.sta, self.gto = 0, 0
            elif self.sta == 0:
                self.sta, self.activating_s = 1, 0.0
        elif name == "POS":
            self.pre = value
        elif name in ("GTO", "ATR", "SPE", "FOR"):
            setattr(self, {"GTO": "gto", "ATR": "atr", "SPE": "spe", "FOR": "force"}[name], value)
        else:
            return False
        return True

    def reply(self, line: str, event: Event) -> str | None:
        """The answer to one command line (None: say nothing); ``event`` logs what happened."""
        if not self.answering:
            return None
        words = line.split()
        if len(words) == 2 and words[0] == "GET" and (value := self.read(words[1])) is not None:
            return f"{words[1]} {value}"
        if len(words) >= 3 and words[0] == "SET" and len(words) % 2 == 1:
            pairs = [(name, int(value)) for name, value in zip(words[1::2], words[2::2], strict=True)
                     if value.isdigit()]
            if len(pairs) == len(words) // 2 and all(self.write(name, value) for name, value in pairs):
                moves = self.gto and self.sta == 3 and self.pre != round(self.position)
                if moves and any(name in ("GTO", "POS") for name, _ in pairs):
                    self.obj = MOVING
                    way = "closing" if self.pre > self.position else "opening"
                    event(f"robotiq: {way} to {self.pre} (speed {self.spe}, force {self.force})")
                return "ack"
        return "?"

    @property
    def holding(self) -> bool:
        """The fingers stopped on the object."""
        return self.obj == CONTACT_CLOSING

    def tick(self, dt: float, event: Event) -> None:
        """One controller cycle of activation and finger motion."""
        if self.sta == 1:
            self.activating_s += dt
            if self.activating_s >= ACTIVATION_S:
                self.sta = 3
                event("robotiq: activated")
            return
        if self.sta != 3 or not self.gto:
            return
        held_at = self.object_position
        blocked = held_at is not None and self.pre > held_at
        stop = min(self.pre, held_at) if held_at is not None and blocked and self.position <= held_at \
            else self.pre
        if self.obj == CONTACT_CLOSING and blocked:
            return
        speed = (SLOWEST_MM_S + (FASTEST_MM_S - SLOWEST_MM_S) * self.spe / 255) / STROKE_MM * 255
        step = speed * dt
        if abs(stop - self.position) > step:
            self.position += step if stop > self.position else -step
            self.obj = MOVING
            return
        self.position = float(stop)
        if stop != self.pre:
            if self.obj != CONTACT_CLOSING:
                event(f"robotiq: object detected at {stop}")
            self.obj = CONTACT_CLOSING
        else:
            self.obj = AT_POSITION


def serve(gripper: RobotiqModel, lock: AbstractContextManager, event: Event, sock: socket.socket) -> None:
    """One client of the URCap socket; commands are answered under ``lock`` (the controller's, which
    advances ``gripper`` each cycle), ``event`` logs what happened."""
    for line in read_lines(sock):
        with lock:
            answer = gripper.reply(line.strip(), event)
        if answer is not None:
            sock.sendall(answer.encode("ascii"))
