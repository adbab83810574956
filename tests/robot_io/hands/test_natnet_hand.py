"""The NatNet hand source against a stand-in Motive over real UDP on loopback, with the real ``natnet``
client: the rigid body chosen by name, the frame transform, lost tracking as a dropout, the stamps,
staleness, ``handover check-devices`` and the ``[hand_source]`` fields it needs. Every server binds
a port of its own (port 0) on 127.0.0.1, and so does every client."""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest
from natnet import DataFrame, PacketBuffer, Version
from support.lab_file import assert_hand_source_refused, check_devices, hand_line
from support.natnet import HAND, OBJECT, TRACKER_M, motive, natnet_source, natnet_toml, to_tracker_m
from support.priority import realtime_threads
from support.waiting import wait_for

from robot_io.config import HandProfile, LoopConfig
from robot_io.errors import HandSourceError
from robot_io.hands.natnet_hand import RATE_BASELINE_S, NatNetHand, TickRate, reported_latency
from robot_io.hands.tracked_hand import TRACKER_JITTER_M
from robot_io.standins.natnet import (
    MOTIVE_OF,
    NAT_FRAMEOFDATA,
    PROTOCOL_VERSION,
    FrameStamps,
    RigidBodySpec,
    Snapshot,
    frame_of_data,
    hidden,
    pose_at,
)

pytestmark = pytest.mark.soak  # real sockets and threads on the clock: `make soak` repeats them

WANTED, OTHER = np.array([0.55, 0.05, 0.30]), np.array([0.40, -0.20, 0.45])  # robot base [m]
MAX_SPEED = HandProfile().max_speed


class Scene:
    """What the stand-in streams: the hand's pose (changed by the test) and the object's."""

    def __init__(self) -> None:
        self.hand = pose_at(to_tracker_m(WANTED))
        self.lock = threading.Lock()

    def poses(self):
        with self.lock:
            return {HAND.id: self.hand, OBJECT.id: pose_at(to_tracker_m(OTHER))}

    def set_hand(self, pose) -> None:
        with self.lock:
            self.hand = pose


def open_hand(server, rigid_body: str = HAND.name) -> NatNetHand:
    return NatNetHand(natnet_source(server, rigid_body), TRACKER_M, MAX_SPEED)


@contextmanager
def tracking(hand: NatNetHand) -> Iterator[NatNetHand]:
    """``hand`` once it has a tracked sample; closed when the block ends."""
    try:
        wait_for(lambda: hand.valid_age() is not None, "a tracked sample", seen=lambda: hand.received)
        yield hand
    finally:
        hand.close()


class StampRecordingHand(NatNetHand):
    """The real NatNet source, recording each sample's stamp with the instant it was put and the
    position it carried (tracker frame)."""

    def __init__(self, *args) -> None:
        #: (measured_at, put at, tracker xyz), instants on time.monotonic
        self.stamps: list[tuple[float, float, np.ndarray]] = []
        super().__init__(*args)

    def put(self, measured_at: float, tracker_xyz) -> None:
        self.stamps.append((measured_at, time.monotonic(), np.array(tracker_xyz, dtype=float)))
        super().put(measured_at, tracker_xyz)


@pytest.mark.parametrize("protocol", MOTIVE_OF, ids=lambda protocol: "NatNet {}.{}".format(*protocol))
def test_the_named_rigid_body_arrives_in_the_robot_base_frame_stamped_before_its_arrival(protocol):
    """At each protocol Motive streams: 3.1 (Motive 2.x), 4.0 (3.0) and 4.1 (3.1 and later)."""
    scene = Scene()
    with motive(scene.poses, protocol=protocol) as server:
        hand = StampRecordingHand(natnet_source(server), TRACKER_M, MAX_SPEED)
        try:
            wait_for(lambda: hand.latency_s is not None, "the latency the frames report",
                     seen=lambda: f"{hand.frames} frames")
        finally:
            hand.close()
    assert hand.body_id == HAND.id
    assert f"(NatNet {protocol[0]}.{protocol[1]}." in hand.server_detail
    # its data (float32 metres), not the object's, in the robot base frame
    assert hand.latest(0.0).position == pytest.approx(WANTED, abs=1e-6)
    # the latency each frame reports (mid-exposure to transmission, in host-clock ticks) is the
    # stand-in's, and the newest sample is stamped that much before it arrived (an order of
    # instants on one clock, not a duration measured)
    assert hand.latency_s == pytest.approx(server.latency_s, abs=1e-4)
    measured_at, put_at, _ = hand.stamps[-1]
    assert put_at - measured_at >= server.latency_s - 1e-4


