"""Rehearsal without hardware on the real code path (``serve --rehearse``, ``run-session --rehearse``).

It starts the project's stand-in UR controller (:mod:`robot_io.standins.ur`) on a free loopback
address and a hand publisher (:mod:`robot_io.standins.hand_publisher`) that plays the simulated participant's
hand on LSL (or UDP, or as a rigid body of a stand-in NatNet server) and makes the stand-in pull on
the object once the hand holds it at H. The lab configuration is pointed at them — ``[arm] kind =
"ur"`` at that address, ``[hand_source]`` the publisher's stream, ``[gripper]`` the UR's tool output,
or, when the lab's file says ``[gripper] kind = "robotiq_socket"``, the stand-in's Robotiq URCap
socket at that address — so a session runs through ``ur_rtde``, ``pylsl`` (or ``natnet``), the lab's
kind of gripper and the force release exactly as on the rig. The stand-in and the publisher run under
SCHED_FIFO where the OS allows it (``realtime_priority``): the controller and the tracker they stand
for have hardware of their own, which this machine's load cannot slow. A lab whose ``[recording]``
drives its LabRecorder over the remote control (``kind = "labrecorder_rcs"``) rehearses against the
project's stand-in LabRecorder (:mod:`robot_io.standins.labrecorder_rcs`, LabRecorder's own engine)
on a free loopback port instead, so the recording is rehearsed too without LabRecorder's GUI.
"""

from __future__ import annotations

import contextlib
import logging
import os
import random
import socket
import subprocess
import sys
from collections.abc import Callable
from typing import Literal

import numpy as np
import pylsl

from app.session.config import LabConfig
from app.session.lsl_outlets import outlet_names
from robot_io.arms.kinds import ARMS
from robot_io.grippers.gripper import GripperKind, ToolOutputKind
from robot_io.grippers.kinds import GRIPPERS
from robot_io.grippers.robotiq import ROBOTIQ_PORT, RobotiqSocketKind
from robot_io.hands.config import NatNetSource, UDPSource
from robot_io.hands.simulated_hand import Scenario
from robot_io.standins.hand_publisher import HandPublisher, PublisherSpec
from robot_io.standins.labrecorder_rcs import RemoteControl, StandInLabRecorder
from robot_io.standins.ur.control import ControlClient
from robot_io.standins.ur.control_script import MOVEL
from robot_io.standins.ur.standin import RTDE_PORT

log = logging.getLogger(__name__)

HandKind = Literal["lsl", "udp", "natnet"]
#: The rigid body a NatNet rehearsal streams the hand as when the lab names none.
REHEARSAL_RIGID_BODY = "hand"
#: How long the rig waits to resolve the rehearsal's own hand stream [s]. The stream is known to be
#: up (its publisher runs): the lab's resolve_timeout_s (5 s) is for a tracker that may be off, and
#: on a loaded machine the rig's resolve of a running stream took longer than that.
PUBLISHED_RESOLVE_S = 30.0


def free_loopback_host() -> str:
    """A 127.0.0.x address whose RTDE port is free (the stand-in's ports are fixed, as a UR's)."""
    for _ in range(200):
        host = f"127.0.{random.randint(1, 254)}.{random.randint(2, 254)}"
        with socket.socket() as probe, contextlib.suppress(OSError):
            probe.bind((host, RTDE_PORT))
            return host
    raise OSError("no free loopback address for the stand-in controller")


def free_udp_port(host: str) -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]


#: What a rehearsal chooses afresh on every run (a free loopback address, a stream name, a port).
#: It is not the rig: resuming a rehearsed session in a new rehearsal is not a rig change.
CHOSEN_PER_RUN = {"ur": ("host",), "gripper": ("host",),
                  "hand_source": ("lsl_stream_name", "udp_host", "udp_port", "natnet_server",
                                  "natnet_command_port")}


def rehearsal_rig(rig: dict) -> dict:
    """``rig`` (the rig tables, as JSON) as a rehearsal is compared with another: what it chooses
    per run reads ``"rehearsal"``."""
    return {table: None if values is None else
            {key: "rehearsal" if key in CHOSEN_PER_RUN.get(table, ()) else value
             for key, value in values.items()}
            for table, values in rig.items()}


