"""robot_io.rig.silence: the silence a watcher judges is the time it ran for, whatever its lateness."""

from __future__ import annotations

import threading
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robot_io.rig.silence import WatchedSilence, waited

PERIOD = 0.05
#: how much later than asked each look came [s]: on time, jitter, or a machine held still for seconds
lateness = st.lists(st.one_of(st.just(0.0), st.floats(0.0, 0.01), st.floats(0.0, 5.0)), max_size=60)


def look_in_turn(silence: WatchedSilence, start: float, late: list[float]) -> float:
    """Each look asked for as the one before came back, ``late[i]`` later than due; the last return."""
    now = start
    for extra in late:
        asked, now = now, now + PERIOD + extra
        silence.looked(asked, now)
    return now


@given(late=lateness, start=st.floats(0.0, 1e6))
def test_the_watched_silence_is_the_time_of_the_looks_and_the_rest_is_unwatched(late, start):
    silence = WatchedSilence(PERIOD, start)
    now = look_in_turn(silence, start, late)
    assert silence.silent(now) == pytest.approx(now - start)
    assert silence.unwatched == pytest.approx(sum(late), abs=1e-6)
    # the watcher ran for one period per look: a limit is crossed after as many of its own looks as
    # if it had never been held still, so the stop it owes comes as soon as it could act
    assert silence.watched(now) == pytest.approx(len(late) * PERIOD, abs=1e-6)
    assert 0.0 <= silence.watched(now) <= silence.silent(now) + 1e-9


@given(before=lateness, after=lateness)
def test_a_sign_of_life_starts_the_silence_again(before, after):
    silence = WatchedSilence(PERIOD, 0.0)
    heard_at = look_in_turn(silence, 0.0, before)
    silence.heard(heard_at)
    now = look_in_turn(silence, heard_at, after)
    assert silence.unwatched == pytest.approx(sum(after), abs=1e-6)
    assert silence.watched(now) == pytest.approx(len(after) * PERIOD, abs=1e-6)


def test_a_look_that_came_early_counts_no_lateness():
    silence = WatchedSilence(PERIOD, 10.0)
    silence.looked(10.0, 10.0 + PERIOD / 2)  # a poll that a message ended early
    assert silence.unwatched == 0.0 and silence.watched(10.0 + PERIOD / 2) == pytest.approx(PERIOD / 2)


def test_a_wait_held_still_past_its_limit_still_waits_its_own_time():
    """``waited`` with looks that each come back a whole limit late (the machine held still): it
    does not give up after the first, but after as many looks as the limit holds."""
    looks: list[float] = []

    def late_look(look: float) -> bool:
        looks.append(look)
        time.sleep(look + 0.2)  # every look 0.2 s late: the first already passes the limit
        return False

    assert not waited(late_look, limit=0.1, look=0.02)
    # 0.1 s of its own waiting at 20 ms a look (the moments between looks count as its own too,
    # which a loaded machine may stretch): never the one look the clock alone would allow
    assert 3 <= len(looks) <= 5, looks


def test_a_wait_ends_as_soon_as_what_it_waits_for_has_come():
    came = threading.Event()
    threading.Timer(0.05, came.set).start()
    assert waited(came.wait, limit=5.0, look=0.5)
