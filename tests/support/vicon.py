# ruff: noqa: N802  (the clients keep the method names of the SDKs they stand for)
"""Vicon's DataStream SDK as the Vicon hand source sees it, without the SDK (which does not install
here: docs/hardware.md, "Vicon (DataStream SDK)"): :class:`RecordedClient` replays frames in the
return shapes of Vicon's own Python client (``vicon_dssdk.ViconDataStream.Client``), and
:func:`pyvicon_module` is a ``pyvicon_datastream`` module (0.2.4) whose client returns what the real
one's C++ wrapper does."""

from __future__ import annotations

import enum
import json
import time
import types
from pathlib import Path

import numpy as np

from robot_io.hands.config import ViconSource
from support.hand_replay import TRACKER

#: Frames of a stream with the subjects "object" (first) and "hand" (tests/robot_io/data/).
RECORDED = json.loads((Path(__file__).parents[1] / "robot_io/data/vicon_frames.json").read_text())["frames"]
SERVER = "192.168.1.30"


class DataStreamException(Exception):
    """As ``vicon_dssdk``'s: a call the SDK refused, with the SDK's result's name."""


class RecordedClient:
    """Vicon's Python client replaying ``frames`` (each as in ``vicon_frames.json``): each
    ``GetFrame()`` takes the next one — with ``rate_hz``, the one whose time has come since the first
    call (those it passed are lost, as the prefetching SDK keeps only its latest frame) — and once
    they are all taken the last one stays. A name the frame lacks is refused as the SDK refuses it."""

    def __init__(self, frames, rate_hz: float | None = None, version: str | None = "1.11.0") -> None:
        self.frames, self.rate_hz, self.version = list(frames), rate_hz, version
        self.index = -1
        self.started: float | None = None
        self.connected = True
        self.calls = 0  # of GetFrame

    def GetFrame(self) -> bool:
        self.calls += 1
        if not self.connected:
            raise DataStreamException("NotConnected")
        self.started = self.started or time.monotonic()
        wanted = self.index + 1 if self.rate_hz is None else \
            int((time.monotonic() - self.started) * self.rate_hz)
        self.index = max(self.index, min(wanted, len(self.frames) - 1))
        return self.index >= 0

    def _frame(self) -> dict:
        if self.index < 0:
            raise DataStreamException("NoFrame")
        return self.frames[self.index]

    def GetFrameNumber(self) -> int:
        return self._frame()["GetFrameNumber"]

    def GetFrameRate(self) -> float:
        return self._frame()["GetFrameRate"]

    def GetLatencyTotal(self) -> float:
        return self._frame()["GetLatencyTotal"]

    def GetSubjectNames(self) -> list[str]:
        return [name for name, _ in self._frame()["subjects"]]

    def _segments(self, subject: str) -> list:
        found = next((segments for name, segments in self._frame()["subjects"] if name == subject), None)
        if found is None:
            raise DataStreamException("InvalidSubjectName")
        return found

    def GetSegmentNames(self, subject: str) -> list[str]:
        return [name for name, _ in self._segments(subject)]

    def GetSegmentGlobalTranslation(self, subject: str, segment: str):
        found = next((value for name, value in self._segments(subject) if name == segment), None)
        if found is None:
            raise DataStreamException("InvalidSegmentName")
        translation, occluded = found
        return tuple(translation), occluded

    def Disconnect(self) -> None:
        self.connected = False


def frame(number: int, subjects, latency_s: float = 0.008, rate_hz: float = 100.0) -> dict:
    """One frame as in ``vicon_frames.json``; ``subjects``: [(name, [(segment, (xyz, occluded))])]."""
    return {"GetFrameNumber": number, "GetFrameRate": rate_hz, "GetLatencyTotal": latency_s,
            "subjects": subjects}


def hand_at(number: int, xyz_mm, latency_s: float = 0.008) -> dict:
    """A frame with the subject "object" and, after it, "hand" at ``xyz_mm``."""
    return frame(number, [("object", [("object", ((100.0, 300.0, 130.0), False))]),
                          ("hand", [("hand", (tuple(xyz_mm), False))])], latency_s)


