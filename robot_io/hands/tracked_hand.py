"""What the LSL, UDP, NatNet and Vicon hand sources share: a receiver thread, the frame transform,
dropouts, and trial-time stamps.

A receiver thread puts samples in (NatNet: the ``natnet`` client's own thread); the control loop
takes the newest with :meth:`TrackedHand.latest`. Each sample carries the ``time.monotonic()``
instant it was measured (LSL: the outlet's time stamp mapped to this machine's clock; UDP: the
arrival time, or the sender's when it sends one on this machine's monotonic clock; NatNet: the
arrival minus the latency the frame reports; Vicon: when the frame was seen minus the SDK's latency,
on the cameras' frame clock). ``latest(now)`` turns it into trial time, assuming the loop's clock
runs on ``time.monotonic`` as the real clock does:
t_trial = t_sample − (time.monotonic() − now).

Dropouts: an occluded marker (NaN, or exactly zero as Vicon sends it) becomes a NaN sample, which the
loop counts and ignores; no sample at all for ``staleness_limit_s`` makes the loop stop the arm.

Invalid samples are validated before they are kept, and each is one dropout, never the newest sample:
a non-finite time stamp (it would compare false with every later one and freeze the source), a
position farther than ``PLAUSIBLE_RANGE_M`` from the robot base (a tracker glitch or a wrong unit,
e.g. 1e308 mm), and a jump: a position farther from the last accepted one than ``[hand] max_speed``
allows in the time between them, plus ``TRACKER_JITTER_M`` (a marker swapped or mislabelled; a hand
cannot move so). They are counted in ``invalid`` (and in ``dropouts``), logged once, and the latest
is :attr:`TrackedHand.refusal`. A jump that persists is lost tracking: the loop sees no valid sample
and stops the arm after ``staleness_limit_s``, as for an occluded marker; once the new position is
as far as ``max_speed`` could have carried the hand, it is accepted (a hand that moved unseen).

The link itself: each source counts in :attr:`TrackedHand.link` (a :class:`Link`) the packets it
dropped as unreadable and the times its link to the tracker was lost and came back; :meth:`Link.notice`
says it in one line, which the rig process reports to the dashboard's Devices panel. Nothing received
for :data:`LINK_STALL_S`, after something was, is a lost link: the receiver thread then calls
:meth:`TrackedHand.reconnect` (what a source can do to heal it: its module docstring; UDP has nothing
to reconnect and waits) and tries again every ``LINK_STALL_S`` while nothing comes; the next sample
is the link back.
"""

from __future__ import annotations

import logging
import math
import threading
import time

import numpy as np

from robot_io.errors import HandSourceError
from robot_io.hands.frame import FrameTransform
from robot_io.hands.hand import HandSample
from robot_io.vector import all_finite, norm

log = logging.getLogger(__name__)

#: A hand position farther than this from the robot base in any axis is not a hand in the lab [m].
PLAUSIBLE_RANGE_M = 5.0
#: What a tracker's noise may add to the distance a hand can move between two samples [m].
TRACKER_JITTER_M = 0.01
#: Nothing received for this long, after something was, is a lost link [s]. Trackers stream at 30 Hz
#: or more; a live stream is never this silent.
LINK_STALL_S = 0.5
#: How long one try to connect again may wait for the tracker [s].
RECONNECT_TIMEOUT_S = 1.0
#: How long :meth:`TrackedHand.close` waits for the receiver to end [s]: its longest call is one try
#: to reconnect (RECONNECT_TIMEOUT_S) or one receive (≤ 0.1 s), with room for a loaded machine.
RECEIVER_JOIN_S = 4 * RECONNECT_TIMEOUT_S