class Swing:
    """A hand swinging along the robot's x at up to PEAK_SPEED (a reach's peak), measured the
    instant the stand-in takes it (a Snapshot: the frame's exposure is that instant)."""

    AMPLITUDE, PEAK_SPEED = 0.1, 1.5  # m, m/s

    def at(self, instant: float) -> np.ndarray:
        """Where the hand is at ``instant`` (time.monotonic), in the robot base [m]."""
        swing = self.AMPLITUDE * np.sin(self.PEAK_SPEED / self.AMPLITUDE * instant)
        return WANTED + np.array([swing, 0.0, 0.0])

    def poses(self) -> Snapshot:
        now = time.monotonic()
        return Snapshot({HAND.id: pose_at(to_tracker_m(self.at(now)))}, now)


#: How long the receiving thread is held in the test of a stalled receiver [s] (at the stand-in's
#: 120 Hz, 24 frames wait in the socket and then arrive together).
STALL_S = 0.2


def test_frames_delivered_late_together_keep_the_instants_they_were_measured():
    """A receiver that stalls (this process got no CPU, or the network held the packets) is then
    given every frame sent meanwhile at once. Stamped on their arrival, 0.2 s of a hand moving at
    1.5 m/s would land within a millisecond and be refused as jumps (as the rehearsal's NatNet hand
    was when two suites shared two cores); stamped from the frames' own clock each sample keeps the
    instant it was measured, and none is refused.

    Motive's sender and the receiver run under SCHED_FIFO, as a rig's do (Motive has a PC of its
    own): a stamp is only as good as the promptest frame of the last second (frame_clock.py). On
    the normal policy, beside a CPU hog and three other workers (`make soak`, 1 run in 10), three
    samples were refused, the first "a jump of 0.039 m in 0.000 s": at most 1.5 m/s, some 26 ms of
    the swing stamped as one instant, as when the least offset of the window drops by that much
    (every frame of a second seen late, then a prompt one)."""
    swing = Swing()
    with realtime_threads(), motive(swing.poses) as server:
        hand = StampRecordingHand(natnet_source(server), TRACKER_M, MAX_SPEED)
        stalled, resumed = threading.Event(), threading.Event()

        def stall(frame: DataFrame) -> None:  # the client's receiving thread, before the hand's
            if stalled.is_set():
                resumed.wait()

        hand.client.on_data_frame_received_event.handlers.insert(0, stall)
        try:
            wait_for(lambda: hand.latency_s is not None, "the latency the frames report",
                     seen=lambda: f"{hand.frames} frames")
            stalled.set()
            sent = server.frames_sent
            wait_for(lambda: server.frames_sent >= sent + round(STALL_S * server.rate_hz),
                     f"the frames of {STALL_S} s sent while the receiver stalls",
                     seen=lambda: f"{server.frames_sent - sent} sent")
            held, waiting = len(hand.stamps), server.frames_sent - sent
            stalled.clear()
            released = time.monotonic()
            resumed.set()
            wait_for(lambda: len(hand.stamps) >= held + waiting,
                     f"the {waiting} frames sent during the stall, received",
                     seen=lambda: f"{len(hand.stamps) - held} received")
        finally:
            hand.close()
    assert (hand.invalid, hand.refusal) == (0, None)
    assert hand.stamps[held][1] >= released, "the receiver was not held"
    # each sample's position is where the hand was at its stamp (within the tracker's jitter: a
    # stamp late by the least delay of loopback, at 1.5 m/s)
    for measured_at, _, xyz in hand.stamps:
        assert np.linalg.norm(xyz - to_tracker_m(swing.at(measured_at))) <= TRACKER_JITTER_M


