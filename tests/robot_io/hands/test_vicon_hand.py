"""The Vicon hand source without Vicon's SDK (it does not install here: docs/hardware.md, "Vicon
(DataStream SDK)"): the mapping of the SDK's frames onto samples against frames in its return shapes
(``tests/robot_io/data/vicon_frames.json``), the adapter of ``pyvicon-datastream`` against a module
with its wrapper's shapes, the frame clock, ``handover check-devices``, the missing extra and the
``[hand_source]`` fields it needs."""

from __future__ import annotations

import logging
import re
import sys
import time

import numpy as np
import pytest
from support.hand_replay import TRACKER
from support.lab_file import assert_hand_source_refused, check_devices, hand_line
from support.priority import realtime_threads
from support.vicon import (
    RECORDED,
    SERVER,
    RecordedClient,
    Result,
    StreamMode,
    frame,
    hand_at,
    pyvicon_module,
    vicon_source,
    vicon_toml,
)
from support.waiting import wait_for

from robot_io.config import ControllerConfig, HandProfile, LoopConfig
from robot_io.devices import open_hand
from robot_io.errors import HandSourceError
from robot_io.hands import vicon_hand
from robot_io.hands.vicon_hand import INSTALL, CameraFrameClock, ViconHand, read_frame
from robot_io.rig.devices import RigDevices
from robot_io.rig.messages import RigSpec

MAX_SPEED = HandProfile().max_speed
#: The hand's translation in each new frame of RECORDED (None: lost), and the latency each reports.
HAND_MM = [(250.0, -50.0, 280.0), (254.1, -49.2, 281.3), None, (258.0, -48.6, 282.4), None,
           (261.9, -48.0, 283.6)]
LATENCY_S = [0.0083, 0.0081, 0.0084, 0.0082, 0.0083, 0.0082]


class RecordingHand(ViconHand):
    """The real Vicon source, recording what it puts and when."""

    def __init__(self, *args, **kwargs) -> None:
        self.puts: list[tuple[float, float, np.ndarray]] = []  # (measured_at, put at, tracker mm)
        super().__init__(*args, **kwargs)

    def put(self, measured_at: float, tracker_xyz) -> None:
        self.puts.append((measured_at, time.monotonic(), np.asarray(tracker_xyz, dtype=float)))
        super().put(measured_at, tracker_xyz)


def opened(client: RecordedClient, hand_class=ViconHand, **update) -> ViconHand:
    connected = []

    def connect(host: str, port: int) -> RecordedClient:
        connected.append((host, port))
        return client

    hand = hand_class(vicon_source(**update), TRACKER, MAX_SPEED, connect=connect)
    assert connected == [(SERVER, 801)]
    return hand


def test_each_new_frame_is_one_sample_of_the_named_segment_in_the_robot_base_frame():
    """The subject "hand" although "object" streams first; millimetres through the calibration;
    an occluded segment and a subject absent from the frame are lost hands, never zeros; a frame
    that comes twice is one sample, a frame number skipped is counted; each sample is stamped at
    least the SDK's latency before it was put."""
    client = RecordedClient(RECORDED)
    hand = opened(client, RecordingHand)
    try:
        wait_for(lambda: client.index == len(RECORDED) - 1 and hand.frames == len(HAND_MM),
                 "every recorded frame read", seen=lambda: (client.index, hand.frames))
    finally:
        hand.close()
    puts = [xyz for _, _, xyz in hand.puts]
    assert len(puts) == len(HAND_MM)
    for put, expected in zip(puts, HAND_MM, strict=True):
        if expected is None:
            assert np.all(np.isnan(put))
        else:
            assert put == pytest.approx(expected)
    assert hand.latest(0.0).position == pytest.approx(TRACKER.apply(np.array(HAND_MM[-1])))
    assert (hand.dropouts, hand.invalid, hand.missed) == (2, 0, 1)
    for (measured_at, put_at, _), latency in zip(hand.puts, LATENCY_S, strict=True):
        assert put_at - measured_at >= latency - 1e-9
    assert not client.connected  # closed