class Link:
    """What a source's link to its tracker went through, in counts and one line of words:
    unreadable packets dropped, and outages (lost, then back after how long). Thread-safe."""

    def __init__(self, source: str, healing: str) -> None:
        self.source, self.healing = source, healing
        self._lock = threading.Lock()
        #: packets (frames, datagrams, samples) dropped because they could not be read
        self.malformed = 0
        #: times the link was lost
        self.outages = 0
        self.down_since: float | None = None  # time.monotonic() it was lost; None: up
        self.why: str | None = None  # why it was lost (the latest outage)
        self.last_outage_s: float | None = None  # how long the latest outage lasted [s]

    def dropped(self, what: str) -> None:
        """One packet that could not be read, dropped (logged the first time)."""
        with self._lock:
            self.malformed += 1
            first = self.malformed == 1
        if first:
            log.warning("%s: an unreadable packet was dropped (%s); further ones are counted",
                        self.source, what)

    def lost(self, why: str, since: float | None = None) -> None:
        """The link is down since ``since`` (``time.monotonic``: the last packet's arrival; None:
        now); once per outage, repeats while it is down change nothing."""
        with self._lock:
            if self.down_since is not None:
                return
            self.down_since, self.why = time.monotonic() if since is None else since, why
            self.outages += 1
        log.warning("%s: link lost (%s); %s", self.source, why, self.healing)

    def back(self) -> None:
        """The link is up again (nothing if it was not down)."""
        with self._lock:
            if self.down_since is None:
                return
            self.last_outage_s = time.monotonic() - self.down_since
            self.down_since = None
        log.warning("%s: link back after %.2f s", self.source, self.last_outage_s)

    @property
    def up(self) -> bool:
        return self.down_since is None

    def notice(self) -> str | None:
        """One line for the Devices panel; None while nothing happened."""
        with self._lock:
            parts = [f"{self.malformed} unreadable packet{'s' * (self.malformed != 1)} dropped"] \
                if self.malformed else []
            if self.down_since is not None:
                at = time.strftime("%H:%M:%S", time.localtime(time.time() - (time.monotonic()
                                                                              - self.down_since)))
                parts.append(f"link lost at {at} ({self.why}), {self.healing}")
            elif self.outages:
                parts.append(f"link lost {self.outages}× and back, the last time after "
                             f"{self.last_outage_s:.1f} s ({self.why})")
        return "; ".join(parts) or None


