"""``[hand_source]``: one table per kind of hand source, each with its own keys and defaults, and
the tracker → robot-base calibration they share (``docs/hardware.md``).

The table's ``kind`` chooses the model (a pydantic discriminated union): ``kind = "natnet"``
validates NatNet's keys only, with NatNet's defaults (``units_to_m = 1.0``: NatNet streams metres).
The keys are those a lab writes (``natnet_server``, ``vicon_subject``, ``lsl_stream_type`` …). A key
of another kind is refused naming the kind it belongs to, unless it holds that kind's default: a
table written before the kinds had tables of their own (and every session stored then) lists every
kind's keys, and a default says nothing.

Each kind registers itself once, in :data:`HAND_SOURCES` (a :class:`robot_io.kinds.Kinds`, the
pattern arms and grippers follow too): its model names the class that reads it
(:attr:`HandSourceBase.reader`, imported only when it is opened, so reading a configuration never
imports a tracker's client library).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, TypeAlias

import numpy as np
from pydantic import Field, field_validator, model_validator

from robot_io.bounds import ROTATION_TOLERANCE, RotationRow, ScenePoint, in_range
from robot_io.errors import ConfigError
from robot_io.kinds import DeviceKind, Kinds

if TYPE_CHECKING:
    from robot_io.hands.frame import FrameTransform
    from robot_io.hands.tracked_hand import TrackedHand

#: How long to look for a stream (Vicon: its first frame) before giving up [s].
ResolveTimeout = Annotated[float, in_range(0, 60, "s")]
#: Tracker units → metres.
UnitsToM = Annotated[float, in_range(0, 1, "m per unit")]


class HandSourceBase(DeviceKind):
    """What every hand source shares: its kind and the tracker → robot-base calibration."""

    #: ``"module:Class"`` of the tracked hand that reads this kind; None: not a tracker.
    reader: ClassVar[str | None] = None
    #: The address the tracker serves on: (field, whose address it is, an example); never assumed.
    server: ClassVar[tuple[str, str, str] | None] = None
    #: Names the source reads, each required (field → what it needs): never "the first one streamed".
    names: ClassVar[Mapping[str, str]] = MappingProxyType({})
    #: The one unit the tracker streams (units_to_m, why): any other value is refused.
    unit: ClassVar[tuple[float, str] | None] = None

    units_to_m: UnitsToM = Field(0.001, description="tracker units → metres (Vicon, OptiTrack over "
                                                    "LSL: mm; NatNet streams metres: 1.0)")
    rotation: tuple[RotationRow, RotationRow, RotationRow] = Field(
        ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
        description="tracker → robot base rotation (rows), from `handover calibrate-tracker`")
    translation: ScenePoint = Field(
        (0.0, 0.0, 0.0), description="tracker → robot base translation [m]")

    @field_validator("rotation")
    @classmethod
    def _proper_rotation(cls, rotation: tuple) -> tuple:
        """A rotation, not any matrix: orthonormal within :data:`ROTATION_TOLERANCE` and det +1. A
        singular matrix would squash the hand onto a plane, a reflection mirror it."""
        matrix = np.array(rotation, dtype=float)
        error, det = float(np.max(np.abs(matrix.T @ matrix - np.eye(3)))), float(np.linalg.det(matrix))
        if error > ROTATION_TOLERANCE or det < 0:
            # (no "rotation" in the words: robot_io.errors.explain then prefixes the field and value)
            raise ValueError(f"must be orthonormal (|RᵀR − I| ≤ {ROTATION_TOLERANCE:g}, here {error:.3g}) "
                             f"with determinant +1 (here {det:.3g}): it turns, never squashes or "
                             "mirrors; paste the rows `handover calibrate-tracker` prints")
        return rotation

    @model_validator(mode="after")
    def _tracker_complete(self) -> HandSourceBase:
        """A tracker's server address (never assumed, as [ur] host), the names of what it reads
        (never "the first one streamed"), and the unit it streams: a units_to_m for another unit
        would put the hand a thousand times too close or too far."""
        if self.server is not None:
            field, whose, example = self.server
            if getattr(self, field) is None:
                raise ConfigError(f'[hand_source] {field} is not set; kind = "{self.kind}" needs {whose}. '
                                  f'Set it (e.g. {field} = "{example}"): it has no default, so no '
                                  "tracker at an assumed address is ever read")
        for field, needs in self.names.items():
            if not getattr(self, field):
                raise ConfigError(f'[hand_source] {field} is not set; kind = "{self.kind}" needs {needs}')
        if self.unit is not None and self.units_to_m != self.unit[0]:
            value, why = self.unit
            raise ConfigError(f"hand_source.units_to_m = {self.units_to_m:g} but {why}: set units_to_m = "
                              f'{value} with kind = "{self.kind}"')
        return self

    def open(self, transform: FrameTransform, max_speed: float) -> TrackedHand:
        """The tracked hand that reads this source, connected (its client library imported now)."""
        if self.reader is None:
            raise ConfigError(f'[hand_source] kind = "{self.kind}" is no tracker: it has nothing to open')
        module, name = self.reader.split(":")
        return getattr(importlib.import_module(module), name)(self, transform, max_speed)

    def as_kind(self, kind: str, **update: Any) -> HandSourceBase:
        """This table as ``kind``'s, validated anew: the calibration and every key both kinds have
        are kept, ``update`` is applied."""
        return HAND_SOURCES.as_kind(self, kind, **update)


class SimulatedSource(HandSourceBase):
    """The simulated participant's hand (``robot_io.hands.simulated_hand``); no tracker."""

    simulated = True

    kind: Literal["simulated"] = "simulated"