def parsed(exposure: float, transmit: float, *, received: float | None = None) -> DataFrame:
    """A stand-in frame measured at ``exposure`` and sent at ``transmit`` [s], as the natnet
    client parses it."""
    packet = frame_of_data(1, {HAND.id: pose_at(to_tracker_m(WANTED))}, exposure,
                           FrameStamps(exposure, exposure if received is None else received, transmit))
    buffer = PacketBuffer(packet)
    assert buffer.read("<HH") == (NAT_FRAMEOFDATA, len(packet) - 4)
    return DataFrame.read_from_buffer(buffer, Version(*PROTOCOL_VERSION))


def test_the_reported_latency_needs_the_tick_rate_and_refuses_what_is_no_latency():
    """The tick rate is learned over RATE_BASELINE_S of frames; a latency that is negative or above
    half a second is none (the frame is stamped on arrival) and the rate is learned anew."""
    rate = TickRate()
    assert reported_latency(parsed(10.0, 10.004), rate) is None  # the rate is not known yet
    later = 10.0 + RATE_BASELINE_S
    assert reported_latency(parsed(later, later + 0.004), rate) == pytest.approx(0.004, abs=1e-6)
    assert reported_latency(parsed(later + 1, later + 3), rate) is None and rate.hz is None
    no_exposure = parsed(0.0, 0.010, received=0.006)
    assert no_exposure.suffix.stamp_camera_mid_exposure == 0 and no_exposure.suffix.stamp_data_received


def test_a_rigid_body_motive_lost_is_a_dropout_never_zero_nor_its_last_position():
    scene = Scene()
    with motive(scene.poses) as server, tracking(open_hand(server)) as hand:
        scene.set_hand(hidden())  # tracking-valid off; Motive's position is zeros then
        lost = wait_for(lambda: (s := hand.latest(0.0)) is not None and not s.is_valid() and s,
                        "a lost-hand sample", seen=lambda: hand.latest(0.0))
        dropouts = hand.dropouts
        scene.set_hand(pose_at(to_tracker_m(WANTED)))
        back = wait_for(lambda: (s := hand.latest(0.0)).is_valid() and s, "the hand seen again",
                        seen=lambda: hand.latest(0.0))
    assert np.all(np.isnan(lost.position)) and dropouts >= 1 and hand.invalid == 0
    assert back.position == pytest.approx(WANTED, abs=1e-6)


def test_a_rigid_body_left_out_of_the_frame_is_a_dropout():
    with motive(lambda: {OBJECT.id: pose_at(to_tracker_m(OTHER))}) as server:
        hand = open_hand(server)
        try:
            wait_for(lambda: hand.received >= 3, "three frames", seen=lambda: hand.received)
        finally:
            hand.close()
    assert hand.dropouts == hand.received and hand.valid_age() is None


@pytest.mark.parametrize(("bodies", "name", "problem"), [
    ((HAND, OBJECT), "left hand", "no rigid body is"),
    ((HAND, RigidBodySpec("hand", 8), OBJECT), "hand", "2 rigid bodies are"),
])
def test_a_missing_or_ambiguous_name_is_refused_naming_the_rigid_bodies_that_exist(bodies, name,
                                                                                     problem):
    with motive(dict, bodies) as server, pytest.raises(HandSourceError) as refused:
        open_hand(server, name)
    message = str(refused.value)
    assert f"hand_source.natnet_rigid_body = {name!r}: {problem} named so" in message
    listed = ", ".join(f"{body.name!r} (id {body.id})" for body in bodies)
    assert message.endswith(f"its rigid bodies: {listed}")


def test_a_server_that_stops_streaming_leaves_the_hand_stale():
    scene = Scene()
    limit = LoopConfig().staleness_limit_s
    with motive(scene.poses) as server:
        hand = open_hand(server)
        wait_for(lambda: hand.received > 0, "a sample before the stop", seen=lambda: hand.received)
    try:  # the server has closed: no frame comes any more, and the newest ages past the limit
        wait_for(lambda: hand.age() > limit, f"the newest sample older than {limit} s",
                 seen=hand.age)
        with pytest.raises(HandSourceError, match=r"newest valid sample is .* s old"):
            hand.wait_for_sample(0.2, limit)
    finally:
        hand.close()