def rehearsal_gripper(gripper: GripperKind, host: str) -> RobotiqSocketKind | ToolOutputKind:
    """The lab's gripper on the stand-in at ``host``: a Robotiq on the stand-in's URCap socket; any
    other kind (none included) on the stand-in's tool output, as the rehearsal always drove it."""
    if isinstance(gripper, RobotiqSocketKind):
        return gripper.model_copy(update={"host": host, "port": ROBOTIQ_PORT})
    output = GRIPPERS.as_kind(gripper, "tool_output")
    assert isinstance(output, ToolOutputKind), "the tool_output kind's model"
    return output


def tool_output_of(gripper: GripperKind) -> ToolOutputKind:
    """The tool output the stand-in watches: a tool-output gripper's, else the kind's default."""
    return gripper if isinstance(gripper, ToolOutputKind) else ToolOutputKind(kind="tool_output")


def recorded_by_rehearsal(lab: LabConfig, hand_stream: str) -> Callable[[pylsl.StreamInfo], bool]:
    """What a rehearsal's stand-in LabRecorder sees of the network: the session's own outlets
    (``<[record] lsl_name>-robot`` and ``-markers``), the rehearsal's hand on LSL (``hand_stream``)
    and the lab's ``[recording] streams`` by name or type. LabRecorder would record every stream on
    the network; a rehearsal records its own, so that two on one machine do not record each other."""
    named = {*outlet_names(lab.record), hand_stream, *lab.recording.streams}
    return lambda info: info.name() in named or info.type() in lab.recording.streams


def gripper_moves(gripper: GripperKind, events: list[str]) -> tuple[int, int]:
    """How often the stand-in's events show the gripper opened and closed."""
    if isinstance(gripper, RobotiqSocketKind):
        return (sum(event.startswith("robotiq: opening") for event in events),
                sum(event.startswith("robotiq: closing") for event in events))
    output = tool_output_of(gripper)
    opened = closed = 0
    previous = None
    for event in events:
        if event.startswith("tool digital outputs = "):
            state = bool(int(event.rsplit(" ", 1)[1], 2) >> output.tool_output & 1) == output.open_level
            if state != previous:
                opened, closed = opened + state, closed + (not state)
            previous = state
    return opened, closed


