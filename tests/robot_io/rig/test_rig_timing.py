"""The rig's timing watch on its sample stream (robot_io.rig.timing): rows on time say nothing;
late cycles and old hand samples are reported with their figures, once per growth."""

from __future__ import annotations

import numpy as np

from robot_io.config import LoopConfig
from robot_io.control.recorder import SLICES
from robot_io.rig.stream import SampleStream, StreamRecorder
from robot_io.rig.timing import TimingWatch

LOOP = LoopConfig(rate_hz=125)


def write_rows(recorder: StreamRecorder, n: int, lateness: float, age: float) -> None:
    for _ in range(n):
        row = recorder.next_row()
        t = recorder.count / LOOP.rate_hz
        row[SLICES["t"]], row[SLICES["lateness_s"]], row[SLICES["hand_t"]] = t, lateness, t - age


def test_rows_on_time_say_nothing_and_old_hand_samples_are_reported():
    stream = SampleStream(200)
    try:
        watch = TimingWatch(LOOP, realtime_priority=True)
        recorder = StreamRecorder(stream, trial_index=4)
        write_rows(recorder, 50, lateness=0.001, age=0.02)  # the normal policy's jitter, a 50 Hz tracker
        assert watch.check(stream) is None
        write_rows(recorder, 20, lateness=0.001, age=0.07)  # the tracker's samples fall behind
        write_rows(recorder, 1, lateness=0.0, age=0.0)  # the row being written is not read
        timing = watch.check(stream)
        assert timing is not None and timing.trial_index == 4 and timing.late_cycles == 0
        assert np.isclose(timing.oldest_hand_sample_s, 0.07)
        assert watch.check(stream) is None  # nothing new: reported once
        assert timing.describe() == (
            "timing degraded in trial 4 so far: the hand samples it steered by were up to 70 ms old (the "
            "tracker counts as lost at 100 ms) — the machine is too busy even for the rig's "
            "real-time priority: close other programs")
    finally:
        stream.close(unlink=True)


def test_the_trials_end_reports_its_whole_figures_at_once_in_the_singular_where_one():
    """The terminal said the first report of a trial (3 cycles, 34 ms) and the dashboard its latest
    (11 cycles, 52 ms) (issue 45, item 16): the trial's end reports the figures of all its rows,
    without waiting REPORT_AGAIN_S, marked final; and one cycle is "1 control cycle"."""
    stream = SampleStream(200)
    try:
        watch = TimingWatch(LOOP, realtime_priority=False)
        recorder = StreamRecorder(stream, trial_index=7)
        write_rows(recorder, 20, lateness=0.001, age=0.02)
        write_rows(recorder, 1, lateness=0.034, age=0.02)
        write_rows(recorder, 1, lateness=0.0, age=0.02)  # being written: not read yet
        first = watch.check(stream)
        assert first is not None and (first.late_cycles, first.final) == (1, False)
        assert first.describe().startswith(
            "timing degraded in trial 7 so far: 1 control cycle started late, by up to 34 ms")
        write_rows(recorder, 1, lateness=0.052, age=0.02)  # the trial's last row
        assert watch.check(stream) is None  # within REPORT_AGAIN_S of the first report
        last = watch.check(stream, final=True)
        assert last is not None and (last.late_cycles, last.final) == (2, True)
        assert last.describe() == (
            "timing degraded in trial 7: 2 control cycles started late, by up to 52 ms (warned "
            "above 16 ms) — the rig runs without real-time priority: grant it (docs/hardware.md, "
            "\"Real-time priority\") or close other programs")
        clean = TimingWatch(LOOP, realtime_priority=False)
        assert clean.check(stream, final=True) is not None  # the whole trial, read at its end
    finally:
        stream.close(unlink=True)