def test_no_server_is_refused_in_plain_words():
    with motive(dict) as server:
        address = server.address  # a port that was bound and is free again: nothing answers there
    source = natnet_source(server).model_copy(update={"resolve_timeout_s": 0.3})
    with pytest.raises(HandSourceError, match=f"no NatNet server answered at {address[0]}:{address[1]}"):
        NatNetHand(source, TRACKER_M, MAX_SPEED)


def test_check_devices_reports_the_rigid_body_rate_and_latency(tmp_path, capsys):
    hand = pose_at((0.95, 0.10, 0.05))  # A, with the identity calibration of natnet_toml
    # Motive's sender and the check's receiver under SCHED_FIFO (Motive has a PC of its own): on the
    # normal policy a loaded run can starve them past the staleness limit (test_tracker_validation).
    with realtime_threads(), motive(lambda: {HAND.id: hand, OBJECT.id: pose_at((0.5, 0.0, 0.3))}) as server:
        code, out = check_devices(tmp_path, capsys, natnet_toml(server))
        refused, refused_out = check_devices(tmp_path, capsys, natnet_toml(server, "left hand"))
    line = hand_line(out)
    assert code == 0, out
    assert re.fullmatch(rf"hand: natnet, \d+ samples/s, newest \d+ ms old, 0 occluded; rigid body "
                        rf"'hand' \(id 7\) from Motive \(NatNet 3\.1\.0\.0\) at 127\.0\.0\.1:"
                        rf"{server.address[1]}, \d+ Hz, latency 4\.0 ms", line), line
    assert refused == 1
    assert ("hand: NOT OK — hand_source.natnet_rigid_body = 'left hand': no rigid body is named so"
            in refused_out and "its rigid bodies: 'hand' (id 7), 'object' (id 9)" in refused_out)


@pytest.mark.parametrize(("text", "message"), [
    ('kind = "natnet"\nnatnet_rigid_body = "hand"\nunits_to_m = 1.0\n',
     '[hand_source] natnet_server is not set; kind = "natnet" needs the Motive PC\'s address'),
    ('kind = "natnet"\nnatnet_server = "192.168.1.20"\nunits_to_m = 1.0\n',
     "[hand_source] natnet_rigid_body is not set"),
    ('kind = "natnet"\nnatnet_server = "192.168.1.20"\nnatnet_rigid_body = "hand"\nunits_to_m = 0.001\n',
     "hand_source.units_to_m = 0.001 but NatNet streams metres: set units_to_m = 1.0"),
    ('kind = "natnet"\nnatnet_command_port = 70000\n', "natnet_command_port"),
])
def test_an_incomplete_natnet_table_is_refused_naming_the_field(tmp_path, capsys, text, message):
    assert_hand_source_refused(tmp_path, capsys, text, message)


def test_a_truncated_frame_is_dropped_and_counted_and_the_frames_after_it_are_read(capfd):
    """Issue 38: one truncated frame raised struct.error in the natnet client's receiving thread,
    which ended; every later frame arrived unread and every later trial ended tracker_lost. And the
    natnet library printed a warning for it on stdout, one per bad frame (issue 45, item 18): it is
    counted with the others, and said once in the log."""
    scene = Scene()
    read: list[int] = []  # the numbers of the frames the client read, in order
    with motive(scene.poses) as server, tracking(open_hand(server)) as hand:
        hand.client.on_data_frame_received_event.handlers.append(
            lambda frame: read.append(frame.prefix.frame_number))
        wait_for(lambda: read, "a frame's number noted", seen=lambda: hand.received)
        server.send_truncated_frame()
        wait_for(lambda: server.truncated_sent == 1, "the truncated frame sent",
                 seen=lambda: server.frames_sent)
        cut_at = server.frames_sent
        wait_for(lambda: read and read[-1] >= cut_at + 60, "60 frames read after the truncated one",
                 seen=lambda: f"{len(read)} read, the last {read[-1:]}, of {server.frames_sent} sent; "
                              f"the link: {hand.link.notice()}")
    lost = sorted(set(range(read[0], read[-1] + 1)) - set(read))
    print(f"\nNatNet, one truncated frame: frames {lost} of {read[0]}–{read[-1]} not read; no outage")
    assert len(lost) == 1 and lost[0] <= cut_at
    assert (hand.link.malformed, hand.link.outages) == (1, 0)
    assert hand.link.notice() == "1 unreadable packet dropped"
    assert hand.latest(0.0).position == pytest.approx(WANTED, abs=1e-6)
    printed = capfd.readouterr()
    assert "Warning" not in printed.out + printed.err, printed


