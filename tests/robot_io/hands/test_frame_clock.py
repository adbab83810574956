"""robot_io.hands.frame_clock: a tracker frame's camera time onto this machine's clock, by the least
delay of a recent window (the Vicon and the NatNet hand sources stamp their frames with it)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robot_io.hands.frame_clock import FrameClock


@given(rate=st.sampled_from([50.0, 100.0, 120.0, 250.0]), first=st.integers(0, 10**7),
       steps=st.lists(st.integers(1, 3), min_size=1, max_size=40),
       delays=st.lists(st.floats(0.0, 0.02), min_size=41, max_size=41))
def test_the_frame_clock_takes_off_the_least_delay_seen(rate, first, steps, delays):
    """Frames seen late by d_i after their camera time: within the window each is stamped at its
    camera time plus the least delay so far, never later than it was seen."""
    clock, origin = FrameClock(window_s=10.0), 1000.0  # all of them within the window
    numbers = [first, *(first + sum(steps[:i + 1]) for i in range(len(steps)))]
    for i, number in enumerate(numbers):
        camera = origin + (number - first) / rate
        stamp = clock.stamp(camera, camera + delays[i])
        assert stamp <= camera + delays[i]
        assert stamp - camera == pytest.approx(min(delays[:i + 1]), abs=1e-9)


def test_frames_seen_late_together_keep_the_cameras_spacing():
    """A stall, then the frames exposed meanwhile seen at once: each keeps its camera time plus
    the least delay seen before the stall."""
    clock = FrameClock(window_s=1.0)
    before = [clock.stamp(n / 100.0, 100.0 + n / 100.0 + 0.002) for n in range(50)]
    burst = [clock.stamp(n / 100.0, 100.0 + 0.7 + 0.001 * (n - 50)) for n in range(50, 70)]
    assert before[-1] == pytest.approx(100.0 + 0.49 + 0.002)
    assert burst == pytest.approx([100.0 + n / 100.0 + 0.002 for n in range(50, 70)])


def test_the_frame_clock_forgets_an_old_offset_and_starts_anew_on_a_new_stream():
    clock = FrameClock(window_s=1.0)
    assert clock.stamp(0.0, 5.0) == 5.0
    # 2 s on, every frame seen 3 ms late: the undelayed first frame has left the window
    stamps = [clock.stamp(n / 100.0, 5.0 + n / 100.0 + 0.003) for n in range(1, 201)]
    assert stamps[50] == pytest.approx(5.0 + 51 / 100.0)
    assert stamps[-1] == pytest.approx(5.0 + 2.0 + 0.003)
    assert clock.stamp(0.03, 9.0) == 9.0  # the camera time went back: a new stream
    assert clock.stamp(0.03, 9.5) == 9.5  # and one that stands still likewise
    clock.reset()
    assert clock.stamp(0.04, 9.7) == 9.7  # forgotten on request
