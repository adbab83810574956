"""UTC ↔ monotonic (robot_io.clock): the stored times of the rig's stages and the LSL markers' time
stamps go through it, so a thread preempted between two clock readings must not move them.

The preemption is made, not hoped for: robot_io.clock's ``time.monotonic`` is wrapped so that one of
its readings (any of the first ones, Hypothesis picks which) comes 20 ms late, as when the machine
gives the core away between two lines. Reading the two clocks once each put the mapping 20 ms off;
the tightest of several brackets keeps it within microseconds."""

from __future__ import annotations

import time
from types import SimpleNamespace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.clocks import utc_minus

from robot_io import clock

#: The preemption between two readings [s], and how far off a mapping may be despite it [s].
PREEMPTED_S, TOLERANCE_S = 0.02, 1e-3


def late_once(which: int):
    """``time.monotonic`` whose reading number ``which`` (0-based) is taken PREEMPTED_S late."""
    calls = iter(range(10**6))

    def monotonic() -> float:
        if next(calls) == which:
            time.sleep(PREEMPTED_S)
        return time.monotonic()
    return SimpleNamespace(monotonic=monotonic, time=time.time)


@settings(max_examples=12, deadline=None)
@given(which=st.integers(0, 3), back=st.floats(0.0, 3600.0))
def test_a_preempted_reading_does_not_move_the_mapping(which: int, back: float) -> None:
    offset = utc_minus(time.monotonic)
    moment = time.monotonic() - back
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(clock, "time", late_once(which))
        utc = clock.utc_of_monotonic(moment)
    assert abs(utc.timestamp() - (moment + offset)) < TOLERANCE_S
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(clock, "time", late_once(which))
        again = clock.monotonic_of_utc(utc)
    assert abs(again - moment) < TOLERANCE_S


def test_a_stored_time_maps_back_to_its_reading_within_microseconds() -> None:
    moment = time.monotonic() - 12.5
    stored = clock.utc_of_monotonic(moment).isoformat(timespec="microseconds")
    assert abs(clock.monotonic_of_utc(stored) - moment) < 1e-4
