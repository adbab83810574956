"""The rig's shared objects under open-and-close stress (docs/architecture.md, "Shared objects and
their lifetimes"): the sample stream in shared memory, the rig client with its reader and watchdog,
and the tracked hands' native handles. Each scenario runs in a child process (support.lifetimes), so
a crash of the interpreter fails the test with its signal; ``make soak`` runs each for 500 cycles
beside a CPU hog, the suite a few."""

from __future__ import annotations

from support.lifetimes import stress_marks, survive

from robot_io.rig.stream import SampleStream

pytestmark = stress_marks()


def test_a_released_stream_reads_as_empty_and_a_second_release_does_nothing():
    stream = SampleStream(10)
    stream._header[:3] = (4, 7, 1)
    assert stream.count == 4 and stream.trial_index == 7 and len(stream.rows_of(7, 0)) == 4
    stream.close(unlink=True)
    assert stream.released and stream.count == 0 and stream.trial_index == -1
    assert not stream.finished and len(stream.columns()["t"]) == 0 and len(stream.view()["t"]) == 0
    assert len(stream.rows_of(7, 0)) == 0
    stream.close(unlink=True)  # the block is gone: nothing to do, nothing raised


def test_reads_racing_the_streams_release_never_touch_freed_memory():
    """Three threads copy rows (a trial's end, the live view, the LSL feed) while the main thread
    releases the block. Before the stream's lock, a copy from the unmapped block was a segmentation
    fault within the first 200 cycles."""
    survive("stream", 60)


def test_a_rig_closed_or_killed_at_any_moment_hands_on_each_trials_end_with_its_rows():
    """Rig processes opened, a trial run, then closed or killed at a random moment while a screen
    reads the stream and the reader hands on the trial's end (a participant switch, a shutdown,
    the rig's death). Before the reader became the stream's second holder, close() unmapped the
    block under the reader's read of a trial's rows (the segmentation fault of serve's close).
    About 1 s a cycle (a rig process each)."""
    survive("rig", 5)


def test_hand_sources_closed_while_they_receive_release_their_handles_after_the_receiver():
    """LSL and UDP hand sources closed at a random moment of their receiving; a handle is released
    only once the receiver thread has ended."""
    survive("hands", 20)
