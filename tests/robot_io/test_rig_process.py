"""The rig process (robot_io.rig) with the mock arm and the simulated hand: a trial through real
messages and the shared-memory stream, and what happens when the rig dies or hangs."""

from __future__ import annotations

import os
import queue
import signal
import time

import numpy as np
import pytest

from robot_io.config import ControllerConfig
from robot_io.rig.client import RigClient
from robot_io.rig.messages import RigDied, RigSpec, RunTrial, StageReached, TrialDone
from robot_io.simulated_hand import Scenario
from robot_io.stages import Stage
from robot_io.theta import Theta

pytestmark = pytest.mark.slow


class Reports:
    def __init__(self) -> None:
        self.queue: queue.Queue = queue.Queue()

    def __call__(self, report) -> None:
        self.queue.put(report)

    def until(self, predicate, timeout: float = 30.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                report = self.queue.get(timeout=0.1)
            except queue.Empty:
                continue
            if predicate(report):
                return report
        raise AssertionError("the expected report never came")


def trial(index: int = 1) -> RunTrial:
    return RunTrial(trial_index=index, theta=Theta(a=5.0, delta=-0.2, k=5.0), hand_seed=7,
                    auto_loaded=True, auto_go=True)


def rig(realtime: bool, reports: Reports) -> RigClient:
    return RigClient(RigSpec(config=ControllerConfig(), scenario=Scenario.STRAIGHTFORWARD,
                             realtime=realtime), reports)


def test_a_trial_through_the_rig_process_streams_its_samples_through_shared_memory():
    reports = Reports()
    client = rig(realtime=False, reports=reports)
    try:
        assert client.devices.arm == "mock" and client.pid != os.getpid()
        client.run_trial(trial())
        done = reports.until(lambda r: isinstance(r, TrialDone))
        samples = client.stream.columns()
    finally:
        client.close()
    assert done.summary.outcome == "completed" and done.rows == done.summary.cycles
    assert len(samples["t"]) == done.rows
    np.testing.assert_allclose(np.diff(samples["t"]), 1 / 500)
    assert samples["stage"][-1] == 3 and np.nanmax(samples["pull"]) == pytest.approx(
        done.summary.peak_pull_n)


def test_a_rig_killed_mid_reach_is_reported_with_the_stage_and_its_samples_so_far_remain():
    reports = Reports()
    client = rig(realtime=True, reports=reports)
    try:
        client.run_trial(trial())
        reports.until(lambda r: isinstance(r, StageReached) and r.stage is Stage.REACH)
        time.sleep(0.3)
        os.kill(client.pid, signal.SIGKILL)
        died = reports.until(lambda r: isinstance(r, RigDied))
        samples = client.stream.columns()
    finally:
        client.close()
    assert died.trial_index == 1
    assert "killed by signal 9" in died.reason and "during reach" in died.reason
    assert 100 < len(samples["t"]) < 500  # about 0.3 s at 500 Hz, cut where the rig died


def test_a_rig_that_hangs_mid_reach_is_stopped_by_the_backstop_without_being_asked():
    reports = Reports()
    client = rig(realtime=True, reports=reports)
    try:
        client.run_trial(trial())
        reports.until(lambda r: isinstance(r, StageReached) and r.stage is Stage.REACH)
        os.kill(client.pid, signal.SIGSTOP)  # the loop freezes: no sample, no answer
        began = time.monotonic()
        died = reports.until(lambda r: isinstance(r, RigDied), timeout=5.0)
        took = time.monotonic() - began
    finally:
        client.close()
    assert "killed by signal 9" in died.reason and took < 2.0


def test_stop_reaches_a_hung_rig_through_the_backstop():
    reports = Reports()
    client = rig(realtime=True, reports=reports)
    try:
        client.run_trial(trial())
        reports.until(lambda r: isinstance(r, StageReached) and r.stage is Stage.GO)
        os.kill(client.pid, signal.SIGSTOP)
        acknowledged = client.stop("stopped by the experimenter (Stop)")
        alive = client.alive
    finally:
        client.close()
    assert not acknowledged and not alive
