"""Which LSL stream the hand source reads when several are on the network: the one whose type (and
name) the configuration names, never "the first that answered"; with no name and two of the type,
none. Real outlets on this machine; every stream's type, name and source_id is unique to the test
(pid + uuid), so another test, suite or rehearsal publishing at the same time cannot answer."""

from __future__ import annotations

import os
import threading
import uuid
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pylsl
import pytest
from support.hand_replay import TRACKER, to_tracker
from support.waiting import wait_for

from robot_io.config import HandProfile
from robot_io.errors import HandSourceError
from robot_io.hands.config import LSLSource
from robot_io.hands.frame import FrameTransform
from robot_io.hands.lsl_hand import LSLHand, xpath_literal

pytestmark = pytest.mark.soak  # real processes and sockets on the clock: `make soak` repeats them

WANTED, OTHER = np.array([0.55, 0.05, 0.30]), np.array([0.40, -0.20, 0.45])  # robot base [m]


def unique(label: str) -> str:
    """A name no other test, process or suite uses."""
    return f"{label}-{os.getpid()}-{uuid.uuid4().hex[:12]}"


def transform() -> FrameTransform:
    return TRACKER  # the outlets push to_tracker(...) positions


MAX_SPEED = HandProfile().max_speed


def source(stream_type: str, name: str | None = None) -> LSLSource:
    return LSLSource(kind="lsl", lsl_stream_type=stream_type, lsl_stream_name=name, resolve_timeout_s=10.0)


@contextmanager
def outlets(stream_type: str, *names: str) -> Iterator[list[pylsl.StreamOutlet]]:
    """An outlet of ``stream_type`` per name, created in that order, each with a source_id of its
    own; yielded once every one of them answers a resolve (so each is on the network)."""
    made = []
    for name in names:
        source_id = unique("source")
        made.append(pylsl.StreamOutlet(pylsl.StreamInfo(name, stream_type, 3, 100.0,
                                                        pylsl.cf_double64, source_id)))
        wait_for(lambda source_id=source_id: pylsl.resolve_bypred(
                     f"source_id={xpath_literal(source_id)}", 1, 0.5),
                 f"the outlet {name!r} ({source_id}) to answer a resolve", timeout=30.0)
    try:
        yield made
    finally:
        made.clear()  # the outlets end with their last reference


def first_position(hand: LSLHand, pushing: dict[int, np.ndarray],
                   into: list[pylsl.StreamOutlet]) -> np.ndarray:
    """Push each outlet's own position (``pushing``: outlet index → robot-base position) until the
    hand has received a sample; the position it holds."""
    def pushed_and_received() -> bool:
        for index, position in pushing.items():
            into[index].push_sample(to_tracker(position).tolist())
        return hand.received > 0

    wait_for(pushed_and_received, "a sample through the hand's inlet", timeout=30.0,
             seen=lambda: f"received {hand.received}")
    return hand.latest(0.0).position


def test_the_named_stream_is_read_even_when_another_of_its_type_came_first():
    stream_type, wanted, other = unique("MocapTest"), unique("wanted"), unique("other")
    with outlets(stream_type, other, wanted) as (other_outlet, wanted_outlet):
        hand = LSLHand(source(stream_type, wanted), transform(), MAX_SPEED)
        try:
            position = first_position(hand, {0: OTHER, 1: WANTED}, [other_outlet, wanted_outlet])
        finally:
            hand.close()
    assert hand.name == wanted
    assert position == pytest.approx(WANTED, abs=1e-9)  # its data, not the other's


def test_the_named_stream_is_waited_for_while_another_of_its_type_answers(monkeypatch):
    """The tracker's bridge starts after the application, while another stream of the type is up:
    a resolve by type alone returned that one at once (and the name filter then left nothing)."""
    stream_type, wanted, other = unique("MocapTest"), unique("wanted"), unique("other")
    resolving = threading.Event()
    for function in ("resolve_bypred", "resolve_byprop"):  # a spy: pylsl's own resolve runs
        real = getattr(pylsl, function)
        monkeypatch.setattr(pylsl, function,
                            lambda *args, real=real, **kw: (resolving.set(), real(*args, **kw))[1])
    opened: list[LSLHand | BaseException] = []

    def open_hand() -> None:
        try:
            opened.append(LSLHand(source(stream_type, wanted), transform(), MAX_SPEED))
        except BaseException as exc:  # handed to the test thread
            opened.append(exc)

    with outlets(stream_type, other) as made:
        opener = threading.Thread(target=open_hand, daemon=True)
        opener.start()
        wait_for(resolving.is_set, "the hand source to start resolving")
        with outlets(stream_type, wanted) as (wanted_outlet,):
            wait_for(lambda: opened, "the hand source to open", seen=opener.is_alive)
            hand = opened[0]
            if isinstance(hand, BaseException):
                raise hand
            try:
                position = first_position(hand, {0: OTHER, 1: WANTED}, [*made, wanted_outlet])
            finally:
                hand.close()
    assert hand.name == wanted and position == pytest.approx(WANTED, abs=1e-9)


def test_a_name_with_both_quote_kinds_is_resolved_by_that_name():
    stream_type, name = unique("MocapTest"), unique("""Bob's "left" hand""")
    with outlets(stream_type, unique("other"), name) as made:
        hand = LSLHand(source(stream_type, name), transform(), MAX_SPEED)
        try:
            position = first_position(hand, {0: OTHER, 1: WANTED}, made)
        finally:
            hand.close()
    assert hand.name == name and position == pytest.approx(WANTED, abs=1e-9)


def test_without_a_name_two_streams_of_the_type_are_refused_and_listed():
    stream_type, first, second = unique("MocapTest"), unique("first"), unique("second")
    with outlets(stream_type, first, second), pytest.raises(HandSourceError) as refused:
        LSLHand(source(stream_type), transform(), MAX_SPEED)
    message = str(refused.value)
    assert f"2 streams answered as the LSL stream of type {stream_type!r}" in message
    assert repr(first) in message and repr(second) in message and "source_id" in message
    assert "set hand_source.lsl_stream_name" in message


def test_two_streams_of_the_same_name_and_type_are_refused():
    stream_type, name = unique("MocapTest"), unique("twice")
    with outlets(stream_type, name, name), pytest.raises(HandSourceError,
                                                        match=r"2 streams answered .* named"):
        LSLHand(source(stream_type, name), transform(), MAX_SPEED)


def test_without_a_name_the_one_stream_of_the_type_is_read():
    stream_type, name = unique("MocapTest"), unique("only")
    with outlets(stream_type, name) as made:
        hand = LSLHand(source(stream_type), transform(), MAX_SPEED)
        try:
            position = first_position(hand, {0: WANTED}, made)
        finally:
            hand.close()
    assert hand.name == name and position == pytest.approx(WANTED, abs=1e-9)


@pytest.mark.parametrize("value", ["plain", "it's", 'say "hi"', """both ' and " """])
def test_xpath_literal_spells_any_value(value):
    literal = xpath_literal(value)
    if literal.startswith("concat("):
        assert literal.count("\"'\"") == value.count("'")
    else:
        assert literal[0] == literal[-1] and literal[1:-1] == value and literal[0] not in value