class TrackedHand:
    """Thread-safe newest sample of a tracked hand, in the robot base frame."""

    #: What the source does while its link is down, in the words of :meth:`Link.notice`.
    HEALING = "waiting for it"
    #: The tracker's protocol, as the devices' report names it ("NatNet", "LSL", …).
    PROTOCOL = ""

    def __init__(self, transform: FrameTransform, max_speed: float) -> None:
        self.transform, self.max_speed = transform, max_speed
        self._lock = threading.Lock()
        self._newest: tuple[float, np.ndarray] | None = None
        self.received = 0
        self.dropouts = 0
        #: samples refused: a non-finite time stamp, an implausible position or a jump (also dropouts)
        self.invalid = 0
        #: why the latest refused sample was refused (None: none was)
        self.refusal: str | None = None
        self._newest_valid_at: float | None = None
        self._accepted: tuple[float, np.ndarray] | None = None  # the newest valid sample
        self._thread: threading.Thread | None = None
        self._running = False
        self.link = Link(type(self).__name__, self.HEALING)
        self._arrived_at: float | None = None  # time.monotonic() the newest sample was put

    def put(self, measured_at: float, tracker_xyz) -> None:
        """One sample: ``measured_at`` on ``time.monotonic``, position in tracker units. An occluded
        or invalid sample is a dropout: a NaN position (the loop counts and ignores it); one whose
        own time stamp is not finite is stamped with its arrival."""
        raw = np.asarray(tracker_xyz, dtype=float)
        measured_at = float(measured_at)
        problem = None
        if not math.isfinite(measured_at):
            problem, measured_at = f"non-finite time stamp {measured_at}", time.monotonic()
        if problem or raw.shape != (3,) or not all_finite(raw) or not raw.any():
            position = np.full(3, np.nan)
        else:
            position = self.transform.apply(raw)
            if not (np.abs(position) <= PLAUSIBLE_RANGE_M).all():
                problem = problem or (f"implausible position {raw.tolist()} (tracker units), more "
                                      f"than {PLAUSIBLE_RANGE_M} m from the robot base")
                position = np.full(3, np.nan)
        with self._lock:
            if problem is None and not np.isnan(position[0]):
                problem = self._jump(measured_at, position)
                if problem is not None:
                    position = np.full(3, np.nan)
            if problem is not None:
                self.invalid += 1
                self.refusal = problem
                if self.invalid == 1:
                    log.warning("%s: sample refused as a dropout: %s", type(self).__name__, problem)
            if np.isnan(position[0]):
                self.dropouts += 1
            elif self._newest_valid_at is None or measured_at > self._newest_valid_at:
                self._newest_valid_at = measured_at
                self._accepted = (measured_at, position)
            if self._newest is None or measured_at >= self._newest[0]:
                self._newest = (measured_at, position)
            self.received += 1
            self._arrived_at = time.monotonic()
        if not self.link.up:
            self.link.back()

    def _jump(self, measured_at: float, position: np.ndarray) -> str | None:
        """Why ``position`` cannot be the hand, if it is farther from the newest accepted sample
        than ``max_speed`` · Δt + ``TRACKER_JITTER_M`` (None: it can be)."""
        if self._accepted is None:
            return None
        since = abs(measured_at - self._accepted[0])
        distance = norm(position - self._accepted[1])
        if distance <= self.max_speed * since + TRACKER_JITTER_M:
            return None
        return (f"a jump of {distance:.3f} m in {since:.3f} s from the last accepted sample "
                f"(faster than hand.max_speed = {self.max_speed:g} m/s)")

    def latest(self, now: float) -> HandSample | None:
        with self._lock:
            newest = self._newest
        if newest is None:
            return None
        return HandSample(newest[0] - (time.monotonic() - now), newest[1])

    def wait_for_sample(self, timeout: float, max_age_s: float) -> None:
        """Block until the newest valid sample is at most ``max_age_s`` old (start a trial only once
        the tracker is live: a first sample that arrives late, as LSL's first ~0.6 s do, is not)."""
        deadline = time.monotonic() + timeout
        while (age := self.valid_age()) is None or age > max_age_s:
            if time.monotonic() > deadline:
                got = "no valid sample" if age is None else f"the newest valid sample is {age:.3f} s old"
                raise HandSourceError(f"{type(self).__name__}: {got} after {timeout} s "
                                      f"(wanted one at most {max_age_s} s old)")
            time.sleep(0.005)

    def age(self) -> float | None:
        """Seconds since the newest sample was measured; None before the first."""
        with self._lock:
            return None if self._newest is None else time.monotonic() - self._newest[0]

    def valid_age(self) -> float | None:
        """Seconds since the newest sample with a position was measured; None before the first."""
        with self._lock:
            newest = self._newest_valid_at
        return None if newest is None else time.monotonic() - newest

    def describe(self) -> str:
        """Where the samples come from, in words (after :attr:`PROTOCOL` in the devices' report)."""
        raise NotImplementedError

    def detail(self) -> str:
        """What ``handover check-devices`` adds about this source (subclasses that know more)."""
        return ""

    # -- receiver thread -----------------------------------------------------------------------
    def start(self) -> None:
        self._running = True
        self._thread = threading.Thread(target=self._receive_loop, name=type(self).__name__,
                                        daemon=True)
        self._thread.start()

    def _receive_loop(self) -> None:
        while self._running:
            try:
                self.receive_once()
            except Exception:
                log.exception("%s: receiving failed; retrying", type(self).__name__)
                time.sleep(0.1)
            self._watch_link()

    def _watch_link(self) -> None:
        """Nothing received for LINK_STALL_S (after something was) is a lost link: one try to
        :meth:`reconnect`, the next LINK_STALL_S later if nothing comes meanwhile."""
        arrived = self._arrived_at
        if arrived is None or (silent := time.monotonic() - arrived) < LINK_STALL_S:
            return
        self.link.lost(f"nothing received for {silent:.1f} s", since=arrived)
        self.reconnect()
        with self._lock:
            assert self._arrived_at is not None, "set by put, never unset"
            self._arrived_at = max(self._arrived_at, time.monotonic())

    def reconnect(self) -> None:
        """One try to open the link to the tracker anew, waiting at most RECONNECT_TIMEOUT_S; never
        raises (subclasses that can; by default the source waits for the tracker to send again)."""

    def receive_once(self) -> None:
        """Block briefly (≤ 0.1 s) for samples and :meth:`put` them; subclasses implement it."""
        raise NotImplementedError

    def close(self) -> None:
        """Stop the receiver, then release what it alone used (:meth:`_release`: an LSL inlet, a
        socket, the Vicon client), in that order: a native handle released under a thread still in
        one of its calls can crash the process or, for a socket, read a reused file number. A
        receiver that has not ended within :data:`RECEIVER_JOIN_S` keeps its handle (said in the
        log): a leak until the rig process exits, never a release under a running call."""
        self._running = False
        thread = self._thread
        if thread is not None:
            thread.join(RECEIVER_JOIN_S)
            if thread.is_alive():
                log.error("%s: its receiver did not end within %g s; its link is left open until "
                          "the process exits", type(self).__name__, RECEIVER_JOIN_S)
                return
        self._release()

    def _release(self) -> None:
        """Release the handles only the receiver used (subclasses that have any)."""
