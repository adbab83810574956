"""A stand-in Motive per test (:mod:`robot_io.standins.natnet`) on 127.0.0.1, on a port of its own,
and the ``[hand_source]`` that reads it with the real ``natnet`` client."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager, nullcontext

import numpy as np

from robot_io.hands.config import NatNetSource
from robot_io.hands.frame import FrameTransform
from robot_io.standins.natnet import PROTOCOL_VERSION, NatNetStandin, Poses, RigidBodySpec
from support.hand_replay import TRACKER
from support.priority import realtime_threads

#: The tests' tracker frame (turned and offset as :data:`support.hand_replay.TRACKER`), in metres as
#: NatNet streams.
TRACKER_M = FrameTransform(TRACKER.rotation, TRACKER.translation, 1.0)
HAND, OBJECT = RigidBodySpec("hand", 7), RigidBodySpec("object", 9)


def to_tracker_m(base_xyz: np.ndarray) -> tuple[float, float, float]:
    """Robot base [m] → the tests' tracker frame [m]."""
    return tuple(TRACKER_M.invert(np.asarray(base_xyz, dtype=float)).tolist())


@contextmanager
def motive(poses: Poses, bodies: Sequence[RigidBodySpec] = (HAND, OBJECT),
           rate_hz: float = 120.0, port: int = 0,
           protocol: tuple[int, int] = PROTOCOL_VERSION, realtime: bool = False
           ) -> Iterator[NatNetStandin]:
    """A stand-in Motive streaming ``poses`` on 127.0.0.1 (port 0: the kernel's free port; the
    port of one that closed: that Motive restarted) in NatNet ``protocol``; closed when the block
    ends. ``realtime``: its threads under SCHED_FIFO, as Motive on a PC of its own, while the
    calling thread keeps its policy (a ``serve`` it starts inherits nothing)."""
    with realtime_threads() if realtime else nullcontext():
        server = NatNetStandin(bodies, poses, port=port, rate_hz=rate_hz, protocol=protocol).start()
    try:
        yield server
    finally:
        server.close()


def natnet_source(server: NatNetStandin, rigid_body: str = HAND.name, **update) -> NatNetSource:
    """``[hand_source]`` reading ``rigid_body`` from ``server``, calibrated as :data:`TRACKER_M`."""
    return NatNetSource(kind="natnet", natnet_server=server.address[0],
                            natnet_command_port=server.address[1], natnet_rigid_body=rigid_body,
                            units_to_m=1.0, rotation=tuple(map(tuple, TRACKER_M.rotation)),
                            translation=tuple(TRACKER_M.translation), resolve_timeout_s=10.0, **update)


def natnet_toml(server: NatNetStandin, rigid_body: str = HAND.name) -> str:
    """The ``lab.toml`` lines of :func:`natnet_source` (identity calibration)."""
    return (f'[hand_source]\nkind = "natnet"\nnatnet_server = "{server.address[0]}"\n'
            f"natnet_command_port = {server.address[1]}\nnatnet_rigid_body = \"{rigid_body}\"\n"
            "units_to_m = 1.0\n")