def to_tracker_mm(base_xyz) -> tuple[float, float, float]:
    """Robot base [m] → the tests' tracker frame [mm]."""
    return tuple(TRACKER.invert(np.asarray(base_xyz, dtype=float)).tolist())


def vicon_source(**update) -> ViconSource:
    """``[hand_source]`` reading the segment "hand" of the subject "hand", calibrated as TRACKER."""
    return ViconSource(**{
        "kind": "vicon", "vicon_server": SERVER, "vicon_subject": "hand", "vicon_segment": "hand",
        "rotation": tuple(map(tuple, TRACKER.rotation)), "translation": tuple(TRACKER.translation),
        "resolve_timeout_s": 1.0, **update})


def vicon_toml(subject: str = "hand") -> str:
    """The ``lab.toml`` lines of a Vicon source (identity calibration)."""
    return (f'[hand_source]\nkind = "vicon"\nvicon_server = "{SERVER}"\nvicon_subject = "{subject}"\n'
            'vicon_segment = "hand"\n')


class Result(enum.Enum):
    """``pyvicon_datastream.Result`` (the SDK's result codes), the members the source meets."""

    Success = 2
    ClientConnectionFailed = 6
    NotConnected = 9
    NoFrame = 10


class StreamMode(enum.Enum):
    ClientPull = 0
    ClientPullPreFetch = 1
    ServerPush = 2


def pyvicon_module(frames, connect_result: Result = Result.Success) -> types.ModuleType:
    """A ``pyvicon_datastream`` whose ``PyViconDatastream`` serves ``frames`` (as
    :class:`RecordedClient`, unpaced) with the 0.2.4 wrapper's shapes: results as ``Result``, counts
    and names as they are (a name None and a count None where the SDK refused), a translation as a
    numpy array, or None where the segment is occluded or the call failed. Its clients are kept in
    the module's ``clients`` with the calls they got."""
    module = types.ModuleType("pyvicon_datastream")
    module.Result, module.StreamMode, module.clients = Result, StreamMode, []

    class PyViconDatastream:
        def __init__(self) -> None:
            self.__version__ = "1.11.0"
            self.recorded = RecordedClient(frames)
            self.calls: list[tuple] = []
            module.clients.append(self)

        def connect(self, ip: str) -> Result:
            self.calls.append(("connect", ip))
            return connect_result

        def enable_segment_data(self) -> Result:
            self.calls.append(("enable_segment_data",))
            return Result.Success

        def set_stream_mode(self, mode: StreamMode) -> Result:
            self.calls.append(("set_stream_mode", mode))
            return Result.Success

        def get_frame(self) -> Result:
            if not self.recorded.connected:
                return Result.NotConnected
            return Result.Success if self.recorded.GetFrame() else Result.NoFrame

        def get_frame_number(self) -> int:
            return self.recorded.GetFrameNumber()

        def get_frame_rate(self) -> float:
            return self.recorded.GetFrameRate()

        def get_latency_total(self) -> float:
            return self.recorded.GetLatencyTotal()

        def get_subject_count(self) -> int:
            return len(self.recorded.GetSubjectNames())

        def get_subject_name(self, index: int) -> str | None:
            names = self.recorded.GetSubjectNames()
            return names[index] if index < len(names) else None

        def get_segment_count(self, name: str) -> int | None:
            try:
                return len(self.recorded.GetSegmentNames(name))
            except DataStreamException:
                return None

        def get_segment_name(self, name: str, index: int) -> str | None:
            try:
                return self.recorded.GetSegmentNames(name)[index]
            except (DataStreamException, IndexError):
                return None

        def get_segment_global_translation(self, subject_name: str, segment_name: str):
            try:
                translation, occluded = self.recorded.GetSegmentGlobalTranslation(subject_name,
                                                                                   segment_name)
            except DataStreamException:
                return None
            return None if occluded else np.array(translation)

        def disconnect(self) -> Result:
            self.recorded.Disconnect()
            return Result.Success

    module.PyViconDatastream = PyViconDatastream
    return module