def test_motive_restarted_on_its_port_is_connected_again_and_the_rigid_body_resolved_anew():
    """Motive closed, then started again on the same port, forgets its clients and may number
    the rigid bodies anew: the watchdog notices the silence, connects again until Motive answers,
    asks for the model definitions, and the hand is tracked again under its new id."""
    scene = Scene()
    renumbered = RigidBodySpec(HAND.name, 11)
    with motive(scene.poses) as server:
        hand = StampRecordingHand(natnet_source(server), TRACKER_M, MAX_SPEED)
        wait_for(lambda: hand.valid_age() is not None, "a tracked sample", seen=lambda: hand.received)
    try:  # Motive is gone
        wait_for(lambda: not hand.link.up, "the link seen lost", seen=hand.link.notice)
        with motive(lambda: {renumbered.id: scene.poses()[HAND.id]}, (OBJECT, renumbered),
                    port=server.address[1]) as again:
            restarted = time.monotonic()
            wait_for(lambda: hand.link.up and hand.valid_age() is not None
                     and hand.stamps[-1][1] > restarted, "a tracked sample from Motive restarted",
                     seen=lambda: f"{again.frames_sent} sent to {again.clients}; the link: "
                                  f"{hand.link.notice()}")
            back = next(put_at for _, put_at, _ in hand.stamps if put_at > restarted)
    finally:
        hand.close()
    print(f"\nNatNet, Motive restarted: the link was down {hand.link.last_outage_s:.2f} s; tracked "
          f"again {back - restarted:.2f} s after Motive came back")
    assert hand.body_id == renumbered.id and hand.link.outages == 1
    assert hand.latest(0.0).position == pytest.approx(WANTED, abs=1e-6)
    assert re.fullmatch(r"link lost 1× and back, the last time after \d+\.\d s \(nothing received "
                        r"for 0\.\d s\)", hand.link.notice()), hand.link.notice()


@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")  # the fault made
def test_a_receiving_thread_that_ends_anyway_is_noticed_by_its_silence_and_the_client_made_anew():
    """Whatever else ends the natnet client's receiving thread (here an error raised on it, from a
    handler of its frame event, once) leaves every later frame unread: the watchdog sees the
    silence and makes the client anew."""
    scene, crashed = Scene(), threading.Event()

    def crash(frame: DataFrame) -> None:  # the client's receiving thread, before the hand's
        if not crashed.is_set():
            crashed.set()
            raise RuntimeError("the receiving thread ends here")

    with motive(scene.poses) as server, tracking(open_hand(server)) as hand:
        first = hand.client
        first.on_data_frame_received_event.handlers.insert(0, crash)
        wait_for(crashed.is_set, "the receiving thread ended", seen=lambda: hand.received)
        ended_at, received = time.monotonic(), hand.received
        wait_for(lambda: hand.client is not first and hand.received > received and hand.link.up,
                 "frames read by a new client",
                 seen=lambda: f"{hand.received - received} read; the link: {hand.link.notice()}")
        back_after = time.monotonic() - ended_at
    print(f"\nNatNet receiving thread ended: frames read again {back_after:.2f} s later "
          f"({round(back_after * server.rate_hz)} frames at {server.rate_hz:g} Hz lost)")
    assert hand.link.outages == 1 and hand.link.malformed == 0