class Rehearsal:
    """The stand-in controller and the hand publisher; :meth:`close` ends both."""

    def __init__(self, lab: LabConfig, hand: HandKind = "lsl", series: str = "cb3",
                 realtime_priority: bool = True) -> None:
        self.host = free_loopback_host()
        self.standin = subprocess.Popen(
            [sys.executable, "-m", "robot_io.standins.ur", "--host", self.host, "--series", series,
             "--exit-with-stdin", *(["--realtime-priority"] if realtime_priority else [])],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
            # a session of its own, as a real controller is no process of the terminal's: Ctrl-C
            # (and Ctrl-Z) there are the application's, which stops the arm and then ends the
            # stand-in (its stdin); killed by Ctrl-C, it took the arm away mid-trial
            start_new_session=True)
        self.publisher: HandPublisher | None = None
        #: the stand-in LabRecorder's remote control (a ``labrecorder_rcs`` lab only)
        self.recorder: RemoteControl | None = None
        try:
            assert self.standin.stdout is not None, "started with stdout=PIPE"
            line = self.standin.stdout.readline()
            if line.strip() != f"ready {self.host}":
                raise OSError(f"the stand-in controller did not start ({line.strip()!r})")
            stream = f"handover-rehearsal-{os.getpid()}-{self.host}"
            resolve = max(getattr(lab.hand_source, "resolve_timeout_s", 0.0), PUBLISHED_RESOLVE_S)
            if hand == "udp":
                played = {"udp_host": "127.0.0.1", "udp_port": free_udp_port("127.0.0.1")}
            elif hand == "natnet":  # its command port is the stand-in's, known once it has bound it
                played = {"natnet_server": "127.0.0.1", "natnet_local_address": None, "units_to_m": 1.0,
                          "resolve_timeout_s": resolve, "natnet_rigid_body": getattr(
                              lab.hand_source, "natnet_rigid_body", None) or REHEARSAL_RIGID_BODY}
            else:
                played = {"lsl_stream_name": stream, "resolve_timeout_s": resolve}
            source = lab.hand_source.as_kind(hand, **played)
            self.lab = lab.with_rig(
                arm=ARMS.as_kind(lab.arm, "ur"),
                ur=lab.ur.model_copy(update={"host": self.host}),
                hand_source=source,
                gripper=rehearsal_gripper(lab.gripper, self.host))
            self.control = ControlClient(self.host)
            self.configure_pull(taken=True)
            self.publisher = HandPublisher(PublisherSpec(
                config=self.lab.controller, standin_host=self.host,
                lsl_name=stream if hand == "lsl" else None,
                udp_target=((source.udp_host, source.udp_port) if isinstance(source, UDPSource)
                            else None),
                natnet_rigid_body=(source.natnet_rigid_body if isinstance(source, NatNetSource)
                                   else None),
                realtime_priority=realtime_priority))
            if hand == "natnet":
                self.lab = self.lab.with_rig(hand_source=source.model_copy(
                    update={"natnet_command_port": self.publisher.natnet_port}))
            if lab.recording.kind == "labrecorder_rcs":
                self.recorder = RemoteControl(StandInLabRecorder(
                    sees=recorded_by_rehearsal(lab, stream)))
                log.info("rehearsal: the stand-in LabRecorder's remote control on 127.0.0.1:%d "
                         "instead of the lab's at %s:%d", self.recorder.port, lab.recording.rcs_host,
                         lab.recording.rcs_port)
                self.lab = self.lab.model_copy(update={"recording": lab.recording.model_copy(
                    update={"rcs_host": "127.0.0.1", "rcs_port": self.recorder.port})})
        except BaseException:
            self.close()
            raise
        log.info("rehearsal: stand-in UR at %s, simulated hand on %s", self.host, hand)

    def configure_pull(self, taken: bool) -> None:
        """The stand-in's pull once the simulated hand holds the object at H: the lab's
        ``[hand] pull_n`` away from H towards the hand's start, or none (``taken=False``: the
        participant never takes the object, so the hold ends ``not_taken``)."""
        scene = self.lab.scene
        self.control("configure_pull", direction=list(scene.point("hand_start")
                                                      - scene.point("handover_point")),
                     pull_n=self.lab.hand.pull_n if taken else 0.0,
                     grasp_delay_s=self.lab.hand.grasp_delay_s,
                     tool_output=tool_output_of(self.lab.gripper).tool_output,
                     open_level=tool_output_of(self.lab.gripper).open_level,
                     gripper=self.lab.gripper.kind)

    def play(self, scenario: Scenario, seed: int, go_monotonic: float) -> None:
        self.hand_publisher().play(scenario, seed, go_monotonic)

    def rest(self) -> None:
        self.hand_publisher().rest()

    def hand_publisher(self) -> HandPublisher:
        """The simulated hand (None only while ``__init__`` runs, which closes the rehearsal if it
        fails)."""
        assert self.publisher is not None, "a rehearsal has its hand once it is made"
        return self.publisher

    def observed(self) -> dict[str, int | float]:
        """What the stand-in controller saw: gripper openings and closings (on the tool output, or
        the Robotiq's moves), moves to R, and where the TCP is now (distance to R, m)."""
        start = self.lab.scene.point("robot_start")
        opened, closed = gripper_moves(self.lab.gripper, self.control("events")["events"])
        moves_to_r = sum(1 for _, command, values in self.control("received")["received"]
                         if command == MOVEL and np.linalg.norm(np.asarray(values[:3]) - start) < 1e-6)
        pose = np.asarray(self.control("state")["pose"][:3])
        return {"gripper_opened": opened, "gripper_closed": closed, "moves_to_R": moves_to_r,
                "tcp_to_R_m": float(np.linalg.norm(pose - start))}

    def close(self) -> None:
        if self.recorder is not None:  # the session has stopped its recording before this
            self.recorder.close()
        if self.publisher is not None:
            self.publisher.close()
        with contextlib.suppress(Exception):
            self.control.close()
        if self.standin.stdin:
            self.standin.stdin.close()
        try:
            self.standin.wait(5)
        except subprocess.TimeoutExpired:
            self.standin.kill()
            self.standin.wait(5)
        if self.standin.stdout:
            self.standin.stdout.close()  # its pipe now, not when the garbage collector gets to it