@pytest.mark.parametrize(("translation", "occluded", "latency", "reading"), [
    ((250.0, -50.0, 280.0), False, 0.008, ((250.0, -50.0, 280.0), 0.008)),
    ((0.0, 0.0, 0.0), True, 0.008, (None, 0.008)),  # as the SDK reports an occluded segment
    ((250.0, -50.0, 280.0), True, 0.008, (None, 0.008)),  # occluded is lost whatever the numbers
    ((250.0, -50.0, 280.0), False, 0.0, ((250.0, -50.0, 280.0), None)),  # 0.0: no latency reported
    ((250.0, -50.0, 280.0), False, 0.7, ((250.0, -50.0, 280.0), None)),  # no latency of a tracker
])
def test_a_frame_is_read_as_the_sdk_reports_it(translation, occluded, latency, reading):
    client = RecordedClient([frame(7, [("hand", [("hand", (translation, occluded))])], latency)])
    assert client.GetFrame()
    got = read_frame(client, "hand", "hand")
    assert (got.position_mm, got.latency_s) == reading
    assert (got.frame_number, got.frame_rate_hz) == (7, 100.0)


HAND = ("hand", [("hand", ((250.0, -50.0, 280.0), False))])
OBJECT = ("object", [("object", ((100.0, 300.0, 130.0), False))])


@pytest.mark.parametrize(("subjects", "update", "message"), [
    ([OBJECT, HAND], {"vicon_subject": "left hand"},
     "hand_source.vicon_subject = 'left hand': no subject is named so in the Vicon DataStream at "
     "192.168.1.30:801; its subjects: 'object' (segments 'object'), 'hand' (segments 'hand')"),
    ([OBJECT, HAND], {"vicon_segment": "wrist"},
     "hand_source.vicon_segment = 'wrist': no segment is named so in subject 'hand' on the Vicon "
     "DataStream at 192.168.1.30:801; its subjects: 'object' (segments 'object'), 'hand' (segments "
     "'hand')"),
    ([HAND, OBJECT, HAND], {}, "hand_source.vicon_subject = 'hand': 2 subjects are named so"),
    ([("hand", [("hand", ((0.0, 0.0, 0.0), True)), ("hand", ((1.0, 2.0, 3.0), False))])], {},
     "hand_source.vicon_segment = 'hand': 2 segments are named so in subject 'hand'"),
])
def test_a_missing_or_ambiguous_name_is_refused_naming_what_the_stream_holds(subjects, update, message):
    client = RecordedClient([frame(1, subjects)])
    with pytest.raises(HandSourceError) as refused:
        opened(client, **update)
    assert message in str(refused.value)
    assert not client.connected


def test_a_server_that_sends_no_frame_is_refused_in_plain_words():
    client = RecordedClient([])
    with pytest.raises(HandSourceError, match=re.escape(
            f"the Vicon DataStream at {SERVER}:801 sent no frame within resolve_timeout_s = 0.05 s")):
        opened(client, resolve_timeout_s=0.05)
    assert not client.connected


def test_a_stream_that_stops_leaves_the_hand_stale():
    """The prefetching SDK keeps returning its latest frame: that is no new sample."""
    client = RecordedClient(RECORDED[:2])
    limit = LoopConfig().staleness_limit_s
    hand = opened(client)
    try:
        wait_for(lambda: hand.age() is not None and hand.age() > limit,
                 f"the newest sample older than {limit} s", seen=hand.age)
        with pytest.raises(HandSourceError, match=r"newest valid sample is .* s old"):
            hand.wait_for_sample(0.2, limit)
        assert client.calls > 10 and hand.frames == 2
    finally:
        hand.close()


def test_a_lost_connection_is_logged_once_and_the_source_closes(caplog):
    client = RecordedClient(RECORDED)
    hand = opened(client)
    try:
        wait_for(lambda: hand.frames == len(HAND_MM), "every recorded frame read",
                 seen=lambda: hand.frames)
        with caplog.at_level(logging.ERROR, logger="robot_io.hands.vicon_hand"):
            client.connected = False
            calls = client.calls
            wait_for(lambda: client.calls >= calls + 3, "three polls after the connection was lost",
                     seen=lambda: client.calls)
    finally:
        hand.close()
    assert [record.message for record in caplog.records] == [
        "Vicon hand source: reading a frame failed (logged once until one is read)"]


def test_the_camera_frame_clock_counts_frames_at_the_camera_rate_and_starts_anew_on_a_new_one():
    """Vicon's frames are numbers at a camera rate: camera time is number / rate (the least-delay
    offset is robot_io.hands.frame_clock's, tests/robot_io/hands/test_frame_clock.py); a new rate or a number
    that goes back starts anew, and a frame without a rate is stamped when seen."""
    clock = CameraFrameClock(window_s=1.0)
    assert clock.stamp_frame(100, 100.0, 5.0) == 5.0
    assert clock.stamp_frame(101, 100.0, 5.1) == pytest.approx(5.01)  # seen 90 ms late
    assert clock.stamp_frame(202, 200.0, 5.2) == 5.2  # another camera rate: anew
    assert clock.stamp_frame(203, 200.0, 5.3) == pytest.approx(5.205)
    assert clock.stamp_frame(3, 200.0, 9.0) == 9.0  # the number went back: a new stream
    assert clock.stamp_frame(4, 0.0, 9.5) == 9.5  # no camera rate: when seen
    assert clock.stamp_frame(5, 200.0, 9.6) == 9.6