class LSLSource(HandSourceBase):
    """A Lab Streaming Layer stream of the hand marker (``robot_io.hands.lsl_hand``)."""

    reader = "robot_io.hands.lsl_hand:LSLHand"

    kind: Literal["lsl"]
    lsl_stream_type: str = Field("Mocap", description="LSL: type of the stream to resolve")
    lsl_stream_name: str | None = Field(None, description="LSL: name of the stream (None: any)")
    lsl_channels: tuple[int, int, int] = Field((0, 1, 2), description="LSL: channels of x, y, z")
    resolve_timeout_s: ResolveTimeout = Field(5.0, description="give up finding the stream after [s]")


class UDPSource(HandSourceBase):
    """JSON datagrams of the hand marker (``robot_io.hands.udp_hand``)."""

    reader = "robot_io.hands.udp_hand:UDPHand"

    kind: Literal["udp"]
    udp_host: str = Field("0.0.0.0", description="UDP: address to listen on")
    udp_port: int = Field(9870, ge=1, le=65535, description="UDP: port to listen on")


class NatNetSource(HandSourceBase):
    """OptiTrack Motive's NatNet stream, unicast (``robot_io.hands.natnet_hand``)."""

    reader = "robot_io.hands.natnet_hand:NatNetHand"
    server = ("natnet_server", "the Motive PC's address", "192.168.1.20")
    names = MappingProxyType({"natnet_rigid_body": "the name of the hand's rigid body as Motive "
                                                   'streams it (e.g. natnet_rigid_body = "hand")'})
    unit = (1.0, "NatNet streams metres")

    kind: Literal["natnet"]
    units_to_m: UnitsToM = Field(1.0, description="NatNet streams metres: 1.0 (the only value)")
    natnet_server: str | None = Field(
        None, description="NatNet: the Motive PC's address, required; never assumed (a stand-in: "
                          "127.0.0.1)")
    natnet_local_address: str | None = Field(
        None, description="NatNet: this machine's address to receive on (None: the one it reaches "
                          "natnet_server from)")
    natnet_command_port: int = Field(
        1510, ge=1, le=65535, description="NatNet: Motive's command port (Motive's default 1510)")
    natnet_rigid_body: str | None = Field(
        None, description="NatNet: the name of the hand's rigid body in Motive, required (never the "
                          "first one streamed)")
    resolve_timeout_s: ResolveTimeout = Field(5.0, description="give up finding the stream after [s]")


class ViconSource(HandSourceBase):
    """Vicon's DataStream through its SDK, the optional extra [vicon] (``robot_io.hands.vicon_hand``)."""

    reader = "robot_io.hands.vicon_hand:ViconHand"
    server = ("vicon_server", "the address of the PC running Vicon Tracker, Nexus or Shogun",
              "192.168.1.30")
    names = MappingProxyType({
        field: f'the hand\'s {what} name as Vicon streams it (e.g. {field} = "hand"; in Tracker an '
               "object's one segment has the object's name)"
        for field, what in (("vicon_subject", "subject"), ("vicon_segment", "segment"))})
    unit = (0.001, "the Vicon DataStream reports millimetres")

    kind: Literal["vicon"]
    vicon_server: str | None = Field(
        None, description="Vicon: the address of the PC that runs Tracker, Nexus or Shogun (its "
                          "DataStream server), required; never assumed")
    vicon_port: int = Field(
        801, ge=1, le=65535, description="Vicon: the DataStream port (801, the one Vicon serves on)")
    vicon_subject: str | None = Field(
        None, description="Vicon: the name of the hand's subject (Tracker: its object), required "
                          "(never the first one streamed)")
    vicon_segment: str | None = Field(
        None, description="Vicon: the segment of that subject whose position is the hand, required "
                          "(Tracker: an object's one segment has its name)")
    resolve_timeout_s: ResolveTimeout = Field(
        5.0, description="give up waiting for the first frame after [s]")


#: Every kind of hand source, by its ``kind``: the one place a new kind is registered.
HAND_SOURCES: Kinds[HandSourceBase] = Kinds(
    "hand_source", "simulated", SimulatedSource, LSLSource, UDPSource, NatNetSource, ViconSource)


if TYPE_CHECKING:
    #: To the type checker, a table of any kind: the field's type is made at run time.
    HandSourceConfig: TypeAlias = HandSourceBase
else:
    #: ``[hand_source]``: one of :data:`HAND_SOURCES`, chosen by ``kind``.
    HandSourceConfig = HAND_SOURCES.field(HandSourceBase)