def test_pyvicon_datastream_is_asked_for_prefetched_segments_and_adapted(monkeypatch):
    """Through open_hand, as the rig opens it: the SDK imported, connected to host:port, segments
    on, the prefetching mode; its None for an occluded segment is a lost hand."""
    module = pyvicon_module(RECORDED)
    monkeypatch.setitem(sys.modules, "pyvicon_datastream", module)
    hand = open_hand(ControllerConfig(hand_source=vicon_source()))
    try:
        wait_for(lambda: hand.frames == len(HAND_MM), "every recorded frame read",
                 seen=lambda: hand.frames)
        assert hand.describe() == (f"subject 'hand', segment 'hand' from {SERVER}:801 "
                                   "(DataStream SDK 1.11.0)")
    finally:
        hand.close()
    (client,) = module.clients
    assert client.calls == [("connect", f"{SERVER}:801"), ("enable_segment_data",),
                            ("set_stream_mode", StreamMode.ClientPullPreFetch)]
    assert (hand.dropouts, hand.invalid) == (2, 0)
    assert hand.latest(0.0).position == pytest.approx(TRACKER.apply(np.array(HAND_MM[-1])))
    assert not client.recorded.connected


def test_a_server_pyvicon_datastream_cannot_reach_is_refused_naming_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyvicon_datastream",
                        pyvicon_module(RECORDED, Result.ClientConnectionFailed))
    with pytest.raises(HandSourceError, match=re.escape(
            f"no Vicon DataStream server answered at {SERVER}:801 (ClientConnectionFailed)")):
        open_hand(ControllerConfig(hand_source=vicon_source()))


def test_without_the_extra_the_source_says_how_to_install_it(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pyvicon_datastream", None)  # its import fails, installed or not
    with pytest.raises(HandSourceError, match=re.escape(INSTALL)):
        open_hand(ControllerConfig(hand_source=vicon_source()))
    code, out = check_devices(tmp_path, capsys, vicon_toml())
    line = hand_line(out)
    assert code == 1
    assert line.startswith('hand: NOT OK — [hand_source] kind = "vicon" needs the Vicon DataStream '
                           "SDK, which is not installed") and line.endswith(
        "pip install 'handover-lab[vicon]' (docs/hardware.md, \"Vicon (DataStream SDK)\")"), line


def test_check_devices_reports_the_segment_the_rates_and_the_latency(tmp_path, monkeypatch, capsys):
    a_mm = (950.0, 100.0, 50.0)  # A, with the identity calibration of vicon_toml
    stream = [hand_at(1000 + n, a_mm) for n in range(400)]
    monkeypatch.setattr(vicon_hand, "connect_sdk", lambda host, port: RecordedClient(stream, 100.0))
    with realtime_threads():  # the receiver under SCHED_FIFO, as in test_natnet_hand's check
        code, out = check_devices(tmp_path, capsys, vicon_toml())
        refused, refused_out = check_devices(tmp_path, capsys, vicon_toml("left hand"))
    line = hand_line(out)
    assert code == 0, out
    assert re.fullmatch(rf"hand: vicon, \d+ samples/s, newest \d+ ms old, 0 occluded; subject 'hand', "
                        rf"segment 'hand' from {SERVER}:801 \(DataStream SDK 1\.11\.0\), \d+ Hz, "
                        r"cameras at 100 Hz, latency 8\.0 ms(, \d+ frames missed)?", line), line
    # (frames missed: the replay, as the prefetching SDK, keeps only the latest frame for a late poll)
    assert refused == 1
    assert ("hand: NOT OK — hand_source.vicon_subject = 'left hand': no subject is named so in the "
            f"Vicon DataStream at {SERVER}:801; its subjects: 'object' (segments 'object'), 'hand' "
            "(segments 'hand')" in refused_out), refused_out


@pytest.mark.parametrize(("text", "message"), [
    ('kind = "vicon"\nvicon_subject = "hand"\nvicon_segment = "hand"\n',
     '[hand_source] vicon_server is not set; kind = "vicon" needs the address of the PC running '
     "Vicon Tracker, Nexus or Shogun"),
    ('kind = "vicon"\nvicon_server = "192.168.1.30"\nvicon_segment = "hand"\n',
     "[hand_source] vicon_subject is not set"),
    ('kind = "vicon"\nvicon_server = "192.168.1.30"\nvicon_subject = "hand"\n',
     "[hand_source] vicon_segment is not set"),
    ('kind = "vicon"\nvicon_server = "192.168.1.30"\nvicon_subject = "hand"\nvicon_segment = "hand"\n'
     "units_to_m = 1.0\n",
     "hand_source.units_to_m = 1 but the Vicon DataStream reports millimetres: set units_to_m = 0.001"),
    ('kind = "vicon"\nvicon_port = 70000\n', "vicon_port"),
])
def test_an_incomplete_vicon_table_is_refused_naming_the_field(tmp_path, capsys, text, message):
    assert_hand_source_refused(tmp_path, capsys, text, message)


def test_the_rig_opens_the_vicon_source_and_reports_it(monkeypatch):
    monkeypatch.setattr(vicon_hand, "connect_sdk", lambda host, port: RecordedClient(RECORDED))
    devices = RigDevices(RigSpec(config=ControllerConfig(hand_source=vicon_source())))
    try:
        report = devices.report()
        assert isinstance(devices.for_trial(0).hand, ViconHand)
    finally:
        devices.close()
    assert (report.hand_source, report.hand_detail) == (
        "vicon", f"Vicon subject 'hand', segment 'hand' from {SERVER}:801 (DataStream SDK 1.11.0)")


def stream_mm(first: int, count: int) -> list[dict]:
    """``count`` frames from number ``first``, the hand still at HAND_MM[0]."""
    return [hand_at(first + n, HAND_MM[0]) for n in range(count)]


def test_a_frame_that_cannot_be_read_is_dropped_and_counted_and_the_next_one_is_read(caplog):
    """A frame whose translation is no number (the SDK's reply garbled): it cost a logged
    traceback and 0.1 s without polling; now it is one frame dropped."""
    bad = frame(3, [("hand", [("hand", ((None, 0.0, 0.0), False))])])
    client = RecordedClient([*stream_mm(1, 2), bad, *stream_mm(4, 3)])
    with caplog.at_level(logging.WARNING, logger="robot_io"):
        hand = opened(client)
        try:
            wait_for(lambda: hand.frames == 5, "every readable frame read",
                     seen=lambda: f"{hand.frames} read; the link: {hand.link.notice()}")
        finally:
            hand.close()
    print(f"\nVicon, one unreadable frame among 6: {6 - hand.frames} lost, {hand.missed} missed")
    assert (hand.link.malformed, hand.missed) == (1, 0)
    assert [(r.levelname, r.exc_info) for r in caplog.records] == [("WARNING", None)]


def test_a_vicon_server_that_goes_away_and_comes_back_is_connected_again():
    """The SDK reports the connection lost (Tracker closed); while the server is away a connection
    is refused; once it is back, the source connects anew, resolves the names and reads on."""
    server = {"up": True}
    clients: list[RecordedClient] = []
    stream = stream_mm(1, 6000)  # a minute at 100 Hz (the server's stream starts anew each time)

    def connect(host: str, port: int) -> RecordedClient:
        if not server["up"]:
            raise HandSourceError(f"no Vicon DataStream server answered at {host}:{port}")
        clients.append(RecordedClient(stream, 100.0))
        return clients[-1]

    hand = ViconHand(vicon_source(), TRACKER, MAX_SPEED, connect=connect)
    try:
        wait_for(lambda: hand.frames >= 3, "three frames", seen=lambda: hand.frames)
        server["up"], clients[0].connected = False, False  # Tracker closed
        wait_for(lambda: not hand.link.up, "the link seen lost", seen=hand.link.notice)
        frames, came_back = hand.frames, time.monotonic()
        server["up"] = True
        wait_for(lambda: hand.frames > frames and hand.link.up, "frames from the server back",
                 seen=lambda: f"{len(clients)} connections, {hand.frames - frames} frames; the link: "
                              f"{hand.link.notice()}")
        read_again_after = time.monotonic() - came_back
    finally:
        hand.close()
    print(f"\nVicon server gone and back: read again {read_again_after:.2f} s after it came back "
          f"(down {hand.link.last_outage_s:.2f} s in all)")
    assert len(clients) == 2 and hand.link.outages == 1 and not clients[0].connected
    assert hand.latest(0.0).position == pytest.approx(TRACKER.apply(np.array(HAND_MM[0])), abs=1e-9)
